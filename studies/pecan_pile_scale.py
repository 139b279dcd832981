"""Does the pecan pile test read the cited angle of repose on a wider plate?

The plate test (:func:`articutool.sim.calibrate.angle_of_repose_deg`) puts 110 pieces on a
50 mm plate, two to five piece lengths across, and its heap is a mesa a few pieces thick
(docs/food.md). This runs the same test with the tube and plate scaled by ``--scale`` and the
pieces by its cube (the same fill height), with the no-slip passes given, and writes the
test's result, appended to ``--out``. ``--parts`` instead reads the piles in ``--out`` and
prints each heap's three parts, least-squares lines through its ring tops (``surface_mm``):
the top's slope over the inner 60 % of the plate's radius, the outer face's slope beyond it,
and the foot (the last ring's top).

    PYTHONPATH=src nice .venv/bin/python studies/pecan_pile_scale.py --scale 2 --seed 0 \\
        --passes 10 --out studies/results/pecan_pile_scale.json
    .venv/bin/python studies/pecan_pile_scale.py --parts --out studies/results/pecan_pile_scale.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

INNER = 0.6  # the top's share of the plate's radius


def heap_parts(surface_mm: list[list[float]], plate_radius_mm: float) -> dict[str, float]:
    """The top's and the outer face's slopes (degrees, positive falling outwards) and the
    foot's height (mm) of a heap's ring tops ``(radius, height)`` in mm."""
    from articutool.sim.calibrate import envelope_slope_deg

    inner = [(r, z) for r, z in surface_mm if r < INNER * plate_radius_mm]
    outer = [(r, z) for r, z in surface_mm if r >= INNER * plate_radius_mm]
    return {"top_deg": envelope_slope_deg(inner), "outer_face_deg": envelope_slope_deg(outer),
            "foot_mm": float(surface_mm[-1][1])}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=float, default=1.5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--passes", type=int, default=10)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--parts", action="store_true", help="print the piles' parts in --out")
    a = ap.parse_args(argv)
    if a.parts:
        for r in json.loads(a.out.read_text())["piles"]:
            parts = heap_parts(r["surface_mm"], r["plate_radius_mm"])
            print(json.dumps({k: r[k] for k in ("scale", "seed", "passes", "angle_deg",
                                                "flank_angle_deg")} | parts))
        return 0
    import articutool.sim.calibrate as cal
    from articutool.experiments.runner import source_version
    from articutool.sim.params import PhysicsParams

    n = round(cal.PILE_PIECES * a.scale**3)
    p = PhysicsParams.load()
    food = p.foods["pecans"].model_copy(update={"noslip_iterations": a.passes})
    p = p.model_copy(update={"foods": {**p.foods, "pecans": food}})
    r = cal.angle_of_repose_deg(food, p, n=n, seed=a.seed, scale=a.scale)
    row = {"scale": a.scale, "seed": a.seed, "passes": a.passes, "pieces": n,
           "plate_radius_mm": round(cal.PLATE_RADIUS_M * a.scale * 1e3, 1),
           "source": source_version(),
           **{k: v for k, v in r.items() if k != "state_sha256"}}
    doc = json.loads(a.out.read_text()) if a.out.exists() else {"piles": []}
    doc["piles"].append(row)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(json.dumps(row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
