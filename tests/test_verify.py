"""Plan-then-verify (Alg. 2) against an analytic arm whose tool-base motion is known exactly."""

import tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.spec import default_spec_path, load_spec, parse_spec
from articutool.tool.kinematics import up_vector
from articutool.trajectory import JointTrajectory, TrajectoryError
from articutool.verify.verifier import densify, verify_trajectory


def _gimbal_spec(**wrist: object):
    """The spec with arm joints that may turn at 100 rad/s: the analytic gimbal arm below is
    not the Jaco (0.63 rad/s), and these tests drive it fast to exercise the wrist's limits;
    the Jaco's own limits are checked in test_verify_arm_limits.py."""
    raw = tomllib.loads(default_spec_path().read_text())
    for joint in raw["arm"]["joints"]:
        joint["max_velocity"] = 100.0
    raw["wrist"].update(wrist)
    return parse_spec(raw)


SPEC = _gimbal_spec()
assert load_spec().wrist == SPEC.wrist
NAMES = SPEC.arm.joint_names


def Rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def Ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def Rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


# F0 level at q = 0: F0's +x (the wrist's up at zero) along world +z.
R0 = Ry(-np.pi / 2)


class GimbalArm:
    """Tool base orientation R = Rz(q1) Ry(q2) Rx(q3) R0; joints 4-6 do not move it."""

    def tool_base_rotations(self, q):
        return np.stack([Rz(a) @ Ry(b) @ Rx(c) @ R0 for a, b, c in q[:, :3]])

    def tool_base_angular_velocity(self, q, qd):
        out = []
        for (a, b, _), (da, db, dc) in zip(q[:, :3], qd[:, :3], strict=True):
            out.append(np.array([0, 0, da]) + Rz(a) @ np.array([0, db, 0])
                       + Rz(a) @ Ry(b) @ np.array([dc, 0, 0]))
        return np.stack(out)


ARM = GimbalArm()


def arm_traj(times, gimbal, rates):
    """Arm trajectory with joints 1-3 set to the gimbal angles; joints 2/3 offset to mid-range."""
    n = len(times)
    mid = (SPEC.arm.lower + SPEC.arm.upper) / 2
    q = np.tile(mid, (n, 1))
    qd = np.zeros((n, 6))
    q[:, :3] = gimbal
    qd[:, :3] = rates
    return JointTrajectory(tuple(NAMES), np.asarray(times, float), q, qd)


def mid_offsets():
    return ((SPEC.arm.lower + SPEC.arm.upper) / 2)[:3]


def ramp(axis, rate, duration, n=21, start=None):
    """Constant-rate rotation of one gimbal axis."""
    t = np.linspace(0, duration, n)
    g = np.tile(mid_offsets() if start is None else start, (n, 1)).astype(float)
    g[:, axis] += rate * t
    r = np.zeros((n, 3))
    r[:, axis] = rate
    return arm_traj(t, g, r)


class CentredArm(GimbalArm):
    """The gimbal with joint 1-3 mid-range offsets removed, so q = mid means 'level'."""

    def tool_base_rotations(self, q):
        q = q.copy()
        q[:, :3] -= mid_offsets()
        return super().tool_base_rotations(q)

    def tool_base_angular_velocity(self, q, qd):
        q = q.copy()
        q[:, :3] -= mid_offsets()
        return super().tool_base_angular_velocity(q, qd)


CARM = CentredArm()


def test_still_arm_is_feasible_with_zero_wrist_motion():
    tr = ramp(0, 0.0, 2.0)
    rep = verify_trajectory(tr, CARM, SPEC)
    assert rep.feasible and rep.reason == "ok"
    np.testing.assert_allclose(rep.max_required_velocity, 0.0, atol=1e-12)
    np.testing.assert_allclose(rep.wrist_trajectory.positions, 0.0, atol=1e-9)
    assert rep.velocity_margin == pytest.approx(1.0)


