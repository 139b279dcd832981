"""Where the feeding world's time goes: MuJoCo's own timers and a Python profile, per food.

For each food, the scripted acquisition (``articutool sim --food F --script scoop``) twice
on one core, same seed:

1. unprofiled: the CPU time of the whole run (world build, settle, script), the part inside
   ``FeedingWorld.step`` (the world's real-time factor counts that), the CPU time inside
   ``mj_step`` (C; the rest of ``step`` is the Python around it) and MuJoCo's timers
   (``mjData.timer``: step, forward, collision broad/narrow phase, constraint solver — which
   includes the no-slip solver —, …), summed over the run. MuJoCo's timers are wall-clock,
   so on a loaded machine read them as shares of ``step``;
2. under cProfile: the Python functions with the most own time. cProfile's clock is
   wall-clock too, and under load a preempted thread's wait lands on the call it was in
   (often ``time.thread_time``, a system call here); its overhead also inflates Python
   against C: read its shares against run 1's CPU totals.

    .venv/bin/python benchmarks/profile_sim.py --out results/sim_profile.json
    PYTHONPATH=src .venv/bin/python benchmarks/profile_sim.py --python-cost --out -

``--python-cost``: the world's own Python per step with the physics stubbed out (below); run
it on two source trees to compare them.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import sys
import time
from pathlib import Path

import mujoco

from bench_io import machine, write_json

_TIMERS = ("STEP", "FORWARD", "POSITION", "POS_KINEMATICS", "POS_INERTIA", "POS_COLLISION",
           "COL_BROAD", "COL_NARROW", "POS_MAKE", "POS_PROJECT", "VELOCITY", "ACTUATION",
           "CONSTRAINT", "ADVANCE", "INVERSE")


def _timers(world) -> dict[str, dict[str, float]]:
    out = {}
    for name in _TIMERS:
        t = world.data.timer[getattr(mujoco.mjtTimer, f"mjTIMER_{name}")]
        out[name.lower()] = {"s": round(t.duration, 3), "calls": int(t.number)}
    return out


def _run(food: str, seed: int, mj_cpu: list[float] | None = None):
    from articutool.sim.scenes import acquire
    from articutool.sim.world import FeedingWorld

    step = mujoco.mj_step
    if mj_cpu is not None:  # the CPU time inside mj_step (MuJoCo's timers are wall-clock)
        def timed(m, d, nstep=1):
            c = time.thread_time()
            step(m, d, nstep)
            mj_cpu[0] += time.thread_time() - c
        mujoco.mj_step = timed
    c0 = time.thread_time()
    w = FeedingWorld.make(food, seed=seed)
    c_built = time.thread_time()
    try:
        acquire(w, level=True)
    finally:
        mujoco.mj_step = step
    return w, c_built - c0, time.thread_time() - c0


def profile(food: str, seed: int, top: int) -> dict:
    mj_cpu = [0.0]
    w, build_s, total_s = _run(food, seed, mj_cpu)
    tm = _timers(w)
    step_cpu = w.stepping_cpu_s
    mj = round(mj_cpu[0], 3)
    res = {
        "simulated_s": round(w.time, 3), "physics_steps": tm["step"]["calls"],
        "cpu_total_s": round(total_s, 2), "cpu_build_and_settle_s": round(build_s, 2),
        "cpu_in_world_step_s": round(step_cpu, 2),
        "realtime_factor": round(w.realtime_factor, 3),
        "mj_step_cpu_s": mj,
        "python_in_world_step_s": round(step_cpu - mj, 2),
        "outside_world_step_s": round(total_s - step_cpu, 2),
        "mujoco_timers_wall": tm,
        "mujoco_timer_share_of_step": {k: round(v["s"] / max(tm["step"]["s"], 1e-9), 3)
                                       for k, v in tm.items()},
        "per_step_us": {"mj_step": round(1e6 * mj / max(tm["step"]["calls"], 1), 1),
                        "python_around_it": round(1e6 * (step_cpu - mj)
                                                  / max(tm["step"]["calls"], 1), 1)},
        "contacts_at_end": int(w.data.ncon),
    }
    prof = cProfile.Profile()
    prof.enable()
    _run(food, seed)
    prof.disable()
    st = pstats.Stats(prof)
    rows = []
    for (fn, line, name), (_cc, nc, tt, ct, _callers) in st.stats.items():  # type: ignore[attr-defined]
        rows.append({"function": f"{Path(fn).name}:{line}({name})", "calls": nc,
                     "own_s": round(tt, 3), "cumulative_s": round(ct, 3)})
    rows.sort(key=lambda r: -r["own_s"])
    res["cprofile_total_s"] = round(sum(r["own_s"] for r in rows), 2)
    res["cprofile_top_own"] = rows[:top]
    return res


def python_cost(food: str, seed: int, seconds: float = 5.0) -> dict:
    """The world's own Python per physics step with the physics stubbed out (``mj_step``
    only advances the clock): arm references, the wrist's velocity loop, sensor samples, the
    tool's tick and the food ledger, while the arm follows a trajectory and the tool levels."""
    from articutool.sim.world import FeedingWorld
    from articutool.tool.api import Mode

    w = FeedingWorld.make(food, seed=seed)
    w.tool.set_mode(Mode.LEVELING)
    q = w.arm_q.copy()
    q[0] += 0.3
    w.move_arm(q, duration=4 * seconds, wait=False)
    step = mujoco.mj_step
    mujoco.mj_step = lambda m, d, nstep=1: setattr(d, "time", d.time + nstep * m.opt.timestep)
    try:
        c = time.thread_time()
        w.run(seconds)
        cpu = time.thread_time() - c
    finally:
        mujoco.mj_step = step
    n = round(seconds / w.dt)
    return {"food": food, "steps": n, "python_per_step_us": round(1e6 * cpu / n, 1)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--foods", default="pecans,water,noodles")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--out", default="results/sim_profile.json")
    ap.add_argument("--python-cost", action="store_true",
                    help="only the world's Python per step, physics stubbed (see python_cost)")
    args = ap.parse_args(argv)
    if args.python_cost:
        import articutool

        rows = [python_cost(f, args.seed) for f in args.foods.split(",")]
        doc = {"code": str(Path(articutool.__file__).parent), "loadavg": os.getloadavg(),
               "runs": rows}
        print(json.dumps(doc))
        if args.out != "-":
            Path(args.out).write_text(json.dumps(doc, indent=2) + "\n")
        return 0
    out = {"machine": machine(),
           "script": "scoop", "seed": args.seed, "foods": {}}
    for food in args.foods.split(","):
        out["foods"][food] = profile(food, args.seed, args.top)
        f = out["foods"][food]
        print(food, {k: v for k, v in f.items() if not isinstance(v, dict | list)}, flush=True)
    out["machine"]["loadavg_end"] = os.getloadavg()
    write_json(args.out, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
