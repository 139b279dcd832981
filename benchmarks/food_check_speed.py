"""Speed of the food-aware check: the slosh model on a 10 s transport, and what the food
check adds to plan-then-verify on the packaged 200-waypoint transport, measured side by side.

    .venv/bin/python benchmarks/food_check_speed.py --out results/food_check_speed.json

Clock: the process's CPU time (``time.process_time``), robust on a shared machine; each figure
is the median over ``--repeats`` interleaved runs (with and without the food check alternate,
so machine load hits both alike). The load average at the start is in the JSON.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np

from articutool.arm.model import ArmModel
from articutool.food.definitions import load_food_definitions
from articutool.food.dish import spoon_dish
from articutool.food.loads import food_load
from articutool.food.slosh import STANDARD_GRAVITY, SloshModel
from articutool.spec import load_spec
from articutool.trajectory import JointTrajectory
from articutool.verify.verifier import verify_trajectory
from bench_io import machine, write_json

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _cpu(f, *a, **kw) -> float:
    t0 = time.process_time()
    f(*a, **kw)
    return time.process_time() - t0


def _median_ms(xs: list[float]) -> float:
    return round(1e3 * statistics.median(xs), 4)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--out", default="results/food_check_speed.json")
    args = ap.parse_args()
    load0 = os.getloadavg()
    spec = load_spec()
    model = ArmModel(spec, "soup_spoon")
    traj = JointTrajectory.load(EXAMPLES / "transport_feasible.json")
    water = food_load(load_food_definitions()["water"], 8.0)

    # The slosh model alone: a 10 s transport's apparent gravity sampled at 100 Hz.
    slosh = SloshModel(spoon_dish(spec.utensil("soup_spoon")), 8e-6)
    t = np.linspace(0.0, 10.0, 1001)
    a = 1.5 * np.sin(2 * np.pi * t / 10.0)[:, None] * np.array([0.6, 0.8, 0.0])
    g_app = np.array([0.0, 0.0, -STANDARD_GRAVITY]) - a
    g_dish = g_app[:, [2, 1, 0]]
    c, s = np.cos(0.3 * t), np.sin(0.3 * t)
    R = np.zeros((t.size, 3, 3))  # dish x = world up, turning about it
    R[:, 2, 0] = 1.0
    R[:, 0, 1], R[:, 1, 1] = -s, c
    R[:, 0, 2], R[:, 1, 2] = c, s
    pos = np.column_stack([0.3 * c, 0.3 * s, 0.2 + 0.05 * t])
    slosh.predict(t, g_dish)  # warm (imports, table)
    from_g = [_cpu(slosh.predict, t, g_dish) for _ in range(args.repeats)]
    from_poses = [_cpu(slosh.predict_poses, t, pos, R) for _ in range(args.repeats)]

    # Plan-then-verify with and without the food check, interleaved.
    verify_trajectory(traj, model, spec, load=water)  # warm
    plain, food = [], []
    for _ in range(args.repeats):
        plain.append(_cpu(verify_trajectory, traj, model, spec))
        food.append(_cpu(verify_trajectory, traj, model, spec, load=water))
    rep = verify_trajectory(traj, model, spec, load=water)
    doc = {
        "clock": "process CPU time (time.process_time), median of interleaved repeats",
        "repeats": args.repeats,
        "machine": machine(),
        "loadavg_start": load0,
        "loadavg_end": os.getloadavg(),
        "slosh_10s_transport": {
            "grid_samples": int(slosh.predict(t, g_dish).t.size),
            "from_apparent_gravity_ms": _median_ms(from_g),
            "from_poses_ms": _median_ms(from_poses),
            "goal_ms": 1.0,
        },
        "verify_200_waypoints": {
            "waypoints": len(traj), "duration_s": round(traj.duration, 3),
            "food_grid_samples": int(rep.food.prediction.t.size),
            "plain_ms": _median_ms(plain),
            "with_food_ms": _median_ms(food),
            "added_ms": round(_median_ms(food) - _median_ms(plain), 4),
            "goal_added_ms": 5.0,
        },
    }
    write_json(args.out, doc)


if __name__ == "__main__":
    main()
