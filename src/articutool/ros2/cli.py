"""``articutool ros2``: serve the Articutool on a ROS 2 graph (see :mod:`articutool.ros2.node`).

Refuses to start (exit 2) unless DDS discovery stays on this host or the user passes
``--allow-remote-ros-clients`` (:mod:`articutool.ros2.exposure`); host-only, it binds DDS to
loopback and shared memory and refuses to run (exit 2) if any socket of the process is bound
to another address once its participant exists (:mod:`articutool.ros2.host_only`).
Configured by flags and by ROS 2 parameters (:mod:`articutool.ros2.params`; ``--ros-args -p
name:=value`` overrides a flag). Exit codes: 0 stopped by SIGINT/SIGTERM (any goal it
forwarded cancelled, the command lease released), 1 the tool was not heard within the wait or
rclpy/articutool_interfaces are not installed, 2 bad input (link config, endpoints, a
parameter, discovery open without the flag, a socket bound beyond loopback when host-only).
"""

from __future__ import annotations

import argparse
import faulthandler
import os
import signal
import sys
import threading
from typing import Any

__all__ = ["add_commands", "run"]


def add_commands(subparsers: Any) -> None:
    """Register ``articutool ros2``."""
    from articutool.cli_support import MAX_WAIT_S, seconds
    from articutool.link.options import add_config_args
    from articutool.ros2.exposure import ALLOW_FLAG

    p = subparsers.add_parser(
        "ros2", help="serve the tool's API as a ROS 2 node (rclpy), forwarding over the link",
        description="An rclpy node on the PC serving the upstream Articutool's ROS 2 names "
                    "(those ADA's behaviours call: /articutool/set_orientation_control, "
                    "/orientation_control/execute_primitive, "
                    "/orientation_calibration_service/trigger_calibration, "
                    "/articutool/joint_states, ...) plus /articutool/stop and "
                    "/articutool/verify_trajectory (plan-then-verify). Commands are forwarded "
                    "to the tool over the paired, signed link. DDS has no authentication: "
                    "the node starts only when ROS_AUTOMATIC_DISCOVERY_RANGE is LOCALHOST or "
                    f"OFF, or with {ALLOW_FLAG}. Parameters (--ros-args -p NAME:=VALUE): "
                    "tool_id, link_config, namespace, wait_s, call_timeout_s, tool_timeout_s, "
                    "joint_names, offset_units (default radians, what ADA sends), "
                    "republish_joint_states, utensil. SIGINT/SIGTERM cancel running goals "
                    "and stop.")
    add_config_args(p)
    p.add_argument("--ros-namespace", default="", metavar="NS",
                   help="put every ROS 2 name under /NS (default: the upstream names exactly)")
    p.add_argument("--wait", type=seconds(MAX_WAIT_S), default=10.0, metavar="S",
                   help=f"seconds to wait for the tool to be heard, in (0, {MAX_WAIT_S:g}] "
                        "(default 10)")
    p.add_argument(ALLOW_FLAG, action="store_true", dest="allow_remote",
                   help="serve even when DDS discovery reaches other hosts, with DDS on every "
                        "interface (without it DDS is bound to loopback and shared memory): "
                        "then ANY process on the ROS 2 domain, on any host of the network, can "
                        "command the wrist (DDS has no authentication here)")
    p.add_argument("--verify-only", action="store_true",
                   help="serve only /articutool/verify_trajectory (no tool, no link)")
    p.add_argument("--ros-args", nargs=argparse.REMAINDER, default=None, dest="ros_args",
                   metavar="ARGS", help="ROS 2 arguments (-p name:=value, -r from:=to, ...); "
                                        "must come last")
    p.set_defaults(func=run)


def _err(msg: str, code: int) -> int:
    print(f"error: {msg}", file=sys.stderr)
    return code


def _defaults(args: argparse.Namespace, cfg: Any) -> dict[str, Any]:
    return {"tool_id": cfg.tool_id, "link_config": args.link_config or "",
            "namespace": args.ros_namespace, "wait_s": float(args.wait),
            "call_timeout_s": float(cfg.call_timeout),
            "tool_timeout_s": float(cfg.tool_timeout),
            "joint_names": ["atool_joint1", "atool_joint2"], "offset_units": "radians",
            "republish_joint_states": True, "utensil": "spoon"}


