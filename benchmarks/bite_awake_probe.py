"""Where a bite's stepping time goes, second by second: what keeps a container's pile awake.

Runs the demo's bite (``articutool meal --food F --bites 1``: the Articutool's strategy, one
seed) and, for every simulated second, writes the CPU seconds the world's stepping took
(``FeedingWorld``'s own clock: CPU time of the stepping thread), the mean number of contacts and
of awake bodies, and the free bodies moving fastest at the second's end (linear speed m/s,
angular speed rad/s, position): a pile that moves faster than ``sleep_tolerance`` while
nothing touches it stays awake and costs the step of a scoop.

    .venv/bin/python benchmarks/bite_awake_probe.py --seed 2 [--physics FILE] --out F.json
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import mujoco
import numpy as np

from bench_io import machine, write_json


def probe(food: str, seed: int, physics: str | None, top: int) -> dict:
    """The bite's per-second rows and its outcome (see module doc)."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    from articutool.meal.bites import make_bite_world, run_bite

    setup = make_bite_world(food, "articutool", seed, physics=physics)
    w = setup.world
    m = w.model
    free_joint = mujoco.mjtJoint.mjJNT_FREE
    free = [b for b in range(m.nbody)
            if m.body_jntnum[b] == 1 and m.jnt_type[m.body_jntadr[b]] == free_joint]
    dofs = np.array([m.jnt_dofadr[m.body_jntadr[b]] for b in free], dtype=int)
    rows: list[dict] = []
    acc = {"t": w.time, "cpu": w.stepping_cpu_s, "ncon": 0, "awake": 0, "n": 0}

    def tick(world) -> None:
        d = world.data
        acc["ncon"] += d.ncon
        acc["awake"] += int(d.nbody_awake)
        acc["n"] += 1
        if world.time - acc["t"] < 1.0 - 1e-9:
            return
        v = np.linalg.norm(d.qvel[dofs[:, None] + np.arange(3)], axis=1)
        om = np.linalg.norm(d.qvel[dofs[:, None] + np.arange(3, 6)], axis=1)
        fastest = np.argsort(-v)[:top]
        rows.append({
            "t_s": round(world.time, 2),
            "stepping_cpu_s": round(world.stepping_cpu_s - acc["cpu"], 3),
            "contacts": round(acc["ncon"] / acc["n"]),
            "awake_bodies": round(acc["awake"] / acc["n"]),
            "fastest": [{"body": mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, free[i]),
                         "speed_m_s": round(float(v[i]), 4), "spin_rad_s": round(float(om[i]), 2),
                         "pos_m": np.round(d.xpos[free[i]], 4).tolist()} for i in fastest]})
        acc.update(t=world.time, cpu=world.stepping_cpu_s, ncon=0, awake=0, n=0)

    w.on_tick.append(tick)
    c0 = time.thread_time()
    try:
        r = run_bite(setup)
    finally:
        setup.arm.close()
    return {"food": food, "seed": seed, "physics": physics or "packaged",
            "sleep_tolerance": float(m.opt.sleep_tolerance), "simulated_s": round(r.sim_time_s, 2),
            "stepping_cpu_s": round(w.stepping_cpu_s, 2),
            "thread_cpu_s": round(time.thread_time() - c0, 2),
            "delivered_g": round(r.delivered_g, 3), "seconds": rows}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--food", default="pecans")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--physics", default=None, help="another physics parameter file")
    ap.add_argument("--top", type=int, default=3, help="fastest bodies listed per second")
    ap.add_argument("--out", default="-")
    args = ap.parse_args()
    result = {"clock": "CPU s of the stepping thread (FeedingWorld's own clock)",
              "machine": machine(),
              **probe(args.food, args.seed, args.physics, args.top)}
    if args.out == "-":
        print(json.dumps(result, indent=1))
    else:
        write_json(Path(args.out), result)


if __name__ == "__main__":
    main()
