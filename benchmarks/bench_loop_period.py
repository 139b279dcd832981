"""The wrist's 50 Hz loop under link floods and a CPU hog: period p50/p99/max and overruns.

The real tool (``articutool tool``, simulated wrist, leveling, paired: mutual TLS on one
loopback port, plain TCP on another) runs as its own process(es). A CPU hog (one process
spinning, pinned to the last CPU) runs for the whole benchmark. For each flood level ``k``
in ``--levels`` (default 0, 1, 2, 4) a fresh tool is started, heard by a paired watcher,
left to settle, and then ``k`` flooder processes (``tests/link_flooder.py --mode unsigned``,
what any local process can send: set_mode, cancel, send_goal, clear_fault and get_result
claiming to be the paired PC) each send ``--rate`` requests/s (default 2 000) to the plain
port for ``--seconds`` (default 600). Level 0 is the control: the hog alone.

The loop's figures are the tool's own (its health telemetry, ``LoopStats``): periods are
wake-to-wake intervals of the loop thread on ``CLOCK_MONOTONIC`` (wall time), percentiles
from a 0.1 ms histogram, ``overruns`` ticks that ended after the next deadline, and
``periods_over_2x`` periods of 40 ms or longer (to the 0.1 ms bin). Percentiles and the
maximum cover the tool's whole run (the flood is all of it but the settle seconds), counters
the flood alone. Beside them: the load average (1 min, sampled every 5 s), the CPU time of
each tool process (user + system, from ``/proc``; a process's CPU time is not disturbed by
the other sessions on a shared machine, wall time is), the hypervisor's steal time, whether
the loop ran at real-time priority, and what the flooders achieved.

A control runs beside the tool during each flood: one Python thread at the tool's priority
doing nothing but sleep to 20 ms deadlines, sampling the steal time each period. Its late
periods and the steal bursts (20 ms or more of steal within one period), with their wall
times, say what the machine itself took; each period over 40 ms of the tool's is timed (to
the 0.5 s poll of its telemetry) and counted as coinciding when the control was late or a
steal burst came within 1 s of it. Writes JSON::

    .venv/bin/python benchmarks/bench_loop_period.py --out results/loop_period.json
    .venv/bin/python benchmarks/bench_loop_period.py --short   # one 2x level for 4 s

``--without-cap-sys-nice`` runs the tool as a process without ``CAP_SYS_NICE`` would run
(``setpriv --bounding-set -sys_nice``; Linux): what an unprivileged user gets on a Pi.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from articutool.link.client import ArticutoolClient
from articutool.link.config import load_config
from articutool.link.pairing import pair
from paired_tool import ROOT, free_port

FLOODER = ROOT / "tests" / "link_flooder.py"
ENV = dict(os.environ, PYTHONPATH=str(ROOT / "src"), PYTHONUNBUFFERED="1")
_TICKS_PER_S = os.sysconf("SC_CLK_TCK")
_HOG = ("import os, sys; os.sched_setaffinity(0, {int(sys.argv[1])}); print('READY', "
        "flush=True)\nwhile True: pass")
# The control: the least a loop can be, one Python thread at the tool's priority sleeping to
# 20 ms deadlines, beside the tool. What it misses, the machine took (it also samples the
# hypervisor's steal time each period). Prints JSON when its stdin closes.
_PROBE = r"""
import json, os, sys, threading, time
rt = sys.argv[1] == "1"
if rt:
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(50))
    except OSError:
        rt = False
T = os.sysconf("SC_CLK_TCK")
def steal():
    return int(open("/proc/stat").readline().split()[8]) / T
stop = threading.Event()
threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
print("READY", flush=True)
n = over = 0
worst = 0.0
events, bursts = [], []
t = last = time.monotonic()
s0 = steal()
while not stop.is_set():
    t += 0.02
    d = t - time.monotonic()
    if d > 0:
        time.sleep(d)
    now = time.monotonic()
    s = steal()
    period, stolen = now - last, s - s0
    n += 1
    worst = max(worst, period)
    if period >= 0.04:
        over += 1
    if period > 0.03:
        events.append([round(time.time(), 2), round(period * 1e3, 1), round(stolen * 1e3, 1)])
    if stolen >= 0.02:
        bursts.append([round(time.time(), 2), round(stolen * 1e3, 1)])
    last, s0 = now, s
    if now - t > 0.02:
        t = now
print(json.dumps({"realtime": rt, "periods": n, "period_max_ms": round(worst * 1e3, 1),
                  "periods_over_2x": over, "late_periods": events[:200],
                  "steal_bursts_over_20ms": bursts[:200], "steal_bursts": len(bursts)}))
"""


def _cpu_s(pid: int) -> float:
    """User + system CPU seconds of ``pid`` (NaN once it is gone)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / _TICKS_PER_S


