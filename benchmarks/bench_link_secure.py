"""What pairing costs: service round trips plain vs. mutual TLS + signatures.

Runs the fake tool (tests/link_fake_tool.py) in its own process twice, side by side in one
invocation: unpaired on plain loopback TCP, and paired (``articutool pair``: mutual TLS and
signed commands verified by the tool); measures ``set_orientation_control`` round trips from
a client in this process, and the per-message signing and verification cost in-process::

    .venv/bin/python benchmarks/bench_link_secure.py --calls 500 --out results/link_secure.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path
from typing import Any

import numpy as np

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.auth import Signer, Verifier
from articutool.link.client import ArticutoolClient
from articutool.link.config import LinkConfig, load_config
from articutool.link.pairing import pair
from articutool.link.transport import Names

ROOT = Path(__file__).resolve().parent.parent


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _rtt(cfg: LinkConfig, tool_args: list[str], calls: int) -> dict[str, Any]:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    tool = subprocess.Popen([sys.executable, str(ROOT / "tests" / "link_fake_tool.py"),
                             *tool_args], stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                            text=True, env=env)
    client = ArticutoolClient(cfg)
    try:
        t0 = time.monotonic()
        if not client.wait_for_tool(30.0):
            raise SystemExit("tool not heard within 30 s")
        first_heard = time.monotonic() - t0
        for _ in range(20):
            client.set_mode("disabled")
            time.sleep(0.01)
        rtt = []
        for _ in range(calls):  # 100 calls/s: below the tool's per-endpoint rate limit
            t = time.perf_counter()
            ok, msg = client.set_mode("disabled")
            rtt.append(time.perf_counter() - t)
            assert ok, msg
            time.sleep(max(0.0, 0.01 - (time.perf_counter() - t)))
        a = np.array(rtt) * 1e3
        return {"calls": calls, "rtt_ms_median": round(float(np.median(a)), 3),
                "rtt_ms_p99": round(float(np.percentile(a, 99)), 3),
                "rtt_ms_max": round(float(a.max()), 3),
                "first_heard_s": round(first_heard, 2)}
    finally:
        client.close()
        tool.communicate(input="", timeout=15)


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print and optionally write the JSON figures."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--calls", type=int, default=500)
    p.add_argument("--out", default=None)
    a = p.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="articutool-secure-"))
    pair(tmp, "wrist-1", ["pc-1"])
    out: dict[str, Any] = {"command": "python benchmarks/bench_link_secure.py " +
                           " ".join(argv if argv is not None else sys.argv[1:]),
                           "machine": platform.machine(), "cpus": os.cpu_count(),
                           "python": platform.python_version()}
    port = _free_port()
    plain = LinkConfig(connect=(f"tcp/127.0.0.1:{port}",), listen=(), tool_id="wrist-1")
    out["plain_tcp"] = _rtt(plain, ["--listen", f"tcp/127.0.0.1:{port}", "--tool-id",
                                    "wrist-1"], a.calls)
    port = _free_port()
    paired = load_config(tmp / "pc-1" / "link.toml").replace(
        connect=(f"tls/127.0.0.1:{port}",), listen=())
    out["paired_mtls_signed"] = _rtt(paired, [
        "--link-config", str(tmp / "wrist-1" / "link.toml"), "--listen",
        f"tls/127.0.0.1:{port}"], a.calls)
    signer = Signer(tmp / "pc-1" / "cert.pem", tmp / "pc-1" / "key.pem")
    verifier = Verifier(tmp / "ca" / "ca.pem")
    ep = Names(tool_id="wrist-1").send_goal
    payload = cdr.encode(m.send_goal_request(uuid.uuid4().bytes, "TWIRL_CW", [1.0, 2.0]),
                       ep.request_type)
    n = 2000
    t = time.perf_counter()
    atts = [signer.attachment(ep.name, payload) for _ in range(n)]
    sign_us = (time.perf_counter() - t) / n * 1e6
    t = time.perf_counter()
    for att in atts:
        verifier.verify(ep.name, payload, att)
    verify_us = (time.perf_counter() - t) / n * 1e6
    t = time.perf_counter()
    for _ in range(n):
        cdr.decode(payload, ep.request_type)
    decode_us = (time.perf_counter() - t) / n * 1e6
    out["per_message_us"] = {"sign": round(sign_us, 1), "verify": round(verify_us, 1),
                             "decode_send_goal": round(decode_us, 1),
                             "attachment_bytes": len(atts[0])}
    text = json.dumps(out, indent=1)
    print(text)
    if a.out:
        Path(a.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
