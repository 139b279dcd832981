"""Where a noodle step's C time goes, and what each solver knob would buy and cost in the
capstan law (a measurement, not a change: the shipped parameters stay those of
``data/physics.toml``).

The fork's acquisition (``articutool sim --food noodles --script scoop``) is run until the fork
has pressed into the nest (more than ``--contacts`` contacts) for 0.3 s — the whole nest awake,
the costliest state of the scene — and that state is kept. Then, for each setting, the kept
state is restored (``mj_copyData``), the model's options are reset to the shipped ones and the
setting applied, and ``mj_step`` runs ``--steps`` steps in C with the controls held: the CPU
time per step (thread clock), MuJoCo's timers as shares of the step, contacts and constraint
rows, the main solver's iterations, and whether MuJoCo reported an instability. For each
setting the strand calibration's capstan test on the fork-wide bar runs with the same options
(``sim/strand_laws.capstan_hold_ratio``; the law is e^(μπ), the tolerance ±20 %).

Settings: the shipped one (CG, 30 iterations, 10 no-slip passes); 5, 3 and 2 passes (as the
pecans' creep law settled on 2); no-slip off; no-slip off with
MuJoCo's ``impratio`` (friction rows stiffer than normal rows by that ratio, MuJoCo's own
remedy for slip with elliptic cones) at 100 and 300, with 30, 50 and 100 CG iterations.

    .venv/bin/python benchmarks/noodle_step_cost.py --contacts 400 \\
        --out results/noodle_step_cost.json
    .venv/bin/python benchmarks/noodle_step_cost.py --physics nest20.toml \\
        --out results/noodle_step_cost_20g.json
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import time
from unittest import mock

import mujoco

from bench_io import machine, write_json

_TIMERS = ("POS_COLLISION", "POS_MAKE", "POS_PROJECT", "CONSTRAINT", "POS_INERTIA", "ADVANCE",
           "VELOCITY")
_OPTS = ("noslip_iterations", "iterations", "tolerance", "impratio")
SETTINGS: dict[str, dict[str, float]] = {
    "shipped": {},
    "noslip_5": {"noslip_iterations": 5},
    "noslip_3": {"noslip_iterations": 3},
    "noslip_2": {"noslip_iterations": 2},
    "noslip_off": {"noslip_iterations": 0},
    "noslip_off_impratio100_it30": {"noslip_iterations": 0, "impratio": 100},
    "noslip_off_impratio100_it50": {"noslip_iterations": 0, "impratio": 100, "iterations": 50},
    "noslip_off_impratio300_it100": {"noslip_iterations": 0, "impratio": 300, "iterations": 100},
    "noslip_off_impratio300_it100_tol1e-8": {"noslip_iterations": 0, "impratio": 300,
                                             "iterations": 100, "tolerance": 1e-8},
}


class _StopError(Exception):
    pass


def _capstan(change: dict[str, float]) -> dict[str, float]:
    """The calibration's capstan test on the fork-wide bar with these solver options."""
    from articutool.sim import strand_laws as sl
    from articutool.sim.params import PhysicsParams
    from articutool.spec import load_spec

    p = PhysicsParams.load()
    world = {k: v for k, v in change.items() if k in ("iterations", "tolerance")}
    p = p.model_copy(update={"world": p.world.model_copy(update=world)})
    food = p.food("noodles")
    if "noslip_iterations" in change:
        food = food.model_copy(update={"noslip_iterations": int(change["noslip_iterations"])})
    bar = sl.fork_half_width(load_spec(), "fork")
    ei = food.young * math.pi * food.strand_radius**4 / 4
    rc = bar + food.strand_radius
    w_hang = food.piece_mass / food.strand_length * sl.GRAVITY * (food.strand_length
                                                                  - math.pi * rc) / 2
    load = max(10 * ei / rc**2 - w_hang, 0.0)
    shipped_spec = sl.solver_spec
    imp = change.get("impratio", 1.0)

    def with_impratio(*a, **k):  # the rig's solver with this setting's impratio
        spec = shipped_spec(*a, **k)
        spec.option.impratio = imp
        return spec

    with mock.patch.object(sl, "solver_spec", with_impratio):
        r = sl.capstan_hold_ratio(food, p, bar, sl._fork_law(food, tack=False), load)
    return {"hold_ratio": r["hold_ratio"], "law_e_mu_pi": r["law_e_mu_pi"],
            "error": round(r["hold_ratio"] / r["law_e_mu_pi"] - 1, 3),
            "passes_20pct": abs(r["hold_ratio"] / r["law_e_mu_pi"] - 1) <= 0.2,
            "cpu_s": r["cpu_s"]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--contacts", type=int, default=1000)
    ap.add_argument("--physics", help="another physics file (e.g. a 20 g nest: fill_g = 20)")
    ap.add_argument("--out", default="results/noodle_step_cost.json")
    args = ap.parse_args(argv)
    from articutool.sim.params import PhysicsParams
    from articutool.sim.scenes import skewer
    from articutool.sim.world import FeedingWorld

    info = machine()
    params = PhysicsParams.load(args.physics)
    w = FeedingWorld.make("noodles", seed=args.seed, params=params)
    pressed: list[float] = []

    def hook(world: FeedingWorld) -> None:
        if world.data.ncon > args.contacts:
            pressed.append(world.time)
            if world.time - pressed[0] > 0.3:
                raise _StopError

    w.on_tick.append(hook)
    with contextlib.suppress(_StopError):
        skewer(w)
    m, kept = w.model, mujoco.MjData(w.model)
    mujoco.mj_copyData(kept, m, w.data)
    shipped = {k: getattr(m.opt, k) for k in _OPTS}
    rows = {}
    for name, change in SETTINGS.items():
        d = mujoco.MjData(m)
        mujoco.mj_copyData(d, m, kept)
        for k, v in {**shipped, **change}.items():
            setattr(m.opt, k, v)
        for i in range(len(d.timer)):
            d.timer[i].duration, d.timer[i].number = 0.0, 0
        c = time.thread_time()
        mujoco.mj_step(m, d, args.steps)
        cpu = time.thread_time() - c
        step_wall = d.timer[mujoco.mjtTimer.mjTIMER_STEP].duration
        rows[name] = {
            "change": change, "cpu_ms_per_step": round(1e3 * cpu / args.steps, 1),
            "realtime_factor_physics_only": round(args.steps * m.opt.timestep / cpu, 4),
            "timer_share_of_step": {t.lower(): round(
                d.timer[getattr(mujoco.mjtTimer, f"mjTIMER_{t}")].duration / step_wall, 3)
                for t in _TIMERS},
            "contacts": int(d.ncon), "constraint_rows": int(d.nefc),
            "solver_iterations": int(d.solver_niter[0]),
            "unstable": bool(d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number),
            "capstan_bar": _capstan(change)}
        print(name, rows[name], flush=True)
    for k, v in shipped.items():
        setattr(m.opt, k, v)
    out = {"seed": args.seed, "steps": args.steps,
           "fill_g": params.food("noodles").fill_g,
           "state": f"fork pressed into the nest (> {args.contacts} contacts for 0.3 s) at "
                    f"t = {w.time:.2f} s", "dofs": int(m.nv), "machine": info,
           "settings": rows}
    write_json(args.out, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
