"""What an awake pecan bowl's step costs under each contact dimension and static-friction setting,
beside the creep law (a measurement, not a change: the shipped parameters stay those of
``data/physics.toml``).

The 125 g bowl is built and settled as a bite's world is (``FeedingWorld.make("pecans")``),
then sleeping is switched off so every piece is awake (the bowl while the spoon is in it: the
costly part of a bite; a resting bowl sleeps). For each setting the settled state is restored
(``mj_copyData``), the options reset to the shipped ones and the setting applied (``condim``:
every food geom's contact dimension; 3 sliding, 6 with torsion and rolling), 5 steps taken,
then ``--steps`` steps timed on the thread's CPU clock: CPU ms a step, contacts, the main
solver's iterations, and the largest piece speed at the end (a pile that keeps moving faster
than ``sleep_tolerance`` never sleeps). Beside each setting, the creep law of
``sim-calibrate`` (:func:`articutool.sim.calibrate.creep_mm`: a half on 10-20° steel, 3 s).

    .venv/bin/python benchmarks/pecan_step_cost.py --out results/pecan_step_cost.json
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import mujoco
import numpy as np

from bench_io import machine, write_json

SETTINGS: dict[str, dict[str, int]] = {
    "condim 6, no-slip 10 passes": {"condim": 6, "noslip_iterations": 10},
    "condim 6, no-slip 2 passes": {"condim": 6, "noslip_iterations": 2},
    "condim 6, no no-slip": {"condim": 6, "noslip_iterations": 0},
    "condim 4, no-slip 2 passes": {"condim": 4, "noslip_iterations": 2},
    "condim 3, no-slip 2 passes": {"condim": 3, "noslip_iterations": 2},
    "condim 3, no-slip 1 pass": {"condim": 3, "noslip_iterations": 1},
    "condim 3, no no-slip": {"condim": 3, "noslip_iterations": 0},
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="results/pecan_step_cost.json")
    args = ap.parse_args(argv)
    from articutool.sim.calibrate import CREEP_SLOPES_DEG, creep_mm
    from articutool.sim.world import FeedingWorld

    w = FeedingWorld.make("pecans", seed=args.seed)
    m, d, params = w.model, w.data, w.params
    food = params.food("pecans")
    m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    kept = mujoco.MjData(m)
    mujoco.mj_copyData(kept, m, d)
    food_geom = np.isin(m.geom_bodyid, w.ledger.item_body)
    lin = np.concatenate([m.body_dofadr[b] + np.arange(3) for b in w.ledger.item_body])
    rows = {}
    for name, setting in SETTINGS.items():
        m.opt.noslip_iterations = setting["noslip_iterations"]
        m.geom_condim[food_geom] = setting["condim"]
        mujoco.mj_copyData(d, m, kept)
        mujoco.mj_step(m, d, 5)
        ncon = nefc = niter = 0
        c0 = time.thread_time()
        for _ in range(args.steps):
            mujoco.mj_step(m, d)
            ncon += d.ncon
            nefc += d.nefc
            niter += int(d.solver_niter[0])
        cpu = time.thread_time() - c0
        c = food.contacts
        law = food.model_copy(update={
            "noslip_iterations": setting["noslip_iterations"],
            "contacts": c.model_copy(update={
                k: getattr(c, k).model_copy(update={"condim": setting["condim"]})
                for k in ("food", "utensil", "container", "surface")})})
        rows[name] = {
            "cpu_ms_per_step": round(cpu / args.steps * 1e3, 2),
            "contacts": ncon // args.steps, "constraint_rows": nefc // args.steps,
            "solver_iterations": round(niter / args.steps, 1),
            "max_piece_speed_m_s": round(float(np.max(np.linalg.norm(
                d.qvel[lin].reshape(-1, 3), axis=1))), 4),
            "creep_mm": [round(creep_mm(law, params, a), 4) for a in CREEP_SLOPES_DEG]}
        print(name, rows[name], flush=True)
    write_json(args.out, {"machine": {**machine(), "loadavg_end": os.getloadavg()},
                          "seed": args.seed, "steps": args.steps,
                          "sleep_tolerance_m_s": params.world.sleep_tolerance,
                          "creep_slopes_deg": list(CREEP_SLOPES_DEG), "settings": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
