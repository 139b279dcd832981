"""At what angles do a noodle nest's strands cross, and what would the film's tack law give them?

The nest is built (seed ``--seed``, laid, not settled) and falls ``--seconds``; then, with
MuJoCo's sleeping off so that every pair is collided, each strand–strand contact point's angle
between the two capsules' axes is read, and the crossing law at that angle beside the model's
one value: two cylinders crossed at θ wet an ellipse of 2π·r·h / sin θ
(:attr:`articutool.sim.params.Strands.tack_per_crossing` is the right angle's). Beyond
``--min-deg`` the ellipse fits on a segment; below, the contact is a line's (the strands'
band law per metre, not per point). A measurement: the model is unchanged.

    PYTHONPATH=src nice -n 5 .venv/bin/python studies/noodle_crossings.py \
        --out studies/results/noodle_crossings.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

# JSON written as the benchmarks write it (benchmarks/bench_io.py).
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from bench_io import write_json


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=5100)
    ap.add_argument("--seconds", type=float, default=1.0)
    ap.add_argument("--min-deg", type=float, default=12.0)
    ap.add_argument("--out", default="studies/results/noodle_crossings.json")
    args = ap.parse_args(argv)
    import mujoco

    from articutool.sim.world import FeedingWorld

    w = FeedingWorld.make("noodles", seed=args.seed, settle=False)
    w.run(args.seconds, tick=False)
    m, d = w.model, w.data
    food = w.params.food("noodles")
    m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    mujoco.mj_forward(m, d)
    ang = []
    for c in d.contact[:d.ncon]:
        if m.geom(c.geom1).name.startswith("strand") and m.geom(c.geom2).name.startswith("strand"):
            a1 = d.geom_xmat[c.geom1].reshape(3, 3)[:, 2]
            a2 = d.geom_xmat[c.geom2].reshape(3, 3)[:, 2]
            ang.append(float(np.degrees(np.arccos(min(abs(float(a1 @ a2)), 1.0)))))
    a = np.array(ang)
    crossing = a[a > args.min_deg]
    ratio = 1.0 / np.sin(np.radians(crossing))
    f90 = food.tack_per_crossing
    out = {"seed": args.seed, "fell_s": args.seconds, "strand_contacts": len(a),
           "angle_deg_quantiles_10_25_50_75_90": np.percentile(a, [10, 25, 50, 75, 90])
           .round(1).tolist(),
           "over_30_deg": int((a > 30).sum()), "under_10_deg": int((a < 10).sum()),
           "min_deg": args.min_deg, "crossings": len(crossing),
           "law_over_right_angle_median": round(float(np.median(ratio)), 3),
           "law_over_right_angle_mean": round(float(ratio.mean()), 3),
           "law_median_N": round(float(np.median(ratio)) * f90, 7),
           "law_mean_N": round(float(ratio.mean()) * f90, 7),
           "model_N": round(f90, 7), "angles_deg": [round(x, 2) for x in ang]}
    print({k: v for k, v in out.items() if k != "angles_deg"}, flush=True)
    write_json(args.out, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