def _steal_s() -> float:
    """CPU time the hypervisor gave to others while this (virtual) machine wanted it, all CPUs
    (``steal`` in ``/proc/stat``): nothing inside the machine, real-time priority included,
    runs then."""
    fields = Path("/proc/stat").read_text().splitlines()[0].split()
    return int(fields[8]) / _TICKS_PER_S if len(fields) > 8 else float("nan")


def _tree(pid: int) -> list[int]:
    """``pid`` and its descendants (the tool's link process)."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        for task in Path(f"/proc/{p}/task").glob("*"):
            with contextlib.suppress(OSError):
                todo += [int(c) for c in (task / "children").read_text().split()]
    return out


def _comm(pid: int) -> str:
    try:
        return " ".join(Path(f"/proc/{pid}/cmdline").read_text().split("\0")[1:4])
    except OSError:
        return "?"


def _health(client: ArticutoolClient) -> dict[str, float]:
    st = client.latest_state()
    if st is None:
        return {}
    out = {"loop_overruns": float(st.loop_overruns), "loop_period_mean": st.loop_period_mean,
           "loop_jitter": st.loop_jitter}
    out.update({k: v for k, v in st.extra.items()
                if k.startswith(("link_", "loop_", "tick_"))})
    return out


def _flooder(port: int, rate: float, seconds: float) -> subprocess.Popen[str]:
    proc = subprocess.Popen(
        [sys.executable, str(FLOODER), "--connect", f"tcp/127.0.0.1:{port}", "--mode",
         "unsigned", "--rate", str(rate), "--seconds", str(seconds)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=ENV)
    assert proc.stdout is not None
    if proc.stdout.readline().strip() != "READY":
        raise SystemExit("a flooder did not start")
    return proc


def _stop_flooder(proc: subprocess.Popen[str]) -> tuple[int, float]:
    out, _ = proc.communicate(input="", timeout=60)
    line = next((ln.split() for ln in out.splitlines() if ln.startswith("SENT")), None)
    return (int(line[1]), float(line[2])) if line else (0, 0.0)


def run_level(k: int, a: argparse.Namespace, folder: Path) -> dict[str, Any]:
    """One fresh tool, ``a.settle`` s quiet, then ``k`` flooders for ``a.seconds`` s."""
    tls, plain = free_port(), free_port()
    log = folder / f"tool-{k}x.log"
    prefix = ["setpriv", "--bounding-set", "-sys_nice"] if a.without_cap_sys_nice else []
    cmd = [*prefix, sys.executable, "-m", "articutool", "tool", "--level", "--link-config",
           str(folder / "wrist-1" / "link.toml"), "--listen", f"tls/127.0.0.1:{tls}",
           "--listen", f"tcp/127.0.0.1:{plain}",
           "--duration", str(a.settle + a.seconds + 120)]
    with log.open("w") as out:
        tool = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=out,
                                stderr=subprocess.STDOUT, env=ENV)
    cfg = load_config(folder / "pc-1" / "link.toml").replace(
        connect=(f"tls/127.0.0.1:{tls}",), listen=())
    watcher = ArticutoolClient(cfg)
    res: dict[str, Any] = {"flooders": k}
    floods: list[subprocess.Popen[str]] = []
    try:
        if not watcher.wait_for_tool(60.0):
            raise SystemExit(f"tool not heard within 60 s; see {log}")
        time.sleep(a.settle)
        pids = _tree(tool.pid)
        res["tool_processes"] = {str(p): _comm(p) for p in pids}
        h0 = _health(watcher)
        cpu0 = {p: _cpu_s(p) for p in pids}
        steal0 = _steal_s()
        probe = subprocess.Popen(
            [*prefix, sys.executable, "-c", _PROBE, "0" if a.without_cap_sys_nice else "1"],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        assert probe.stdout is not None and probe.stdout.readline().strip() == "READY"
        floods = [_flooder(plain, a.rate, a.seconds + 60) for _ in range(k)]
        t0 = time.monotonic()
        load: list[float] = []
        spikes: list[float] = []  # wall times at which the tool's count over 40 ms grew
        seen, next_load = h0.get("loop_periods_over_2x", 0.0), t0
        while time.monotonic() - t0 < a.seconds:
            time.sleep(0.5)
            now = _health(watcher).get("loop_periods_over_2x", seen)
            spikes += [round(time.time(), 1)] * int(now - seen)
            seen = now
            if time.monotonic() >= next_load:
                load.append(os.getloadavg()[0])
                next_load += 5.0
        sent = [_stop_flooder(f) for f in floods]
        floods = []
        control = json.loads(probe.communicate(input="", timeout=30)[0])
        elapsed = time.monotonic() - t0
        cpu1 = {p: _cpu_s(p) for p in pids}
        steal = _steal_s() - steal0
        time.sleep(1.5)  # the last health message after the flood
        h1 = _health(watcher)
        period = 1.0 / 50.0
        res.update({
            "seconds": round(elapsed, 1),
            "sent_per_flooder": [s for s, _ in sent],
            "requests_per_s_achieved": round(sum(s for s, _ in sent) / elapsed, 1),
            "loop_realtime": h1.get("loop_realtime"),
            "period_p50_ms": 1e3 * h1["loop_period_p50"],
            "period_p99_ms": 1e3 * h1["loop_period_p99"],
            "period_max_ms": 1e3 * h1["loop_period_max"],
            "period_mean_ms": 1e3 * h1["loop_period_mean"],
            "jitter_ms": 1e3 * h1["loop_jitter"],
            "periods": int(h1["loop_period_count"]),
            "overruns": int(h1["loop_overruns"] - h0["loop_overruns"]),
            "periods_over_2x": int(h1["loop_periods_over_2x"] - h0["loop_periods_over_2x"]),
            "periods_over_2x_whole_run": int(h1["loop_periods_over_2x"]),
            "goal_met": bool(h1["loop_period_max"] <= 2 * period
                             and h1["loop_periods_over_2x"] == 0),
            "tick_compute_max_ms": 1e3 * h1.get("tick_compute_max_s", float("nan")),
            "cpu_s_per_process": {str(p): round(cpu1[p] - cpu0[p], 2) for p in pids},
            "steal_s_all_cpus": round(steal, 2),
            "load_avg_1min": {"min": min(load, default=None), "max": max(load, default=None),
                              "mean": round(sum(load) / len(load), 2) if load else None},
            "link_counters_delta": {key: h1.get(key, 0) - h0.get(key, 0) for key in h1
                                    if key.startswith("link_")},
            "tool_spikes_at": spikes,
            "control": control,
            "tool_spikes_with_the_control_late_or_steal_within_1s": sum(
                any(abs(t - e[0]) <= 1.0 for e in control["late_periods"]
                    + control["steal_bursts_over_20ms"]) for t in spikes),
        })
    finally:
        for f in floods:
            f.kill()
        watcher.close()
        if tool.poll() is None:
            tool.send_signal(signal.SIGTERM)  # SIGINT is ignored in a background job
        try:
            tool.wait(timeout=30)
        except subprocess.TimeoutExpired:
            tool.kill()
            tool.wait()
        text = log.read_text(errors="replace")
        res["tool_exit_code"] = tool.returncode
        res["tool_stopped_cleanly"] = "stopped: motors stopped, torque off" in text
        res["tool_tracebacks"] = text.count("Traceback")
    return res


def main(argv: list[str] | None = None) -> int:
    """Run the levels; print and optionally write the JSON."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--levels", type=int, nargs="+", default=[0, 1, 2, 4],
                   help="flooder processes per level (default 0 1 2 4)")
    p.add_argument("--rate", type=float, default=2000.0, help="requests/s per flooder")
    p.add_argument("--seconds", type=float, default=600.0, help="flood length per level (s)")
    p.add_argument("--settle", type=float, default=3.0, help="quiet seconds before a flood")
    p.add_argument("--no-hog", action="store_true", help="without the CPU hog")
    p.add_argument("--without-cap-sys-nice", action="store_true",
                   help="run the tool without CAP_SYS_NICE (setpriv), as an unprivileged "
                        "user on a Pi: no real-time priority, no negative nice")
    p.add_argument("--short", action="store_true",
                   help="one 2x level for 4 s after 1 s quiet (for a test)")
    p.add_argument("--out", default=None, help="write the JSON here too")
    a = p.parse_args(argv)
    if a.short:
        a.levels, a.seconds, a.settle = [2], 4.0, 1.0
    cpus = sorted(os.sched_getaffinity(0))
    folder = Path(tempfile.mkdtemp(prefix="articutool-loop-"))
    pair(folder, "wrist-1", ["pc-1"])
    hog = None
    if not a.no_hog:
        hog = subprocess.Popen([sys.executable, "-c", _HOG, str(cpus[-1])],
                               stdout=subprocess.PIPE, text=True)
        assert hog.stdout is not None and hog.stdout.readline().strip() == "READY"
    result: dict[str, Any] = {
        "command": "python benchmarks/bench_loop_period.py " + " ".join(
            argv if argv is not None else sys.argv[1:]),
        "clock": "loop periods: CLOCK_MONOTONIC (wall) in the tool's loop thread; CPU: "
                 "user+system of each process",
        "machine": platform.machine(), "cpus": os.cpu_count(),
        "python": platform.python_version(), "rate_per_flooder": a.rate,
        "flood_seconds": a.seconds, "hog_cpu": None if hog is None else cpus[-1],
        "tool_without_cap_sys_nice": a.without_cap_sys_nice,
        "load_avg_at_start": list(os.getloadavg()), "levels": []}
    try:
        for k in a.levels:
            result["levels"].append(run_level(k, a, folder))
            print(json.dumps(result["levels"][-1]), file=sys.stderr, flush=True)
    finally:
        if hog is not None:
            hog.kill()
            hog.wait()
    result["load_avg_at_end"] = list(os.getloadavg())
    result["tool_logs"] = str(folder)
    text = json.dumps(result, indent=1)
    print(text)
    if a.out:
        Path(a.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