def _configure(args: argparse.Namespace, values: dict[str, Any], defaults: dict[str, Any]
               ) -> Any:
    """The LinkConfig in force: the parameter's link config (flags re-applied), then the
    parameters that differ from what the flags gave."""
    from articutool.link.config import config_from_args

    if values["link_config"] != defaults["link_config"]:
        args = argparse.Namespace(**{**vars(args), "link_config": values["link_config"] or None})
    cfg = config_from_args(args)
    changes = {}
    if values["tool_id"] != defaults["tool_id"]:
        changes["tool_id"] = values["tool_id"]
    for name, key in (("call_timeout_s", "call_timeout"), ("tool_timeout_s", "tool_timeout")):
        if values[name] != defaults[name]:
            changes[key] = values[name]
    return cfg.replace(**changes) if changes else cfg


def run(args: argparse.Namespace) -> int:
    """Handler of ``articutool ros2``. A fatal signal inside the C of rcl, rmw or DDS prints
    where every Python thread was (``faulthandler``) before the process ends; an error is
    printed before the node is torn down, so it is seen whatever the teardown does."""
    faulthandler.enable()
    from articutool.link.config import ConfigError, check_ros_environment, config_from_args
    from articutool.ros2.exposure import ALLOW_FLAG, discovery_scope
    from articutool.ros2.host_only import apply_profile
    from articutool.ros2.names import check_namespace

    try:
        cfg0 = config_from_args(args)
        check_namespace(args.ros_namespace, "--ros-namespace")
    except (ConfigError, ValueError) as err:
        return _err(str(err), 2)
    try:  # before rcl reads them: it would raise deep in rclpy.init, or exit(102)
        check_ros_environment(os.environ)
    except ValueError as err:
        return _err(str(err), 2)
    scope = discovery_scope(os.environ)
    if not scope.host_only and not args.allow_remote:
        return _err(f"refusing to serve the wrist to the network: {scope.why}. DDS has no "
                    "authentication, so any process on this ROS 2 domain on any reachable "
                    "host could command the wrist. Set ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST "
                    f"(or OFF) for this process, or pass {ALLOW_FLAG} to open it knowingly",
                    2)
    # before rmw reads them: Fast DDS on loopback and shared memory only
    profile = None if args.allow_remote else apply_profile(os.environ)
    try:
        return _run(args, cfg0, profile, scope.why)
    finally:
        if profile is not None:
            profile.remove()


