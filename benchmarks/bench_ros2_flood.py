"""Every call answered under a flood of bad calls at the ROS 2 door: counts, round trips and
the node's memory.

Four processes: the real tool (``articutool tool --no-level``, simulated wrist, paired,
loopback TLS), ``articutool ros2`` (host-only) forwarding to it, a flooder
(``tests/ros2_flooder.py``: a plain rclpy node sending ``--rate`` bad calls per second for
``--seconds`` s, round robin over mode 7, a 500° offset, NaN, unknown primitives, cancels of
unknown goals, calibration and empty verifications, with ``--depth``-deep client queues) and
this process as a plain rclpy client that, while the flood runs, sends a burst of ``--burst``
cancels of unknown goals at once and ``--stops`` calls of ``/articutool/stop``; once the flood
stops it times the next call (DISABLED on ``/articutool/set_orientation_control``).

A call counts as answered when its reply arrives within ``--deadline`` s of its send (the
flood's own calls: by the end of ``--grace`` s after it stops). Round trips are wall clock
(``time.perf_counter``); the node's CPU is its ``/proc`` user + system time; memory is its
resident set (``VmRSS``) before the flood, at its peak (sampled every 0.2 s), and
``--settle`` s after the flood. Writes JSON::

    .venv/bin/python benchmarks/bench_ros2_flood.py --out results/ros2_flood.json
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).parent))
from bench_ros2_stops import (  # noqa: E402
    FLOODER,
    Client,
    _cpu_s,
    start_graph,
    stop_all,
    write_result,
)
from paired_tool import rss_mb  # noqa: E402


class _Peak:
    """The peak of ``rss_mb(pid)`` sampled every ``period`` s until :meth:`stop`."""

    def __init__(self, pid: int, period: float = 0.2) -> None:
        self.peak = rss_mb(pid)
        self._stop = threading.Event()

        def run() -> None:
            while not self._stop.wait(period):
                self.peak = max(self.peak, rss_mb(pid))
        self._thread = threading.Thread(target=run, daemon=True)
        self._thread.start()

    def stop(self) -> float:
        self._stop.set()
        self._thread.join()
        return round(self.peak, 1)


def flood(args: argparse.Namespace, env: dict[str, str], node_pid: int) -> dict[str, Any]:
    """One flood with the burst, the stops and the next call; the node's figures."""
    client = Client(int(env["ROS_DOMAIN_ID"]))
    soc = client.SOC
    try:
        before = client.calls(client.soc, lambda: soc.Request(control_mode=0), 1, 0.0,
                              args.deadline)
        rss0, cpu0 = rss_mb(node_pid), _cpu_s(node_pid)
        flooder = subprocess.Popen(
            [sys.executable, str(FLOODER), "--rate", str(args.rate), "--seconds",
             str(args.seconds), "--depth", str(args.depth), "--grace", str(args.grace),
             "--kinds", args.kinds, "--stats"], env=env, text=True, stdin=subprocess.PIPE,
            stdout=subprocess.PIPE)
        assert flooder.stdout is not None
        assert flooder.stdout.readline().strip() == "READY", "flooder did not start"
        t0 = time.monotonic()
        peak = _Peak(node_pid)
        client.spin_until(lambda: False, min(1.0, args.seconds / 4))
        burst = client.burst(args.burst, args.deadline)
        stops = client.calls(client.stop, client.Trigger.Request, args.stops,
                             max(0.0, (args.seconds - (time.monotonic() - t0)) / 2
                                 / max(1, args.stops)), args.deadline)
        client.spin_until(lambda: False, max(0.0, t0 + args.seconds - time.monotonic()))
        after = client.calls(client.soc, lambda: soc.Request(control_mode=0), 1, 0.0,
                             args.deadline)
        text, _ = flooder.communicate(input="", timeout=args.seconds + args.grace + 120)
        cpu = _cpu_s(node_pid) - cpu0
        rss_peak = peak.stop()
        client.spin_until(lambda: False, args.settle)
        rss_settled = rss_mb(node_pid)
    finally:
        client.close()
    stats = next((json.loads(line[6:]) for line in text.splitlines()
                  if line.startswith("STATS ")), {})
    return {"flood": stats, "cancel_burst": burst, "stop_service": stops,
            "next_call_before_flood": before, "next_call_after_flood": after,
            "node_cpu_s_during": round(cpu, 2),
            "node_rss_mb": {"before": round(rss0, 1), "peak": rss_peak,
                            f"after_{args.settle:g}_s": round(rss_settled, 1)},
            "loadavg_end": os.getloadavg()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--depth", type=int, default=1000,
                    help="the flooder's client queue depth (10 is rclpy's default: a client "
                         "that slow loses replies in its own queue, docs/ros2.md)")
    ap.add_argument("--kinds", default="mode,offset,nan,goal,cancel,calibration,verify",
                    help="the flooder's kinds of bad call (tests/ros2_flooder.py)")
    ap.add_argument("--burst", type=int, default=600)
    ap.add_argument("--stops", type=int, default=10)
    ap.add_argument("--deadline", type=float, default=15.0)
    ap.add_argument("--grace", type=float, default=15.0)
    ap.add_argument("--settle", type=float, default=10.0)
    ap.add_argument("--node-log", default="", help="write the node's stderr here")
    ap.add_argument("--out", default="results/ros2_flood.json")
    args = ap.parse_args()
    log = open(args.node_log, "w") if args.node_log else subprocess.DEVNULL  # noqa: SIM115
    env, tool, node = start_graph("ros2-flood-", stderr=log)
    try:
        result = flood(args, env, node.pid)
    finally:
        stop_all((node, tool.proc))
    print(json.dumps(result, indent=1), flush=True)
    write_result(args, "round trips: wall clock (time.perf_counter) from send to reply; "
                       "node_cpu_s: /proc user+system CPU time; RSS: /proc VmRSS", result=result)
    return 0


if __name__ == "__main__":
    sys.exit(main())
