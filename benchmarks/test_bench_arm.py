"""Arm-model call costs that planners and the verifier pay per state.

    .venv/bin/python -m pytest benchmarks/test_bench_arm.py --benchmark-only
"""

import numpy as np

from articutool.arm.model import ArmModel
from articutool.spec import load_spec

SPEC = load_spec()
MODEL8 = ArmModel(SPEC, dof=8)
MODEL6 = ArmModel(SPEC, dof=6)
Q6 = SPEC.arm.configuration("AbovePlate")
Q8 = np.r_[Q6, 0.0, 0.0]
BATCH = np.random.default_rng(0).uniform(SPEC.arm.lower, SPEC.arm.upper, size=(1000, 6))


def test_ee_pose(benchmark):
    assert benchmark(MODEL8.ee_pose, Q6).shape == (4, 4)


def test_in_collision_8dof(benchmark):
    assert benchmark(MODEL8.in_collision, Q8) is False


def test_in_collision_6dof(benchmark):
    assert benchmark(MODEL6.in_collision, Q6) is False


def test_min_distance_8dof(benchmark):
    assert benchmark(MODEL8.min_distance, Q8) > 0


def test_tool_base_kinematics_1000(benchmark):
    R, w = benchmark(MODEL8.tool_base_kinematics, BATCH, np.ones_like(BATCH))
    assert R.shape == (1000, 3, 3) and w.shape == (1000, 3)
