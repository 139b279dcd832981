"""Stops under a flood: how many of a PC's stops the real tool accepts, and
how long each takes, while other processes flood it.

The tool is ``articutool tool --no-level`` (simulated wrist, the real 50 Hz runtime) in its
own process. Paired scenarios: the tool is paired with pc-1 and pc-2, listens on loopback
TLS and also on plain loopback TCP (what any local process reaches); pc-1, over TLS, sends
``--stops`` ``mode disabled`` one after another (``--gap`` s apart) while flooders, each its
own process (``tests/link_flooder.py``), send at ``--rate`` requests/s:

- ``quiet``: no flood (the control);
- ``unsigned``: set_mode/cancel/send_goal/clear_fault/get_result claiming to be pc-1, on
  plain TCP;
- ``forged``: the same with pc-1's real certificate and random signatures (the tool checks
  every signature: the most CPU per message an outsider can cost it);
- ``replay``: one captured signed stop of pc-1, over and over;
- ``paired_pc2``: pc-2 (paired, over TLS) floods the same commands, signed;
- ``all``: all four floods at once (the worst).

Unpaired scenario ``unpaired_cancels``: the tool unpaired on loopback (the simulation
default), a flood of cancels (all goals and random ids), a client's ``mode disabled``.

A stop is *accepted* when the call returns ``success=true``; its latency is the call's round
trip (the tool runs it at its next tick, every 20 ms). Loop overruns and link counters are
the tool's health telemetry, before and after. Writes JSON::

    .venv/bin/python benchmarks/bench_link_stops.py --out results/link_stops.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.auth import Signer
from articutool.link.client import ArticutoolClient, LinkError
from articutool.link.config import LinkConfig
from articutool.link.transport import Names, key_expr
from articutool.tool.api import Mode
from bench_link_flood import _health
from paired_tool import ROOT, free_port, start_paired_tool

FLOODER = ROOT / "tests" / "link_flooder.py"
ENV = dict(os.environ, PYTHONPATH=str(ROOT / "src"))


def _flooder(*args: str) -> subprocess.Popen[str]:
    proc = subprocess.Popen([sys.executable, str(FLOODER), *args], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, env=ENV)
    assert proc.stdout is not None
    if proc.stdout.readline().strip() != "READY":
        raise SystemExit(f"flooder {args} did not start")
    return proc


def _stop_flooder(proc: subprocess.Popen[str]) -> tuple[int, float]:
    """Stop it: (requests sent, seconds it flooded)."""
    out, _ = proc.communicate(input="", timeout=30)
    line = next((ln.split() for ln in out.splitlines() if ln.startswith("SENT")), None)
    return (int(line[1]), float(line[2])) if line else (0, 0.0)


def _stops(client: ArticutoolClient, n: int, gap: float) -> dict[str, Any]:
    """``n`` stops, one after another: accepted count, latencies, the refusals' texts."""
    lat, refusals = [], []
    for _ in range(n):
        t0 = time.perf_counter()
        try:
            ok, msg = client.set_mode("disabled")
        except LinkError as err:
            ok, msg = False, str(err)
        dt = time.perf_counter() - t0
        if ok:
            lat.append(dt)
        else:
            refusals.append(msg)
        time.sleep(gap)
    a = np.array(lat) * 1e3 if lat else np.array([np.nan])
    return {"sent": n, "accepted": len(lat), "refused": len(refusals),
            "refusal_examples": sorted(set(refusals))[:3],
            "latency_ms": {"median": round(float(np.median(a)), 2),
                           "p95": round(float(np.percentile(a, 95)), 2),
                           "max": round(float(a.max()), 2)}}


def _measure(tool: subprocess.Popen[Any], client: ArticutoolClient,
             start_floods: Callable[[], list[subprocess.Popen[str]]],
             a: argparse.Namespace) -> dict[str, Any]:
    """With the tool heard: start the floods, send the stops, read the tool's health; then
    stop the floods, the client and the tool."""
    floods: list[subprocess.Popen[str]] = []
    try:
        if not client.wait_for_tool(30.0):
            raise SystemExit("tool process not heard within 30 s")
        time.sleep(1.0)
        floods = start_floods()
        time.sleep(a.settle)  # the flood is on
        h0 = _health(client)
        t0 = time.monotonic()
        res = _stops(client, a.stops, a.gap)
        elapsed = time.monotonic() - t0
        time.sleep(0.3)  # a last health message
        h1 = _health(client)
        sent = [_stop_flooder(f) for f in floods]
    finally:
        for f in floods:
            if f.returncode is None:
                f.kill()
        client.close()
        tool.terminate()
        tool.wait(timeout=20)
    res["stops_seconds"] = round(elapsed, 2)
    res["flood_requests_sent"] = [n for n, _ in sent]
    res["flood_requests_per_s"] = round(sum(n / s for n, s in sent if s > 0), 1)
    res["loop_overruns"] = h1.get("loop_overruns", 0) - h0.get("loop_overruns", 0)
    res["loop_period_max_s_cumulative"] = h1.get("loop_period_max")
    res["link_counters_delta"] = {k: h1.get(k, 0) - h0.get(k, 0) for k in h1
                                  if k.startswith("link_") and h1.get(k, 0) != h0.get(k, 0)}
    return res