def test_yaw_needs_no_wrist_motion_thanks_to_the_cross_product():
    # Rotating about world z leaves the up vector in F0 unchanged: ω_corr ∥ u, so ω × u = 0.
    rep = verify_trajectory(ramp(0, 0.6, 3.0), CARM, SPEC)
    assert rep.feasible
    np.testing.assert_allclose(rep.max_required_velocity, 0.0, atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(st.integers(1, 2), st.floats(-0.8, 0.8).filter(lambda x: abs(x) > 0.05))
def test_required_rates_equal_the_derivative_of_the_leveling_solution(axis, rate):
    # Eq. 4.7 (rates) and Eqs. 4.2-4.3 (positions) must describe the same wrist motion.
    rep = verify_trajectory(ramp(axis, rate, 1.0), CARM, SPEC, max_step_deg=0.25)
    assert rep.feasible, rep.message
    w = rep.wrist_trajectory
    fd = np.gradient(w.positions, w.times, axis=0)
    np.testing.assert_allclose(w.velocities[1:-1], fd[1:-1], atol=2e-3 * max(1, abs(rate)))
    # Every sample is level: the tool's up in the world is +z.
    R = CARM.tool_base_rotations(densify(ramp(axis, rate, 1.0), CARM, np.radians(0.25))[1])
    up_world = np.einsum("kij,kj->ki", R, up_vector(w.positions))
    np.testing.assert_allclose(up_world, np.tile([0, 0, 1.0], (len(w), 1)), atol=1e-9)


def test_tilting_faster_than_the_motors_is_a_velocity_failure():
    rep = verify_trajectory(ramp(1, 5.0, 0.25), CARM, SPEC)
    assert not rep.feasible and rep.reason == "velocity"
    assert rep.first_failure_time == pytest.approx(0.0)
    assert rep.velocity_margin < 0
    assert "rad/s" in rep.message


def test_a_fast_motion_between_sparse_waypoints_is_caught_by_densification():
    # Both waypoints at rest; a 90° tilt in 0.2 s happens in between.
    t = [0.0, 0.2]
    g = np.tile(mid_offsets(), (2, 1))
    g[1, 1] += np.pi / 2
    tr = arm_traj(t, g, np.zeros((2, 3)))
    rep = verify_trajectory(tr, CARM, SPEC)
    assert not rep.feasible and rep.reason == "velocity"
    assert rep.samples_checked > 2  # densified: 90° in ≤ 1° steps
    assert 0.0 < rep.first_failure_time < 0.2
    assert rep.first_failure_index == 0


def test_densified_steps_respect_the_bound():
    tr = ramp(2, 0.8, 2.0, n=3)
    for step in (0.5, 1.0, 3.0):
        t, q, qd, R = densify(tr, CARM, np.radians(step))
        tr_ = np.einsum("kij,kij->k", R[:-1], R[1:])
        ang = np.degrees(np.arccos(np.clip((tr_ - 1) / 2, -1, 1)))
        assert ang.max() <= step + 1e-9
        assert np.isin(tr.times, t).all()  # every waypoint is a sample
        at = np.searchsorted(t, tr.times)  # ... with the waypoint's own values, exactly
        assert np.array_equal(q[at], tr.positions) and np.array_equal(qd[at], tr.velocities)


def test_branch_switch_is_a_discontinuity():
    # Tilt the base past 90°: the up vector in F0 crosses vx = 0 and pitch must flip by π.
    rep2 = verify_trajectory(ramp(1, 0.5, 4.0), CARM, SPEC)
    assert not rep2.feasible and rep2.reason == "discontinuity", rep2.message
    assert rep2.branch_switches == 1
    assert rep2.first_failure_time == pytest.approx(np.pi / 2 / 0.5, abs=0.04)  # one 1° step


def _narrow_spec():
    return _gimbal_spec(roll_limits=[-0.5, 0.5], pitch_limits=[-0.5, 0.5])


def test_no_leveling_solution_inside_narrow_limits():
    spec = _narrow_spec()
    rep = verify_trajectory(ramp(1, 0.5, 2.0), CARM, spec)
    assert not rep.feasible and rep.reason == "no_leveling_solution"
    assert rep.first_failure_time == pytest.approx(1.0, abs=0.04)  # one 1° step
    assert "inside the limits" in rep.message
    assert rep.wrist_trajectory.times[-1] < rep.first_failure_time


def test_arm_joint_limits_are_checked():
    tr = ramp(0, 0.0, 1.0)
    q = tr.positions.copy()
    q[3, 1] = SPEC.arm.upper[1] + 0.1
    bad = JointTrajectory(tr.joint_names, tr.times, q, tr.velocities)
    rep = verify_trajectory(bad, CARM, SPEC)
    assert rep.reason == "arm_joint_limit" and rep.first_failure_index == 3
    assert "j2n6s200_joint_2" in rep.message


def test_joint_order_does_not_matter():
    tr = ramp(1, 0.5, 1.0)
    assert tr.reordered(tr.joint_names) is tr  # in order already: nothing to copy
    perm = [5, 3, 1, 0, 2, 4]
    shuffled = JointTrajectory(tuple(tr.joint_names[i] for i in perm), tr.times,
                               tr.positions[:, perm], tr.velocities[:, perm])
    a = verify_trajectory(tr, CARM, SPEC)
    b = verify_trajectory(shuffled, CARM, SPEC)
    assert a.max_required_velocity == pytest.approx(b.max_required_velocity)


def test_bad_input_is_rejected():
    tr = ramp(0, 0.0, 1.0)
    other = JointTrajectory(("a", "b"), tr.times, tr.positions[:, :2], tr.velocities[:, :2])
    with pytest.raises(TrajectoryError, match="missing"):
        verify_trajectory(other, CARM, SPEC)
    with pytest.raises(TrajectoryError, match="max_step_deg"):
        verify_trajectory(tr, CARM, SPEC, max_step_deg=0.0)
    with pytest.raises(TrajectoryError, match="q_wrist_start"):
        verify_trajectory(tr, CARM, SPEC, q_wrist_start=(np.nan, 0.0))


def test_report_serialises():
    rep = verify_trajectory(ramp(1, 0.5, 1.0), CARM, SPEC)
    d = rep.to_dict(include_trajectory=True)
    assert d["feasible"] is True and len(d["max_required_velocity"]) == 2
    assert d["wrist_trajectory"]["joint_names"] == list(SPEC.wrist.joint_names)


def _near_singularity_pass(eps, rate=0.3):
    """The base rolled 90° less ``eps`` (the up vector in F0 near the pitch axis, |cos roll| ≈
    eps), then tilted through it: the leveling pitch swings by nearly π within a few
    milliseconds along one solution curve, while the Eq. 4.7 rates at the 1° samples stay
    small (the samples are far from the pole compared with eps)."""
    t = np.linspace(0, 0.2 / rate, 3)
    g = np.tile(mid_offsets(), (3, 1)).astype(float)
    r = np.zeros((3, 3))
    g[:, 2] += np.pi / 2 - eps
    g[:, 1] += -0.1 + rate * t
    r[:, 1] = rate
    return arm_traj(t, g, r)


@pytest.mark.parametrize("eps", [0.0, 1e-4, 1e-3, -1e-3])
def test_a_jump_along_one_solution_curve_is_a_discontinuity(eps):
    rep = verify_trajectory(_near_singularity_pass(eps), CARM, SPEC)
    assert not rep.feasible and rep.reason == "discontinuity", rep.message
    assert rep.branch_switches == 0 and "along one solution" in rep.message
    t = rep.first_failure_time
    assert 0.0 < t < 0.2 / 0.3
    # Where it fails the base is at the pole: its tilt has crossed 0.1 rad (t = 1/3 s).
    assert abs(t - 0.1 / 0.3) < 0.04
    # Every step of the wrist trajectory before the failure is one the motors can make.
    w = rep.wrist_trajectory
    assert (np.abs(np.diff(w.positions, axis=0))
            <= SPEC.wrist.velocity_limits * np.diff(w.times)[:, None] + 1e-12).all()


@settings(max_examples=40, deadline=None)
@given(st.floats(-0.01, 0.01), st.floats(0.05, 0.8))
def test_the_wrist_trajectory_never_steps_faster_than_the_motors(eps, rate):
    """Whatever the verdict, the leveling trajectory it returns (up to any failure) is one
    the motors can follow, sample to sample — near the singularity too."""
    rep = verify_trajectory(_near_singularity_pass(eps, rate), CARM, SPEC)
    w = rep.wrist_trajectory
    assert w is not None and len(w) > 1
    steps = np.abs(np.diff(w.positions, axis=0))
    assert (steps <= SPEC.wrist.velocity_limits * np.diff(w.times)[:, None] + 1e-12).all()


def test_no_sample_evaluated_gives_no_velocity_margin():
    """An arm limit stops the check before any wrist rate is computed: the margin is unknown
    (NaN; null in JSON), not 100 %."""
    tr = ramp(0, 0.0, 1.0)
    q = tr.positions.copy()
    q[0, 1] = SPEC.arm.upper[1] + 0.1
    rep = verify_trajectory(JointTrajectory(tr.joint_names, tr.times, q, tr.velocities),
                            CARM, SPEC)
    assert rep.reason == "arm_joint_limit" and rep.samples_checked == 0
    assert np.isnan(rep.velocity_margin) and np.isnan(rep.max_required_velocity).all()
    d = rep.to_dict()
    assert d["velocity_margin"] is None and d["max_required_velocity"] == [None, None]
    import json

    json.loads(json.dumps(d, allow_nan=False))  # strict JSON
