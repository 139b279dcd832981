"""``articutool verify``: plan-then-verify an arm trajectory file."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

__all__ = ["add_commands"]


def _cmd_verify(args: argparse.Namespace) -> int:
    from articutool.arm.model import ArmModel
    from articutool.cli_support import UsageError, spec_from_args
    from articutool.trajectory import JointTrajectory
    from articutool.verify.verifier import verify_trajectory

    spec = spec_from_args(args)
    if args.utensil not in spec.utensils:
        raise UsageError(f"--utensil must be one of {sorted(spec.utensils)}; got {args.utensil!r}")
    if args.wrist_out is not None:
        out = Path(args.wrist_out)
        if out.exists():
            raise UsageError(f"--wrist-out {out} exists; refusing to overwrite it")
        if not out.parent.is_dir():
            raise UsageError(f"--wrist-out {out}: directory {out.parent} does not exist")
    traj = JointTrajectory.load(args.trajectory)
    model = ArmModel(spec, utensil=args.utensil)
    rep = verify_trajectory(traj, model, spec, max_step_deg=args.max_step_deg)
    if args.wrist_out is not None and rep.wrist_trajectory is not None:
        rep.wrist_trajectory.save(args.wrist_out)
    if args.json:
        print(json.dumps(rep.to_dict(), indent=1))
    else:
        status = "FEASIBLE" if rep.feasible else f"INFEASIBLE ({rep.reason})"
        print(f"{status}: {rep.message}")
        print(f"  waypoints {rep.waypoints}, samples checked {rep.samples_checked} "
              f"(≤ {rep.max_step_deg:g}° tool rotation per step)")
        print(f"  max required wrist velocity [pitch, roll]: "
              f"[{rep.max_required_velocity[0]:.3f}, {rep.max_required_velocity[1]:.3f}] rad/s "
              f"(limits {list(rep.velocity_limits)}), margin "
              + (f"{rep.velocity_margin:.1%}" if math.isfinite(rep.velocity_margin)
                 else "unknown (no sample's rates evaluated)"))
        print(f"  branch switches {rep.branch_switches}, "
              f"min |cos roll| {rep.min_singularity_measure:.3f}")
        if rep.first_failure_time is not None:
            print(f"  first failure at t = {rep.first_failure_time:.3f} s "
                  f"(after waypoint {rep.first_failure_index})")
    return 0 if rep.feasible else 1


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``verify``."""
    from articutool.cli_support import add_spec_option

    p = sub.add_parser(
        "verify",
        help="check that the wrist can keep the utensil level along an arm trajectory "
             "(exit 0 feasible, 1 infeasible, 2 bad input)",
    )
    p.add_argument("trajectory", metavar="TRAJ.json", help="arm JointTrajectory as JSON")
    p.add_argument("--utensil", default="spoon", help="utensil on the wrist (default: spoon)")
    p.add_argument("--max-step-deg", type=float, default=1.0,
                   help="densify so no step rotates the tool more than this (default 1°)")
    p.add_argument("--wrist-out", metavar="FILE", default=None,
                   help="write the synchronised leveling (wrist) trajectory as JSON")
    p.add_argument("--json", action="store_true", help="machine-readable report")
    add_spec_option(p)
    p.set_defaults(func=_cmd_verify)
