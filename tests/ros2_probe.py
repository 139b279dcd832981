"""A plain rclpy client that looks for ``/articutool/set_orientation_control`` and asks for a
mode, as any participant on the graph could (run in another network namespace, it stands for
another host)::

    python tests/ros2_probe.py --mode 1 [--find S] [--answer S]

Waits up to ``--find`` s for the service, sends the request whether or not it was found,
waits up to ``--answer`` s for the reply and prints one JSON line: ``found``, ``found_s``,
``answered``, ``success``, ``message``. Only rclpy and the interface package: nothing of ours.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import rclpy
from articutool_interfaces.srv import SetOrientationControl


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--mode", type=int, required=True)
    ap.add_argument("--find", type=float, default=8.0)
    ap.add_argument("--answer", type=float, default=5.0)
    args = ap.parse_args()
    rclpy.init()
    node = rclpy.create_node("articutool_probe")
    client = node.create_client(SetOrientationControl, "/articutool/set_orientation_control")
    t0 = time.monotonic()
    found = client.wait_for_service(timeout_sec=args.find)
    out: dict[str, object] = {"found": found,
                              "found_s": round(time.monotonic() - t0, 2) if found else None}
    future = client.call_async(SetOrientationControl.Request(control_mode=args.mode))
    rclpy.spin_until_future_complete(node, future, timeout_sec=args.answer)
    out["answered"] = future.done()
    if future.done():
        out["success"], out["message"] = future.result().success, future.result().message
    print(json.dumps(out), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
