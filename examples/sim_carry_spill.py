"""The README's carry-spill table: a load placed on the leveled, tared utensil, then the arm
motion that tilts the tool base by 40°; leveling wrist vs locked wrist, 5 seeds each.

    .venv/bin/python examples/sim_carry_spill.py --food water --load 8
    .venv/bin/python examples/sim_carry_spill.py --food pecans --load 7
"""

from __future__ import annotations

import argparse
import json

from articutool.sim.scenes import base_tilt_motion, load
from articutool.sim.world import FeedingWorld


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--food", default="water")
    ap.add_argument("--load", type=float, default=8.0)
    ap.add_argument("--seeds", type=int, default=5)
    args = ap.parse_args()
    out = {}
    for level in (True, False):
        rows = []
        for seed in range(args.seeds):
            w = FeedingWorld.make(args.food, seed=seed, load_g=args.load)
            load(w, level)
            held = w.ledger.masses_g()["utensil"]
            w.move_arm(base_tilt_motion(w, 40.0))
            w.run(1.5)
            rows.append({"seed": seed, "held_g": round(held, 2),
                         "spilled_g": round(held - w.ledger.masses_g()["utensil"], 2)})
        out["leveling" if level else "locked"] = rows
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
