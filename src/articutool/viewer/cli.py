"""``articutool view``: the 3-D web viewer (viser) of the scene, plans and recorded runs.

Every input is read and checked before the server starts (bad input: exit 2, no server);
the server binds to loopback unless ``--host`` says otherwise and prints its URL.
``--export`` renders a recording to a video without a browser and exits.
"""

from __future__ import annotations

import argparse
import math
import signal
import socket
import sys
import time
from pathlib import Path
from typing import Any

__all__ = ["add_commands"]


def _check_address(host: str, port: int) -> None:
    from articutool.cli_support import UsageError

    if not 1 <= port <= 65535:
        raise UsageError(f"--port must be in [1, 65535]; got {port}")
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError) as err:
        raise UsageError(f"--host {host!r} is not an address of this machine ({err})") from None
    family, _, _, _, addr = infos[0]
    with socket.socket(family, socket.SOCK_STREAM) as s:
        # As the server will: a port left in TIME_WAIT is free; one listened on is not.
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(addr)
        except OSError as err:
            raise UsageError(f"--host/--port: cannot listen on {host}:{port} ({err.strerror}); "
                             "choose another --port, or a --host of this machine") from None


def _plan_from_task(args: argparse.Namespace, spec: Any) -> tuple[Any, str, str]:
    """Plan benchmark task ``--plan-task`` with the planner ``--system``; (trajectory, wrist,
    title)."""
    from articutool.bench.taskfile import TaskFileError, check_task_limits, load_task_set
    from articutool.cli_support import UsageError
    from articutool.planning.api import plan
    from articutool.planning.types import PlanRequest

    try:
        ts = load_task_set(args.tasks)
        check_task_limits(ts, spec)
    except TaskFileError as err:
        raise UsageError(f"--tasks: {err}") from None
    ids = [t.task_id for t in ts.tasks]
    task = next((t for t in ts.tasks if t.task_id == args.plan_task), None)
    if task is None:
        raise UsageError(f"--plan-task must be a task id of the task set ({min(ids)}–{max(ids)}"
                         f", {len(ids)} tasks); got {args.plan_task}")
    if args.seed < 0:
        raise UsageError(f"--seed must be an integer >= 0; got {args.seed}")
    print(f"planning task {task.task_id} with {args.planner} (timeout {args.timeout:g} s) …",
          flush=True)
    res = plan(PlanRequest(planner=args.planner, task=task, timeout_s=args.timeout,
                           seed=args.seed, utensil=args.utensil), spec)
    print(f"plan: {'ok' if res.success else 'FAILED'} in {res.planning_time_s * 1000:.0f} ms "
          f"— {res.message}", flush=True)
    title = f"task {task.task_id}, {args.planner}: {'ok' if res.success else 'failed'}"
    if res.trajectory is None:
        from articutool.trajectory import JointTrajectory

        # No plan: show the start and the goal as a two-point straight move, marked failed.
        names = tuple(spec.arm.joint_names)
        q = [list(task.start), list(task.goal)]
        traj = JointTrajectory(names, [0.0, 1.0], q, [[0.0] * 6, [0.0] * 6])
        return traj, "locked", title + f" ({res.message}; start → goal shown as a straight " \
                                       "move, not a plan)"
    wrist = "locked" if args.planner == "strict6" else "leveling"
    return res.trajectory, wrist, title


