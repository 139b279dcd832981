"""Which of the pecans' contact rows set the pile test's angle: rolling resistance or no-slip?

The plate test (:func:`articutool.sim.calibrate.angle_of_repose_deg`, 110 pieces on the 50 mm
plate) run for each variant of the pecans' contact law on seeds 0–2: rolling rows at 0.05 mm
(condim 6: sliding, torsion and rolling), at 0.005 mm, and none (condim 4: sliding and
torsion), each with the no-slip passes given. Every other parameter is the packaged one.
Writes each pile's result beside its variant.

    PYTHONPATH=src nice .venv/bin/python studies/pecan_repose_contacts.py \\
        --variants rolling_0.05mm,no_rolling --passes 2,10 \\
        --out studies/results/pecan_repose_contacts.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

# Each variant's (condim, rolling m) for every pecan partner; torsion and sliding unchanged.
VARIANTS = {"rolling_0.05mm": (6, 5e-5), "rolling_0.005mm": (6, 5e-6), "no_rolling": (4, None)}


def _params(variant: str, passes: int):  # type: ignore[no-untyped-def]
    from articutool.sim.params import PhysicsParams

    p = PhysicsParams.load()
    food = p.foods["pecans"]
    condim, rolling = VARIANTS[variant]
    contacts = food.contacts
    update = {}
    for partner in ("food", "utensil", "container", "surface"):
        c = getattr(contacts, partner)
        fr = c.friction if rolling is None else (c.friction[0], c.friction[1], rolling)
        update[partner] = c.model_copy(update={"condim": condim, "friction": fr})
    contacts = contacts.model_copy(update=update)
    food = food.model_copy(update={"contacts": contacts, "noslip_iterations": passes})
    return food, p.model_copy(update={"foods": {**p.foods, "pecans": food}})


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--passes", default="2,10", help="no-slip passes, comma-separated")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    import articutool.sim.calibrate as cal
    from articutool.experiments.runner import source_version

    variants = [v.strip() for v in a.variants.split(",") if v.strip()]
    unknown = [v for v in variants if v not in VARIANTS]
    if unknown:
        print(f"--variants: unknown {unknown}; known: {', '.join(VARIANTS)}", file=sys.stderr)
        return 2
    rows = []
    cited = None
    for variant in variants:
        for passes in (int(x) for x in a.passes.split(",")):
            food, p = _params(variant, passes)
            cited = food.angle_of_repose_deg
            for seed in range(a.seeds):
                r = cal.angle_of_repose_deg(food, p, seed=seed)
                row = {"variant": variant, "condim": food.contacts.food.condim,
                       "friction": list(food.contacts.food.friction), "passes": passes,
                       "seed": seed, **{k: v for k, v in r.items() if k != "state_sha256"}}
                rows.append(row)
                print(json.dumps({k: row[k] for k in ("variant", "passes", "seed")}
                                 | {"angle_deg": r.get("angle_deg")}), flush=True)
    doc = {"what": __doc__.splitlines()[0], "source": source_version(),
           "cited_deg": cited, "tolerance_deg": cal.REPOSE_TOLERANCE_DEG,
           "clock": "process CPU s per pile", "load_avg": os.getloadavg(), "piles": rows}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
