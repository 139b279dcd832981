"""The verifier checks the arm along the spline, not only at waypoints."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

from articutool.arm.model import ArmModel
from articutool.spec import load_spec
from articutool.trajectory import JointTrajectory
from articutool.verify.verifier import verify_trajectory

SPEC = load_spec()
MODEL = ArmModel(SPEC, dof=6)
HOME = np.array(SPEC.arm.configuration("AbovePlate"), dtype=float)


def _two_waypoints(v_j2: float) -> JointTrajectory:
    """Identical positions 10 s apart, joint 2 moving at ``v_j2`` at the first waypoint."""
    v = np.zeros((2, 6))
    v[0, 1] = v_j2
    return JointTrajectory(SPEC.arm.joint_names, np.array([0.0, 10.0]),
                           np.stack([HOME, HOME]), v)


def test_spline_overshoot_past_the_joint_limit_is_infeasible() -> None:
    traj = _two_waypoints(3.0)
    # The spline the file describes takes joint 2 far outside its limit between waypoints.
    q, _ = traj.sample(np.linspace(0, 10, 2001))
    assert q[:, 1].max() > SPEC.arm.upper[1]
    rep = verify_trajectory(traj, MODEL, SPEC)
    assert not rep.feasible
    assert rep.reason == "arm_joint_limit"
    assert "j2n6s200_joint_2" in rep.message and rep.samples_checked == 0
    assert rep.first_failure_time is not None and 0.0 < rep.first_failure_time < 10.0


def test_arm_velocity_above_its_limit_is_infeasible() -> None:
    # Small enough to stay inside the position limits, too fast for the Jaco (0.63 rad/s).
    traj = _two_waypoints(0.8)
    q, _ = traj.sample(np.linspace(0, 10, 2001))
    assert (q >= SPEC.arm.lower).all() and (q <= SPEC.arm.upper).all()
    rep = verify_trajectory(traj, MODEL, SPEC)
    assert not rep.feasible and rep.reason == "arm_velocity_limit", rep.message
    assert "j2n6s200_joint_2" in rep.message


def test_densification_follows_joint_travel() -> None:
    # A slow wobble of joint 2 within the limits: feasible, and sampled finely along the
    # spline although both waypoints are identical.
    rep = verify_trajectory(_two_waypoints(0.05), MODEL, SPEC)
    assert rep.feasible, rep.message
    assert rep.samples_checked > 20


def test_cli_reports_the_arm_reason(tmp_path) -> None:
    f = tmp_path / "traj.json"
    f.write_text(json.dumps(_two_waypoints(3.0).to_dict()))
    r = subprocess.run([sys.executable, "-m", "articutool.cli", "verify", str(f), "--json"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1, r.stderr
    assert json.loads(r.stdout)["reason"] == "arm_joint_limit"
