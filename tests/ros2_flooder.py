"""Floods ``articutool ros2``'s services with bad calls from its own process, as any DDS
participant on the graph could::

    python tests/ros2_flooder.py --prefix NS --rate HZ [--seconds S] [--kinds KINDS]
                                 [--count N] [--depth N] [--grace S] [--stats]

A plain rclpy node (nothing of ours but the interface package) sends ``--rate`` calls per
second, in batches every 10 ms from a thread while its main thread takes the replies, round
robin over the kinds named (comma-separated):

- ``mode``: SetOrientationControl with control_mode 7 (no such mode);
- ``offset``: SetOrientationControl LEVELING with a 500° pitch offset (refused by the tool);
- ``nan``: SetOrientationControl with a NaN roll offset;
- ``goal``: ExecuteArticutoolPrimitive goals for a primitive that does not exist;
- ``cancel``: cancels of random goal ids;
- ``calibration``: TriggerCalibration;
- ``verify``: VerifyTrajectory with an empty trajectory.

Names follow the node's layout under ``--prefix`` (``""`` for the upstream names).
Prints ``READY`` once its clients have found their servers, then ``SENT <n> ANSWERED <n>
<seconds>`` on exit (stdin closed, after ``--seconds`` or ``--count`` calls, then up to
``--grace`` s for late replies). ``--depth`` is the history depth of its clients' queues
(1000: its own reply queue is not what loses a reply; 10 is rclpy's default). Replies are
taken by rclpy's EventsExecutor: measured here, a client taking them with rclpy's Python
SingleThreadedExecutor cannot take 1 000 replies/s on a loaded 2-core machine and loses them
in its own queue, which would be counted against the server. ``--stats`` adds a line
``STATS <json>``: per kind sent and answered, and round trips (``time.perf_counter``, wall
clock) in ms.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import threading
import time
import uuid
from typing import Any

import rclpy
from action_msgs.srv import CancelGoal
from articutool_interfaces.action import ExecuteArticutoolPrimitive
from articutool_interfaces.srv import SetOrientationControl, TriggerCalibration
from rclpy.experimental import EventsExecutor
from rclpy.qos import QoSProfile

try:
    from articutool_interfaces.srv import VerifyTrajectory
except ImportError:  # an interface package without it
    VerifyTrajectory = None


def _names(prefix: str) -> dict[str, str]:
    p = prefix.rstrip("/")
    return {"soc": f"{p}/articutool/set_orientation_control",
            "action": f"{p}/orientation_control/execute_primitive",
            "calibration": f"{p}/orientation_calibration_service/trigger_calibration",
            "verify": f"{p}/articutool/verify_trajectory"}


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--prefix", default="")
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--seconds", type=float, default=3600.0)
    ap.add_argument("--kinds", default="mode,offset,nan,goal,cancel,calibration,verify")
    ap.add_argument("--count", type=int, default=0, help="stop after this many calls (0: no limit)")
    ap.add_argument("--depth", type=int, default=1000)
    ap.add_argument("--grace", type=float, default=2.0)
    ap.add_argument("--stats", action="store_true")
    args = ap.parse_args()
    names = _names(args.prefix)
    rclpy.init()
    node = rclpy.create_node(f"flooder_{uuid.uuid4().hex[:8]}")
    deep = QoSProfile(depth=args.depth)
    soc = node.create_client(SetOrientationControl, names["soc"], qos_profile=deep)
    cal = node.create_client(TriggerCalibration, names["calibration"], qos_profile=deep)
    goal = node.create_client(ExecuteArticutoolPrimitive.Impl.SendGoalService,
                              f"{names['action']}/_action/send_goal", qos_profile=deep)
    cancel = node.create_client(CancelGoal, f"{names['action']}/_action/cancel_goal",
                                qos_profile=deep)
    ver = (node.create_client(VerifyTrajectory, names["verify"], qos_profile=deep)
           if VerifyTrajectory is not None else None)
    calls: dict[str, tuple[Any, Any]] = {
        "mode": (soc, lambda: SetOrientationControl.Request(control_mode=7)),
        "offset": (soc, lambda: SetOrientationControl.Request(control_mode=1,
                                                             pitch_offset=500.0)),
        "nan": (soc, lambda: SetOrientationControl.Request(control_mode=1,
                                                          roll_offset=math.nan)),
        "calibration": (cal, TriggerCalibration.Request),
        "goal": (goal, lambda: ExecuteArticutoolPrimitive.Impl.SendGoalService.Request(
            goal=ExecuteArticutoolPrimitive.Goal(primitive_name="NO_SUCH_PRIMITIVE"))),
        "cancel": (cancel, CancelGoal.Request),
    }
    if ver is not None:
        calls["verify"] = (ver, VerifyTrajectory.Request)
    kinds = [k for k in args.kinds.split(",") if k]
    for k in kinds:
        if k not in calls:
            print(f"unknown kind {k!r}", file=sys.stderr)
            return 2
        if not calls[k][0].wait_for_service(timeout_sec=30):
            print(f"no server for {k}", file=sys.stderr)
            return 1
    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    print("READY", flush=True)
    answered = [0]
    per_kind = {k: [0, 0] for k in kinds}  # sent, answered
    rtt: list[float] = []

    def on_done(kind: str, t_sent: float) -> Any:
        def done_cb(_f: Any) -> None:
            rtt.append(time.perf_counter() - t_sent)
            answered[0] += 1
            per_kind[kind][1] += 1
        return done_cb
    # Sends from a thread of its own while the main thread takes every reply: a sender that
    # fell behind its schedule must not also stop taking replies (they would pile up in the
    # client's queue and be lost there, not at the node).
    counts = {"sent": 0}
    t0 = time.monotonic()
    finished = threading.Event()

    def send() -> None:
        batch = max(1, round(args.rate / 100))
        while (not done.is_set() and time.monotonic() - t0 < args.seconds
               and not 0 < args.count <= counts["sent"]):
            for _ in range(min(batch, args.count - counts["sent"]) if args.count else batch):
                kind = kinds[counts["sent"] % len(kinds)]
                client, make = calls[kind]
                req = make()
                if isinstance(req, CancelGoal.Request):
                    req.goal_info.goal_id.uuid = list(uuid.uuid4().bytes)
                client.call_async(req).add_done_callback(on_done(kind, time.perf_counter()))
                per_kind[kind][0] += 1
                counts["sent"] += 1
            time.sleep(max(0.0, t0 + counts["sent"] / args.rate - time.monotonic()))
        counts["elapsed"] = time.monotonic() - t0
        finished.set()
    executor = EventsExecutor()
    executor.add_node(node)
    threading.Thread(target=send, name="flood", daemon=True).start()
    while not finished.is_set():
        executor.spin_once(timeout_sec=0.05)
    sent, elapsed = counts["sent"], counts["elapsed"]
    end = time.monotonic() + args.grace  # late replies
    while time.monotonic() < end and answered[0] < sent:
        executor.spin_once(timeout_sec=0.05)
    print(f"SENT {sent} ANSWERED {answered[0]} {elapsed:.3f}", flush=True)
    if args.stats:
        ms = sorted(x * 1e3 for x in rtt)

        def pct(q: float) -> float | None:
            return round(ms[min(len(ms) - 1, int(q * len(ms)))], 2) if ms else None
        print("STATS " + json.dumps({
            "sent": sent, "answered": answered[0], "flood_s": round(elapsed, 3),
            "per_kind": {k: {"sent": s, "answered": a} for k, (s, a) in per_kind.items()},
            "rtt_ms": {"p50": pct(0.5), "p90": pct(0.9), "p99": pct(0.99),
                       "max": round(ms[-1], 2) if ms else None},
            "clock": "time.perf_counter round trip (wall clock)"}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
