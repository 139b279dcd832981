"""At what angles do a settled noodle nest's strands touch, and what does the film's law give them?

Each seed's default nest is built and settled as an experiment's world settles it
(``FeedingWorld.make("noodles", seed=…)``); then every strand–strand contact point's angle
between the two capsules' axes is read (:func:`articutool.sim.strand_laws.strand_contacts`,
sleeping off so that the settled strands list their contacts), with the film's law at that
angle (:func:`articutool.sim.strand_laws.contact_tack`: the wetted ellipse 2π·r·h / sin θ
clipped to the half segment a contact point stands for, the parallel band's at 0°).

It also measures the length of a line contact one contact point stands for, the law's clip
length: the spacing of the points MuJoCo puts on two straight strands crossed at 0-10°.

The pooled mean of the law over the right-angle value, over every seed's contacts, is the
``crossing_factor`` the model's strand geoms carry (``[foods.noodles]`` in physics.toml): a
value derived from the law and the measured angles, not fitted. Study seeds 8100-8102: no
experiment (base 0, seeds 0-999) or tuning search uses them, and the calibration's held-out
nest is seed 8200 (``strand_laws.NEST_SEED``). The law is evaluated with the parameters of the
run (the adhesion the model carries does not enter it, but the settled nest does: re-running
after a change of ``crossing_factor`` moves the angles a little).

    PYTHONPATH=src nice -n 5 .venv/bin/python studies/noodle_crossings.py \\
        --out studies/results/noodle_crossings.json
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

# JSON written as the benchmarks write it (benchmarks/bench_io.py).
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from bench_io import machine, write_json

STUDY_SEEDS = (8100, 8101, 8102)
CHAIN_ANGLES_DEG = (0.0, 2.0, 5.0, 10.0)


def chain_spacing_mm(deg: float) -> float:
    """mm between the strand–strand contact points MuJoCo puts on two straight strands (the
    bowl's builder and contact law) lying one on the other, crossed at ``deg``, their joints
    0.37 of a segment out of step: the length of a line contact one point stands for."""
    import mujoco

    from articutool.sim.food_strands import set_strand_geom, strand_chain
    from articutool.sim.params import PhysicsParams
    from articutool.sim.world_parts import solver_spec

    params = PhysicsParams.load()
    food = params.food("noodles")
    n, ds, r = food.segments, food.segment_length, food.strand_radius
    s = solver_spec(params.world, food)
    t = np.radians(deg)
    turn = np.array([[np.cos(t), -np.sin(t), 0.0], [np.sin(t), np.cos(t), 0.0], [0.0, 0.0, 1.0]])
    x0 = -(n / 2 - 0.37) * ds
    for name, pos, rot in (("strand_a", (-n / 2 * ds, 0.0, 0.0), np.eye(3)),
                           ("strand_b", turn @ np.array([x0, 0.0, 0.0]) + [0.0, 0.0, 2 * r - 1e-5],
                            turn)):
        strand_chain(food, s.worldbody, name, pos, [rot] + [np.eye(3)] * (n - 1),
                     lambda g: set_strand_geom(g, food))
    m = s.compile()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    x = np.sort([float(c.pos @ turn[:, 0] + c.pos @ [1.0, 0.0, 0.0]) / 2
                 for c in d.contact[:d.ncon]])
    return float(np.diff(x).mean()) * 1e3


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(STUDY_SEEDS))
    ap.add_argument("--out", default="studies/results/noodle_crossings.json")
    args = ap.parse_args(argv)
    from articutool.sim.strand_laws import contact_tack, strand_contacts
    from articutool.sim.world import FeedingWorld

    doc: dict = {"command": "studies/noodle_crossings.py " + " ".join(argv or sys.argv[1:]),
                 "machine": machine(), "seeds": []}
    angles, ratios = [], []
    food = None
    for seed in args.seeds:
        c0 = time.process_time()
        w = FeedingWorld.make("noodles", seed=seed)
        food = w.params.food("noodles")
        ang, adh, dist = strand_contacts(w.model, w.data)
        f90 = contact_tack(food, math.pi / 2)
        r = np.array([contact_tack(food, a) for a in ang]) / f90
        deg = np.degrees(ang)
        row = {"seed": seed, "settled_s": round(w.time, 2), "strand_contacts": len(ang),
               "beyond_adhesion_gap": int((dist > food.adhesion_gap).sum()),
               "angle_deg_quantiles_10_25_50_75_90":
                   np.percentile(deg, [10, 25, 50, 75, 90]).round(1).tolist(),
               "law_over_right_angle_mean": round(float(r.mean()), 4),
               "model_adhesion_N": sorted({round(float(x), 9) for x in adh}),
               "cpu_s": round(time.process_time() - c0, 1),
               "angles_deg": [round(float(x), 2) for x in deg]}
        print({k: v for k, v in row.items() if k != "angles_deg"}, flush=True)
        doc["seeds"].append(row)
        angles.append(ang)
        ratios.append(r)
    assert food is not None
    ang, r = np.concatenate(angles), np.concatenate(ratios)
    f90 = contact_tack(food, math.pi / 2)
    doc.update({
        "strand_contacts": len(ang),
        "angle_deg_quantiles_10_25_50_75_90":
            np.percentile(np.degrees(ang), [10, 25, 50, 75, 90]).round(1).tolist(),
        "model_crossing_factor": food.crossing_factor,
        "right_angle_N": round(f90, 9), "parallel_N": round(contact_tack(food, 0.0), 9),
        "crossing_factor": round(float(r.mean()), 3),
        "mean_law_N": round(float(r.mean()) * f90, 9),
        "median_law_N": round(float(np.median(r)) * f90, 9)})
    doc["chain_contact_spacing_mm"] = {f"{a:g}": round(chain_spacing_mm(a), 2)
                                       for a in CHAIN_ANGLES_DEG}
    print({k: v for k, v in doc.items() if k not in ("seeds", "machine")}, flush=True)
    write_json(args.out, doc)
    return 0


if __name__ == "__main__":
    sys.exit(main())
