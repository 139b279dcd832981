"""How often a load of pecans leaves a piece over the spoon's rim: after a maximal scoop, and
after the deposit loader that places Exp. 2b's and 2c's loads.

The loader drops pieces over the dish as a scoop leaves them, a piece's centre over the dish
and its edge free to overhang the rim (docs/accounting.md), and such a piece can tip off in
transport whatever the wrist does. Whether it overhangs as often as a scoop makes one is
measured here on the experiments' own code, per seed:

- **scoop**: the capacity trial (:func:`~articutool.experiments.units.capacity.capacity_trial`:
  one maximal scoop through the 125 g bowl, lifted level and held);
- **loader**: Exp. 2c's control trial (:func:`~articutool.experiments.units.exp2c.exp2c_trial`:
  ``--load-g`` placed at the shedding pose, no primitive, carried to Staging), read right
  after the load is placed; its transport spill is recorded too.

A piece's overhang is how far its capsules reach beyond the rim's ellipse, in the rim's
plane, along the ray from the dish's centre (negative: inside). Seeds are ``--seed0`` + i,
disjoint from every experiment's (repeat r of an experiment has seed 1000·S + r, S = 0).

    nice .venv/bin/python studies/pecan_overhang.py --seeds 20 \\
        --out studies/results/pecan_overhang.json

The JSON is rewritten after every seed; CPU time is the process's.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

# Edge beyond the rim (mm) from which a piece counts as overhanging, for the frequencies;
# every piece's own reach is in the JSON.
THRESHOLDS_MM = (2.0, 5.0)
CAPSULE, SPHERE = 3, 2  # mujoco.mjtGeom


def overhangs_mm(world: Any) -> list[dict[str, float]]:
    """Per piece on the utensil: its mass and how far (mm) its capsules reach beyond the
    rim's ellipse, in the rim's plane along the ray from the dish's centre, and how far its
    centre of mass is beyond it (negative: inside)."""
    from articutool.food.dish import spoon_dish
    from articutool.sim.accounting import CLASS_NAMES

    m, d, ledger = world.model, world.data, world.ledger
    if not set(m.geom_type[m.body_geomadr[int(b)]] for b in ledger.item_body) <= {CAPSULE, SPHERE}:
        raise ValueError("a piece of another shape than capsules or spheres")
    u = world.spec.utensil(world.utensil)
    dish = spoon_dish(u)
    body = m.body("utensil").id
    R, p = d.xmat[body].reshape(3, 3), d.xpos[body]
    on = np.flatnonzero(ledger.item_classes() == CLASS_NAMES.index("utensil"))

    def beyond(y: float, z: float) -> float:
        """Distance (m) beyond the rim along the ray from the dish's centre to (y, z)."""
        dz, r = z - dish.zc, math.hypot(y, z - dish.zc)
        rho = math.hypot(dz / dish.a, y / dish.b)
        return r * (1.0 - 1.0 / rho) if rho > 0 else -min(dish.a, dish.b)

    out = []
    for k in on:
        b = int(ledger.item_body[k])
        reach = -math.inf
        for g in range(m.body_geomadr[b], m.body_geomadr[b] + m.body_geomnum[b]):
            radius = float(m.geom_size[g, 0])
            half = float(m.geom_size[g, 1]) if m.geom_type[g] == CAPSULE else 0.0
            axis = d.geom_xmat[g].reshape(3, 3)[:, 2]
            for s in np.linspace(-1.0, 1.0, 9):
                q = R.T @ (d.geom_xpos[g] + s * half * axis - p)
                reach = max(reach, beyond(q[1], q[2]) + radius)
        c = R.T @ (d.xipos[b] - p)
        out.append({"item": int(k), "g": round(float(ledger.item_g[k]), 4),
                    "edge_mm": round(reach * 1e3, 2), "centre_mm": round(beyond(c[1], c[2]) * 1e3,
                                                                         2)})
    return out


