"""The simulated wrist: motor integration, limits, lag, IMU synthesis and fault injection."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.tool.drivers import make_drivers
from articutool.tool.drivers.base import DriverError, HardwareError
from articutool.tool.drivers.sim import (
    SimFTDriver,
    SimImuDriver,
    SimMotorDriver,
    SimWrist,
    axis_angle_rotation,
    constant_rate_motion,
)
from conftest import packaged_spec

SPEC = packaged_spec()
VMAX = np.array(SPEC.wrist.max_velocity)
RATE = SPEC.imu.rate_hz
DT = SPEC.wrist.period


def opened(sim: SimWrist, torque: bool = True) -> SimMotorDriver:
    m = sim.motor_driver()
    m.open()
    if torque:
        m.enable_torque(True)
    return m


def run(sim: SimWrist, seconds: float, dt: float = DT) -> None:
    for _ in range(round(seconds / dt)):
        sim.step(dt)


# ---------------------------------------------------------------------------- motors ----
@settings(max_examples=30, deadline=None)
@given(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(0.01, 1.0), st.floats(0.0, 0.1))
def test_velocity_integration_matches_first_order_lag(
    vp: float, vr: float, t: float, tau: float
) -> None:
    sim = SimWrist(SPEC, motor_lag=tau, noise=False)
    m = opened(sim)
    v = np.array([vp, vr])
    m.set_velocity(v)
    n = 10
    for _ in range(n):
        sim.step(t / n)
    # q(t) = v (t − τ(1 − e^{−t/τ})), q̇(t) = v (1 − e^{−t/τ}) from rest
    lag = tau * (1 - math.exp(-t / tau)) if tau > 0 else 0.0
    decay = math.exp(-t / tau) if tau > 0 else 0.0
    np.testing.assert_allclose(sim.q, v * (t - lag), atol=1e-12)
    np.testing.assert_allclose(m.read().velocity, v * (1 - decay), atol=1e-12)


def test_step_size_does_not_change_the_trajectory() -> None:
    a, b = (SimWrist(SPEC, noise=False) for _ in range(2))
    for s in (a, b):
        opened(s).set_velocity([0.7, -1.3])
    run(a, 1.0, dt=0.02)
    run(b, 1.0, dt=0.005)
    np.testing.assert_allclose(a.q, b.q, atol=1e-9)


def test_over_limit_and_non_finite_commands_are_refused_without_motion() -> None:
    sim = SimWrist(SPEC, noise=False)
    m = opened(sim)
    m.set_velocity([0.5, 0.0])
    for bad in ([VMAX[0] * 1.01, 0.0], [0.0, math.nan], [math.inf, 0.0], [1.0, 2.0, 3.0]):
        with pytest.raises(ValueError, match=r"qd"):
            m.set_velocity(bad)
    run(sim, 1.0)
    assert sim.qd[1] == 0.0 and sim.qd[0] == pytest.approx(0.5)  # previous command stands
    m.set_velocity(-VMAX)  # exactly the limit is allowed
    run(sim, 0.5)
    np.testing.assert_allclose(sim.qd, -VMAX, rtol=1e-3)


def test_position_mode_saturates_at_the_velocity_limit_and_converges() -> None:
    sim = SimWrist(SPEC, noise=False)
    m = opened(sim)
    m.set_mode("position")
    target = np.array([1.2, -2.5])
    m.set_position(target)
    peak = np.zeros(2)
    for _ in range(150):
        sim.step(DT)
        peak = np.maximum(peak, np.abs(sim.qd))
    assert (peak <= VMAX + 1e-12).all()
    assert peak[1] == pytest.approx(VMAX[1], rel=1e-2)  # large error → saturated
    np.testing.assert_allclose(sim.q, target, atol=1e-3)
    with pytest.raises(DriverError, match="velocity mode"):
        m.set_velocity([0.1, 0.0])
    with pytest.raises(ValueError, match=r"q\[pitch\]"):
        m.set_position([2.0, 0.0])


def test_gentle_contact_with_a_limit_stops_without_error() -> None:
    sim = SimWrist(SPEC, noise=False)
    m = opened(sim)
    m.set_velocity([0.3, 0.0])  # below hard_stop_velocity
    run(sim, 8.0)
    assert sim.q[0] == pytest.approx(SPEC.wrist.pitch_limits[1])
    assert sim.qd[0] == 0.0
    assert m.read().hardware_error == (0, 0)


def test_roll_turn_budget_limits_roll() -> None:
    budget = SPEC.wrist.roll_turn_budget * 2 * math.pi
    sim = SimWrist(SPEC, noise=False, q0=(0.0, -budget + 0.05))
    m = opened(sim)
    m.set_velocity([0.0, -0.2])
    run(sim, 1.0)
    assert sim.q[1] == pytest.approx(-budget)
    assert not m.read().has_hardware_error


def test_hard_hit_raises_overload_and_drops_torque_until_cleared() -> None:
    sim = SimWrist(SPEC, noise=False)
    m = opened(sim)
    m.set_velocity([3.0, 0.0])
    run(sim, 1.0)
    s = m.read()
    assert s.hardware_error[0] & HardwareError.OVERLOAD
    assert s.hardware_error[1] == 0
    assert s.position[0] == pytest.approx(SPEC.wrist.pitch_limits[1])
    m.set_velocity([-1.0, 0.0])  # accepted, but the shut-down motor does not move
    run(sim, 0.5)
    assert sim.q[0] == pytest.approx(SPEC.wrist.pitch_limits[1])
    m.clear_errors()
    assert m.read().hardware_error == (0, 0) and not m.torque_enabled
    m.enable_torque(True)
    m.set_velocity([-1.0, 0.0])
    run(sim, 0.5)
    assert sim.q[0] < SPEC.wrist.pitch_limits[1] - 0.3


def test_torque_off_means_no_motion_and_stop_is_safe_anytime() -> None:
    sim = SimWrist(SPEC, noise=False)
    m = sim.motor_driver()
    m.stop()  # before open
    with pytest.raises(DriverError, match="not open"):
        m.read()
    m.open()
    m.set_velocity([1.0, 1.0])  # torque still off after open
    run(sim, 0.5)
    assert (sim.q == 0).all()
    m.enable_torque(True)
    m.set_velocity([1.0, 1.0])
    run(sim, 0.2)
    m.stop()
    run(sim, 0.5)
    assert np.abs(sim.qd).max() < 1e-6
    m.close()
    m.stop()  # after close


# ------------------------------------------------------------------------------- IMU ----
def collect_imu(sim: SimWrist, imu: SimImuDriver, seconds: float) -> list:
    out = []
    for _ in range(round(seconds / DT)):
        sim.step(DT)
        out += imu.read_all()
    return out


def test_imu_rate_is_independent_of_the_step() -> None:
    for dt in (0.02, 0.007, 0.05):
        sim = SimWrist(SPEC, noise=False)
        imu = sim.imu_driver()
        imu.open()
        n = 0
        for _ in range(round(2.0 / dt)):
            sim.step(dt)
            n += len(imu.read_all())
        assert n == round(2.0 * RATE)
    stamps = [s.stamp for s in collect_imu(sim, imu, 0.2)]
    np.testing.assert_allclose(np.diff(stamps), 1.0 / RATE)


def test_still_imu_reads_gravity_and_bias_statistically() -> None:
    bias = np.array([0.02, -0.01, 0.03])
    sim = SimWrist(SPEC, gyro_bias=bias, seed=1)
    imu = sim.imu_driver()
    imu.open()
    samples = collect_imu(sim, imu, 20.0)
    acc = np.array([s.accel for s in samples])
    gyr = np.array([s.gyro for s in samples])
    n = len(samples)
    sig_a = SPEC.imu.accel_noise_ug_rthz * 1e-6 * SPEC.imu.gravity * math.sqrt(RATE)
    sig_g = math.radians(SPEC.imu.gyro_noise_dps_rthz) * math.sqrt(RATE)
    np.testing.assert_allclose(
        acc.mean(axis=0), [0, 0, SPEC.imu.gravity], atol=5 * sig_a / math.sqrt(n)
    )
    np.testing.assert_allclose(gyr.mean(axis=0), bias, atol=5 * sig_g / math.sqrt(n))
    np.testing.assert_allclose(gyr.std(axis=0), sig_g, rtol=0.15)
    np.testing.assert_allclose(acc.std(axis=0), sig_a, rtol=0.15)
    assert np.linalg.norm(acc, axis=1).mean() == pytest.approx(SPEC.imu.gravity, abs=1e-3)


def test_rotating_tilted_base_gives_rate_in_sensor_frame() -> None:
    R0 = axis_angle_rotation([1, 0, 0], 0.4)
    mount = axis_angle_rotation([0, 0, 1], math.pi / 2)
    omega = np.array([0.1, -0.3, 0.6])  # about Jaco joint speeds
    bias = np.array([0.01, 0.0, -0.02])
    sim = SimWrist(SPEC, gyro_bias=bias, R_base_imu=mount, seed=2)
    sim.set_base_motion(constant_rate_motion(omega, R0))
    imu = sim.imu_driver()
    imu.open()
    samples = collect_imu(sim, imu, 10.0)
    gyr = np.array([s.gyro for s in samples])
    # ω is invariant under rotation about itself, so R(t)ᵀω = R0ᵀω.
    expected = (R0 @ mount).T @ omega + bias
    sig_g = math.radians(SPEC.imu.gyro_noise_dps_rthz) * math.sqrt(RATE)
    np.testing.assert_allclose(gyr.mean(axis=0), expected, atol=5 * sig_g / math.sqrt(len(gyr)))
    # specific force follows the rotating frame exactly (noise-free twin)
    quiet = SimWrist(SPEC, R_base_imu=mount, noise=False)
    quiet.set_base_motion(constant_rate_motion(omega, R0))
    qimu = quiet.imu_driver()
    qimu.open()
    for s in collect_imu(quiet, qimu, 2.0):
        R, _, _ = quiet.base_state(s.stamp)
        np.testing.assert_allclose(s.accel, (R @ mount).T @ [0, 0, SPEC.imu.gravity], atol=1e-12)


def test_base_linear_acceleration_adds_to_specific_force() -> None:
    sim = SimWrist(SPEC, noise=False)
    R = axis_angle_rotation([0, 1, 0], -math.pi / 2)
    sim.set_base_pose(R, accel_world=[1.0, 0.0, -2.0])
    imu = sim.imu_driver()
    imu.open()
    s = collect_imu(sim, imu, 0.1)[-1]
    np.testing.assert_allclose(s.accel, R.T @ [1.0, 0.0, SPEC.imu.gravity - 2.0], atol=1e-12)


def test_seed_makes_runs_reproducible() -> None:
    def trace(seed: int) -> np.ndarray:
        sim = SimWrist(SPEC, seed=seed)
        imu = sim.imu_driver()
        imu.open()
        return np.array([s.gyro for s in collect_imu(sim, imu, 0.5)])

    np.testing.assert_array_equal(trace(5), trace(5))
    assert not np.array_equal(trace(5), trace(6))


# ------------------------------------------------------------------------ ground truth ---
def test_tool_up_and_tilt_error() -> None:
    sim = SimWrist(SPEC, noise=False)
    assert sim.tilt_error() == pytest.approx(math.pi / 2)  # F0 = world: up is +x at zero
    R = axis_angle_rotation([0, 1, 0], -math.pi / 2)  # F0's x axis → world z
    sim.set_base_pose(R)
    np.testing.assert_allclose(sim.tool_up_world(), [0, 0, 1], atol=1e-12)
    assert sim.tilt_error() == pytest.approx(0.0, abs=1e-7)
    sim.set_joint_positions([0.3, 0.0])
    assert sim.tilt_error() == pytest.approx(0.3)
    sim.set_joint_positions([0.0, -0.2])
    assert sim.tilt_error() == pytest.approx(0.2)


def test_bad_base_motion_is_refused() -> None:
    sim = SimWrist(SPEC)
    with pytest.raises(ValueError, match="rotation"):
        sim.set_base_pose(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="angular velocity"):
        sim.set_base_motion(lambda t: (np.eye(3), [0.0, math.nan, 0.0]))
    with pytest.raises(ValueError, match="dt"):
        sim.step(0.0)


# ---------------------------------------------------------------------------- faults ----
def test_fault_injection() -> None:
    sim = SimWrist(SPEC, noise=False)
    m, imu, ft = make_drivers(SPEC, "sim", sim=sim)
    for d in (m, imu, ft):
        d.open()
    m.enable_torque(True)
    assert len(collect_imu(sim, imu, 0.2)) == round(0.2 * RATE)
    sim.set_imu_stale(True)
    assert collect_imu(sim, imu, 0.5) == []
    assert imu.read() is None
    sim.set_imu_stale(False)
    assert len(collect_imu(sim, imu, 0.1)) == round(0.1 * RATE)

    sim.set_hardware_error("roll", HardwareError.OVERHEATING)
    s = m.read()
    assert s.hardware_error == (0, int(HardwareError.OVERHEATING))
    assert "roll: OVERHEATING" in s.describe_errors()
    m.set_velocity([0.2, 0.2])
    run(sim, 0.5)
    assert sim.qd[0] == pytest.approx(0.2) and sim.qd[1] == 0.0  # roll shut down

    assert m.read().input_voltage == pytest.approx(SPEC.motors.supply_v)
    sim.set_battery(12.0, sag_v_per_s=0.01)
    run(sim, 10.0)
    assert m.read().input_voltage == pytest.approx(11.9)


def test_sim_ft_offset_and_tare() -> None:
    offset = np.array([0.5, -0.2, 1.0, 0.01, 0.0, -0.02])
    sim = SimWrist(SPEC, seed=3, ft_offset=offset)
    ft = sim.ft_driver()
    assert isinstance(ft, SimFTDriver)
    ft.open()
    ft.tare()
    run(sim, 0.5)
    ft.read_all()
    np.testing.assert_allclose(ft.offset, offset, atol=0.03)
    sim.set_external_wrench([0.0, 0.0, -2.0])
    run(sim, 0.2)
    s = ft.read()
    assert s is not None
    np.testing.assert_allclose(s.force, [0.0, 0.0, -2.0], atol=0.15)


def test_make_drivers_rejects_unknown_kind() -> None:
    with pytest.raises(ValueError, match="sim' or 'hardware"):
        make_drivers(SPEC, "bogus")  # type: ignore[arg-type]
