"""Physics-world benchmark: real-time factor of a bite per food beside the laws its speed
settings must keep, and whether a speed setting changes outcomes.

The clock is the CPU time of the simulating thread (``time.thread_time``): a real-time factor
is simulated s ÷ CPU s of that thread, so load on the other core hardly moves it (the machine
is shared: CPU time of one thread still varies with the load, through caches and memory
bandwidth; each row keeps the 1-minute load average when it started).

Each run is one child process (one core), one seed, one food, one of two scripts:

- ``bite`` (the default): the demo's bite (``articutool meal --food F --bites 1``: the feeding
  tree with the Articutool's strategy for the food — acquire, shed, transport to Staging,
  present, the simulated user eats; ~40-70 s simulated). ``realtime_factor``: simulated s ÷
  CPU s of the world's stepping over the bite (``FeedingWorld.step``: MuJoCo, the tool's
  runtime, the accounting; the figure the targets are about); ``realtime_factor_end_to_end``:
  the bite's simulated s ÷ the thread's CPU s over the whole bite (the tree, IK and the
  planners' work on this thread included); outcome: the grams delivered.
- ``scoop``: the scripted acquisition (``articutool sim --food F --script scoop``: settle,
  level, tare, a Cartesian scoop through the pile or the fork's skewer, lift, level; ~19-25 s
  simulated); end to end counts building and settling the world too; outcome: the mass
  acquired (pecans, noodles) or, for water (which the scripted scoop does not acquire), the
  mass kept by a locked soup spoon loaded with 8 g through the 40° carry tilt, with
  ``realtime_factor_load`` that placed load's world on the same clock.

Beside the runs, the law the pecans' speed settings must keep: the creep of a resting half on a
10-20° steel slope (``laws.pecans``; :func:`articutool.sim.calibrate.creep_mm`), and the
effective contact parameters MuJoCo uses between two pieces (``contacts.pecans``).

``--code NAME=SRC`` (repeatable) runs the same seeds on several copies of the source
(``git archive <rev> src | tar -x -C /tmp/old``), interleaved seed by seed so that the
machine's load falls on both alike: before/after side by side in one run. ``--variants``
(with ``--script scoop``) compares solver settings (the shipped one; sleeping off; a 1 ms and
a 4 ms step): a setting is acceptable when its outcome distribution matches the 1 ms
reference's.

    .venv/bin/python benchmarks/bench_sim.py --seeds 5 --out results/sim_benchmark.json
    .venv/bin/python benchmarks/bench_sim.py --seeds 3 --foods pecans \\
        --code before=/tmp/old/src --code after=src --out results/sim_speed_before_after.json
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench_io import machine, write_json


def _variant_params(name: str):
    from articutool.sim.params import PhysicsParams

    base = PhysicsParams.load()
    world = {"shipped": {}, "no_sleep": {"sleep": False}, "step_1ms": {"timestep": 0.001},
             "step_4ms": {"timestep": 0.004}}[name]
    return base.model_copy(update={"world": base.world.model_copy(update=world)})


CLOCK = "CPU s of the simulating thread (time.thread_time)"


def bite(food: str, seed: int) -> dict:
    """One demo bite in this process (see module doc)."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    from articutool.meal.bites import make_bite_world, run_bite

    load = os.getloadavg()[0]
    setup = make_bite_world(food, "articutool", seed)
    w = setup.world
    sim0, cpu0 = w.stepped_s, w.stepping_cpu_s
    c0, t0 = time.thread_time(), time.perf_counter()
    try:
        r = run_bite(setup)
    finally:
        setup.arm.close()
    cpu, wall = time.thread_time() - c0, time.perf_counter() - t0
    step_cpu = w.stepping_cpu_s - cpu0
    return {"seed": seed, "realtime_factor": round((w.stepped_s - sim0) / step_cpu, 3),
            "realtime_factor_end_to_end": round(r.sim_time_s / cpu, 3),
            "simulated_s": round(r.sim_time_s, 2), "cpu_s": round(cpu, 2),
            "stepping_cpu_s": round(step_cpu, 2), "wall_s": round(wall, 2),
            "loadavg_1min_start": round(load, 2), "end_state": r.end_state,
            "acquired_g": round(r.acquired_g, 3), "outcome_g": round(r.delivered_g, 3)}


