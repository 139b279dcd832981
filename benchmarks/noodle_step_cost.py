"""Where a noodle step's C time goes, and what each solver knob would buy (a measurement, not
a change: the shipped parameters stay those of ``data/physics.toml``).

The fork's acquisition (``articutool sim --food noodles --script scoop``) is run up to the
fork pressed into the nest and 0.5 s of its twirl (the whole nest awake, the costliest part of
the scene); that state is kept. Then, for each setting, the kept state is restored
(``mj_copyData``) and ``mj_step`` runs ``--steps`` steps in C with the controls held: the CPU
time per step, MuJoCo's timers as shares of the step, contacts and constraint rows. Settings:
the shipped one, no-slip off, no-slip 5 passes, the main solver's iterations halved, sleeping
off. A faster setting here changes the physics (it is a different solver): it would have to be
argued and its outcomes measured (benchmarks/sim_outcomes.py) by whoever owns the noodle model.

    .venv/bin/python benchmarks/noodle_step_cost.py --out results/noodle_step_cost.json
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time

import mujoco

from bench_io import write_json

_TIMERS = ("STEP", "POS_COLLISION", "COL_BROAD", "COL_NARROW", "POS_MAKE", "POS_PROJECT",
           "CONSTRAINT", "ADVANCE", "POS_KINEMATICS", "POS_INERTIA", "VELOCITY")


class _StopError(Exception):
    pass


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=250)
    ap.add_argument("--out", default="results/noodle_step_cost.json")
    args = ap.parse_args(argv)
    from articutool.sim.scenes import skewer
    from articutool.sim.world import FeedingWorld

    w = FeedingWorld.build("noodles", seed=args.seed)

    def stop(phase: str) -> None:
        if phase == "in":
            raise _StopError

    with contextlib.suppress(_StopError):
        skewer(w, on_phase=stop)
    ok, msg = w.tool.start_primitive("TWIRL_CW", [2.9, 3.0])
    assert ok, msg
    w.run(0.5)
    m, kept = w.model, mujoco.MjData(w.model)
    mujoco.mj_copyData(kept, m, w.data)
    base = {k: getattr(m.opt, k) for k in ("noslip_iterations", "iterations")}
    settings = {"shipped": {}, "noslip_off": {"noslip_iterations": 0},
                "noslip_5": {"noslip_iterations": 5},
                "iterations_half": {"iterations": max(1, base["iterations"] // 2)},
                "sleep_off": {"sleep": False}}
    rows = {}
    for name, change in settings.items():
        d = mujoco.MjData(m)
        mujoco.mj_copyData(d, m, kept)
        for k, v in base.items():
            setattr(m.opt, k, v)
        flag = int(mujoco.mjtEnableBit.mjENBL_SLEEP)
        m.opt.enableflags |= flag
        for k, v in change.items():
            if k == "sleep":
                m.opt.enableflags &= ~flag
            else:
                setattr(m.opt, k, v)
        for i in range(len(d.timer)):
            d.timer[i].duration, d.timer[i].number = 0.0, 0
        c = time.thread_time()
        mujoco.mj_step(m, d, args.steps)
        cpu = time.thread_time() - c
        step_wall = d.timer[mujoco.mjtTimer.mjTIMER_STEP].duration
        rows[name] = {
            "change": change, "cpu_ms_per_step": round(1e3 * cpu / args.steps, 3),
            "realtime_factor_physics_only": round(args.steps * m.opt.timestep / cpu, 3),
            "timer_share_of_step": {t.lower(): round(
                d.timer[getattr(mujoco.mjtTimer, f"mjTIMER_{t}")].duration / step_wall, 3)
                for t in _TIMERS},
            "contacts": int(d.ncon), "constraint_rows": int(d.nefc),
            "awake_dofs": int(d.nv_awake), "dofs": int(m.nv)}
        print(name, rows[name], flush=True)
    out = {"seed": args.seed, "steps": args.steps, "state": "fork pressed in, 0.5 s of twirl",
           "loadavg": os.getloadavg(), "mujoco": mujoco.__version__, "settings": rows}
    write_json(args.out, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
