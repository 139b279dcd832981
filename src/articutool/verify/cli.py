"""``articutool verify``: plan-then-verify an arm trajectory file."""

from __future__ import annotations

import argparse
import json
import math

__all__ = ["add_commands"]


def _load(args: argparse.Namespace, spec: object) -> object:
    """The ``--load FOOD:GRAMS`` as a FoodLoad checked against the utensil (UsageError)."""
    from articutool.cli_support import UsageError
    from articutool.food.definitions import FoodError, load_food_definitions
    from articutool.food.loads import LoadError, named_load, parse_load
    from articutool.verify.food import spill_model

    try:
        food, grams = parse_load(args.load)
        try:
            foods = load_food_definitions(args.physics)
        except FoodError as err:
            raise UsageError(f"--physics: {err}") from None
        load = named_load(food, grams, foods)
        spill_model(spec, args.utensil, load)  # type: ignore[arg-type]
    except LoadError as err:
        raise UsageError(str(err)) from None
    return load


def _print_food(rep: object) -> None:
    f = rep.food  # type: ignore[attr-defined]
    sf = rep.slosh_free  # type: ignore[attr-defined]
    if sf is not None and not sf.ok:
        print(f"  slosh-free wrist not used: {sf.message}")
    if f is None:
        return
    p = f.prediction
    print(f"  load {f.load.grams:g} g {f.load.food} ({f.load.kind}), wrist "
          f"{f.wrist.replace('_', '-')}: peak apparent tilt {p.peak_apparent_tilt_deg:.2f}°, "
          f"peak surface tilt {p.peak_surface_tilt_deg:.2f}°, margin to the first spill "
          f"{p.min_margin_deg:.2f}°, predicted spill {p.spilled_g:.3f} g")


def _cmd_verify(args: argparse.Namespace) -> int:
    from articutool.cli_support import UsageError, new_output_file, spec_from_args

    spec = spec_from_args(args)
    if args.utensil not in spec.utensils:
        raise UsageError(f"--utensil must be one of {sorted(spec.utensils)}; got {args.utensil!r}")
    if args.slosh_free and args.load is None:
        raise UsageError("--slosh-free needs --load FOOD:GRAMS")
    load = _load(args, spec) if args.load is not None else None
    new_output_file("--wrist-out", args.wrist_out, (".json",))
    from articutool.trajectory import JointTrajectory

    traj = JointTrajectory.load(args.trajectory)
    from articutool.arm.model import ArmModel  # the kinematics: once the trajectory is good
    from articutool.verify.verifier import verify_trajectory

    model = ArmModel(spec, utensil=args.utensil)
    rep = verify_trajectory(traj, model, spec, max_step_deg=args.max_step_deg,
                            load=load, utensil=args.utensil,  # type: ignore[arg-type]
                            slosh_free=args.slosh_free)
    if args.wrist_out is not None:
        sf = rep.slosh_free
        if sf is not None and sf.ok:
            sf.combined().save(args.wrist_out)
        elif rep.wrist_trajectory is not None:
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
        _print_food(rep)
    return 0 if rep.feasible else 1


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``verify``."""
    from articutool.cli_support import add_spec_option

    p = sub.add_parser(
        "verify",
        help="check that the wrist can keep the utensil level along an arm trajectory, and "
             "with --load that the food does not spill (exit 0 feasible, 1 infeasible or "
             "predicted to spill, 2 bad input)",
    )
    p.add_argument("trajectory", metavar="TRAJ.json", help="arm JointTrajectory as JSON")
    p.add_argument("--utensil", default="spoon", help="utensil on the wrist (default: spoon)")
    p.add_argument("--max-step-deg", type=float, default=1.0,
                   help="densify so no step rotates the tool more than this (default 1°)")
    p.add_argument("--wrist-out", metavar="FILE", default=None,
                   help="write the synchronised leveling (wrist) trajectory as JSON; with "
                        "--slosh-free the arm's and the slosh-free wrist's joints on one clock")
    p.add_argument("--load", metavar="FOOD:GRAMS", default=None,
                   help="food-aware verification: the load on the utensil (e.g. water:8); "
                        "predicts the dish's apparent tilt, the liquid's surface tilt, the "
                        "margin to the first spill and the grams spilled")
    p.add_argument("--slosh-free", action="store_true",
                   help="with --load: level against the apparent gravity g - a of the planned "
                        "motion (plain leveling if the tool would refuse that trajectory)")
    p.add_argument("--physics", metavar="FILE", default=None,
                   help="physics parameters TOML for the food's properties (default: packaged)")
    p.add_argument("--json", action="store_true", help="machine-readable report")
    add_spec_option(p)
    p.set_defaults(func=_cmd_verify)
