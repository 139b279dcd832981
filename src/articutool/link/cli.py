"""``articutool client …``: command a running Articutool from the PC; ``articutool pair``.

Exit codes: 0 success, 1 the tool said no (``success=false``) or could not be reached,
2 bad input (argparse errors, bad config, bad mode/offsets, an endpoint that cannot be
opened), 130 interrupted (Ctrl-C during ``primitive`` first cancels the primitive it started).
Every number is checked before anything is sent.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import Any

__all__ = ["add_commands", "run"]


def _finite(s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {s!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite: {s!r}")
    return v


def _add_pair(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "pair", help="create the certificates that let a tool and PCs trust each other",
        description="Create a small CA (reused if --dir has one) and a certificate, key and "
                    "link config for the tool and each PC. Keys are written 0600; existing "
                    "files are never overwritten (exit 2 naming the file). Copy DIR/<tool> to "
                    "the tool (e.g. the Pi) and DIR/<pc> to each PC; keep DIR/ca/ca.key "
                    "offline.")
    p.add_argument("--dir", required=True, metavar="DIR", help="where to write (created)")
    p.add_argument("--tool", required=True, metavar="NAME",
                   help="the tool's identity (its tool_id), e.g. wrist-1")
    p.add_argument("--pc", action="append", required=True, metavar="NAME",
                   help="a PC allowed to command the tool (repeatable)")
    p.add_argument("--tool-host", default="raspberrypi.local", metavar="HOST",
                   help="the tool's address, written into the PCs' link configs")
    p.add_argument("--port", type=int, default=7447, help="the tool's TLS port (default 7447)")
    p.add_argument("--days", type=int, default=3650, help="certificate validity (default 3650)")
    p.set_defaults(func=run_pair)


def run_pair(args: argparse.Namespace) -> int:
    """Handler of ``articutool pair``."""
    from articutool.link.pairing import PairingError, pair

    try:
        done = pair(args.dir, args.tool, args.pc, days=args.days, port=args.port,
                    tool_host=args.tool_host)
    except PairingError as err:
        return _usage(str(err))
    except OSError as err:
        return _usage(f"--dir: cannot write there: {err}")
    print(("created the pairing CA and " if done.ca_created else "reused the pairing CA; ")
          + f"wrote {len(done.files)} files:")
    for f in done.files:
        print(f"  {oct(f.stat().st_mode & 0o777)[2:]}  {f}")
    if done.tool_kept:
        print(f"tool: {args.dir}/{args.tool}/ was paired before and is unchanged")
    else:
        print(f"tool: copy {args.dir}/{args.tool}/ to the tool and run "
              f"'articutool tool --link-config {args.dir}/{args.tool}/link.toml'")
    for pc in args.pc:
        print(f"PC:   copy {args.dir}/{pc}/ to that PC and run "
              f"'articutool client --link-config {args.dir}/{pc}/link.toml state'")
    return 0


def add_commands(subparsers: Any) -> None:
    """Register ``client mode|primitive|state|take-over|release`` and ``pair``."""
    _add_pair(subparsers)
    from articutool.cli_support import MAX_WAIT_S, add_spec_option, seconds
    from articutool.link.options import add_config_args

    p = subparsers.add_parser("client", help="command an Articutool over the link (PC side)")
    add_config_args(p)
    add_spec_option(p)  # the wrist limits that bound the leveling offsets
    p.add_argument("--wait", type=seconds(MAX_WAIT_S), default=3.0, metavar="S",
                   help=f"seconds to wait for the tool to be heard, in (0, {MAX_WAIT_S:g}] "
                        "(default 3)")
    p.add_argument("--record", metavar="FILE.mcap", default=None,
                   help="record every message this client's link carries (ROS 2 CDR in "
                        "MCAP, schemas embedded); never overwrites")
    sub = p.add_subparsers(dest="client_command", required=True, metavar="ACTION")
    pm = sub.add_parser("mode", help="set the control mode (SetOrientationControl)")
    pm.add_argument("mode", choices=("leveling", "disabled"))
    pm.add_argument("--pitch-offset", type=_finite, default=0.0, metavar="DEG",
                    help="within the pitch joint's limits (spec.wrist)")
    pm.add_argument("--roll-offset", type=_finite, default=0.0, metavar="DEG",
                    help="within the roll joint's limits (spec.wrist)")
    pp = sub.add_parser("primitive", help="run a primitive (ExecuteArticutoolPrimitive)")
    pp.add_argument("name")
    pp.add_argument("params", nargs="*", type=_finite, metavar="P")
    pp.add_argument("--json", action="store_true", help="print the action result as JSON")
    pp.add_argument("--timeout", type=seconds(MAX_WAIT_S), default=None, metavar="S",
                    help=f"cancel the primitive after S seconds, in (0, {MAX_WAIT_S:g}]")
    sub.add_parser("clear-fault", help="clear the tool's fault (reboots the motors after a "
                   "hardware error once the cause is gone); then set a mode")
    sub.add_parser("take-over", help="take the command lease from the client holding it "
                   "(audited on the tool; for a caregiver's stop)")
    sub.add_parser("release", help="give this PC's command lease back")
    ps = sub.add_parser("state", help="print the latest tool state")
    ps.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def _usage(msg: str) -> int:
    print(f"error: {msg}", file=sys.stderr)
    return 2


def _check_offsets(args: argparse.Namespace) -> None:
    """``--pitch-offset``/``--roll-offset`` within the spec's wrist joint limits (degrees)."""
    from articutool.cli_support import UsageError, spec_from_args

    limits = spec_from_args(args).wrist.limits
    for flag, v, (lo, hi) in (("--pitch-offset", args.pitch_offset, limits[0]),
                              ("--roll-offset", args.roll_offset, limits[1])):
        lo_d, hi_d = math.degrees(lo), math.degrees(hi)
        if not lo_d <= v <= hi_d:
            raise UsageError(f"{flag} must be in [{lo_d:g}, {hi_d:g}] degrees (spec.wrist "
                             f"limits); got {v:g}")


