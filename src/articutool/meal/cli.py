"""``articutool meal``: bites with the feeding tree in the physics world.

Prints the tree's progress live (the running behaviour, planning attempts, simulated time)
and one record per bite; ``--json`` prints the records; ``--show-tree`` prints the tree and
writes it as a Graphviz file instead of running.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
from pathlib import Path
from typing import Any

__all__ = ["add_commands"]

_SYSTEMS = ("articutool", "baseline")
_TREE_SUFFIXES = (".dot", ".png", ".svg")


def _check(args: argparse.Namespace) -> Any:
    """Validate the arguments (exit 2 naming the field) and return the strategy library."""
    from articutool.cli_support import MAX_MASS_G, UsageError, spec_from_args
    from articutool.feeding.strategies import StrategyError, StrategyLibrary

    if args.threshold is not None and not (math.isfinite(args.threshold)
                                           and 0 <= args.threshold <= MAX_MASS_G):
        raise UsageError(f"--threshold must be a mass in [0, {MAX_MASS_G:g}] g; "
                         f"got {args.threshold}")
    if not 1 <= args.bites <= 100:
        raise UsageError(f"--bites must be an integer in [1, 100]; got {args.bites}")
    if args.seed < 0:
        raise UsageError(f"--seed must be an integer >= 0; got {args.seed}")
    try:
        lib = StrategyLibrary.load(spec_from_args(args), args.strategies)
    except StrategyError as err:
        raise UsageError(f"--strategies: {err}") from None
    foods = sorted({s.food for s in lib.strategies.values() if s.system == args.system})
    if args.food not in foods:
        raise UsageError(f"--food: no {args.system} strategy for {args.food!r}; allowed: "
                         f"{', '.join(foods)}")
    return lib


def _threshold(args: argparse.Namespace) -> float:
    """The meaningful-success threshold: ``--threshold``, else derived from our own Exp. 1
    data, as the thesis derived its own (exit 2 when there is none). Read after every
    argument is checked: the data are consulted only for a well-formed command."""
    from articutool.cli_support import MAX_MASS_G, UsageError

    if args.threshold is not None:
        return float(args.threshold)
    from articutool.thresholds import DEFAULT_OUT, exp1_means

    threshold = exp1_means().get(args.food)
    if threshold is None:
        raise UsageError(f"--threshold: no Exp. 1 result for {args.food} in {DEFAULT_OUT} "
                         "to derive it from; run `articutool experiment exp1` or pass "
                         "--threshold G")
    if not (math.isfinite(threshold) and 0 <= threshold <= MAX_MASS_G):
        raise UsageError(f"--threshold must be a mass in [0, {MAX_MASS_G:g}] g; got {threshold}")
    return threshold


def _show_tree(args: argparse.Namespace, lib: Any, out: Path | None) -> int:
    import numpy as np
    import py_trees

    from articutool.arm.scene import SCOOP_HEADING, Scene, container_floor
    from articutool.feeding.bite import bite_tree
    from articutool.feeding.insertion import acquisition_waypoints, dish_outline
    from articutool.feeding.system import System
    from articutool.sim.params import PhysicsParams
    from articutool.spec import load_spec

    name, strat = lib.choose(args.food, args.system, np.random.default_rng(args.seed))
    container = PhysicsParams.load().food(args.food).container
    wps = acquisition_waypoints(strat, container_floor(Scene.load(), container), SCOOP_HEADING,
                                dish_outline(load_spec(), strat.utensil))
    # The tree's shape needs no arm, tool or user; nothing is ticked.
    root = bite_tree(None, None, strat, wps, lambda: 0.0,  # type: ignore[arg-type]
                     system=System.from_strategy(strat), user=None)  # type: ignore[arg-type]
    print(f"bite tree for {args.food} with {args.system} (strategy {name}):")
    print(py_trees.display.unicode_tree(root))
    if out is not None:
        graph = py_trees.display.dot_tree(root)
        if out.suffix.lower() == ".dot":
            graph.write(str(out), format="raw")
        else:
            if shutil.which("dot") is None:
                print(f"error: --show-tree: writing {out.suffix} needs Graphviz's `dot` "
                      "(`make` installs it: Debian package graphviz); .dot works without",
                      file=sys.stderr)
                return 2
            graph.write(str(out), format=out.suffix.lower()[1:])
        print(f"tree: {out}")
    return 0


def _print_bite(r: Any) -> None:
    spills = ", ".join(f"{g:.2f} g on the {'user' if p == 'critical' else p}"
                       for p, g in r.spilled_by_place.items() if g > 0) or "none"
    attempts = ", ".join(f"{k} {v}" for k, v in r.planning_attempts_by_goal.items())
    print(f"bite {r.bite + 1}: {r.outcome.replace('_', ' ')} ({r.strategy})")
    print(f"  acquired {r.acquired_g:.2f} g, shed into the bowl {r.shed_g:.2f} g, "
          f"delivered {r.delivered_g:.2f} g; spilled: {spills}")
    print(f"  planning attempts: {attempts or 'none'}; planning {r.planning_wall_s:.1f} s "
          f"(planner wall time; {r.planning_wait_sim_s:.1f} s simulated wait), "
          f"motion {r.motion_time_s:.1f} s; utensil tilt in transport max "
          f"{r.transport_max_tilt_deg:.1f}°")
    print(f"  {r.sim_time_s:.1f} s simulated in {r.wall_time_s:.1f} s wall")
    if r.failed_stage:
        print(f"  {r.end_state} at: {r.failed_stage}")


def _cmd_meal(args: argparse.Namespace) -> int:
    from articutool.cli_support import UsageError, new_output_file

    lib = _check(args)
    if args.show_tree is not False:
        return _show_tree(args, lib, new_output_file("--show-tree", args.show_tree, _TREE_SUFFIXES))
    video = new_output_file("--video", args.video, (".mp4", ".gif"))
    record = new_output_file("--record", args.record, (".npz", ".mcap"))
    args.threshold = _threshold(args)
    from articutool.meal.bites import make_bite_world, run_meal
    from articutool.meal.progress import TreeProgress

    try:
        setup = make_bite_world(args.food, args.system, args.seed, strategies=args.strategies)
    except ValueError as err:
        raise UsageError(str(err)) from None
    recorder = None
    if video is not None:
        from articutool.sim.render import Recorder, RenderError

        try:
            # A short video: 8 frames/s at 480×360 (software EGL renders ~0.2 s a frame).
            recorder = Recorder(setup.world, fps=8.0, camera="overview", width=480,
                                height=360)
        except RenderError as err:
            print(f"error: --video: {err}", file=sys.stderr)
            return 1
    data_rec = mcap_rec = None
    meta = {"food": args.food, "system": args.system, "seed": args.seed,
            "strategy": setup.strategy_name}
    visitors: list[Any] = []
    if record is not None and record.suffix.lower() == ".mcap":
        from articutool.link.recording import RecordingError
        from articutool.sim.mcap_record import WorldMcapRecorder

        try:
            mcap_rec = WorldMcapRecorder(setup.world, record, metadata=meta)
        except RecordingError as err:
            raise UsageError(f"--record: {err}") from None
        visitors.append(mcap_rec.tree_visitor)
    elif record is not None:
        from articutool.sim.recording import Recorder as DataRecorder

        data_rec = DataRecorder(setup.world, extra={"meal": meta})
    from articutool.sim.world import PhysicsResetError

    progress = TreeProgress(setup.world, live=not args.json)
    try:
        bites = run_meal(args.food, args.system, bites=args.bites, seed=args.seed,
                         threshold_g=args.threshold, setup=setup,
                         visitors=[progress, *visitors],
                         on_bite=None if args.json else _print_bite)
    except PhysicsResetError as err:
        print(f"error: {err}; the meal stopped", file=sys.stderr)
        return 1
    finally:
        progress.stop()
        if mcap_rec is not None:  # also on Ctrl-C: the file is then complete
            mcap_rec.close()
    if recorder is not None:
        recorder.save(video)
    if data_rec is not None:
        data_rec.save(record)
    if args.json:
        print(json.dumps({"food": args.food, "system": args.system, "seed": args.seed,
                          "threshold_g": args.threshold,
                          "bites": [b.to_dict() for b in bites],
                          "video": str(video) if video else None,
                          "recording": str(record) if record else None}, indent=2))
    else:
        for what, path in (("video", video), ("recording", record)):
            if path is not None:
                print(f"{what}: {path}")
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``meal``."""
    from articutool.cli_support import add_spec_option

    p = sub.add_parser("meal", help="bites with the feeding behaviour tree in the physics "
                       "world (acquire, level, shed, transport, present, return)")
    p.add_argument("--food", default="noodles", help="food with a strategy in the action "
                   "library (packaged: noodles, pecans, water; default: noodles)")
    p.add_argument("--system", choices=_SYSTEMS, default="articutool",
                   help="articutool (active wrist, decoupled transport) or baseline (rigid "
                        "6-DOF, wrist locked, strict ±20° transport)")
    p.add_argument("--bites", type=int, default=1, help="bites in the meal (1–100)")
    p.add_argument("--seed", type=int, default=0,
                   help="food placement, sensor noise, planner and strategy choice")
    p.add_argument("--strategies", metavar="FILE", default=None,
                   help="action library: TOML, or JSON if it ends in .json (default: the "
                        "packaged strategies.toml)")
    p.add_argument("--threshold", type=float, default=None, metavar="G",
                   help="a bite above G grams is a meaningful success (default: our Exp. 1 "
                        "Articutool mean for the food, results/experiments)")
    p.add_argument("--video", metavar="FILE", default=None,
                   help="record the meal (.mp4 or .gif, overview camera); never overwrites")
    p.add_argument("--record", metavar="FILE", default=None,
                   help="record the meal: .mcap (ROS 2 messages: tool telemetry and commands "
                        "as the link carries them, arm joints, food, tree status) or .npz "
                        "(the full MuJoCo state for articutool view --recording); never "
                        "overwrites")
    p.add_argument("--json", action="store_true", help="the bite records as JSON")
    p.add_argument("--show-tree", nargs="?", const=None, default=False, metavar="FILE",
                   help="print the bite tree and write it to FILE (.dot, .png, .svg) "
                        "instead of running")
    add_spec_option(p)
    p.set_defaults(func=_cmd_meal)
