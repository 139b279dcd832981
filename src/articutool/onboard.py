"""``articutool tool``: run the onboard tool loop in the foreground.

The onboard program (thesis §3.3): it composes the tool runtime (``tool/``) with the link
server (``link/``), so it sits above both layers and neither imports it.

::

    articutool tool [--driver sim|hardware] [--spec FILE] [--duration S] [--level/--no-level]

Two processes. This one owns the drivers and runs the runtime's 50 Hz loop; the link (the
Zenoh session, the signature checks, the link server) runs in a second process
(``onboard_link.py``) fed through a bounded channel (``tool/channel.py``), so no message from
the network costs the loop's process any CPU or its interpreter lock. The loop's process runs
at real-time priority (``SCHED_FIFO`` 50) where the system allows it (root, ``CAP_SYS_NICE``
or an ``RLIMIT_RTPRIO``), every thread in it included, so neither the link process nor any
other program can delay a tick; where it does not, the loop runs at nice -10 if allowed, the
link process at nice 10, and a warning on stderr says how to allow real-time priority
(:func:`realtime_priority`). The health telemetry reports which (``loop_realtime``).

The loop runs in its own thread; the main thread only draws the status line and waits, so
Ctrl-C (SIGINT) or SIGTERM never interrupts a tick halfway through a bus write: it sets the
stop event, the loop stops the motors, and the drivers are closed (torque off); the link
process is closed last (it ignores both signals and ends when the channel closes). Exit code
0 after a clean stop, 1 when the motors did not confirm it or when the link process ended
first (the loop then stops the motors: a tool no stop can reach does not go on moving), 2 for
bad input, a link that cannot be served (endpoint in use, address not on this host) or
drivers that cannot be opened (no hardware): each is one line on stderr, and nothing moves,
since they are all checked before the loop starts.

``--driver sim`` (the default) runs against :class:`~articutool.tool.drivers.sim.SimWrist`
advanced in real time by the loop itself (:func:`real_time_clock`: reading the clock steps
the world to the present), on a base that tilts and turns gently so leveling is visible.
``--driver hardware`` opens the Dynamixel pair, the IMU and the F/T sensor on the ports in
the spec. Either way the loop's thread is the only busy thread of its process: the main
thread wakes for the status line and nothing else shares the interpreter lock with the loop.

The link process is started, and its session opened, before the drivers; its endpoints are
declared once the drivers are open and before the loop starts; it is closed after the loop.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import logging
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    import numpy as np

    from articutool.onboard_link import LinkProcess
    from articutool.spec import Spec
    from articutool.tool.api import ToolState
    from articutool.tool.drivers.sim import SimWrist

__all__ = [
    "add_commands",
    "format_status",
    "gentle_base_motion",
    "main",
    "real_time_clock",
    "realtime_priority",
    "run_tool",
]

_STATUS_HZ = 5.0  # status line refresh
_LEVEL_WAIT = 5.0  # s to wait for fresh IMU data before giving up on --level
_LEVEL_RETRY_S = 0.05  # s between attempts to engage LEVELING meanwhile
_SWITCH_S = 0.001  # s, the interpreter's thread switch interval in the loop's process
_RT_PRIORITY = 50  # SCHED_FIFO priority of the loop's process (ros2_control's default)
_LOOP_NICE = -10  # the loop's nice value when real-time priority is refused
_LINK_NICE = 10  # the link process's nice value then


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    """Register ``articutool tool``."""
    from articutool.cli_support import MAX_RUN_S, add_spec_option, seconds

    p = subparsers.add_parser(
        "tool", help="run the onboard tool loop (50 Hz) in the foreground",
        description="Run the tool runtime with a live status line; Ctrl-C stops the motors.")
    add_spec_option(p)
    p.add_argument("--driver", choices=("sim", "hardware"), default="sim",
                   help="simulated wrist (default) or the real motors, IMU and F/T sensor")
    p.add_argument("--duration", type=seconds(MAX_RUN_S), default=None, metavar="S",
                   help=f"stop after S seconds, in (0, {MAX_RUN_S:g}] (default: run until "
                        "Ctrl-C)")
    p.add_argument("--level", action=argparse.BooleanOptionalAction, default=None,
                   help="engage LEVELING once the IMU is ready (default: on with --driver sim, "
                        "off with --driver hardware)")
    p.add_argument("--serve", action=argparse.BooleanOptionalAction, default=True,
                   help="serve the Articutool API over Zenoh (default: on, loopback unless "
                        "--listen/--link-config say otherwise)")
    from articutool.link.options import add_config_args

    add_config_args(p)
    p.add_argument("--insecure-listen", action="store_true",
                   help="start although the tool accepts unsigned commands and could be "
                        "reached from the network (a plain endpoint on a network address, "
                        "multicast scouting): anyone on that network can then command it")
    p.add_argument("--record", metavar="FILE.mcap", default=None,
                   help="record every message the link carries (ROS 2 CDR in MCAP, schemas "
                        "embedded); needs --serve; never overwrites")
    p.set_defaults(func=_cmd_tool)


def gentle_base_motion(t: float) -> tuple[np.ndarray, np.ndarray]:
    """A slow demo motion of the tool base for ``--driver sim``: F0's +x (the wrist's up at
    zero) starts along world up; the base yaws ±40° and tilts ±20° about a tilted axis
    (periods 20 s and 8 s, peak rate ≈ 0.3 rad/s). Returns (R_world←F0, ω_world)."""
    import numpy as np

    from articutool.tool.drivers.sim import axis_angle_rotation

    z = np.array([0.0, 0.0, 1.0])
    axis = np.array([1.0, 0.5, 0.3]) / math.sqrt(1.34)
    w1, w2 = 2 * math.pi / 20.0, 2 * math.pi / 8.0
    a1, a2 = math.radians(40.0), math.radians(20.0)
    psi, dpsi = a1 * math.sin(w1 * t), a1 * w1 * math.cos(w1 * t)
    phi, dphi = a2 * math.sin(w2 * t), a2 * w2 * math.cos(w2 * t)
    Rz = axis_angle_rotation(z, psi)
    R0 = axis_angle_rotation([0.0, 1.0, 0.0], -math.pi / 2)
    R = Rz @ axis_angle_rotation(axis, phi) @ R0
    return R, dpsi * z + dphi * (Rz @ axis)


def real_time_clock(sim: SimWrist) -> Callable[[], float]:
    """``sim``'s clock for a runtime run in real time: each read first advances the simulated
    world by the real time elapsed since the previous read (``time.monotonic``), so the world
    moves exactly as far as the loop, which reads the clock once per tick, has lived. No
    thread of its own: the loop's thread is the only one that runs the world (thread-safe for
    other readers)."""
    lock = threading.Lock()
    last: list[float] = []

    def clock() -> float:
        with lock:
            now = time.monotonic()
            if last and now > last[0]:
                sim.step(now - last[0])
            last[:] = [now]
        return sim.clock()

    return clock


def format_status(s: ToolState) -> str:
    """One status line: mode, joints, tilt, loop period/jitter, battery, fault."""
    deg = math.degrees
    ex = s.extra
    tilt = ex.get("tilt_deg", math.nan)
    parts = [
        f"{s.mode.name:<10}",
        f"pitch {deg(s.position[0]):+7.2f}° roll {deg(s.position[1]):+8.2f}°",
        f"tilt {tilt:5.2f}°",
        f"loop {s.loop_period_mean * 1e3:5.2f} ms ±{s.loop_jitter * 1e3:4.2f}"
        f" ({s.loop_overruns} overruns)",
        f"battery {s.battery_voltage:4.1f} V ~{ex.get('battery_remaining_pct', math.nan):3.0f}%",
    ]
    if ex.get("imu_stale", 0.0):
        parts.append("IMU stale")
    if ex.get("leveling_stalled", 0.0):
        parts.append("leveling STALLED")
    parts.append(f"FAULT: {s.fault}" if s.fault else "ok")
    return " | ".join(parts)


def run_tool(
    runtime: object,
    *,
    duration: float | None = None,
    level: bool = False,
    out: TextIO | None = None,
    stop_event: threading.Event | None = None,
    opened: bool = False,
) -> int:
    """Open ``runtime`` (unless ``opened``), start its loop in a thread, show status until
    ``duration`` elapses, ``stop_event`` is set or Ctrl-C; then stop the motors and close.
    Returns 0, or 1 when the motors did not confirm the final stop.

    ``runtime`` is a :class:`~articutool.tool.runtime.ToolRuntime` (open/run/close + ToolAPI).
    This thread wakes only to draw the status line (5 Hz on a terminal, 1 Hz otherwise) and,
    with ``level``, to try engaging LEVELING (every 50 ms until it succeeds): the loop's is
    the only busy thread of the process.
    """
    from articutool.tool.api import Mode

    out = sys.stdout if out is None else out
    stop = threading.Event() if stop_event is None else stop_event
    tty = out.isatty()
    rt = runtime
    if not opened:
        rt.open()  # type: ignore[attr-defined]
    loop = _same_priority(rt.run)  # type: ignore[attr-defined]
    threads = [threading.Thread(target=loop, args=(stop,), name="tool-loop", daemon=True)]
    previous = _install_sigterm(stop)
    t_start = time.monotonic()
    leveled = not level
    last_line = ""
    try:
        for th in threads:
            th.start()
        interval = 1.0 / _STATUS_HZ if tty else 1.0  # logs get one line a second
        next_print = t_start
        while not stop.is_set():
            now = time.monotonic()
            if duration is not None and now - t_start >= duration:
                break
            if not leveled:
                ok, msg = rt.set_mode(Mode.LEVELING)  # type: ignore[attr-defined]
                if ok or now - t_start > _LEVEL_WAIT:
                    leveled = True
                    print(msg if ok else f"could not engage leveling: {msg}", file=out)
            if now >= next_print:
                line = format_status(rt.state())  # type: ignore[attr-defined]
                if tty:
                    out.write("\r" + line.ljust(len(last_line)))
                    out.flush()
                else:
                    print(line, file=out, flush=True)
                last_line = line
                next_print += interval
            wake = next_print if leveled else min(next_print, now + _LEVEL_RETRY_S)
            if duration is not None:
                wake = min(wake, t_start + duration)
            stop.wait(max(0.0, wake - time.monotonic()))
    except KeyboardInterrupt:
        pass
    finally:
        stop.set()
        for th in threads:
            th.join(timeout=2.0)
        final = rt.state()  # type: ignore[attr-defined]
        rt.close()  # type: ignore[attr-defined]
        _restore_sigterm(previous)
        if tty:
            out.write("\n")
        print(format_status(final), file=out)
        stopped = rt.motors_stopped  # type: ignore[attr-defined]
        if stopped:
            print("stopped: motors stopped, torque off, drivers closed", file=out)
        else:
            fault = rt.fault  # type: ignore[attr-defined]
            watchdog_s = rt.spec.motors.bus_watchdog_s  # type: ignore[attr-defined]
            print(f"error: the motors did not confirm the stop ({fault}); they stop "
                  f"themselves {watchdog_s:g} s after the last packet (bus watchdog)", file=out)
    return 0 if stopped else 1


def _same_priority(fn: Callable[..., None]) -> Callable[..., None]:
    """``fn`` run at the calling thread's scheduling policy and priority (a real-time policy
    set with ``SCHED_RESET_ON_FORK`` is not inherited by new threads: every thread that
    holds the interpreter lock in the loop's process must have it, or the scheduler could
    stop that thread while the loop waits for the lock)."""
    try:
        policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
    except (AttributeError, OSError):
        return fn

    def run(*args: object) -> None:
        with contextlib.suppress(OSError):
            os.sched_setscheduler(0, policy, param)
        fn(*args)
    return run


def _install_sigterm(stop: threading.Event) -> object:
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, lambda *_: stop.set())


def _restore_sigterm(previous: object) -> None:
    if previous is not None and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, previous)  # type: ignore[arg-type]


def _close_failed(runtime: object) -> None:
    """Close a runtime whose ``open`` failed: its drivers are partly or not open, so the
    close errors are expected; the one-line error already says why (no tracebacks)."""
    logger = logging.getLogger(type(runtime).__module__)
    was = logger.disabled
    logger.disabled = True
    try:
        runtime.close()  # type: ignore[attr-defined]
    finally:
        logger.disabled = was


def _check_exposure(cfg: object, insecure: bool) -> None:
    """Refuse (exit 2) a tool that accepts unsigned commands and could be reached from the
    network, however its endpoints were configured."""
    from articutool.cli_support import UsageError
    from articutool.link.zenoh_transport import exposure

    if cfg.requires_pairing or insecure:  # type: ignore[attr-defined]
        return
    found = exposure(cfg, "tool")  # type: ignore[arg-type]
    if found:
        raise UsageError(
            f"{'; '.join(found)}: the tool accepts unsigned commands, so anyone on that "
            "network could command it (set by --listen/--connect, the link config's "
            "listen/connect/multicast_scouting or its [extra] zenoh settings); pair first "
            "('articutool pair', then --link-config <tool>/link.toml, which listens on "
            "tls/), use loopback only, or pass --insecure-listen")


def realtime_priority() -> tuple[bool, str]:
    """Give the calling thread, and the threads it starts, real-time priority
    (``SCHED_FIFO`` ``_RT_PRIORITY``, reset in any child process); else try nice
    ``_LOOP_NICE``. Returns (real-time, a note saying what it got and, if not, how to
    allow it)."""
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK,
                              os.sched_param(_RT_PRIORITY))
        return True, f"loop at real-time priority (SCHED_FIFO {_RT_PRIORITY})"
    except (AttributeError, OSError) as err:
        why = getattr(err, "strerror", None) or str(err)
    try:
        os.setpriority(os.PRIO_PROCESS, 0, _LOOP_NICE)
        got = f"nice {_LOOP_NICE}"
    except OSError:
        got = "normal priority"
    return False, (f"the loop runs at {got}, not real-time priority: SCHED_FIFO refused "
                   f"({why}); allow it with LimitRTPRIO={_RT_PRIORITY} (or "
                   "AmbientCapabilities=CAP_SYS_NICE) in the tool's systemd unit, or an "
                   "'rtprio' line in /etc/security/limits.conf. The network still cannot "
                   "delay the loop's process, but other programs on this computer can")


def _cmd_tool(args: argparse.Namespace) -> int:
    from articutool.cli_support import UsageError, new_output_file, spec_from_args

    spec = spec_from_args(args)
    record = new_output_file("--record", args.record, (".mcap",))
    if record is not None and not args.serve:
        raise UsageError("--record records the link's messages: it needs --serve")
    cfg = None
    if args.serve:
        from articutool.link.config import ConfigError, config_from_args

        try:
            cfg = config_from_args(args)
            _check_exposure(cfg, args.insecure_listen)  # builds the zenoh config: ConfigError
        except ConfigError as err:
            raise UsageError(str(err)) from None
    # The loop's process runs at real-time priority where allowed (its threads inherit it,
    # the link process does not); the threads in it (loop, simulated world, status line)
    # then share the interpreter with no thread the scheduler could hold back.
    realtime, note = realtime_priority()
    sys.setswitchinterval(_SWITCH_S)
    link = None
    if cfg is not None:  # open the link before anything moves: a tool that cannot serve says so
        from articutool.onboard_link import LinkProcess, LinkProcessError

        try:
            link = LinkProcess(cfg, spec, record, nice=0 if realtime else _LINK_NICE)
        except LinkProcessError as err:
            raise UsageError(str(err)) from None
    try:
        return _run_with_drivers(args, spec, link, realtime, note)
    finally:
        if link is not None:
            link.close()  # last: after the loop stopped and the motors are off


def _run_with_drivers(args: argparse.Namespace, spec: Spec, link: LinkProcess | None,
                      realtime: bool, note: str) -> int:
    from articutool.cli_support import UsageError
    from articutool.tool.drivers import make_drivers
    from articutool.tool.runtime import ToolRuntime

    level = args.level if args.level is not None else args.driver == "sim"
    sim = None
    clock: Callable[[], float] = time.monotonic
    if args.driver == "sim":
        from articutool.tool.drivers.sim import SimWrist

        sim = SimWrist(spec, gyro_bias=(0.005, -0.004, 0.003))
        sim.set_base_motion(gentle_base_motion)
        clock = real_time_clock(sim)
    try:
        motors, imu, ft = make_drivers(spec, args.driver, sim=sim)
    except Exception as err:  # hardware drivers import dynamixel_sdk / pyserial lazily
        raise UsageError(f"cannot create the {args.driver} drivers: {err}") from None
    runtime = ToolRuntime(spec, motors, imu, ft, clock=clock)
    try:
        runtime.open()
    except Exception as err:  # port missing, motors silent: before the loop, nothing moved
        _close_failed(runtime)
        raise UsageError(f"cannot open the {args.driver} drivers: {err}") from None
    stop = threading.Event()
    lost: list[str] = []
    if link is not None:
        from articutool.onboard_link import LinkProcessError

        def on_lost(reason: str) -> None:  # on the loop's thread: stop the tool
            lost.append(reason)
            stop.set()
        try:  # endpoints declared before the loop runs
            link.attach(runtime, extra={"loop_realtime": 1.0 if realtime else 0.0},
                        on_lost=on_lost)
        except BaseException as err:
            runtime.close()
            if isinstance(err, LinkProcessError):
                raise UsageError(str(err)) from None
            raise
    if not realtime:
        print(f"warning: {note}", file=sys.stderr)
    # A full collection of the ~46 000 objects start-up leaves took 11-20 ms of CPU, holding
    # the interpreter lock, whichever thread ran it: collected once now and frozen, later
    # collections only look at what the loop itself allocates.
    gc.collect()
    gc.freeze()
    runtime.clock()  # a simulated world catches up to the present here, not in the first tick
    code = run_tool(runtime, duration=args.duration, level=level, stop_event=stop,
                    opened=True)
    if lost:
        print(f"error: the link process ended ({lost[0]}; exit code "
              f"{link.proc.poll() if link is not None else None}): the motors were stopped, "
              "since no stop could reach the tool", file=sys.stderr)
        return 1
    return code


def main(argv: Sequence[str] | None = None) -> int:
    """``articutool tool`` on its own (``python -m articutool.onboard``)."""
    from articutool.cli_support import UsageError
    from articutool.spec import SpecError

    parser = argparse.ArgumentParser(prog="articutool")
    add_commands(parser.add_subparsers(dest="command", required=True))
    try:
        args = parser.parse_args(["tool", *(sys.argv[1:] if argv is None else argv)])
    except SystemExit as done:  # argparse refused the arguments (2) or printed --help (0)
        return done.code if isinstance(done.code, int) else 2
    try:
        return int(args.func(args))
    except (SpecError, UsageError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