def one(food: str, seed: int, variant: str) -> dict:
    """One scripted scoop in this process (see module doc)."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    from articutool.sim.scenes import acquire, base_tilt_motion
    from articutool.sim.world import FeedingWorld
    from articutool.tool.api import Mode

    params = _variant_params(variant)
    load = os.getloadavg()[0]
    c0, t0 = time.thread_time(), time.perf_counter()
    w = FeedingWorld.make(food, seed=seed, params=params)
    acquire(w, level=True)
    cpu, wall = time.thread_time() - c0, time.perf_counter() - t0
    outcome = w.ledger.masses_g()["utensil"]
    row = {"seed": seed, "realtime_factor": round(w.realtime_factor, 3),
           "realtime_factor_end_to_end": round(w.time / cpu, 3),
           "simulated_s": round(w.time, 2), "cpu_s": round(cpu, 2), "wall_s": round(wall, 2),
           "loadavg_1min_start": round(load, 2)}
    if food == "water":
        w = FeedingWorld.make("water", seed=seed, params=params, load_g=8.0)
        w.tool.set_mode(Mode.LEVELING)
        w.run(1.0)
        w.tool.set_mode(Mode.DISABLED)
        w.placement.place(settle_s=1.0)
        w.move_arm(base_tilt_motion(w, 40.0))
        w.run(1.5)
        outcome = w.ledger.masses_g()["utensil"]
        row["realtime_factor_load"] = round(w.realtime_factor, 3)
        row["load_particles"] = w.ledger.n_items
    row["outcome_g"] = round(outcome, 3)
    return row


def _creep_law() -> dict:
    """The law the pecan model's speed settings must keep: a half resting on a steel slope
    creeps less than ``CREEP_LIMIT_MM`` in ``CREEP_HOLD_S`` (``sim-calibrate`` checks it too)."""
    from articutool.sim.calibrate import CREEP_HOLD_S, CREEP_LIMIT_MM, CREEP_SLOPES_DEG, creep_mm
    from articutool.sim.params import PhysicsParams

    params = PhysicsParams.load()
    creep = [round(creep_mm(params.food("pecans"), params, a), 4) for a in CREEP_SLOPES_DEG]
    return {"slopes_deg": list(CREEP_SLOPES_DEG), "hold_s": CREEP_HOLD_S, "creep_mm": creep,
            "limit_mm": CREEP_LIMIT_MM, "holds": max(creep) < CREEP_LIMIT_MM}


def _pecan_contact() -> dict:
    """The contact parameters MuJoCo uses between two pecan pieces (read from ``data.contact``
    of the settled bowl, stepped with sleeping off so that the pile's contacts exist)."""
    import mujoco

    from articutool.sim.world import FeedingWorld

    w = FeedingWorld.make("pecans", seed=0)
    m, d = w.model, w.data
    m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    mujoco.mj_step(m, d, 2)
    food = {int(g) for b in w.ledger.item_body for g in range(m.ngeom) if m.geom_bodyid[g] == b}
    con = next(c for c in d.contact[:d.ncon] if int(c.geom[0]) in food and int(c.geom[1]) in food)
    return {"condim": int(con.dim), "friction": [float(f) for f in con.friction],
            "solref": [float(x) for x in con.solref], "mu": float(con.mu),
            "noslip_iterations": int(m.opt.noslip_iterations)}


def _child(src: str, food: str, seed: int, variant: str, script: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(Path(src).resolve()), MUJOCO_GL="egl")
    out = subprocess.run([sys.executable, __file__, "--one", food, str(seed), variant, script],
                         env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _summary(rows: list[dict], food: str, script: str) -> dict:
    acq = [r["outcome_g"] for r in rows]
    rtf = [r["realtime_factor"] for r in rows]
    e2e = [r["realtime_factor_end_to_end"] for r in rows]
    load = [r["realtime_factor_load"] for r in rows if "realtime_factor_load" in r]
    extra = ({"realtime_factor_load_median": round(statistics.median(load), 3),
              "realtime_factor_load_min": round(min(load), 3)} if load else {})
    return {**extra,"realtime_factor_median": round(statistics.median(rtf), 3),
            "realtime_factor_min": round(min(rtf), 3),
            "realtime_factor_end_to_end_median": round(statistics.median(e2e), 3),
            "loadavg_1min_median": round(statistics.median(r["loadavg_1min_start"]
                                                           for r in rows), 2),
            "outcome": "mass delivered" if script == "bite"
            else "mass kept through a locked 40° carry (8 g placed)"
            if food == "water" else "mass acquired",
            "outcome_g_mean": round(statistics.mean(acq), 3),
            "outcome_g_sd": round(statistics.stdev(acq), 3) if len(acq) > 1 else 0.0,
            "runs": rows}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--one", nargs=4, metavar=("FOOD", "SEED", "VARIANT", "SCRIPT"),
                    help=argparse.SUPPRESS)
    ap.add_argument("--script", choices=("bite", "scoop"), default="bite",
                    help="the demo's bite through the feeding tree, or the scripted scoop")
    ap.add_argument("--foods", default="pecans,water,noodles", help="comma-separated foods")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--variants", default="shipped",
                    help="comma-separated: shipped, no_sleep, step_1ms, step_4ms (those "
                         "other than shipped with --script scoop)")
    ap.add_argument("--code", action="append", default=[], metavar="NAME=SRC",
                    help="a source tree to run (default: this checkout's src)")
    ap.add_argument("--out", default="results/sim_benchmark.json")
    args = ap.parse_args(argv)
    if args.one:
        food, seed, variant, script = args.one
        print(json.dumps(bite(food, int(seed)) if script == "bite"
                         else one(food, int(seed), variant)))
        return 0
    if args.script == "bite" and args.variants != "shipped":
        ap.error("--variants: only 'shipped' with --script bite (use --script scoop)")
    codes = dict(c.split("=", 1) for c in args.code) or {
        "this": str(Path(__file__).resolve().parents[1] / "src")}
    out: dict = {"machine": machine(), "clock": CLOCK,
                 "script": args.script, "code": codes, "results": {}}
    for food in args.foods.split(","):
        for variant in args.variants.split(","):
            rows: dict[str, list[dict]] = {name: [] for name in codes}
            for seed in range(args.seeds):
                for name, src in codes.items():  # interleaved: the load falls on each alike
                    rows[name].append(_child(src, food, seed, variant, args.script))
                    print(food, variant, name, rows[name][-1], flush=True)
            for name, rs in rows.items():
                res = out["results"].setdefault(food, {}).setdefault(variant, {})
                res[name] = _summary(rs, food, args.script)
    if "pecans" in args.foods.split(","):
        out["laws"] = {"pecans": _creep_law()}
        out["contacts"] = {"pecans": _pecan_contact()}
        print("pecans creep law", out["laws"]["pecans"], flush=True)
        print("pecans contact", out["contacts"]["pecans"], flush=True)
    out["machine"]["loadavg_end"] = os.getloadavg()
    write_json(args.out, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