def _run(args: argparse.Namespace, cfg0: Any, profile: Any, why: str) -> int:
    from articutool.ros2.build_interfaces import skip_reason
    from articutool.ros2.exposure import ALLOW_FLAG

    try:
        import articutool_interfaces.srv  # noqa: F401
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
    except ImportError as err:
        reason = skip_reason() or f"{err} (run `make` to build articutool_interfaces)"
        return _err(f"ROS 2 is not available here: {reason}", 1)
    if profile is None:
        print(f"warning: {ALLOW_FLAG}: {why}; DDS listens on "
              "every interface: any DDS participant that reaches this host (or names it as a "
              "static peer) can command the wrist", file=sys.stderr, flush=True)

    stop = threading.Event()
    previous = {s: signal.signal(s, lambda *_: stop.set())
                for s in (signal.SIGINT, signal.SIGTERM)}
    ros_args = ["--ros-args", *args.ros_args] if args.ros_args else []
    ctx = rclpy.Context()
    try:
        rclpy.init(args=ros_args, context=ctx, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as err:
        for s, h in previous.items():
            signal.signal(s, h)
        return _err(f"--ros-args: {err}", 2)
    client = ros = node = None
    executors: list[Any] = []
    try:
        code, client, ros, node = _start(args, cfg0, ctx, stop, profile)
        if code is not None:
            return code
        assert ros is not None
        main = SingleThreadedExecutor(context=ctx)
        main.add_node(ros.node)
        executors.append(main)
        if ros.safety_node is not None:
            safety = SingleThreadedExecutor(context=ctx)
            safety.add_node(ros.safety_node)
            executors.append(safety)
            threading.Thread(target=_spin, args=(safety, stop), name="ros2-safety",
                             daemon=True).start()
        what = ("verify_trajectory only" if client is None else
                f"tool {client.cfg.tool_id!r}")
        print(f"articutool ros2: node {ros.node.get_fully_qualified_name()} serving "
              f"{ros.names['verify_trajectory'].rsplit('/', 2)[0] or '/'}… for {what} "
              "(Ctrl-C or SIGTERM stops)", flush=True)
        _spin(main, stop)
        print("articutool ros2: stopping (cancelling forwarded goals)", flush=True)
        ros.cancel_all()
        return 0
    finally:
        for ex in executors:
            ex.shutdown(timeout_sec=2.0)
        if ros is not None:
            ros.destroy()
        elif node is not None:
            node.destroy_node()
        if client is not None:
            client.close()
        rclpy.try_shutdown(context=ctx)
        for s, h in previous.items():
            signal.signal(s, h)


def _spin(executor: Any, stop: threading.Event) -> None:
    """Spin until ``stop``. An error raised out of one callback (measured: rclpy's action
    server failing to expire goals under a flood of goals) is reported and spinning goes
    on: it must not end the thread that serves the stops."""
    from rclpy.executors import ExternalShutdownException, ShutdownException

    seen: set[str] = set()
    while not stop.is_set():
        try:
            executor.spin_once(timeout_sec=0.1)
        except (ExternalShutdownException, ShutdownException):
            return
        except Exception as err:
            why = f"{type(err).__name__}: {err}"
            if why not in seen:  # once per kind of error, not once per request
                seen.add(why)
                print(f"warning: a ROS 2 callback failed ({why}); serving on",
                      file=sys.stderr, flush=True)


def _start(args: argparse.Namespace, cfg0: Any, ctx: Any, stop: threading.Event,
           profile: Any) -> tuple[int | None, Any, Any, Any]:
    """Create the rclpy node (its DDS participant: host-only, check its sockets before the
    link opens any), declare the parameters, build the link client, wait for the tool and
    create the ROS 2 node: (exit code or None, client, ArticutoolRos2Node, rclpy node)."""
    from rclpy.node import Node

    from articutool.link.client import ArticutoolClient, ToolConflictError
    from articutool.link.config import ConfigError
    from articutool.link.transport import LinkOpenError
    from articutool.ros2.host_only import exposed_sockets
    from articutool.ros2.names import check_namespace
    from articutool.ros2.node import ArticutoolRos2Node, NodeSettings
    from articutool.ros2.params import ParamError, declare_all, unknown_overrides
    from articutool.ros2.verify_service import Verifier
    from articutool.spec import load_spec

    node = Node("articutool_ros2", context=ctx)
    # Every socket the process holds now is the participant's: the link is not open yet.
    wide = [] if profile is None else exposed_sockets()
    if profile is not None:
        profile.remove()  # read by Fast DDS when the participant was made
    if wide:
        code = _err(f"refusing to run host-only: DDS socket(s) bound beyond loopback "
                    f"({', '.join(map(str, wide))}), reachable from other hosts. The node's "
                    "loopback-only Fast DDS profile was not applied as written (another RMW "
                    "or DDS configuration in force?)", 2)
        node.destroy_node()
        return code, None, None, None
    defaults = _defaults(args, cfg0)
    try:
        values = declare_all(node, defaults)
        unknown = unknown_overrides(node)
        if unknown:
            raise ParamError(f"unknown parameter(s) {unknown}; known: tool_id, link_config, "
                             "namespace, wait_s, call_timeout_s, tool_timeout_s, joint_names, "
                             "offset_units, republish_joint_states, utensil")
        check_namespace(values["namespace"], "parameter namespace")
        cfg = _configure(args, values, defaults)
        spec = load_spec()
        verifier = Verifier(spec, values["utensil"], values["joint_names"])
    except (ParamError, ConfigError, ValueError) as err:
        code = _err(str(err), 2)
        node.destroy_node()
        return code, None, None, None
    settings = NodeSettings(namespace=values["namespace"], joint_names=values["joint_names"],
                            offset_units=values["offset_units"], verifier=verifier,
                            republish_joint_states=values["republish_joint_states"])
    if args.verify_only:
        return None, None, ArticutoolRos2Node(None, settings, context=ctx, node=node), node
    try:
        client = ArticutoolClient(cfg)
    except (ConfigError, LinkOpenError) as err:
        code = _err(str(err), 2)
        node.destroy_node()
        return code, None, None, None
    wait = float(values["wait_s"])
    try:
        heard = client.wait_for_tool(wait)
    except ToolConflictError as err:
        return _err(str(err), 1), client, None, node
    if not heard:
        listen, connect = cfg.endpoints("client")
        return (_err(f"no Articutool heard within {wait:g} s (connect={list(connect)}, "
                     f"listen={list(listen)})", 1), client, None, node)
    if stop.is_set():
        return 0, client, None, node
    return None, client, ArticutoolRos2Node(client, settings, context=ctx, node=node), node
