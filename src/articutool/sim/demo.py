"""``articutool demo``: plan, verify and execute one transport in simulation (the main job).

1. Plan Resting → Staging with the decoupled planner (6-DOF arm, loose orientation
   constraint, wrist-aware time parameterisation, plan-then-verify).
2. Verify it independently (Alg. 2) and report the velocity margin.
3. Execute it in simulation: the arm follows the trajectory while the simulated wrist, run by
   the onboard filter and leveling loop, keeps the spoon level; report the utensil's tilt.
4. Save a plot of the tilt, the tool base's tilt and the wrist joints.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from articutool.spec import Spec

__all__ = ["add_commands", "run_demo"]

_DEFAULT_PLOT = Path("results/demo_transport.png")


def run_demo(
    spec: Spec,
    *,
    utensil: str = "spoon",
    seed: int = 0,
    timeout_s: float = 10.0,
    plot_path: Path | None = None,
) -> dict[str, Any]:
    """Run the demo; returns the figures (see module docstring)."""
    import articutool.planning.ompl_planner  # noqa: F401  (import OMPL/toppra before timing)
    from articutool.arm.ik import staging_configuration
    from articutool.arm.model import ArmModel
    from articutool.planning.api import plan
    from articutool.planning.types import PlanRequest, TransportTask
    from articutool.sim.transport import simulate_transport
    from articutool.verify.verifier import verify_trajectory

    model = ArmModel(spec, utensil=utensil)
    start = spec.arm.configuration("Resting")
    goal, backoff = staging_configuration(spec, model, seed)
    task = TransportTask(task_id=0, start=tuple(start), goal=tuple(goal))
    t0 = time.perf_counter()
    result = plan(PlanRequest(planner="decoupled", task=task, timeout_s=timeout_s, seed=seed,
                              utensil=utensil), spec)
    plan_time = time.perf_counter() - t0
    figures: dict[str, Any] = {
        "start": "Resting", "goal": "Staging", "staging_backoff_m": backoff,
        "utensil": utensil, "seed": seed,
        "plan_success": result.success, "plan_time_s": plan_time,
        "planner_reported_time_s": result.planning_time_s, "attempts": result.attempts,
        "verification_rejections": result.verification_rejections,
        "plan_message": result.message,
    }
    if not result.success or result.trajectory is None:
        figures.update(feasible=False)
        return figures
    traj = result.trajectory
    rep = verify_trajectory(traj, model, spec)
    figures.update(
        feasible=rep.feasible, verification_reason=rep.reason,
        velocity_margin=rep.velocity_margin,
        max_required_wrist_velocity=list(rep.max_required_velocity),
        duration_s=traj.duration, path_length_rad=result.path_length, waypoints=len(traj),
    )
    if not rep.feasible:
        return figures
    sim = simulate_transport(traj, model, spec, seed=seed)
    figures.update(
        max_tilt_error_deg=sim.max_tilt_error_deg,
        rms_tilt_error_deg=sim.rms_tilt_error_deg,
        final_tilt_error_deg=sim.final_tilt_error_deg,
        max_base_tilt_deg=float(sim.base_tilt_deg[(sim.times >= 0)].max()),
        sim_faults=list(sim.faults),
    )
    if plot_path is not None:
        _plot(sim, plot_path)
        figures["plot"] = str(plot_path)
    return figures


def _plot(sim: Any, path: Path) -> None:
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    ax1.plot(sim.times, sim.base_tilt_deg, color="0.6", label="tool base (rigid tool) tilt")
    ax1.plot(sim.times, sim.tilt_deg, color="C1", label="spoon tilt with wrist leveling")
    ax1.axvspan(0, sim.duration_s, color="C0", alpha=0.06, label="arm moving")
    ax1.set_ylabel("tilt from level (deg)")
    ax1.set_yscale("symlog", linthresh=1.0)
    ax1.legend(loc="upper right", fontsize=8)
    ax1.set_title("Decoupled transport Resting → Staging, simulated wrist leveling")
    ax2.plot(sim.times, np.degrees(sim.wrist_q[:, 0]), label="pitch")
    ax2.plot(sim.times, np.degrees(sim.wrist_q[:, 1]), label="roll")
    ax2.set_xlabel("time from start of arm motion (s)")
    ax2.set_ylabel("wrist joints (deg)")
    ax2.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    from articutool.datafile import publish_new

    path.parent.mkdir(parents=True, exist_ok=True)
    try:  # a new file: nothing replaced or written through a link
        publish_new(path, lambda tmp: fig.savefig(tmp, dpi=110))
    finally:
        plt.close(fig)


def _plot_path(arg: str, default: bool) -> Path:
    """Where ``--plot`` says: a file, which must not exist (never overwritten), or, in a
    folder (an existing one, or one written with a trailing slash, created), the first of
    ``demo_transport.png``, ``demo_transport-2.png``, … that does not exist; the default
    ``--plot`` is such a folder choice too, so ``make demo`` can run again. Checked (the file
    created and removed) before any planning."""
    from matplotlib.figure import Figure

    from articutool.cli_support import UsageError, new_output_file, output_dir

    p = Path(arg)
    pick_free = default or p.is_dir() or arg.endswith(("/", "\\"))
    if p.is_dir() or arg.endswith(("/", "\\")):
        p = p / _DEFAULT_PLOT.name
    formats = Figure().canvas.get_supported_filetypes()
    if p.suffix.lstrip(".").lower() not in formats:
        raise UsageError(f"--plot {arg}: the file name must end in one of "
                         f"{', '.join('.' + f for f in sorted(formats))} (e.g. .png)")
    if p.parent.exists() and not p.parent.is_dir():
        raise UsageError(f"--plot {arg}: {p.parent} is not a directory")
    if pick_free:
        output_dir("--plot", p.parent)
        stem, n = p.stem, 1
        while p.exists() or p.is_symlink():
            n += 1
            p = p.with_name(f"{stem}-{n}{p.suffix}")
    out = new_output_file("--plot", str(p), tuple("." + f for f in formats))
    assert out is not None
    return out


def _cmd_demo(args: argparse.Namespace) -> int:
    from articutool.cli_support import UsageError, spec_from_args

    if args.seed < 0:
        raise UsageError(f"--seed must be an integer >= 0; got {args.seed}")
    spec = spec_from_args(args)
    if args.utensil not in spec.utensils:
        raise UsageError(f"--utensil must be one of {sorted(spec.utensils)}; got {args.utensil!r}")
    plot = None if args.no_plot else _plot_path(args.plot or str(_DEFAULT_PLOT),
                                                 default=args.plot is None)  # loads matplotlib
    figures = run_demo(spec, utensil=args.utensil, seed=args.seed, timeout_s=args.timeout,
                       plot_path=plot)
    if args.json:
        print(json.dumps(figures, indent=1))
    else:
        _print(figures)
    ok = figures.get("feasible", False) and not figures.get("sim_faults")
    return 0 if ok else 1


def _print(f: dict[str, Any]) -> None:
    print(f"plan   Resting → Staging (decoupled, {f['utensil']}): "
          f"{'ok' if f['plan_success'] else 'FAILED'} in {f['plan_time_s'] * 1e3:.0f} ms, "
          f"{f['attempts']} attempt(s), {f['verification_rejections']} verifier rejection(s)")
    if not f["plan_success"]:
        print(f"       {f['plan_message']}")
        return
    print(f"verify {'feasible' if f['feasible'] else 'INFEASIBLE'}: velocity margin "
          f"{f['velocity_margin']:.1%}, peak wrist rates "
          f"{f['max_required_wrist_velocity'][0]:.2f} / {f['max_required_wrist_velocity'][1]:.2f}"
          f" rad/s, duration {f['duration_s']:.2f} s")
    if "max_tilt_error_deg" in f:
        print(f"sim    spoon tilt while moving: max {f['max_tilt_error_deg']:.2f}°, "
              f"RMS {f['rms_tilt_error_deg']:.2f}° (tool base tilted up to "
              f"{f['max_base_tilt_deg']:.1f}°); final {f['final_tilt_error_deg']:.2f}°")
        if f["sim_faults"]:
            print(f"       faults: {f['sim_faults']}")
    if "plot" in f:
        print(f"plot   {f['plot']}")


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``demo``."""
    from articutool.cli_support import MAX_WAIT_S, add_spec_option, seconds

    p = sub.add_parser("demo", help="plan, verify and execute one transport in simulation")
    p.add_argument("--utensil", default="spoon", help="utensil (default: spoon)")
    p.add_argument("--seed", type=int, default=0, help="planner and simulation seed")
    p.add_argument("--timeout", type=seconds(MAX_WAIT_S), default=10.0, metavar="S",
                   help=f"planning budget in (0, {MAX_WAIT_S:g}] s (default 10)")
    p.add_argument("--plot", default=None,
                   help=f"where to save the plot: a new .png/.pdf/.svg file, or a directory to "
                        f"write {_DEFAULT_PLOT.name} (or -2, -3, … when taken) into (default: "
                        f"{_DEFAULT_PLOT})")
    p.add_argument("--no-plot", action="store_true", help="do not save a plot")
    p.add_argument("--json", action="store_true", help="machine-readable figures")
    add_spec_option(p)
    p.set_defaults(func=_cmd_demo)
