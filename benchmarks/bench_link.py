"""Link benchmark: service round-trip latency and 50 Hz state-stream loss over loopback.

Runs the fake tool (tests/link_fake_tool.py) as a separate process serving over Zenoh and a
client in this process, then writes JSON::

    .venv/bin/python benchmarks/bench_link.py --duration 180 --calls 2000 --out link.json

Latency: ``set_orientation_control`` round trips (request → tool → reply), median and p99.
Loss: joint_states received by the client vs. published by the tool (the tool's publish
counter travels in the health diagnostics as ``link_ticks``) over ``--duration`` seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from articutool.link.client import ArticutoolClient
from articutool.link.config import LinkConfig

ROOT = Path(__file__).resolve().parent.parent


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print and optionally write the JSON figures."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=180.0, help="stream-loss window (s)")
    p.add_argument("--calls", type=int, default=2000, help="service round trips")
    p.add_argument("--out", default=None, help="write the JSON here too")
    a = p.parse_args(argv)
    port = _free_port()
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    tool = subprocess.Popen([sys.executable, str(ROOT / "tests" / "link_fake_tool.py"),
                             "--listen", f"tcp/127.0.0.1:{port}"], stdin=subprocess.PIPE,
                            stdout=subprocess.DEVNULL, text=True, env=env)
    cfg = LinkConfig(connect=(f"tcp/127.0.0.1:{port}",), listen=())
    client = ArticutoolClient(cfg)
    try:
        if not client.wait_for_tool(20.0):
            raise SystemExit("tool process not heard within 20 s")
        for _ in range(20):  # warm-up
            client.set_mode("disabled")
            time.sleep(0.01)
        rtt = []
        for i in range(a.calls):  # 100 calls/s: below the tool's per-endpoint rate limit
            t0 = time.perf_counter()
            ok, _ = client.set_mode("leveling" if i % 2 else "disabled")
            rtt.append(time.perf_counter() - t0)
            assert ok
            time.sleep(max(0.0, 0.01 - (time.perf_counter() - t0)))
        client.set_mode("disabled")

        def ticks() -> tuple[float, int]:
            st = client.latest_state()
            assert st is not None
            return st.extra["link_ticks"], client.counters["joint_states"]

        time.sleep(0.5)
        t_start, r_start = ticks()
        time.sleep(a.duration)
        t_end, r_end = ticks()
        published, received = int(t_end - t_start), int(r_end - r_start)
        ms = np.asarray(rtt) * 1e3
        out = {
            "transport": "zenoh peer-to-peer, tcp loopback, two processes",
            "host": f"{platform.machine()} {platform.system()} py{platform.python_version()}",
            "service_round_trip_ms": {"calls": a.calls, "median": float(np.median(ms)),
                                      "p99": float(np.percentile(ms, 99)),
                                      "max": float(ms.max())},
            "state_stream": {"duration_s": a.duration, "published": published,
                             "received": received,
                             "rate_hz": published / a.duration,
                             "loss_fraction": max(0.0, 1 - received / max(published, 1))},
            "client_decode_errors": client.counters["decode_errors"],
        }
    finally:
        client.close()
        tool.communicate(input="", timeout=10)
    text = json.dumps(out, indent=1)
    print(text)
    if a.out:
        Path(a.out).write_text(text + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
