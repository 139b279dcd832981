"""Plan-then-verify speed: a 200-waypoint transport (target: about a millisecond, so a plan can be
verified before every motion).

    .venv/bin/python -m pytest benchmarks/test_bench_verify.py --benchmark-only
"""

from pathlib import Path

import numpy as np
import pytest

from articutool.arm.model import ArmModel
from articutool.spec import load_spec
from articutool.trajectory import JointTrajectory
from articutool.verify.verifier import verify_trajectory

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SPEC = load_spec()
MODEL = ArmModel(SPEC)


@pytest.fixture(scope="module")
def traj():
    t = JointTrajectory.load(EXAMPLES / "transport_feasible.json")
    assert len(t) == 200
    return t


def test_verify_200_waypoints(benchmark, traj):
    rep = benchmark(verify_trajectory, traj, MODEL, SPEC)
    assert rep.feasible
    benchmark.extra_info["samples_checked"] = rep.samples_checked


def test_verify_200_waypoints_coarse(benchmark, traj):
    rep = benchmark(verify_trajectory, traj, MODEL, SPEC, max_step_deg=5.0)
    assert rep.feasible


def test_tool_base_rotations_200(benchmark, traj):
    R = benchmark(MODEL.tool_base_rotations, traj.positions)
    assert R.shape == (200, 3, 3)


def test_pinocchio_loop_200_for_comparison(benchmark, traj):
    # The per-point Pinocchio path the vectorised FK replaces, measured side by side.
    def loop():
        return np.stack([MODEL.tool_base_pose(q)[:3, :3] for q in traj.positions])

    R = benchmark(loop)
    np.testing.assert_allclose(R, MODEL.tool_base_rotations(traj.positions), atol=1e-12)