def run(args: argparse.Namespace) -> int:
    """Handler of ``articutool client``."""
    from articutool.cli_support import new_output_file
    from articutool.link.client import (
        ArticutoolClient,
        LinkError,
        ToolConflictError,
        check_primitive_request,
    )
    from articutool.link.config import ConfigError, config_from_args
    from articutool.link.transport import LinkOpenError

    if args.client_command == "mode":
        _check_offsets(args)
    record = new_output_file("--record", args.record, (".mcap",))
    recorder = None
    try:
        cfg = config_from_args(args)
        if args.client_command == "primitive":  # before connecting: bad input is said first
            check_primitive_request(cfg, args.name, args.params)
        if record is None:
            client = ArticutoolClient(cfg)
        else:
            client, recorder = _recording_client(cfg, record)
    except (ConfigError, LinkOpenError, ValueError) as err:
        return _usage(str(err))
    try:
        try:
            heard = client.wait_for_tool(args.wait)
        except ToolConflictError as err:
            print(f"error: {err}", file=sys.stderr)
            return 1
        if not heard:
            listen, connect = cfg.endpoints("client")
            print(f"error: no Articutool heard within {args.wait:g} s "
                  f"(connect={list(connect)}, listen={list(listen)})", file=sys.stderr)
            return 1
        cmd = args.client_command
        if cmd == "mode":
            ok, msg = client.set_mode(args.mode, args.pitch_offset, args.roll_offset)
            print(f"{'ok' if ok else 'refused'}: {msg}")
            return 0 if ok else 1
        if cmd in ("clear-fault", "take-over", "release"):
            fn = {"clear-fault": client.clear_fault, "take-over": client.take_over,
                  "release": client.release}[cmd]
            ok, msg = fn()
            print(f"{'ok' if ok else 'refused'}: {msg}")
            return 0 if ok else 1
        if cmd == "primitive":
            def show(fb: Any) -> None:
                if not args.json:
                    print(f"  {fb.percent_complete:5.1f}%  {fb.feedback}", file=sys.stderr)
            try:
                res = client.run_primitive(args.name, args.params, show, timeout=args.timeout)
            except KeyboardInterrupt:  # run_primitive cancelled the goal on the way out
                print(f"interrupted: cancel of {args.name} requested", file=sys.stderr)
                return 130
            if args.json:
                print(json.dumps(res.to_dict()))
            else:
                print(f"{'success' if res.success else 'failed'}: {res.message}; final joints "
                      f"[pitch, roll] = {[round(v, 4) for v in res.final_joint_values]}")
            return 0 if res.success else 1
        # The streams arrive independently: give each a few periods before printing.
        deadline = time.monotonic() + 1.0
        while time.monotonic() < deadline and not client.has_all_streams():
            time.sleep(0.02)
        st = client.latest_state()
        if st is None:
            print("error: no joint state received yet", file=sys.stderr)
            return 1
        d = {"tool_id": cfg.tool_id, "lease_holder": client.lease_holder(),
             "mode": st.mode.name, "joint_names": list(st.joint_names),
             "position": list(st.position), "velocity": list(st.velocity),
             "orientation_wxyz": list(st.orientation_wxyz), "fault": st.fault,
             "battery_voltage": st.battery_voltage, "loop_period_mean": st.loop_period_mean,
             "loop_jitter": st.loop_jitter, "loop_overruns": st.loop_overruns}
        if args.json:  # JSON has no NaN: unknown numbers become null
            print(json.dumps({k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                              for k, v in d.items()}))
        else:
            for k, v in d.items():
                print(f"{k}: {v}")
        return 0
    except ValueError as err:
        return _usage(str(err))
    except LinkError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    finally:
        client.close()
        if recorder is not None:
            recorder.close()
            print(f"recording: {record} ({recorder.count} messages)", file=sys.stderr)


def _recording_client(cfg: Any, path: Any) -> tuple[Any, Any]:
    """An ArticutoolClient whose Zenoh transport records into the new MCAP file ``path``."""
    import uuid

    from articutool.cli_support import UsageError
    from articutool.link.client import ArticutoolClient
    from articutool.link.recording import McapRecorder, RecordingError, RecordingTransport
    from articutool.link.zenoh_transport import ZenohTransport

    sender = cfg.identity or f"articutool-client-{uuid.uuid4().hex[:8]}"
    try:
        recorder = McapRecorder(path)
    except RecordingError as err:
        raise UsageError(f"--record: {err}") from None
    try:
        link = ZenohTransport(cfg, "client", identity=sender)
    except BaseException:
        recorder.close()
        path.unlink()  # nothing recorded: the file this run created
        raise
    return ArticutoolClient(cfg, RecordingTransport(link, recorder), sender=sender), recorder