def summary(rows: list[dict[str, Any]], key: str) -> dict[str, Any]:
    """How many loads of ``key`` had a piece beyond each threshold, and the largest reach."""
    worst = [max((p["edge_mm"] for p in r[key]["pieces"]), default=-math.inf) for r in rows]
    return {"n": len(rows),
            **{f"loads_with_a_piece_over_{t:g}_mm": sum(w >= t for w in worst)
               for t in THRESHOLDS_MM},
            "largest_edge_mm": [round(w, 2) for w in worst],
            "mean_g": round(float(np.mean([r[key]["g"] for r in rows])), 3) if rows else None}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--seed0", type=int, default=9000)
    ap.add_argument("--load-g", type=float, default=5.07,
                    help="the loader's load (default: Exp. 2c's, the capacity mean)")
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    if not 1 <= a.seeds <= 1000:
        print(f"--seeds must be in [1, 1000]; got {a.seeds}", file=sys.stderr)
        return 2
    if not 0.0 < a.load_g <= 50.0 or not math.isfinite(a.load_g):
        print(f"--load-g must be in (0, 50] g; got {a.load_g}", file=sys.stderr)
        return 2
    if a.out.exists() or a.out.is_symlink():
        print(f"--out: {a.out} exists; not overwriting", file=sys.stderr)
        return 2
    from articutool.datafile import replace_own
    from articutool.experiments.config import ExperimentsConfig
    from articutool.experiments.runner import source_version
    from articutool.experiments.units.capacity import CapacityCondition, capacity_trial
    from articutool.experiments.units.exp2c import Exp2cCondition, exp2c_trial

    cfg = ExperimentsConfig.load()
    doc: dict[str, Any] = {
        "food": "pecans", "loader_load_g": a.load_g, "seeds": [a.seed0, a.seed0 + a.seeds - 1],
        "thresholds_mm": list(THRESHOLDS_MM), "source": source_version(),
        "command": " ".join(["studies/pecan_overhang.py", *(argv or sys.argv[1:])]),
        "rows": []}
    for i in range(a.seeds):
        seed = a.seed0 + i
        worlds: list[Any] = []
        c0 = time.process_time()
        scoop = capacity_trial(CapacityCondition(food="pecans"), seed, cfg, hook=worlds.append)
        scoop_row = {"g": scoop.items_g, "pieces": overhangs_mm(worlds[0]),
                     "cpu_s": round(time.process_time() - c0, 1)}
        placed: dict[str, Any] = {}

        def at_placing(w: Any, placed: dict[str, Any] = placed) -> None:
            place = w.placement.place

            def measured(settle_s: float = 0.5) -> float:
                held = place(settle_s)
                placed.update(g=round(held, 4), pieces=overhangs_mm(w))
                return held

            w.placement.place = measured

        c0 = time.process_time()
        carry = exp2c_trial(Exp2cCondition(food="pecans", condition="control", load_g=a.load_g),
                            seed, cfg, hook=at_placing)
        placed.update(transport_spilled_g=carry.spilled_g, completed=carry.completed,
                      cpu_s=round(time.process_time() - c0, 1))
        doc["rows"].append({"seed": seed, "scoop": scoop_row, "loader": placed})
        doc["summary"] = {"scoop": summary(doc["rows"], "scoop"),
                          "loader": summary(doc["rows"], "loader"),
                          "loader_transport_spills": sum(
                              r["loader"]["transport_spilled_g"] > 0 for r in doc["rows"])}
        doc["loadavg_end"] = [round(x, 2) for x in os.getloadavg()]
        replace_own(a.out, json.dumps(doc, indent=1) + "\n")
        worst_s = max((p["edge_mm"] for p in scoop_row["pieces"]), default=float("nan"))
        worst_l = max((p["edge_mm"] for p in placed["pieces"]), default=float("nan"))
        print(f"seed {seed}: scoop {scoop_row['g']:.2f} g, edge {worst_s:+.1f} mm; loader "
              f"{placed['g']:.2f} g, edge {worst_l:+.1f} mm, transport spill "
              f"{carry.spilled_g:.2f} g ({scoop_row['cpu_s'] + placed['cpu_s']:.0f} CPU s)",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
