"""Physics-world benchmark: real-time factor per food, and whether the speed settings change
outcomes.

For each food and each solver setting, runs the scripted acquisition (``acquire``: settle,
level, tare, a Cartesian scoop through the pile or the fork's skewer, lift, level; ~19-25 s
simulated) on one core for several seeds, and records the real-time factor (simulated s ÷
CPU s of the simulation thread) and an outcome: the mass acquired (pecans, noodles) or, for
water (which the scripted scoop does not acquire), the mass kept by a locked soup spoon
loaded with 8 g through the 40° carry tilt. The settings compared are the shipped one (2 ms,
sleeping on), sleeping off, a 1 ms and a 4 ms step: a setting is acceptable when its outcome
distribution matches the 1 ms reference's (same mean within the seeds' spread).

    .venv/bin/python benchmarks/bench_sim.py --seeds 5 --out results/sim_benchmark.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

from articutool.sim.params import PhysicsParams
from articutool.sim.scenes import acquire, base_tilt_motion
from articutool.sim.world import FeedingWorld
from articutool.tool.api import Mode


def _water_carry(seed: int, params: PhysicsParams) -> tuple[float, FeedingWorld]:
    w = FeedingWorld("water", seed=seed, params=params, load_g=8.0)
    w.tool.set_mode(Mode.LEVELING)
    w.run(1.0)
    w.tool.set_mode(Mode.DISABLED)
    w.place_load(settle_s=1.0)
    w.move_arm(base_tilt_motion(w, 40.0))
    w.run(1.5)
    return w.masses_g()["utensil"], w


def _variant(params: PhysicsParams, **world: object) -> PhysicsParams:
    return params.model_copy(update={"world": params.world.model_copy(update=world)})


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--foods", default="pecans,water", help="comma-separated foods")
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--variants", default="shipped,no_sleep,step_1ms")
    ap.add_argument("--out", default="results/sim_benchmark.json")
    args = ap.parse_args(argv)
    base = PhysicsParams.load()
    variants = {
        "shipped": base,
        "no_sleep": _variant(base, sleep=False),
        "step_1ms": _variant(base, timestep=0.001),
        "step_4ms": _variant(base, timestep=0.004),
    }
    out: dict = {"machine": {"python": sys.version.split()[0], "platform": platform.platform(),
                             "cpus": os.cpu_count()},
                 "script": "scoop", "results": {}}
    for food in args.foods.split(","):
        for name in args.variants.split(","):
            params = variants[name]
            rows = []
            for seed in range(args.seeds):
                t0 = time.perf_counter()
                w = FeedingWorld(food, seed=seed, params=params)
                acquire(w, level=True)
                outcome = w.masses_g()["utensil"]
                rtf, sim_s = w.realtime_factor, w.time
                if food == "water":
                    outcome, _ = _water_carry(seed, params)
                rows.append({"seed": seed, "outcome_g": round(outcome, 3),
                             "realtime_factor": round(rtf, 3),
                             "simulated_s": round(sim_s, 2),
                             "wall_s": round(time.perf_counter() - t0, 2)})
                print(food, name, rows[-1], flush=True)
            acq = [r["outcome_g"] for r in rows]
            rtf = [r["realtime_factor"] for r in rows]
            out["results"].setdefault(food, {})[name] = {
                "timestep": params.world.timestep, "sleep": params.world.sleep,
                "solver": params.world.solver,
                "realtime_factor_median": round(statistics.median(rtf), 3),
                "realtime_factor_min": round(min(rtf), 3),
                "outcome": "mass kept through a locked 40° carry (8 g placed)"
                if food == "water" else "mass acquired",
                "outcome_g_mean": round(statistics.mean(acq), 3),
                "outcome_g_sd": round(statistics.stdev(acq), 3) if len(acq) > 1 else 0.0,
                "runs": rows,
            }
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
