"""``articutool sim``: a short scripted scene in the physics world, and the world's report.

``articutool sim-calibrate``: the calibration experiments that measure what the food models'
parameters produce (angle of repose, what a level utensil holds), so they can be checked
against physical properties — never tuned to an outcome of the thesis.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from articutool.sim.params import PhysicsParams

__all__ = ["add_commands"]


def _world_args(args: argparse.Namespace) -> dict[str, Any]:
    from articutool.cli_support import UsageError, spec_from_args
    from articutool.sim.params import PhysicsError, PhysicsParams

    try:
        params = PhysicsParams.load(args.physics)
    except PhysicsError as err:
        raise UsageError(str(err)) from None
    if args.food not in params.foods:
        raise UsageError(f"--food: unknown food {args.food!r}; allowed: {sorted(params.foods)}")
    spec = spec_from_args(args)
    if args.utensil is not None and args.utensil not in spec.utensils:
        raise UsageError(f"--utensil: unknown utensil {args.utensil!r}; allowed: "
                         f"{sorted(spec.utensils)}")
    if args.seed < 0:
        raise UsageError(f"--seed must be an integer >= 0; got {args.seed}")
    return {"spec": spec, "params": _liquid_options(args, params), "seed": args.seed}


def _liquid_options(args: argparse.Namespace, params: PhysicsParams) -> PhysicsParams:
    """``--liquid`` and ``--liquid-radius`` applied to a liquid food's parameters (exit 2
    outside the validated radii or for a food that is no liquid); the liquid solver loaded
    when the liquid is SPH (exit 2 with the loader's message when it cannot be)."""
    from articutool.cli_support import UsageError
    from articutool.sim.params import SPH_RADIUS_RANGE_M, Liquid
    from articutool.sim.sph_library import LiquidLibraryError, load_splishsplash

    fp = params.food(args.food)
    update: dict = {}
    for opt, key, value in (("--liquid", "load_model", args.liquid),
                            ("--liquid-radius", "sph_particle_radius", args.liquid_radius)):
        if value is None:
            continue
        if not isinstance(fp, Liquid):
            raise UsageError(f"{opt}: {args.food} is {fp.kind}, not a liquid")
        update[key] = value
    if args.liquid_radius is not None:
        lo, hi = SPH_RADIUS_RANGE_M
        r = args.liquid_radius
        if not (math.isfinite(r) and lo * 1e3 - 1e-9 <= r <= hi * 1e3 + 1e-9):
            raise UsageError(f"--liquid-radius must be in [{lo * 1e3:g}, {hi * 1e3:g}] mm "
                             f"(the SPH particle radii the static-tilt checks validated); "
                             f"got {r:g}")
        update["sph_particle_radius"] = r / 1e3
    if update:
        assert isinstance(fp, Liquid)
        fp = fp.model_copy(update=update)
        params = params.model_copy(update={"foods": {**params.foods, args.food: fp}})
    if isinstance(fp, Liquid) and fp.sph_load:  # a load, and the container's fill
        try:
            load_splishsplash()
        except LiquidLibraryError as err:
            raise UsageError(str(err)) from None
    return params


def _check_load(args: argparse.Namespace, kw: dict) -> None:
    """``--load``: a mass the utensil can hold of the food, else exit 2."""
    from articutool.cli_support import UsageError
    from articutool.sim.placement import capacity_bound_reason, utensil_capacity_bound_g

    if args.load is None:
        return
    fp = kw["params"].food(args.food)
    most = utensil_capacity_bound_g(kw["spec"], kw["params"], args.food, args.utensil)
    if not (math.isfinite(args.load) and 0 < args.load <= most):
        raise UsageError(f"--load must be a mass in (0, {most:.2f}] g, the most the "
                         f"{args.utensil or fp.utensil} can hold of {args.food} "
                         f"({capacity_bound_reason(fp)}); got {args.load}")


def _write_mjcf(args: argparse.Namespace) -> int:
    """``--mjcf FILE``: write the world (food placed with the seed, the arm at Resting in the
    keyframe ``start``) for MuJoCo's viewer, and run nothing."""
    from articutool.arm.scene import Scene
    from articutool.cli_support import UsageError, new_output_file
    from articutool.sim.placement import load_supply_g
    from articutool.sim.world_spec import build_world_spec, viewer_mjcf

    out = new_output_file("--mjcf", args.mjcf, (".xml",))
    assert out is not None
    kw = _world_args(args)
    _check_load(args, kw)
    spec, params = kw["spec"], kw["params"]
    utensil = args.utensil or params.food(args.food).utensil
    supply = load_supply_g(params, args.food, args.load)
    try:
        layout = build_world_spec(spec, Scene.load(), params, utensil, args.food, args.seed, supply)
    except ValueError as err:  # e.g. strands cannot be placed as a load
        raise UsageError(f"--load: {err}") from None
    text = viewer_mjcf(layout, spec.arm.configuration("Resting"))
    try:
        with out.open("x", encoding="utf-8") as f:  # never replaces a file or a link
            f.write(text)
    except OSError as err:
        raise UsageError(f"--mjcf: cannot create {out}: {err.strerror}") from None
    print(f"world: {out} ({args.food} on the {utensil}, seed {args.seed}); open it with "
          f"`python -m mujoco.viewer --mjcf {out}` and load the keyframe 'start'")
    return 0


def _cmd_sim(args: argparse.Namespace) -> int:
    from articutool.cli_support import UsageError, new_output_file

    if args.mjcf is not None:
        return _write_mjcf(args)
    new_output_file("--video", args.video, (".mp4", ".gif"))
    new_output_file("--snapshot", args.snapshot, (".png",))
    new_output_file("--record", args.record, (".npz",))
    kw = _world_args(args)
    _check_load(args, kw)
    if args.twirl_turns is not None:
        _check_twirl(args, kw)
    # The world and the planners (toppra, scipy, matplotlib): imported once the input is good.
    from articutool.planning.tip_paths import PathError
    from articutool.sim.render import RenderError
    from articutool.sim.scenes import run_script
    from articutool.sim.world import FeedingWorld, PhysicsResetError
    try:
        world = FeedingWorld.make(args.food, args.utensil, load_g=args.load, **kw)
    except ValueError as err:  # e.g. strands cannot be placed as a load
        raise UsageError(f"--load: {err}") from None
    recorder = None
    data_rec = None
    try:
        if args.video is not None:
            from articutool.sim.render import Recorder

            recorder = Recorder(world)
        if args.record is not None:
            from articutool.sim.recording import Recorder as DataRecorder

            data_rec = DataRecorder(world, extra={
                "script": args.script, "level": args.level, "load_g": args.load})
        report = run_script(world, args.script, level=args.level,
                            twirl_turns=args.twirl_turns)
        if recorder is not None:
            recorder.save(args.video)
        if data_rec is not None:
            from articutool.sim.recording import RecordingError

            try:
                data_rec.save(args.record)
            except RecordingError as err:
                raise UsageError(f"--record: {err}") from None
        if args.snapshot is not None:
            from articutool.sim.render import save_png

            save_png(world, args.snapshot)
    except (RenderError, PathError, PhysicsResetError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    out = report.to_dict()
    out.update(script=args.script, level=args.level, seed=args.seed,
               tool_fault=world.tool.fault, final_tilt_deg=round(world.tilt_deg(), 3))
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"{args.script} with {args.food} on the {world.utensil}, "
          f"{'leveling' if args.level else 'wrist locked'}, seed {args.seed}: "
          f"{report.t:.1f} s simulated at {report.realtime_factor:.2f}x real time")
    ft = (" (F/T sensor: not comparable, turned away from its tare orientation)"
          if report.ft_mass_g is None else f" (F/T sensor: {report.ft_mass_g:.2f} g)")
    g = report.masses_g
    print(f"  on the utensil {g['utensil']:7.2f} g{ft}")
    print(f"  in the bowl    {g['container']:7.2f} g")
    print(f"  on the table   {g['table']:7.2f} g (non-critical spill)")
    print(f"  critical       {g['critical']:7.2f} g (user, wheelchair, floor)")
    for s in report.spills[:8]:
        print(f"  spill at {s.t:6.2f} s: {s.mass_g:.2f} g on {s.where} ({s.place})")
    if len(report.spills) > 8:
        print(f"  … {len(report.spills) - 8} more spill events (--json lists them all)")
    print(f"  utensil tilt at the end {world.tilt_deg():.1f}°; arm tracking error max "
          f"{math.degrees(report.arm_tracking_error_rad):.2f}°"
          + (f"; tool fault: {world.tool.fault}" if world.tool.fault else ""))
    for what, path in (("video", args.video), ("snapshot", args.snapshot),
                       ("recording", args.record)):
        if path is not None:
            print(f"  {what}: {path}")
    return 0


def _check_twirl(args: argparse.Namespace, kw: dict) -> None:
    """``--twirl-turns``: a fork's acquisition only, within the wrist's cable budget."""
    from articutool.cli_support import UsageError
    from articutool.sim.twirl import max_twirl_turns

    hi = max_twirl_turns(kw["spec"])
    n = args.twirl_turns
    if not (math.isfinite(n) and 0 <= n <= hi):
        raise UsageError(f"--twirl-turns must be a number of turns in [0, {hi:g}] (the roll "
                         f"joint's cable budget less 0.1 turn); got {n}")
    utensil = args.utensil or kw["params"].food(args.food).utensil
    if kw["spec"].utensil(utensil).physics.kind != "fork" or args.load is not None:
        raise UsageError("--twirl-turns applies to a fork's acquisition from the bowl "
                         f"(--utensil fork, no --load); got --utensil {utensil}"
                         + (" with --load" if args.load is not None else ""))


def _liquid_load(args: argparse.Namespace, kw: dict, default: float | None) -> float | None:
    """``--load`` of a liquid: a mass the level utensil holds, else exit 2."""
    from articutool.cli_support import UsageError
    from articutool.sim.params import Liquid
    from articutool.sim.placement import capacity_bound_reason, utensil_capacity_bound_g

    food = kw["params"].food(args.food)
    load = args.load if args.load is not None else default
    if load is None or not isinstance(food, Liquid):
        return load
    most = utensil_capacity_bound_g(kw["spec"], kw["params"], args.food, args.utensil)
    if not (math.isfinite(load) and 0 < load <= most):
        raise UsageError(f"--load must be a mass in (0, {most:.2f}] g, the most the "
                         f"{args.utensil or food.utensil} can hold of {args.food} "
                         f"({capacity_bound_reason(food)}); got {load}")
    return load


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from articutool.cli_support import UsageError
    from articutool.sim.calibrate import run_calibration
    from articutool.sim.params import Liquid

    kw = _world_args(args)
    if args.load is not None and not isinstance(kw["params"].food(args.food), Liquid):
        raise UsageError(f"--load: the static-tilt test is for liquids; {args.food} is "
                         f"{kw['params'].food(args.food).kind}")
    load = _liquid_load(args, kw, None)
    try:
        result = run_calibration(args.food, args.utensil, load_g=load, **kw)
    except ValueError as err:
        raise UsageError(str(err)) from None
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    if "capstan_bar" in result:  # strands: the table of laws
        from articutool.sim.strand_laws import table

        print(table(result))
        return 0
    tilt = result.pop("static_tilt", None)
    liquid = result.pop("liquid", None)
    for k, v in result.items():
        print(f"{k:28s} {v}")
    if liquid is not None:
        _print_liquid(liquid)
    if tilt is not None:
        print(f"static tilt of {tilt['load_g']:g} g on the {tilt['utensil']} (held "
              f"{tilt['hold_s']:g} s at each tilt; hydrostatics of the load that stayed):")
        for d in ("tip", "side"):
            t = tilt[d]
            print(f"  {'over the tip' if d == 'tip' else 'sideways'}: {t['kept_g']:.2f} g "
                  f"stayed when placed; onset {t['onset_deg']}° (hydrostatics "
                  f"{t['hydrostatic_onset_deg']}°)")
            print("    tilt °   spilled g   hydrostatics g")
            for r in t["rows"]:
                print(f"    {r['tilt_deg']:6.1f}   {r['spilled_g']:9.2f}   "
                      f"{r['hydrostatic_g']:14.2f}")
        print(f"  {tilt['cpu_s']} s CPU, {tilt['realtime_factor']}x real time")
    return 0


def _print_liquid(liquid: dict[str, Any]) -> None:
    """The SPH liquid's checks, each beside its law."""
    print(f"liquid: {liquid['backend']} {liquid['version']}, particle radius "
          f"{liquid['particle_radius_mm']:g} mm")
    for t in liquid["static_tilt"]:
        o = t["onset"]
        holds = ", ".join(f"{h['tilt_deg']:g}° {h['spilled_g']:.2f} g ({h['hydrostatic_g']:.2f})"
                          for h in t["holds"])
        print(f"  static tilt {t['load_g']:g} g {t['direction']:4s} r {t['particle_radius_mm']:g}"
              f" mm: onset {o['measured_deg']}° ({o['law_deg']}°); {holds}: "
              f"{'passes' if t['passes'] else 'FAILS'}")
    w = liquid["weighing"]
    print(f"  weighing: F/T {w['ft_sensor_g']} g, scale {w['scale_g']} g for {w['held_g']} g: "
          f"{'passes' if w['passes'] else 'FAILS'}")
    from articutool.sim.liquid_tilt import check_passes

    for d in liquid["dynamic"]:
        print(f"  {d.get('check', '?')}: {'passes' if check_passes(d) else 'FAILS'}")


def _common(p: argparse.ArgumentParser) -> None:
    from articutool.cli_support import add_spec_option

    p.add_argument("--food", default="pecans", help="food of the physics parameters "
                   "(packaged: pecans, water, noodles; default: pecans)")
    p.add_argument("--utensil", default=None,
                   help="utensil (default: the food's: spoon, soup_spoon, fork)")
    p.add_argument("--seed", type=int, default=0, help="food placement and sensor noise")
    p.add_argument("--physics", metavar="FILE", default=None,
                   help="physics parameters TOML (default: the packaged physics.toml)")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--liquid", choices=("sph", "spheres"), default=None,
                   help="what a liquid is, in its container and placed on the utensil: sph "
                        "(SPlisHSPlasH in the loop, the default of physics.toml) or spheres "
                        "(MuJoCo spheres, for comparison)")
    p.add_argument("--liquid-radius", type=float, metavar="MM", default=None,
                   help="the SPH particle radius (mm), within the validated 0.75-1.0 mm "
                        "(default: physics.toml's)")
    add_spec_option(p)


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``sim`` and ``sim-calibrate``."""
    p = sub.add_parser("sim", help="a scripted scene in the physics world (MuJoCo) with the "
                       "tool's own software in the loop; prints where the food went")
    _common(p)
    p.add_argument("--script", choices=("scoop", "carry", "tilt"), default="scoop",
                   help="scoop: acquire and lift; carry: then a fast arm motion tilting the "
                        "tool base ~40°; tilt: then the TILT primitive (default: scoop)")
    p.add_argument("--level", action=argparse.BooleanOptionalAction, default=True,
                   help="level the utensil after acquiring (default) or keep the wrist "
                        "locked like a rigid tool")
    p.add_argument("--load", type=float, metavar="G", default=None,
                   help="instead of acquiring, place G grams on the leveled, tared utensil "
                        "(the thesis' Exp. 2b/2c protocol), then run the script's motion")
    p.add_argument("--twirl-turns", type=float, metavar="N", default=None,
                   help="a fork's acquisition: TWIRL_CW N turns in the food (0: a still fork; "
                        "default: the cable budget less 0.1 turn)")
    p.add_argument("--video", metavar="FILE", default=None,
                   help="record the scene (.mp4 or .gif); never overwrites")
    p.add_argument("--snapshot", metavar="FILE", default=None,
                   help="save a PNG of the last frame; never overwrites")
    p.add_argument("--record", metavar="FILE", default=None,
                   help="record the run (.npz: joints, food, spills, tool telemetry) for "
                        "articutool view --recording; never overwrites")
    p.add_argument("--mjcf", metavar="FILE", default=None,
                   help="instead of running, write the world (.xml: robot, scene, the food as "
                        "placed with --seed) for python -m mujoco.viewer --mjcf FILE; its "
                        "keyframe 'start' holds the arm at Resting; never overwrites")
    p.set_defaults(func=_cmd_sim)
    c = sub.add_parser("sim-calibrate", help="calibration experiments of a food model "
                       "(angle of repose, what a level utensil holds; a liquid's static-tilt "
                       "test against the dish's hydrostatics)")
    _common(c)
    c.add_argument("--load", type=float, metavar="G", default=None,
                   help="a liquid's static-tilt test with this load (default 8 g; at most "
                        "what the level utensil holds): grams spilled per tilt beside "
                        "hydrostatics")
    c.set_defaults(func=_cmd_calibrate)
