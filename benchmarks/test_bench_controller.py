"""Per-tick cost of the leveling controller and a primitive (50 Hz loop: budget 20 ms/tick).

Run: ``.venv/bin/python -m pytest benchmarks/test_bench_controller.py --benchmark-only``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from articutool.spec import load_spec
from articutool.tool.controller import LevelingController
from articutool.tool.primitives import make_primitive

SPEC = load_spec()
DT = SPEC.wrist.period
R_LEVEL = np.column_stack([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
R = Rotation.from_rotvec([0.2, -0.1, 0.4]).as_matrix() @ R_LEVEL
Q = np.array([0.1, -0.2])


def test_bench_leveling_update(benchmark):
    ctrl = LevelingController.from_spec(SPEC)
    cmd = benchmark(ctrl.update, R, Q, DT)
    assert np.isfinite(cmd).all() and np.abs(cmd).max() > 0  # outside the deadband: full path


def test_bench_leveling_update_with_rate_feedforward(benchmark):
    ctrl = LevelingController.from_spec(SPEC)
    w = np.array([0.3, -0.2, 0.5])
    cmd = benchmark(ctrl.update, R, Q, DT, w)
    assert np.isfinite(cmd).all()


def test_bench_leveling_from_imu_quaternion(benchmark):
    """The runtime's path: filter quaternion → R_world←F0 → command."""
    from articutool.rotations import quaternion_to_matrix

    ctrl = LevelingController.from_spec(SPEC)
    quat = Rotation.from_matrix(R).as_quat(scalar_first=True)

    def tick():
        return ctrl.update(ctrl.tool_base_orientation(quaternion_to_matrix(quat)), Q, DT)

    assert np.isfinite(benchmark(tick)).all()


def test_bench_primitive_step(benchmark):
    # A fresh vibration per round (setup is not timed): the spec bounds its duration
    # (max_vibrate_s), so one primitive would finish within the benchmark's rounds.
    def fresh():
        return (make_primitive("VIBRATE_ROLL", [5.0, 0.05, SPEC.primitives.max_vibrate_s],
                               SPEC, Q), Q, DT), {}

    cmd = benchmark.pedantic(lambda prim, q, dt: prim.step(q, dt), setup=fresh, rounds=2000)
    assert np.isfinite(cmd).all()
