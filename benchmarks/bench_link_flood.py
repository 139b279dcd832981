"""The network cannot slow the loop: the real tool under a link flood.

Runs ``articutool tool`` (simulated wrist, the real 50 Hz runtime, paired: mutual TLS and
signed commands) as its own process, then from this process:

1. ``--quiet`` seconds of no traffic but telemetry (control: the loop's own overruns);
2. ``--duration`` seconds of flood from a *paired* PC (the worst case: every message passes
   the signature check and reaches the decoder): ``--goals`` SendGoal requests per second
   (replies ignored) and one ``--big-mb`` MB JointTrajectory every ``1 / --big-rate`` s;
   the first ``--warmup`` seconds of the flood are warm-up for the memory figure.

Overruns and the maximum loop period come from the tool's own health telemetry (the
runtime's ``LoopStats``); memory is the tool process's RSS (``/proc/<pid>/status``). Writes
JSON::

    .venv/bin/python benchmarks/bench_link_flood.py --duration 60 --compare-unlimited \\
        --out results/link_flood.json

``--compare-unlimited`` repeats the run with the tool's per-endpoint rate limit off
(``max_rate_hz = 100000``), in the same invocation, to show what the limit buys.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import threading
import time
import uuid
from pathlib import Path
from typing import Any

import zenoh

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.client import ArticutoolClient
from articutool.link.config import load_config
from articutool.link.transport import key_expr
from articutool.link.zenoh_transport import ZenohTransport
from paired_tool import rss_mb, start_paired_tool


def _health(client: ArticutoolClient) -> dict[str, float]:
    st = client.latest_state()
    if st is None:
        return {}
    out = {"loop_overruns": float(st.loop_overruns), "loop_period_mean": st.loop_period_mean,
           "loop_jitter": st.loop_jitter}
    out.update({k: v for k, v in st.extra.items()
                if k.startswith("link_") or k.startswith("loop_") or k.startswith("tick_")})
    return out


class Flood:
    """Sends goals and big trajectories from a paired session until stopped."""

    def __init__(self, transport: ZenohTransport, goals_hz: float, big_bytes: int,
                 big_hz: float) -> None:
        self.tr = transport
        self.goals_hz, self.big_bytes, self.big_hz = goals_hz, big_bytes, big_hz
        self.sent = {"goals": 0, "big": 0}
        self.stop = threading.Event()

    def run(self, names: Any) -> None:
        ep_goal, ep_traj = names.send_goal, names.joint_trajectory
        key = key_expr(self.tr.cfg.domain_id, ep_goal)
        session: zenoh.Session = self.tr._session
        big = b"\x00\x01\x00\x00" + bytes(self.big_bytes - 4)
        batch, period = round(self.goals_hz / 100), 0.01
        next_t, next_big = time.monotonic(), time.monotonic()
        while not self.stop.is_set():
            for _ in range(batch):
                payload = cdr.encode(m.send_goal_request(uuid.uuid4().bytes, "TWIRL", [0.1]),
                                   ep_goal.request_type)
                session.get(key, handler=lambda _r: None, payload=payload,
                            attachment=self.tr._attachment(ep_goal, payload), timeout=1.0)
                self.sent["goals"] += 1
            now = time.monotonic()
            if self.big_hz > 0 and now >= next_big:
                self.tr.publish(ep_traj, big)
                self.sent["big"] += 1
                next_big += 1.0 / self.big_hz
            next_t += period
            self.stop.wait(max(0.0, next_t - time.monotonic()))


def run_once(a: argparse.Namespace, max_rate_hz: float | None) -> dict[str, Any]:
    """One tool process, a quiet phase and a flood; ``max_rate_hz`` None: the default."""
    started = start_paired_tool(
        "articutool-flood-", duration_s=a.quiet + a.duration + 60,
        extra_tool_config="" if max_rate_hz is None else f"max_rate_hz = {max_rate_hz}\n")
    tool, cfg, tool_cfg = started.proc, started.pc_config, started.tool_config
    watcher = ArticutoolClient(cfg)
    flood_tr = ZenohTransport(cfg, "client")
    result: dict[str, Any] = {"tool_max_rate_hz": max_rate_hz or load_config(
        tool_cfg).max_rate_hz}
    try:
        if not watcher.wait_for_tool(30.0):
            raise SystemExit("tool process not heard within 30 s")
        time.sleep(2.0)  # let the loop settle after start-up
        h0 = _health(watcher)
        time.sleep(a.quiet)
        h1 = _health(watcher)
        result["quiet"] = {"seconds": a.quiet,
                           "overruns": h1["loop_overruns"] - h0["loop_overruns"],
                           "loop_period_max_s_cumulative": h1.get("loop_period_max")}
        flood = Flood(flood_tr, a.goals, int(a.big_mb * 1e6), a.big_rate)
        th = threading.Thread(target=flood.run, args=(flood_tr_names(cfg),), daemon=True)
        t0 = time.monotonic()
        th.start()
        rss: list[tuple[float, float]] = []
        warm = None
        while time.monotonic() - t0 < a.duration:
            time.sleep(1.0)
            el = time.monotonic() - t0
            rss.append((round(el, 1), rss_mb(tool.pid)))
            if warm is None and el >= a.warmup:
                warm = rss[-1][1]
        flood.stop.set()
        th.join(timeout=5)
        elapsed = time.monotonic() - t0
        time.sleep(1.0)
        h2 = _health(watcher)
        after_warm = [r for t, r in rss if t >= a.warmup]
        result["flood"] = {
            "seconds": round(elapsed, 1), "sent": flood.sent,
            "goals_per_s_achieved": round(flood.sent["goals"] / elapsed, 1),
            "overruns": h2["loop_overruns"] - h1["loop_overruns"],
            "loop_period_max_s_cumulative": h2.get("loop_period_max"),
            "loop_period_mean_s": h2.get("loop_period_mean"),
            "loop_jitter_s": h2.get("loop_jitter"),
            "tick_compute_max_s": h2.get("tick_compute_max_s"),
            "rss_mb_at_warmup": warm, "rss_mb_end": rss[-1][1] if rss else None,
            "rss_mb_max_after_warmup": max(after_warm) if after_warm else None,
            "rss_growth_mb_after_warmup": (max(after_warm) - warm) if after_warm and warm
            else None,
            "link_counters_delta": {k: h2.get(k, 0) - h1.get(k, 0) for k in h2
                                    if k.startswith("link_")},
            "rss_mb_series": rss}
    finally:
        watcher.close()
        flood_tr.close()
        tool.terminate()
        tool.wait(timeout=20)
    return result


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; print and optionally write the JSON figures."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--duration", type=float, default=60.0, help="flood length (s)")
    p.add_argument("--quiet", type=float, default=20.0, help="control phase, no flood (s)")
    p.add_argument("--warmup", type=float, default=10.0, help="flood warm-up for RSS (s)")
    p.add_argument("--goals", type=float, default=1000.0, help="SendGoal requests per second")
    p.add_argument("--big-mb", type=float, default=16.0, help="big trajectory size (MB)")
    p.add_argument("--big-rate", type=float, default=1.0, help="big trajectories per second")
    p.add_argument("--compare-unlimited", action="store_true",
                   help="then run it again with the tool's rate limit off (max_rate_hz 1e5)")
    p.add_argument("--out", default=None, help="write the JSON here too")
    a = p.parse_args(argv)
    result: dict[str, Any] = {
        "command": "python benchmarks/bench_link_flood.py " +
                   " ".join(argv if argv is not None else sys.argv[1:]),
        "machine": platform.machine(), "cpus": os.cpu_count(),
        "python": platform.python_version(), "goals_per_s": a.goals, "big_mb": a.big_mb,
        "big_per_s": a.big_rate, "runs": [run_once(a, None)]}
    if a.compare_unlimited:
        result["runs"].append(run_once(a, 100_000.0))
    text = json.dumps(result, indent=1)
    print(text)
    if a.out:
        Path(a.out).write_text(text + "\n")
    return 0


def flood_tr_names(cfg: Any) -> Any:
    """The flooded tool's endpoints."""
    from articutool.link.transport import Names
    return Names(cfg.namespace, cfg.tool_id)


if __name__ == "__main__":
    sys.exit(main())
