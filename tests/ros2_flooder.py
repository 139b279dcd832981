"""Floods ``articutool ros2``'s services with bad calls from its own process, as any DDS
participant on the graph could::

    python tests/ros2_flooder.py --prefix NS --rate HZ [--seconds S] [--kinds KINDS]

A plain rclpy node (nothing of ours but the interface package) sends ``--rate`` calls per
second, in batches every 10 ms, round robin over the kinds named (comma-separated):

- ``mode``: SetOrientationControl with control_mode 7 (no such mode);
- ``offset``: SetOrientationControl LEVELING with a 500° pitch offset (refused by the tool);
- ``nan``: SetOrientationControl with a NaN roll offset;
- ``goal``: ExecuteArticutoolPrimitive goals for a primitive that does not exist;
- ``cancel``: cancels of random goal ids;
- ``calibration``: TriggerCalibration;
- ``verify``: VerifyTrajectory with an empty trajectory.

Names follow the node's layout under ``--prefix`` (``""`` for the upstream names).
Prints ``READY`` once its clients have found their servers, then ``SENT <n> ANSWERED <n>
<seconds>`` on exit (stdin closed, or after ``--seconds``).
"""

from __future__ import annotations

import argparse
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
    args = ap.parse_args()
    names = _names(args.prefix)
    rclpy.init()
    node = rclpy.create_node(f"flooder_{uuid.uuid4().hex[:8]}")
    deep = QoSProfile(depth=1000)  # the flood's own replies must not be what is lost
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

    def on_done(_f: Any) -> None:
        answered[0] += 1
    sent, t0 = 0, time.monotonic()
    batch = max(1, round(args.rate / 100))
    while not done.is_set() and time.monotonic() - t0 < args.seconds:
        for _ in range(batch):
            client, make = calls[kinds[sent % len(kinds)]]
            req = make()
            if isinstance(req, CancelGoal.Request):
                req.goal_info.goal_id.uuid = list(uuid.uuid4().bytes)
            client.call_async(req).add_done_callback(on_done)
            sent += 1
        deadline = t0 + sent / args.rate
        while True:  # take replies until the next batch is due
            left = deadline - time.monotonic()
            rclpy.spin_once(node, timeout_sec=max(0.0, left))
            if left <= 0:
                break
    elapsed = time.monotonic() - t0
    end = time.monotonic() + 2.0  # late replies
    while time.monotonic() < end and answered[0] < sent:
        rclpy.spin_once(node, timeout_sec=0.05)
    print(f"SENT {sent} ANSWERED {answered[0]} {elapsed:.3f}", flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
