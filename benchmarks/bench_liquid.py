"""The liquid in the loop: CPU seconds of a 10 s placed-load transport.

An 8 g water load (the SPH liquid at physics.toml's particle radius) placed on the leveled,
tared soup spoon, then 10 s of simulated transport: the hand turned until the tool base tilts
40° and back, again and again, at the Jaco's speed limit, the wrist leveling. The clock is the
process's CPU time (``time.process_time``: every thread, MuJoCo and SPlisHSPlasH), measured
over the 10 s of transport alone; the build and the placement are reported apart.

    .venv/bin/python benchmarks/bench_liquid.py [--out results/liquid_benchmark.json]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from articutool.sim.scenes import base_tilt_motion
from articutool.sim.sph_library import library_version
from articutool.sim.world import FeedingWorld
from articutool.tool.api import Mode
from bench_io import machine

TRANSPORT_S = 10.0
GOAL_CPU_S = 60.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="results/liquid_benchmark.json")
    ap.add_argument("--load", type=float, default=8.0)
    args = ap.parse_args()
    out = Path(args.out)
    if out.is_symlink():
        raise SystemExit(f"--out {out} is a symlink; refusing to write through it")
    c0 = time.process_time()
    w = FeedingWorld.make("water", load_g=args.load, mouth=False)
    w.tool.set_mode(Mode.LEVELING)
    w.run(1.0)
    w.weighing.tare(settle_s=0.2)
    held = w.placement.place(settle_s=0.5)
    c1 = time.process_time()
    q0 = w.arm_q
    q1 = base_tilt_motion(w, 40.0)
    t_end = w.time + TRANSPORT_S
    legs = 0
    while w.time < t_end - 1e-9:
        w.move_arm(q1 if legs % 2 == 0 else q0, wait=False)
        w.run_until(lambda: not w.arm_busy, t_end - w.time)
        legs += 1
    c2 = time.process_time()
    masses = w.ledger.masses_g()
    liquid = w.placement.liquid
    result = {
        "what": f"{TRANSPORT_S:g} s placed-load transport of {args.load:g} g of water (SPH), "
                "the hand turned to tilt the tool base 40° and back, leveling",
        "clock": "process CPU s (time.process_time, all threads)",
        "liquid_backend": "SPlisHSPlasH (pysplishsplash)", "liquid_version": library_version(),
        "particle_radius_mm": liquid.settings.particle_radius * 1e3 if liquid else None,
        "particles": w.ledger.n_items, "held_after_placing_g": round(held, 3),
        "transport_cpu_s": round(c2 - c1, 1), "goal_cpu_s": GOAL_CPU_S,
        "within_goal": (c2 - c1) <= GOAL_CPU_S,
        "build_and_place_cpu_s": round(c1 - c0, 1), "arm_legs": legs,
        "on_utensil_after_g": round(masses["utensil"], 3),
        "handed_off_particles": liquid.handed_off if liquid else None,
        "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
        "machine": machine(),
    }
    w.close()
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
