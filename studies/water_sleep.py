"""Why the water pool does not sleep: its particles' spin, not their motion.

For each seed the water world is built (settled, tool idle, arm at Resting, the spoon far
from the bowl) and run ``--seconds``; every second: the awake dofs (MuJoCo sleeping), the
particles' largest and median linear speed and their largest angular speed, and how many spin
faster than ``sleep_tolerance`` / the dof's length (their surface moving faster than the
tolerance). A frictionless particle (condim 1) takes no torque from its contacts,
so its spin never decays and keeps its island — the whole pool — awake; a measurement, the
water model is unchanged.

    PYTHONPATH=src .venv/bin/python studies/water_sleep.py --out studies/results/water_sleep.json
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
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--seconds", type=int, default=5)
    ap.add_argument("--out", default="studies/results/water_sleep.json")
    args = ap.parse_args(argv)
    from articutool.sim.world import FeedingWorld

    out: dict = {"sleep_tolerance_m_s": None, "seeds": {}}
    for seed in range(args.seeds):
        w = FeedingWorld.make("water", seed=seed)
        m, d = w.model, w.data
        body = w.ledger.item_body
        dof = m.body_dofadr[body]
        spin_limit = m.opt.sleep_tolerance / m.dof_length[dof + 3]  # rad/s, per particle
        out["sleep_tolerance_m_s"] = m.opt.sleep_tolerance
        rows = []
        for _ in range(args.seconds):
            w.run(1.0)
            lin = np.linalg.norm(d.cvel[body][:, 3:], axis=1)
            ang = np.linalg.norm(d.cvel[body][:, :3], axis=1)
            rows.append({"t": round(w.time, 2), "awake_dofs": int(d.nv_awake), "dofs": m.nv,
                         "linear_max_m_s": round(float(lin.max()), 5),
                         "linear_median_m_s": round(float(np.median(lin)), 6),
                         "spin_max_rad_s": round(float(ang.max()), 3),
                         "spinning_over_tolerance": int((ang > spin_limit).sum())})
        out["seeds"][seed] = rows
        print(seed, rows[-1], flush=True)
    write_json(args.out, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
