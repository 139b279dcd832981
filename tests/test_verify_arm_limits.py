"""The verifier checks the arm along the spline, not only at waypoints."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from articutool.arm.model import ArmModel
from articutool.trajectory import JointTrajectory
from articutool.verify.verifier import verify_trajectory


@pytest.fixture(scope="module")
def model(spec):
    return ArmModel(spec, dof=6)


def _two_waypoints(spec, v_j2: float) -> JointTrajectory:  # type: ignore[no-untyped-def]
    """Identical positions 10 s apart (at AbovePlate), joint 2 moving at ``v_j2`` at the
    first waypoint."""
    home = np.array(spec.arm.configuration("AbovePlate"), dtype=float)
    v = np.zeros((2, 6))
    v[0, 1] = v_j2
    return JointTrajectory(spec.arm.joint_names, np.array([0.0, 10.0]),
                           np.stack([home, home]), v)


def test_spline_overshoot_past_the_joint_limit_is_infeasible(spec, model) -> None:
    traj = _two_waypoints(spec, 3.0)
    # The spline the file describes takes joint 2 far outside its limit between waypoints.
    q, _ = traj.sample(np.linspace(0, 10, 2001))
    assert q[:, 1].max() > spec.arm.upper[1]
    rep = verify_trajectory(traj, model, spec)
    assert not rep.feasible
    assert rep.reason == "arm_joint_limit"
    assert "j2n6s200_joint_2" in rep.message and rep.samples_checked == 0
    assert rep.first_failure_time is not None and 0.0 < rep.first_failure_time < 10.0


def test_arm_velocity_above_its_limit_is_infeasible(spec, model) -> None:
    # Small enough to stay inside the position limits, too fast for the Jaco (0.63 rad/s).
    traj = _two_waypoints(spec, 0.8)
    q, _ = traj.sample(np.linspace(0, 10, 2001))
    assert (q >= spec.arm.lower).all() and (q <= spec.arm.upper).all()
    rep = verify_trajectory(traj, model, spec)
    assert not rep.feasible and rep.reason == "arm_velocity_limit", rep.message
    assert "j2n6s200_joint_2" in rep.message


def test_densification_follows_joint_travel(spec, model) -> None:
    # A slow wobble of joint 2 within the limits: feasible, and sampled finely along the
    # spline although both waypoints are identical.
    rep = verify_trajectory(_two_waypoints(spec, 0.05), model, spec)
    assert rep.feasible, rep.message
    assert rep.samples_checked > 20


def test_cli_reports_the_arm_reason(spec, tmp_path) -> None:
    f = tmp_path / "traj.json"
    f.write_text(json.dumps(_two_waypoints(spec, 3.0).to_dict()))
    r = subprocess.run([sys.executable, "-m", "articutool.cli", "verify", str(f), "--json"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1, r.stderr
    assert json.loads(r.stdout)["reason"] == "arm_joint_limit"