def _cmd_view(args: argparse.Namespace) -> int:
    from articutool.cli_support import UsageError, spec_from_args
    from articutool.sim.recording import Recording, RecordingError

    sources = [x for x in (args.plan, args.plan_task, args.recording) if x is not None]
    if len(sources) > 1:
        raise UsageError("give at most one of --plan, --plan-task, --recording")
    if args.export is not None and args.recording is None:
        raise UsageError("--export needs --recording FILE")
    if args.at is not None and args.plan is None and args.plan_task is None and (
            args.recording is None or args.export is not None):
        raise UsageError("--at applies to a plan or a recording shown in the viewer "
                         "(--plan, --plan-task, --recording without --export)")
    if args.export is None and (args.camera is not None or args.fps is not None):
        raise UsageError("--camera and --fps apply only with --export")
    if args.export is not None:
        from articutool.cli_support import new_output_file
        from articutool.sim.render import CAMERAS  # --export renders: it loads this anyway
        from articutool.viewer.export import MAX_FPS

        if args.fps is not None and not (math.isfinite(args.fps) and 0 < args.fps <= MAX_FPS):
            raise UsageError(f"--fps must be in (0, {MAX_FPS:g}] frames/s; got {args.fps}")
        if args.camera is not None and args.camera not in CAMERAS:
            raise UsageError(f"--camera must be one of {', '.join(CAMERAS)}; got "
                             f"{args.camera!r}")
        new_output_file("--export", args.export, (".mp4", ".gif"))  # before any rendering
    spec = spec_from_args(args)
    if args.utensil not in spec.utensils:
        raise UsageError(f"--utensil must be one of {sorted(spec.utensils)}; got "
                         f"{args.utensil!r}")
    rec = motion = None
    if args.recording is not None and Path(args.recording).suffix.lower() == ".mcap":
        from articutool.viewer.mcap_replay import load_mcap_motion

        if args.export is not None:
            raise UsageError("--export renders .npz recordings (the full MuJoCo state); an "
                             ".mcap recording holds joint states only")
        try:
            notes: list[str] = []
            motion = load_mcap_motion(args.recording, spec, notes)
            for note in notes:
                print(f"note: {note}", file=sys.stderr, flush=True)
        except RecordingError as err:
            raise UsageError(f"--recording: {err}") from None
    elif args.recording is not None:
        try:
            rec = Recording.load(args.recording)
        except RecordingError as err:
            raise UsageError(f"--recording: {err}") from None
        if args.export is not None:
            from articutool.sim.render import RenderError
            from articutool.viewer.export import export_video

            try:
                out = export_video(rec, args.export, camera=args.camera or "overview",
                                   fps=args.fps)
            except RecordingError as err:
                raise UsageError(f"--export: {err}") from None
            except RenderError as err:
                print(f"error: {err}", file=sys.stderr)
                return 1
            print(f"video: {out} ({len(rec)} recorded frames, {rec.t[-1] - rec.t[0]:.1f} s)")
            return 0
    _check_address(args.host, args.port)

    from articutool.arm.scene import Scene, SceneError

    try:
        scene = Scene.load(args.scene)
    except SceneError as err:
        raise UsageError(f"--scene: {err}") from None
    view = None
    if args.plan is not None or args.plan_task is not None or motion is not None:
        from articutool.arm.model import ArmModel
        from articutool.viewer.plan import plan_view

        if motion is not None:
            traj, wrist, title = motion, args.wrist, Path(args.recording).name
        elif args.plan is not None:
            from articutool.trajectory import JointTrajectory

            traj = JointTrajectory.load(args.plan)  # TrajectoryError → exit 2 in main
            wrist, title = args.wrist, f"{Path(args.plan).name}"
        else:
            traj, wrist, title = _plan_from_task(args, spec)
        model8 = ArmModel(spec, utensil=args.utensil, scene=scene)
        view = plan_view(traj, model8, spec, wrist=wrist, title=title)
        if args.color == "margin" and view.margin is None:
            raise UsageError("--color margin needs an arm trajectory checked with the leveling "
                             "wrist (plan-then-verify); use --color tilt")
        for line in view.summary:
            print(f"  {line}")

    import mujoco
    import viser

    from articutool.viewer.app import ViewerApp
    from articutool.viewer.geometry import model_for_view

    joint_names = [*spec.arm.joint_names, *spec.wrist.joint_names]
    configs: dict[str, Any] = {}
    if rec is not None:
        model = mujoco.MjModel.from_xml_string(rec.mjcf)
        root = spec.arm.base_frame
        joint_names = list(rec.meta.get("joint_names", joint_names))
    else:
        model, root = model_for_view(spec, scene, args.utensil)
        import numpy as np

        configs = {name: np.concatenate([np.asarray(q, dtype=float), np.zeros(2)])
                   for name, q in spec.arm.configurations.items()}
        if view is not None:
            configs = {}
    def _terminate(signum: int, frame: object) -> None:
        raise KeyboardInterrupt  # SIGTERM stops the server cleanly, as Ctrl-C does

    previous = signal.signal(signal.SIGTERM, _terminate)
    server = viser.ViserServer(host=args.host, port=args.port, verbose=False)
    app = None
    try:
        app = ViewerApp(server, model, root, joint_names, configs)
        if view is not None:
            app.show_plan(view, args.color, start=args.at)
        if rec is not None:
            app.show_replay(rec, start=args.at)
        host = server.get_host()
        shown = f"[{host}]" if ":" in host else host
        print(f"viewer: http://{shown}:{server.get_port()}/ (Ctrl-C stops)", flush=True)
        if host not in ("127.0.0.1", "localhost", "::1"):
            print("warning: the viewer is reachable from the network and has no login; "
                  "prefer the default loopback and an SSH tunnel (ssh -L)", flush=True)
        t_end = math.inf if args.duration is None else time.monotonic() + args.duration
        while time.monotonic() < t_end:
            time.sleep(min(0.2, max(t_end - time.monotonic(), 0.0)))
    except KeyboardInterrupt:
        pass
    finally:
        if app is not None:
            app.close()
        server.stop()
        signal.signal(signal.SIGTERM, previous)
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``view``."""
    from articutool.cli_support import MAX_RUN_S, MAX_WAIT_S, add_spec_option, seconds
    from articutool.planning.types import PLANNERS

    p = sub.add_parser("view", help="3-D web viewer of the scene, the robot's named "
                       "configurations, plans (--plan, --plan-task) and recorded runs "
                       "(--recording); --export renders a recording to video")
    src = p.add_argument_group("what to show (default: the scene and the named configurations)")
    src.add_argument("--plan", metavar="TRAJ.json", default=None,
                     help="a JointTrajectory: 6 arm joints (verified, wrist leveling) or 8")
    src.add_argument("--plan-task", metavar="ID", type=int, default=None,
                     help="plan this task of the benchmark set with --system, then show it")
    src.add_argument("--recording", metavar="FILE", default=None,
                     help="replay a recording: .npz (the physics world, articutool sim/meal "
                          "--record F.npz) or .mcap (joint states of any --record F.mcap)")
    p.add_argument("--system", dest="planner", choices=PLANNERS, default="decoupled",
                   help="planner for --plan-task, the thesis' system (default: decoupled)")
    p.add_argument("--tasks", metavar="FILE", default=None,
                   help="task set for --plan-task (default: the packaged Exp. 2a set)")
    p.add_argument("--timeout", type=seconds(MAX_WAIT_S), default=30.0, metavar="S",
                   help=f"planning budget for --plan-task, in (0, {MAX_WAIT_S:g}] s (default "
                        "30)")
    p.add_argument("--seed", type=int, default=0, help="planner seed for --plan-task")
    p.add_argument("--wrist", choices=("leveling", "locked"), default="leveling",
                   help="for a 6-joint --plan: the wrist levels (verified, default) or is "
                        "locked at zero (rigid tool)")
    p.add_argument("--color", choices=("auto", "margin", "tilt"), default="auto",
                   help="colour the tip path by the verifier's velocity margin or by the "
                        "tilt from vertical (auto: margin when verified)")
    p.add_argument("--at", type=seconds(MAX_RUN_S, zero=True), default=None, metavar="S",
                   help="start the time slider at S seconds (plan or recording time)")
    p.add_argument("--utensil", default="spoon", help="utensil on the wrist (default spoon)")
    p.add_argument("--scene", metavar="FILE", default=None,
                   help="scene TOML (default: the packaged scene)")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1: this machine only)")
    p.add_argument("--port", type=int, default=8080, help="port (default 8080)")
    p.add_argument("--duration", type=seconds(MAX_RUN_S), default=None, metavar="S",
                   help=f"stop serving after S seconds, in (0, {MAX_RUN_S:g}] (default: until "
                        "Ctrl-C)")
    p.add_argument("--export", metavar="VIDEO", default=None,
                   help="with --recording: render it to .mp4/.gif offscreen and exit "
                        "(no browser); never overwrites")
    p.add_argument("--camera", default=None,
                   help="camera for --export: overview, utensil or bowl (default overview)")
    p.add_argument("--fps", type=float, default=None,
                   help="frame rate for --export (default: the recording's rate)")
    add_spec_option(p)
    p.set_defaults(func=_cmd_view)
