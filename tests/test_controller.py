"""Leveling controller (thesis Alg. 1; docs/hardware.md §5): structure, closed loop, properties."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from articutool.rotations import quaternion_to_matrix
from articutool.tool.controller import LevelingController
from articutool.tool.kinematics import (
    jacobian,
    joint_rates_for_rotation,
    nearest_leveling_solution,
    up_vector,
)
from conftest import packaged_spec

SPEC = packaged_spec()
C = SPEC.controller
LIMITS = SPEC.wrist.limits
VMAX = SPEC.wrist.velocity_limits
DT = SPEC.wrist.period
JACO_WRIST_SPEED = SPEC.arm.max_velocity[3:].max()  # rad/s, the Jaco's wrist joints
Z = np.array([0.0, 0.0, 1.0])

# Tool base held as in feeding: F0 x (the up vector at zero joints) along world up, the
# utensil (F0 z) pointing forward along world y; q = 0 is level.
R_LEVEL = np.column_stack([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def tilt(R: np.ndarray, q: np.ndarray, offsets=(0.0, 0.0)) -> float:
    """Angle (rad) between the (offset) tool up vector in the world and world +z."""
    y = R @ up_vector(np.asarray(q) - np.asarray(offsets))
    return math.atan2(math.hypot(y[0], y[1]), y[2])


def rot(rotvec) -> np.ndarray:
    return Rotation.from_rotvec(rotvec).as_matrix()


class Plant:
    """Wrist joints integrating the command (optionally through a first-order motor lag)."""

    def __init__(self, q0, lag: float = 0.0, substeps: int = 10) -> None:
        self.q = np.array(q0, dtype=float)
        self.v = np.zeros(2)
        self.lag = lag
        self.n = substeps

    def step(self, cmd: np.ndarray, R: np.ndarray, omega_world: np.ndarray, dt: float):
        h = dt / self.n
        a = 1.0 - math.exp(-h / self.lag) if self.lag > 0 else 1.0
        dR = rot(omega_world * h)
        for _ in range(self.n):
            self.v = self.v + a * (cmd - self.v)
            self.q = self.q + self.v * h
            R = dR @ R
        return R


# Arm transport: six smooth bursts (half-sine speed profile peaking at the Jaco's wrist joint
# speed) about tilted axes, then a pure yaw; each burst turns the base by ~37°.
TRANSPORT_AXES = [
    (1, 1, 1), (-1, -1, -1), (-1, 0.4, 0.8), (1, -0.4, -0.8), (0.3, 1, 0.2), (-0.3, -1, -0.2),
    (0, 0, 1),
]  # fmt: skip
BURST = 1.2  # s


def transport(ctrl: LevelingController, feedforward: bool, lag: float = 0.0):
    """Run the transport; returns (max tilt rad, peak horizontal base rate, joints, commands)."""
    R = R_LEVEL.copy()
    plant = Plant([0.0, 0.0], lag=lag)
    worst, w_perp, qs, cmds = 0.0, 0.0, [], []
    for axis in TRANSPORT_AXES:
        a = np.array(axis, float) / np.linalg.norm(axis)
        for k in range(round(BURST / DT)):
            w = JACO_WRIST_SPEED * math.sin(math.pi * k * DT / BURST) * a
            cmd = ctrl.update(R, plant.q, DT, base_rate=R.T @ w if feedforward else None)
            cmds.append(cmd)
            R = plant.step(cmd, R, w, DT)
            qs.append(plant.q.copy())
            worst = max(worst, tilt(R, plant.q))
            w_perp = max(w_perp, math.hypot(w[0], w[1]))
    return worst, w_perp, np.array(qs), np.array(cmds)


def assert_safe(qs: np.ndarray, cmds: np.ndarray) -> None:
    assert np.isfinite(cmds).all()
    assert (np.abs(cmds) <= VMAX + 1e-12).all()
    assert (qs >= LIMITS[:, 0] - 1e-9).all() and (qs <= LIMITS[:, 1] + 1e-9).all()


# ------------------------------------------------------------------ structure --
def test_first_tick_is_alg1_p_plus_i_through_eqs_4_6_4_7():
    ctrl = LevelingController.from_spec(SPEC)
    q = np.array([0.2, -0.3])  # |cos θr| > damping threshold: no damping
    R = rot([0.05, -0.08, 0.4]) @ R_LEVEL
    y = R @ up_vector(q)
    axis = np.cross(y, Z) / np.linalg.norm(np.cross(y, Z))
    e = axis * np.arccos(np.clip(y @ Z, -1, 1))
    # First tick: integral = e·dt, no derivative kick.
    expected = joint_rates_for_rotation(q, R.T @ ((C.kp + C.ki * DT) * e), C.pinv_rcond)
    np.testing.assert_allclose(ctrl.update(R, q, DT), expected, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(ctrl.integral, e * DT, rtol=1e-9, atol=1e-15)
    # Second tick: the derivative of the error joins in.
    R2 = rot([0.01, 0.0, 0.0]) @ R
    y2 = R2 @ up_vector(q)
    axis2 = np.cross(y2, Z) / np.linalg.norm(np.cross(y2, Z))
    e2 = axis2 * np.arccos(np.clip(y2 @ Z, -1, 1))
    w = C.kp * e2 + C.ki * (e + e2) * DT + C.kd * (e2 - e) / DT
    np.testing.assert_allclose(
        ctrl.update(R2, q, DT), joint_rates_for_rotation(q, R2.T @ w, C.pinv_rcond), rtol=1e-9
    )


def test_command_turns_the_up_vector_straight_towards_vertical():
    ctrl = LevelingController.from_spec(SPEC)
    q = np.array([0.1, 0.25])
    R = rot([0.06, 0.02, 1.0]) @ R_LEVEL
    qdot = ctrl.update(R, q, DT)
    y = R @ up_vector(q)
    ydot = R @ jacobian(q) @ qdot
    target = Z - (y @ Z) * y  # the great-circle direction from y to +z
    cosang = ydot @ target / (np.linalg.norm(ydot) * np.linalg.norm(target))
    assert cosang > 1 - 1e-9


def test_deadband_zeroes_command_and_resets_integral():
    ctrl = LevelingController.from_spec(SPEC)
    q = np.zeros(2)
    outside = rot([0.0, 3 * C.deadband, 0.0]) @ R_LEVEL
    assert np.abs(ctrl.update(outside, q, DT)).max() > 0
    assert np.abs(ctrl.integral).max() > 0
    inside = rot([0.0, 0.5 * C.deadband, 0.0]) @ R_LEVEL
    np.testing.assert_array_equal(ctrl.update(inside, q, DT), [0.0, 0.0])
    np.testing.assert_array_equal(ctrl.integral, np.zeros(3))
    assert ctrl.error_angle == pytest.approx(0.5 * C.deadband)


def test_integral_is_clamped_per_component():
    ctrl = LevelingController(
        kp=0.0, ki=1.0, kd=0.0, integral_clamp=0.05, deadband=C.deadband,
        limits=LIMITS, max_velocity=VMAX,
    )  # fmt: skip
    R = rot([0.3, -0.4, 0.0]) @ R_LEVEL
    q = np.zeros(2)
    for _ in range(200):  # joints held still: the error persists and integrates
        ctrl.update(R, q, DT)
    assert np.abs(ctrl.integral).max() == pytest.approx(0.05)
    assert (np.abs(ctrl.integral) <= 0.05 + 1e-15).all()


def test_upside_down_still_gives_a_finite_nonzero_command():
    ctrl = LevelingController.from_spec(SPEC)
    R = rot([math.pi, 0.0, 0.0]) @ R_LEVEL
    cmd = ctrl.update(R, np.zeros(2), DT)
    assert ctrl.error_angle == pytest.approx(math.pi)
    assert np.isfinite(cmd).all() and np.abs(cmd).max() > 0


@pytest.mark.parametrize(
    ("R", "q", "dt"),
    [
        (np.full((3, 3), np.nan), np.zeros(2), DT),
        (R_LEVEL, np.array([np.inf, 0.0]), DT),
        (R_LEVEL, np.zeros(2), 0.0),
        (R_LEVEL, np.zeros(2), -DT),
        (R_LEVEL, np.zeros(2), math.nan),
        (np.eye(2), np.zeros(2), DT),
        (R_LEVEL, np.zeros(3), DT),
    ],
)
def test_bad_input_is_a_value_error_and_leaves_state_alone(R, q, dt):
    ctrl = LevelingController.from_spec(SPEC)
    ctrl.update(rot([0.2, 0.1, 0.0]) @ R_LEVEL, np.zeros(2), DT)
    before = ctrl.integral
    with pytest.raises(ValueError):
        ctrl.update(R, q, dt)
    np.testing.assert_array_equal(ctrl.integral, before)


def test_bad_base_rate_and_gains_are_refused():
    ctrl = LevelingController.from_spec(SPEC)
    with pytest.raises(ValueError, match="base_rate"):
        ctrl.update(R_LEVEL, np.zeros(2), DT, base_rate=[0.0, math.nan, 0.0])
    with pytest.raises(ValueError, match="kp"):
        LevelingController(-1, 0, 0, 1, 0.01, LIMITS, VMAX)
    with pytest.raises(ValueError, match="max_velocity"):
        LevelingController(1, 0, 0, 1, 0.01, LIMITS, [1.0, 0.0])
    with pytest.raises(ValueError, match="pitch_offset_rad"):
        ctrl.set_offsets(math.nan, 0.0)
    with pytest.raises(ValueError, match="R_base_imu"):
        LevelingController.from_spec(SPEC, R_base_imu=np.diag([1.0, 1.0, -1.0]))


# ---------------------------------------------------------------- closed loop --
@pytest.mark.parametrize("lag", [0.0, 0.05])
def test_transport_pure_alg1_lags_by_about_rate_over_kp(lag):
    """Pure feedback (Alg. 1): the steady lag of a P loop is ω⊥/Kp; the tool stays within it."""
    worst, w_perp, qs, cmds = transport(LevelingController.from_spec(SPEC), False, lag)
    assert_safe(qs, cmds)
    assert worst < 1.2 * w_perp / C.kp + C.deadband
    print(f"\ntransport (Alg. 1 feedback only, lag {lag} s): max tilt {math.degrees(worst):.2f}°")


@pytest.mark.parametrize("lag", [0.0, 0.05])
def test_transport_with_rate_feedforward_stays_within_a_few_degrees(lag):
    worst, _, qs, cmds = transport(LevelingController.from_spec(SPEC), True, lag)
    assert_safe(qs, cmds)
    assert worst < math.radians(3.0)
    print(f"\ntransport (with gyro feed-forward, lag {lag} s): max tilt {math.degrees(worst):.2f}°")


@pytest.mark.parametrize("tilt_vec", [(0.5, 0.0, 0.0), (0.0, -0.6, 0.0), (0.3, 0.4, 2.0)])
def test_step_response_converges_to_a_leveling_solution(tilt_vec):
    ctrl = LevelingController.from_spec(SPEC)
    R = rot(tilt_vec) @ R_LEVEL
    plant = Plant([0.0, 0.0], lag=0.03)
    errs = []
    for _ in range(int(3.0 / DT)):
        cmd = ctrl.update(R, plant.q, DT)
        R = plant.step(cmd, R, np.zeros(3), DT)
        errs.append(tilt(R, plant.q))
    assert errs[0] > 0.3
    assert max(errs[-25:]) < C.deadband + 1e-3  # settled inside the deadband
    q_level, found = nearest_leveling_solution(R.T @ Z, LIMITS, plant.q)
    assert found
    np.testing.assert_allclose(plant.q, q_level, atol=2 * C.deadband)


@pytest.mark.parametrize("offsets", [(0.3, 0.0), (0.0, -0.5), (-0.25, 0.4)])
def test_offsets_hold_the_commanded_tilt_while_the_base_moves(offsets):
    ctrl = LevelingController.from_spec(SPEC)
    ctrl.set_offsets(*offsets)
    assert ctrl.offsets == pytest.approx(offsets)
    R = rot([0.2, -0.1, 0.5]) @ R_LEVEL
    plant = Plant([0.0, 0.0])
    w = np.array([0.0, 0.15, 0.1])  # a slow drift of the base
    for _ in range(int(4.0 / DT)):
        R = plant.step(ctrl.update(R, plant.q, DT), R, w, DT)
    # The joints sit at (a leveling solution) + offsets.
    q_level, found = nearest_leveling_solution(R.T @ Z, LIMITS, plant.q - offsets)
    assert found
    np.testing.assert_allclose(plant.q - q_level, offsets, atol=0.03)
    # …so the physical tool is tilted from level by the offsets, not level.
    if offsets[0] == 0.0:  # a pure roll offset tilts the up vector by exactly |b|
        assert tilt(R, plant.q) == pytest.approx(abs(offsets[1]), abs=0.03)


def test_joint_limits_are_never_exceeded_when_level_is_out_of_reach():
    ctrl = LevelingController.from_spec(SPEC)
    # Level would need pitch ≈ −(π/2 + 0.4): beyond the pitch limit.
    R = R_LEVEL.copy()
    plant = Plant([0.0, 0.0])
    w = R_LEVEL @ np.array([0.0, 1.0, 0.0]) * 0.5  # about F0 y (the pitch axis)
    qs, cmds = [], []
    for k in range(int(5.0 / DT)):
        wk = w if k * DT < (math.pi / 2 + 0.4) / 0.5 else np.zeros(3)
        cmd = ctrl.update(R, plant.q, DT)
        R = plant.step(cmd, R, wk, DT)
        qs.append(plant.q.copy())
        cmds.append(cmd)
    qs = np.array(qs)
    assert_safe(qs, np.array(cmds))
    # Pinned at the limit: approached exponentially (time constant 1 / limit_gain), never past.
    assert abs(qs[-1, 0]) == pytest.approx(math.pi / 2, abs=1e-4)


def test_a_joint_outside_its_limit_is_not_yanked_back_nor_pushed_further():
    ctrl = LevelingController.from_spec(SPEC)
    wide = np.array([[-10.0, 10.0], [-10.0, 10.0]])
    free = LevelingController(
        C.kp, C.ki, C.kd, C.integral_clamp, C.deadband, wide, VMAX, C.pinv_rcond
    )
    q = np.array([0.0, LIMITS[1, 1] + 0.5])  # roll beyond +π (e.g. after a twirl)
    signs = set()
    for rz in (0.3, -0.3):  # errors asking for roll one way, then the other
        ctrl.reset(), free.reset()
        R = R_LEVEL @ rot([0.0, 0.0, rz]) @ rot([0.0, 0.0, -q[1]])
        want, cmd = free.update(R, q, DT), ctrl.update(R, q, DT)
        signs.add(np.sign(want[1]))
        if want[1] > 0:  # outwards: refused
            assert cmd[1] == 0.0
        else:  # inwards: exactly the unconstrained command, no snap to the limit
            np.testing.assert_allclose(cmd, want, rtol=1e-12)
    assert signs == {1.0, -1.0}


def test_singularity_damps_pitch_as_designed_and_nothing_blows_up():
    thr, power = C.damping_threshold, C.damping_power
    undamped = LevelingController(
        C.kp, C.ki, C.kd, C.integral_clamp, C.deadband, LIMITS, [1e3, 1e3], C.pinv_rcond, 1e-9
    )
    damped = LevelingController(
        C.kp, C.ki, C.kd, C.integral_clamp, C.deadband, LIMITS, [1e3, 1e3], C.pinv_rcond,
        thr, power,
    )  # fmt: skip
    for r in (0.2, 0.8, 1.2, 1.5, math.pi / 2):
        q = np.array([0.1, r])
        R = rot([0.1, 0.15, 0.0]) @ R_LEVEL
        a, b = undamped.update(R, q, DT), damped.update(R, q, DT)
        undamped.reset(), damped.reset()
        c = abs(math.cos(r))
        factor = (c / thr) ** power if c < thr else 1.0
        np.testing.assert_allclose(b, [a[0] * factor, a[1]], rtol=1e-9, atol=1e-12)

    # Closed loop, level solution just off the singularity (pitch axis 0.05 rad from vertical),
    # starting with pitch 0.3 rad from its level value: roll levels the tool; pitch is frozen by
    # the damping, which costs only |cos θr|·Δpitch of tilt (the designed degradation).
    R = R_LEVEL @ rot([0.0, 0.0, -math.pi / 2 + 0.05])
    (_, r_level), _ = nearest_leveling_solution(R.T @ Z, LIMITS, [0.3, 0.0])
    assert abs(math.cos(r_level)) < 0.06
    ctrl = LevelingController.from_spec(SPEC)
    qs, cmds, errs = closed_loop(ctrl, R, [0.3, 0.0], np.zeros(3), 4.0)
    assert_safe(qs, cmds)
    assert abs(qs[-1, 0] - 0.3) < 0.05  # pitch barely moved
    assert errs[-1] <= C.deadband + abs(math.cos(r_level)) * 0.3

    # Base wobbling about the axis only pitch could compensate: the tilt follows the wobble
    # (not correctable there), while commands stay finite, bounded and inside the limits.
    ctrl.reset()
    w = lambda t: 0.4 * math.sin(2.0 * t) * np.array([1.0, 0.0, 0.0])  # noqa: E731
    qs, cmds, errs = closed_loop(ctrl, R, [0.3, 0.0], w, 6.0)
    assert_safe(qs, cmds)
    assert (np.abs(np.cos(qs[:, 1])) < 0.2).any()  # it did stay deep in the damped zone
    print(f"\nwobble at the singularity: max tilt {math.degrees(max(errs[50:])):.1f}°")


def closed_loop(ctrl, R, q0, w, duration, lag=0.03):
    """Run ``ctrl`` on a plant; ``w`` is a constant world rate or a function of time."""
    plant = Plant(q0, lag=lag)
    qs, cmds, errs = [], [], []
    for k in range(int(duration / DT)):
        wk = w(k * DT) if callable(w) else w
        cmd = ctrl.update(R, plant.q, DT)
        R = plant.step(cmd, R, wk, DT)
        qs.append(plant.q.copy())
        cmds.append(cmd)
        errs.append(tilt(R, plant.q))
    return np.array(qs), np.array(cmds), errs


def test_imu_mounting_rotation_is_applied():
    mount = rot([0.3, -0.2, math.pi / 2])  # R_F0←imu: the IMU axes expressed in F0
    ctrl = LevelingController.from_spec(SPEC, R_base_imu=mount)
    R_world_base = rot([0.2, 0.1, 0.3]) @ R_LEVEL
    R_world_imu = R_world_base @ mount
    np.testing.assert_allclose(ctrl.tool_base_orientation(R_world_imu), R_world_base, atol=1e-12)
    w_base = np.array([0.1, -0.2, 0.3])
    np.testing.assert_allclose(ctrl.tool_base_rate(mount.T @ w_base), w_base, atol=1e-12)
    quat = Rotation.from_matrix(R_world_imu).as_quat(scalar_first=True)
    np.testing.assert_allclose(quaternion_to_matrix(quat), R_world_imu, atol=1e-12)
    np.testing.assert_allclose(quaternion_to_matrix(3.0 * quat), R_world_imu, atol=1e-12)
    with pytest.raises(ValueError, match="quaternion"):
        quaternion_to_matrix([1.0, 0.0, math.nan, 0.0])


# ----------------------------------------------------------------- properties --
rotvecs = st.tuples(*[st.floats(-math.pi, math.pi)] * 3)
pitches = st.floats(LIMITS[0, 0] + 0.02, LIMITS[0, 1] - 0.02)
rolls = st.floats(LIMITS[1, 0] + 0.02, LIMITS[1, 1] - 0.02)


@settings(max_examples=300, deadline=None)
@given(rotvecs, pitches, rolls)
def test_command_never_increases_the_error_and_strictly_reduces_it(rv, p, r):
    ctrl = LevelingController.from_spec(SPEC)
    R = rot(rv)
    q = np.array([p, r])
    qdot = ctrl.update(R, q, DT)
    assert np.isfinite(qdot).all() and (np.abs(qdot) <= VMAX + 1e-12).all()
    y = R @ up_vector(q)
    rate = (R @ jacobian(q) @ qdot) @ Z  # d(y·z)/dt: positive means the error shrinks
    assert rate >= -1e-12
    err = ctrl.error_angle
    assume(C.deadband < err < math.pi - 0.05 and abs(math.cos(r)) > 0.05)
    assert rate > 0
    # …and a short step really does reduce the tilt.
    h = 1e-4
    assert tilt(R, q + h * qdot) < err
    assert y @ Z < 1.0


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(rotvecs, st.floats(-6.0, 6.0), st.floats(-12.0, 12.0)), min_size=1,
             max_size=15),
    st.floats(1e-4, 0.2),
    st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)),
)  # fmt: skip
def test_output_is_always_finite_within_speed_and_never_leaves_the_limits(seq, dt, offsets):
    ctrl = LevelingController.from_spec(SPEC)
    ctrl.set_offsets(*offsets)
    for rv, p, r in seq:
        q = np.array([p, r])
        qdot = ctrl.update(rot(rv), q, dt, base_rate=np.array(rv))
        assert np.isfinite(qdot).all()
        assert (np.abs(qdot) <= VMAX + 1e-12).all()
        q_next = q + qdot * dt
        lo, hi = np.minimum(LIMITS[:, 0], q), np.maximum(LIMITS[:, 1], q)
        assert (q_next >= lo - 1e-9).all() and (q_next <= hi + 1e-9).all()


def test_engage_levels_around_the_nearest_turn_within_the_cable_budget():
    ctrl = LevelingController.from_spec(SPEC)
    lo, hi = LIMITS[1]
    assert ctrl.roll_window == (lo, hi)  # before engaging: spec.wrist.roll_limits
    turn = 2 * math.pi
    budget = SPEC.wrist.roll_turn_budget * turn
    # After a twirl of 1.02 turns (and of 0.52: the level solution 2π is the nearest).
    for roll in (1.02 * turn, 0.52 * turn):
        ctrl.engage(R_LEVEL, [0.0, roll])
        assert ctrl.roll_window == pytest.approx((lo + turn, hi + turn))
        R = R_LEVEL @ rot([0.0, 0.0, 0.4])  # the base rolls: the roll must go above 2π
        q = np.array([0.0, turn])
        assert ctrl.update(R, q, DT)[1] != 0.0
    # At the end of the budget the window is moved inside it.
    ctrl.engage(R_LEVEL, [0.0, budget - 0.2])
    assert ctrl.roll_window == pytest.approx((budget - (hi - lo), budget))
    ctrl.engage(R_LEVEL, [0.0, -budget + 0.2])
    assert ctrl.roll_window == pytest.approx((-budget, -budget + (hi - lo)))
    # The nearest level configuration: within half a turn of roll, pitch inside its limits.
    np.testing.assert_allclose(ctrl.nearest_level(R_LEVEL, [0.3, 2.9 * turn]), [0.0, 3 * turn],
                               atol=1e-9)


def test_joints_slow_down_approaching_a_limit():
    """Towards a limit the speed is at most limit_gain × the distance left, so the motors'
    lagging velocity loop cannot carry the joint into the stop."""
    ctrl = LevelingController.from_spec(SPEC)
    for tilt_about_pitch_axis in (2.0, -2.0):  # level needs |pitch| > π/2, either way
        R = R_LEVEL @ rot([0.0, tilt_about_pitch_axis, 0.0])
        towards = np.sign(ctrl.update(R, np.zeros(2), DT)[0])
        limit = LIMITS[0, 1] if towards > 0 else LIMITS[0, 0]
        for gap in (0.5, 0.1, 0.01):
            ctrl.reset()
            v = ctrl.update(R, np.array([limit - towards * gap, 0.0]), DT)[0]
            assert towards * v > 0.0 and abs(v) <= C.limit_gain * gap + 1e-12


@settings(max_examples=150, deadline=None)
@given(rotvecs, st.floats(LIMITS[0, 0], LIMITS[0, 1]),
       st.floats(-SPEC.wrist.roll_turn_budget, SPEC.wrist.roll_turn_budget))
def test_from_any_start_the_lagging_joints_stay_inside_their_range(rv, p, turns):
    """Engaged anywhere inside the limits and the cable budget, with a 30 ms motor lag, the
    joints never leave pitch_limits nor the budget (the sim's stops), and the tool ends level
    or pinned at a limit."""
    budget = SPEC.wrist.roll_turn_budget * 2 * math.pi
    R = rot(rv)
    q0 = np.array([p, turns * 2 * math.pi])
    ctrl = LevelingController.from_spec(SPEC)
    ctrl.engage(R, q0)
    lo, hi = ctrl.roll_window
    assert -budget <= lo < hi <= budget
    plant = Plant(q0, lag=0.03)
    for _ in range(int(3.0 / DT)):
        plant.step(ctrl.update(R, plant.q, DT), R, np.zeros(3), DT)
        assert LIMITS[0, 0] - 1e-9 <= plant.q[0] <= LIMITS[0, 1] + 1e-9
        assert abs(plant.q[1]) <= budget + 1e-9