def paired_scenario(kind: str, a: argparse.Namespace) -> dict[str, Any]:
    """One paired tool process, the ``kind`` of flood, pc-1's stops."""
    q = free_port()
    started = start_paired_tool("articutool-stops-", plain_port=q, pcs=("pc-1", "pc-2"))
    folder, cfg = started.folder, started.pc_config
    plain, rate = f"tcp/127.0.0.1:{q}", str(a.rate)

    def start_floods() -> list[subprocess.Popen[str]]:
        kinds = ("unsigned", "forged", "replay", "paired_pc2") if kind == "all" else (
            () if kind == "quiet" else (kind,))
        floods = []
        for k in kinds:
            args = ["--mode", k, "--rate", rate]
            if k == "forged":
                args += ["--cert", str(folder / "pc-1" / "cert.pem")]
            elif k == "replay":
                soc = Names(tool_id="wrist-1").set_orientation_control
                payload = cdr.encode(m.soc_request(Mode.DISABLED, 0.0, 0.0), soc.request_type)
                att = Signer(folder / "pc-1" / "cert.pem", folder / "pc-1" / "key.pem") \
                    .attachment(soc.name, payload)
                cap = folder / "capture.json"
                cap.write_text(json.dumps({"key": key_expr(0, soc), "payload": payload.hex(),
                                           "attachment": att.hex()}))
                args += ["--capture", str(cap)]
            elif k == "paired_pc2":  # over mutual TLS, signed as pc-2
                args = ["--mode", "signed", "--rate", rate, "--link-config",
                        str(folder / "pc-2" / "link.toml")]
            floods.append(_flooder("--connect", cfg.connect[0] if k == "paired_pc2" else plain,
                                   *args))
        return floods
    return _measure(started.proc, ArticutoolClient(cfg), start_floods, a)


def unpaired_scenario(a: argparse.Namespace) -> dict[str, Any]:
    """The unpaired (loopback) tool, a flood of cancels, a client's stops."""
    ep = f"tcp/127.0.0.1:{free_port()}"
    tool = subprocess.Popen([sys.executable, "-m", "articutool", "tool", "--no-level",
                             "--tool-id", "wrist-1", "--listen", ep],
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, env=ENV)
    client = ArticutoolClient(LinkConfig(connect=(ep,), listen=(), tool_id="wrist-1"),
                              sender="caregiver")
    return _measure(tool, client, lambda: [
        _flooder("--connect", ep, "--mode", "cancels", "--rate", str(a.rate))], a)


SCENARIOS = ("quiet", "unsigned", "forged", "replay", "paired_pc2", "all", "unpaired_cancels")


def main(argv: list[str] | None = None) -> int:
    """Run the scenarios; print and optionally write the JSON figures."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--stops", type=int, default=50, help="stops per scenario")
    p.add_argument("--gap", type=float, default=0.05, help="seconds between stops")
    p.add_argument("--rate", type=float, default=2000.0, help="requests/s per flooder")
    p.add_argument("--settle", type=float, default=1.0, help="flood seconds before the stops")
    p.add_argument("--only", choices=SCENARIOS, action="append", default=None)
    p.add_argument("--out", default=None, help="write the JSON here too")
    a = p.parse_args(argv)
    result: dict[str, Any] = {
        "command": "python benchmarks/bench_link_stops.py " +
                   " ".join(argv if argv is not None else sys.argv[1:]),
        "machine": platform.machine(), "cpus": os.cpu_count(),
        "python": platform.python_version(), "load_average_at_start": os.getloadavg(),
        "stops": a.stops, "gap_s": a.gap, "rate_per_flooder": a.rate,
        "tool_max_rate_hz": LinkConfig().max_rate_hz, "scenarios": {}}
    for s in a.only or SCENARIOS:
        result["scenarios"][s] = unpaired_scenario(a) if s == "unpaired_cancels" else \
            paired_scenario(s, a)
        print(s, json.dumps(result["scenarios"][s]), file=sys.stderr, flush=True)
    text = json.dumps(result, indent=1)
    print(text)
    if a.out:
        Path(a.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
