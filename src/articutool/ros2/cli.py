"""``articutool ros2``: serve the Articutool on a ROS 2 graph (see :mod:`articutool.ros2.node`).

Exit codes: 0 stopped by SIGINT/SIGTERM (any goal it forwarded cancelled, the command lease
released), 1 the tool was not heard within ``--wait`` or rclpy/articutool_interfaces are not
installed, 2 bad input (link config, endpoints, a tool id that is not a ROS 2 name token).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from typing import Any

__all__ = ["add_commands", "run"]


def add_commands(subparsers: Any) -> None:
    """Register ``articutool ros2``."""
    from articutool.link.cli import _wait_seconds
    from articutool.link.config import add_config_args

    p = subparsers.add_parser(
        "ros2", help="serve the tool's API as a ROS 2 node (rclpy), forwarding over the link",
        description="An rclpy node on the PC: service /articutool/<id>/set_orientation_control, "
                    "action /articutool/<id>/execute_primitive, service "
                    "/articutool/<id>/clear_fault, topic /articutool/<id>/joint_trajectory in; "
                    "joint_states, imu/data, health, battery out. Everything is forwarded to "
                    "the tool over the (paired, signed) link; the DDS side follows the usual "
                    "ROS 2 environment (ROS_DOMAIN_ID, RMW_IMPLEMENTATION, "
                    "ROS_AUTOMATIC_DISCOVERY_RANGE). SIGINT/SIGTERM cancel running goals and "
                    "stop.")
    add_config_args(p)
    p.add_argument("--ros-tool-id", default=None, metavar="NAME",
                   help="the <id> in the ROS 2 names (default: the tool id; must be letters, "
                        "digits and underscores)")
    p.add_argument("--wait", type=_wait_seconds, default=10.0, metavar="S",
                   help="seconds to wait for the tool to be heard (default 10)")
    p.set_defaults(func=run)


def _err(msg: str, code: int) -> int:
    print(f"error: {msg}", file=sys.stderr)
    return code


def run(args: argparse.Namespace) -> int:
    """Handler of ``articutool ros2``."""
    from articutool.link.client import ArticutoolClient, ToolConflictError
    from articutool.link.config import ConfigError, check_ros_environment, config_from_args
    from articutool.link.transport import LinkOpenError
    from articutool.ros2.build_interfaces import skip_reason
    from articutool.ros2.node import check_ros_token

    try:
        cfg = config_from_args(args)
        ros_id = check_ros_token(args.ros_tool_id or cfg.tool_id,
                                 "--ros-tool-id" if args.ros_tool_id else
                                 "--tool-id (or pass --ros-tool-id)")
    except (ConfigError, ValueError) as err:
        return _err(str(err), 2)
    try:  # before rcl reads them: it would raise deep in rclpy.init, or exit(102)
        check_ros_environment(os.environ)
    except ValueError as err:
        return _err(str(err), 2)
    try:
        import articutool_interfaces.srv  # noqa: F401
        import rclpy
        from rclpy.executors import MultiThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
    except ImportError as err:
        why = skip_reason() or f"{err} (run `make` to build articutool_interfaces)"
        return _err(f"ROS 2 is not available here: {why}", 1)
    from articutool.ros2.node import ArticutoolRos2Node

    stop = threading.Event()
    previous = {s: signal.signal(s, lambda *_: stop.set())
                for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        client = ArticutoolClient(cfg)
    except (ConfigError, LinkOpenError) as err:
        return _err(str(err), 2)
    rclpy.init(args=[], signal_handler_options=SignalHandlerOptions.NO)
    node = executor = None
    try:
        try:
            heard = client.wait_for_tool(args.wait)
        except ToolConflictError as err:
            return _err(str(err), 1)
        if not heard:
            listen, connect = cfg.endpoints("client")
            return _err(f"no Articutool heard within {args.wait:g} s "
                        f"(connect={list(connect)}, listen={list(listen)})", 1)
        if stop.is_set():
            return 0
        node = ArticutoolRos2Node(client, ros_id)
        executor = MultiThreadedExecutor(num_threads=4)
        executor.add_node(node.node)
        print(f"articutool ros2: node /{node.node.get_name()} serving {node.prefix}/… for "
              f"tool {cfg.tool_id!r} (Ctrl-C or SIGTERM stops)", flush=True)
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.1)
        print("articutool ros2: stopping (cancelling forwarded goals)", flush=True)
        node.cancel_all()
        return 0
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=2.0)
        if node is not None:
            node.destroy()
        client.close()
        rclpy.try_shutdown()
        for s, h in previous.items():
            signal.signal(s, h)
