"""What the bowl's liquid pushes on the spoon during an Exp. 1 dip, read from the library.

The world's bowl of SPH water (``articutool.sim.bowl_liquid``) moves the spoon's dish through
the liquid as an animated boundary, whose force the library does not read, so while the dish
is in the bowl the liquid does not act on the arm or the F/T sensor (docs/limits.md). This
study reads that force: the dish is made a *held* boundary (``sph_scene.Boundary(held=True)``,
a dynamic body of the library's rigid-body solver put back at the dish's pose before every
step, the force read from the velocity change the library gives it), and the force is logged,
not applied, so the trial runs as the world runs it.

One Exp. 1 water acquisition per system through the real feeding tree (stages above and
acquire, the strategies ``water_tilted_dip`` and ``water_baseline``), seeds ``8_600_000 + k``:
disjoint from the experiments' (0–999), the searches' (7 000 000 + k) and the other studies'
(8 000 000 + k, 8 500 000 + k). Logged at every tool tick (50 Hz): the dish's lowest point's
height above the liquid's ideal surface, the liquid's mean force on the dish over the period
(world frame), and after the hand-over the load's force on the utensil (its momentum balance,
``LiquidLoad.force_world``). The law it is checked against: out of the liquid, before the
hand-over, the force is the weight of what the dish holds (the grams handed over, × g), and
it continues into the load's momentum balance across the hand-over.

Run (one process, niced): ``PYTHONPATH=src nice python studies/bowl_liquid_force.py --out
studies/results/bowl_liquid_force.json`` (the JSON names the code that ran, the CPU clock and
the machine's load).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

SYSTEMS = ("articutool", "baseline")
SEED0 = 8_600_000
STAGES = ("above", "acquire")


def _held_dish() -> None:
    """The world's bowl with the dish a held boundary (its force read, not applied)."""
    from articutool.sim import bowl_liquid
    from articutool.sim.sph_scene import Boundary

    plain = bowl_liquid.BowlLiquid._bounds

    def bounds(self: Any) -> list[Boundary]:
        b = plain(self)
        return [x if x.name != "dish" else Boundary("dish", x.vertices, x.faces, held=True)
                for x in b]

    bowl_liquid.BowlLiquid._bounds = bounds  # type: ignore[method-assign]


def run(system: str, seed: int) -> dict[str, Any]:
    """One acquisition; the force on the dish at every tick."""
    from articutool.meal.bites import make_bite_world, run_bite

    cpu0 = time.process_time()  # the world's build included
    setup = make_bite_world("water", system, seed)
    w = setup.world
    bowl = w.bowl
    assert bowl is not None
    rows: list[list[float]] = []

    def tick(world: Any) -> None:
        p, R, _, _ = bowl._pose()
        above, _ = bowl._dish_low(p, R)
        f_bowl = (bowl._liquid.held_force("dish") if bowl.simulated
                  else np.full(3, np.nan))
        load = world.placement.liquid
        f_load = load.force_world() if load is not None else np.full(3, np.nan)
        rows.append([float(world.data.time), above, *f_bowl, *f_load])

    w.on_tick.append(tick)
    try:
        r = run_bite(setup, stages=STAGES)
    finally:
        setup.arm.close()
    a = np.array(rows)
    t, above, fb, fl = a[:, 0], a[:, 1], a[:, 2:5], a[:, 5:8]
    inside = ~np.isnan(fb[:, 0])
    handed = bowl.handed_over_g[0] if bowl.handed_over_g else 0.0
    out: dict[str, Any] = {
        "system": system, "seed": seed, "strategy": setup.strategy_name,
        "completed": r.completed, "acquired_g": round(r.acquired_g, 4),
        "handed_over_g": round(handed, 4), "cpu_s": round(time.process_time() - cpu0, 1),
    }
    if inside.any():
        k = np.flatnonzero(inside)
        sub = above[k] < 0.0
        last = k[-1]  # the last period the bowl's liquid ran: the dish 15 mm above it
        after = np.flatnonzero(~np.isnan(fl[:, 0]) & (t > t[last]))
        mag = np.linalg.norm(fb[k], axis=1)
        out.update({
            "bowl_simulated_s": [round(float(t[k[0]]), 3), round(float(t[last]), 3)],
            "submerged_ticks": int(sub.sum()),
            "peak_force_in_liquid_N": round(float(mag[sub].max()), 5) if sub.any() else None,
            "mean_force_in_liquid_N": ([round(float(x), 5) for x in fb[k][sub].mean(axis=0)]
                                       if sub.any() else None),
            "force_before_hand_over_N": [round(float(x), 5) for x in fb[last]],
            "weight_handed_over_N": round(handed * 1e-3 * -float(w.model.opt.gravity[2]), 5),
            "load_force_after_hand_over_N": ([round(float(x), 5) for x in fl[after[0]]]
                                             if len(after) else None),
        })
    out["series"] = {"t_s": np.round(t, 4).tolist(), "dish_above_surface_m":
                     np.round(above, 5).tolist(),
                     "bowl_force_N": np.where(np.isnan(fb), None, np.round(fb, 6)).tolist(),
                     "load_force_N": np.where(np.isnan(fl), None, np.round(fl, 6)).tolist()}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True, help="the JSON to write (not overwritten)")
    ap.add_argument("--seed", type=int, default=SEED0)
    args = ap.parse_args(argv)
    if args.out.exists() or args.out.is_symlink():
        print(f"--out {args.out} exists; give a new file", file=sys.stderr)
        return 2
    from articutool.experiments.runner import source_version

    _held_dish()
    runs = [run(s, args.seed + i) for i, s in enumerate(SYSTEMS)]
    doc = {"study": "bowl_liquid_force", "source": source_version(),
           "clock": "process CPU (time.process_time)", "load_average": os.getloadavg(),
           "runs": runs}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "x") as f:
        json.dump(doc, f, indent=1)
    for r in runs:
        print(json.dumps({k: v for k, v in r.items() if k != "series"}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
