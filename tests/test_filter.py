"""Tests for the Valenti complementary filter (src/articutool/tool/filter.py; docs/hardware.md §4).

Agreement: ROS is not installable here (Debian packages no imu_tools), so ``_Reference`` below is
an independent, deliberately literal scalar transcription of imu_tools'
``complementary_filter.cpp`` (one method per C++ function, same names for the state, the
conjugate passed explicitly, the zero z terms kept). It shares no code with the module.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from articutool.spec import load_spec
from articutool.tool.filter import ComplementaryFilter

G_STD = 9.80665  # the IMU's g (docs/hardware.md §3); the filter itself compares with 9.81
RATE_HZ = 50.0
DT = 1.0 / RATE_HZ
# Discrete white-noise sigma per sample at 50 Hz (Nyquist bandwidth 25 Hz), docs/hardware.md §3.
GYRO_SIGMA = math.radians(0.015) * math.sqrt(RATE_HZ / 2)  # rad/s
ACCEL_SIGMA = 230e-6 * G_STD * math.sqrt(RATE_HZ / 2)  # m/s²
GYRO_BIAS = np.radians([2.0, -3.0, 1.5])  # rad/s, "a few deg/s"


# ---------------------------------------------------------------------------------------
# Literal transcription of the C++ (reference only; never imported by the package).
# ---------------------------------------------------------------------------------------
def _normalize_vector(x, y, z):
    norm = math.sqrt(x * x + y * y + z * z)
    x /= norm
    y /= norm
    z /= norm
    return x, y, z


def _normalize_quaternion(q0, q1, q2, q3):
    norm = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    q0 /= norm
    q1 /= norm
    q2 /= norm
    q3 /= norm
    return q0, q1, q2, q3


def _invert_quaternion(q0, q1, q2, q3):
    return q0, -q1, -q2, -q3


def _scale_quaternion(gain, dq0, dq1, dq2, dq3, hits):
    interpolation_threshold = 0.9
    if dq0 <= interpolation_threshold:
        hits["slerp"] += 1
        angle = math.acos(dq0)
        A = math.sin(angle * (1.0 - gain)) / math.sin(angle)
        B = math.sin(angle * gain) / math.sin(angle)
        dq0 = A + B * dq0
        dq1 = B * dq1
        dq2 = B * dq2
        dq3 = B * dq3
    else:
        hits["lerp"] += 1
        dq0 = (1.0 - gain) + gain * dq0
        dq1 = gain * dq1
        dq2 = gain * dq2
        dq3 = gain * dq3
    return _normalize_quaternion(dq0, dq1, dq2, dq3)


def _quaternion_multiplication(p0, p1, p2, p3, q0, q1, q2, q3):
    r0 = p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3
    r1 = p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2
    r2 = p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1
    r3 = p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0
    return r0, r1, r2, r3


def _rotate_vector_by_quaternion(x, y, z, q0, q1, q2, q3):
    vx = (
        (q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3) * x
        + 2 * (q1 * q2 - q0 * q3) * y
        + 2 * (q1 * q3 + q0 * q2) * z
    )
    vy = (
        2 * (q1 * q2 + q0 * q3) * x
        + (q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3) * y
        + 2 * (q2 * q3 - q0 * q1) * z
    )
    vz = (
        2 * (q1 * q3 - q0 * q2) * x
        + 2 * (q2 * q3 + q0 * q1) * y
        + (q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) * z
    )
    return vx, vy, vz


class _Reference:
    """ComplementaryFilter of complementary_filter.cpp, statement by statement."""

    kGravity = 9.81  # noqa: N815 (C++ name)
    kAngularVelocityThreshold = 0.2  # noqa: N815 (C++ name)
    kAccelerationThreshold = 0.1  # noqa: N815 (C++ name)
    kDeltaAngularVelocityThreshold = 0.01  # noqa: N815 (C++ name)

    def __init__(self, gain_acc, bias_alpha, do_adaptive_gain, do_bias_estimation):
        self.gain_acc_ = gain_acc
        self.bias_alpha_ = bias_alpha
        self.do_adaptive_gain_ = do_adaptive_gain
        self.do_bias_estimation_ = do_bias_estimation
        self.initialized_ = False
        self.steady_state_ = False
        self.q0_, self.q1_, self.q2_, self.q3_ = 1.0, 0.0, 0.0, 0.0
        self.wx_prev_ = self.wy_prev_ = self.wz_prev_ = 0.0
        self.wx_bias_ = self.wy_bias_ = self.wz_bias_ = 0.0
        self.hits = {"init_up": 0, "init_down": 0, "slerp": 0, "lerp": 0, "steady": 0}
        self.hits.update({"factor_one": 0, "factor_ramp": 0, "factor_zero": 0})

    def update(self, ax, ay, az, wx, wy, wz, dt):
        if not self.initialized_:
            self.q0_, self.q1_, self.q2_, self.q3_ = self.getMeasurement(ax, ay, az)
            self.initialized_ = True
            return
        if self.do_bias_estimation_:
            self.updateBiases(ax, ay, az, wx, wy, wz)
        q0_pred, q1_pred, q2_pred, q3_pred = self.getPrediction(wx, wy, wz, dt)
        dq0_acc, dq1_acc, dq2_acc, dq3_acc = self.getAccCorrection(
            ax, ay, az, q0_pred, q1_pred, q2_pred, q3_pred
        )
        if self.do_adaptive_gain_:
            gain = self.getAdaptiveGain(self.gain_acc_, ax, ay, az)
        else:
            gain = self.gain_acc_
        dq0_acc, dq1_acc, dq2_acc, dq3_acc = _scale_quaternion(
            gain, dq0_acc, dq1_acc, dq2_acc, dq3_acc, self.hits
        )
        self.q0_, self.q1_, self.q2_, self.q3_ = _quaternion_multiplication(
            q0_pred, q1_pred, q2_pred, q3_pred, dq0_acc, dq1_acc, dq2_acc, dq3_acc
        )
        self.q0_, self.q1_, self.q2_, self.q3_ = _normalize_quaternion(
            self.q0_, self.q1_, self.q2_, self.q3_
        )

    def checkState(self, ax, ay, az, wx, wy, wz):
        acc_magnitude = math.sqrt(ax * ax + ay * ay + az * az)
        if math.fabs(acc_magnitude - self.kGravity) > self.kAccelerationThreshold:
            return False
        if (
            math.fabs(wx - self.wx_prev_) > self.kDeltaAngularVelocityThreshold
            or math.fabs(wy - self.wy_prev_) > self.kDeltaAngularVelocityThreshold
            or math.fabs(wz - self.wz_prev_) > self.kDeltaAngularVelocityThreshold
        ):
            return False
        if (  # noqa: SIM103 (kept in the C++ shape)
            math.fabs(wx - self.wx_bias_) > self.kAngularVelocityThreshold
            or math.fabs(wy - self.wy_bias_) > self.kAngularVelocityThreshold
            or math.fabs(wz - self.wz_bias_) > self.kAngularVelocityThreshold
        ):
            return False
        return True

    def updateBiases(self, ax, ay, az, wx, wy, wz):
        self.steady_state_ = self.checkState(ax, ay, az, wx, wy, wz)
        if self.steady_state_:
            self.hits["steady"] += 1
            self.wx_bias_ += self.bias_alpha_ * (wx - self.wx_bias_)
            self.wy_bias_ += self.bias_alpha_ * (wy - self.wy_bias_)
            self.wz_bias_ += self.bias_alpha_ * (wz - self.wz_bias_)
        self.wx_prev_ = wx
        self.wy_prev_ = wy
        self.wz_prev_ = wz

    def getPrediction(self, wx, wy, wz, dt):
        wx_unb = wx - self.wx_bias_
        wy_unb = wy - self.wy_bias_
        wz_unb = wz - self.wz_bias_
        q0_, q1_, q2_, q3_ = self.q0_, self.q1_, self.q2_, self.q3_
        q0_pred = q0_ + 0.5 * dt * (wx_unb * q1_ + wy_unb * q2_ + wz_unb * q3_)
        q1_pred = q1_ + 0.5 * dt * (-wx_unb * q0_ - wy_unb * q3_ + wz_unb * q2_)
        q2_pred = q2_ + 0.5 * dt * (wx_unb * q3_ - wy_unb * q0_ - wz_unb * q1_)
        q3_pred = q3_ + 0.5 * dt * (-wx_unb * q2_ + wy_unb * q1_ - wz_unb * q0_)
        return _normalize_quaternion(q0_pred, q1_pred, q2_pred, q3_pred)

    def getMeasurement(self, ax, ay, az):
        ax, ay, az = _normalize_vector(ax, ay, az)
        if az >= 0:
            self.hits["init_up"] += 1
            q0_meas = math.sqrt((az + 1) * 0.5)
            q1_meas = -ay / (2.0 * q0_meas)
            q2_meas = ax / (2.0 * q0_meas)
            q3_meas = 0
        else:
            self.hits["init_down"] += 1
            X = math.sqrt((1 - az) * 0.5)
            q0_meas = -ay / (2.0 * X)
            q1_meas = X
            q2_meas = 0
            q3_meas = ax / (2.0 * X)
        return q0_meas, q1_meas, q2_meas, q3_meas

    def getAccCorrection(self, ax, ay, az, p0, p1, p2, p3):
        ax, ay, az = _normalize_vector(ax, ay, az)
        gx, gy, gz = _rotate_vector_by_quaternion(ax, ay, az, p0, -p1, -p2, -p3)
        dq0 = math.sqrt((gz + 1) * 0.5)
        dq1 = -gy / (2.0 * dq0)
        dq2 = gx / (2.0 * dq0)
        dq3 = 0.0
        return dq0, dq1, dq2, dq3

    def getOrientation(self):
        return _invert_quaternion(self.q0_, self.q1_, self.q2_, self.q3_)

    def getAdaptiveGain(self, alpha, ax, ay, az):
        a_mag = math.sqrt(ax * ax + ay * ay + az * az)
        error = math.fabs(a_mag - self.kGravity) / self.kGravity
        error1 = 0.1
        error2 = 0.2
        m = 1.0 / (error1 - error2)
        b = 1.0 - m * error1
        if error < error1:
            self.hits["factor_one"] += 1
            factor = 1.0
        elif error < error2:
            self.hits["factor_ramp"] += 1
            factor = m * error + b
        else:
            self.hits["factor_zero"] += 1
            factor = 0.0
        return factor * alpha

    def getBias(self):
        return self.wx_bias_, self.wy_bias_, self.wz_bias_


# ---------------------------------------------------------------------------------------
# Stream generators
# ---------------------------------------------------------------------------------------
def _mixed_stream(seed: int, n: int = 300) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Random IMU samples alternating still, moving, shaken and flipped segments.

    Built to visit every branch of the C++ (see test_mixed_stream_visits_every_branch).
    """
    rng = np.random.default_rng(seed)
    rot = Rotation.random(random_state=rng)
    bias = rng.uniform(-0.1, 0.1, 3)
    out = []
    while len(out) < n:
        kind = rng.choice(["still", "move", "shake", "flip"], p=[0.4, 0.3, 0.2, 0.1])
        for _ in range(int(rng.integers(5, 40))):
            dt = float(rng.uniform(0.004, 0.05))
            if kind == "still":
                gyro = bias + rng.normal(0.0, 1e-3, 3)
                accel = rot.inv().apply([0.0, 0.0, G_STD]) + rng.normal(0.0, 0.01, 3)
            elif kind == "move":
                gyro = rng.uniform(-4.0, 4.0, 3)
                rot = rot * Rotation.from_rotvec((gyro - bias) * dt)
                accel = rot.inv().apply([0.0, 0.0, G_STD]) + rng.normal(0.0, 0.5, 3)
            elif kind == "shake":  # magnitude across the adaptive-gain ramp and beyond
                gyro = bias + rng.normal(0.0, 0.3, 3)
                scale = rng.uniform(0.7, 1.3)
                accel = scale * rot.inv().apply([0.0, 0.0, G_STD]) + rng.normal(0.0, 0.2, 3)
            else:  # sudden new attitude: large corrections (SLERP branch)
                rot = Rotation.random(random_state=rng)
                gyro = rng.uniform(-1.0, 1.0, 3)
                accel = rot.inv().apply([0.0, 0.0, G_STD])
            out.append((accel, gyro, dt))
    return out[:n]


def _run_both(params: dict, stream) -> tuple[ComplementaryFilter, _Reference, float, float]:
    ours = ComplementaryFilter(**params)
    ref = _Reference(
        params["gain_acc"],
        params["bias_alpha"],
        params["adaptive_gain"],
        params["bias_estimation"],
    )
    worst_q = worst_b = 0.0
    for accel, gyro, dt in stream:
        q = ours.update(accel, gyro, dt)
        ref.update(*accel.tolist(), *gyro.tolist(), dt)
        worst_q = max(worst_q, float(np.max(np.abs(q - np.array(ref.getOrientation())))))
        worst_b = max(worst_b, float(np.max(np.abs(ours.bias - np.array(ref.getBias())))))
        assert ours.steady_state == ref.steady_state_
    return ours, ref, worst_q, worst_b


FEATURES = [(a, b) for a in (False, True) for b in (False, True)]


# ---------------------------------------------------------------------------------------
# Agreement with the C++ arithmetic
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(("adaptive_gain", "bias_estimation"), FEATURES)
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    gain_acc=st.floats(0.0, 1.0),
    bias_alpha=st.floats(0.0, 1.0),
)
def test_agrees_with_cpp_transcription(adaptive_gain, bias_estimation, seed, gain_acc, bias_alpha):
    params = dict(
        gain_acc=gain_acc,
        bias_alpha=bias_alpha,
        adaptive_gain=adaptive_gain,
        bias_estimation=bias_estimation,
    )
    _, _, worst_q, worst_b = _run_both(params, _mixed_stream(seed))
    assert worst_q <= 1e-12
    assert worst_b <= 1e-12


def test_mixed_stream_visits_every_branch():
    """The agreement streams exercise every branch of the C++ (else agreement proves little)."""
    params = dict(gain_acc=0.1, bias_alpha=0.05, adaptive_gain=True, bias_estimation=True)
    hits = dict.fromkeys(_Reference(0, 0, 0, 0).hits, 0)
    for seed in range(12):
        _, ref, _, _ = _run_both(params, _mixed_stream(seed))
        for k, v in ref.hits.items():
            hits[k] += v
    assert all(v > 0 for v in hits.values()), hits


def test_cpp_defaults_and_spec_configuration():
    f = ComplementaryFilter()
    assert (f.gain_acc, f.bias_alpha, f.adaptive_gain, f.bias_estimation) == (
        0.01,
        0.01,
        False,
        True,
    )
    spec = load_spec().filter
    g = ComplementaryFilter.from_spec(spec)
    assert (g.gain_acc, g.bias_alpha, g.adaptive_gain, g.bias_estimation) == (
        spec.gain_acc,
        spec.bias_alpha,
        spec.adaptive_gain,
        spec.bias_estimation,
    )


# ---------------------------------------------------------------------------------------
# Hand-checked cases
# ---------------------------------------------------------------------------------------
def _gravity_in_sensor(q: np.ndarray) -> np.ndarray:
    """World +z seen from the sensor, R(q)ᵀ e_z, for q = (w, x, y, z) sensor-in-world."""
    w, x, y, z = q
    return np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])


def test_first_sample_level_is_identity_and_ignores_gyro():
    f = ComplementaryFilter()
    assert not f.initialized
    q = f.update([0.0, 0.0, 9.81], [5.0, -3.0, 2.0], 0.02)
    assert f.initialized
    np.testing.assert_array_equal(q, [1.0, 0.0, 0.0, 0.0])
    np.testing.assert_array_equal(f.bias, [0.0, 0.0, 0.0])


@pytest.mark.parametrize("phi_deg", [0.0, 30.0, 89.0, 91.0, 150.0, 180.0, -120.0])
def test_first_sample_roll_from_accelerometer(phi_deg):
    """Sensor rolled by φ about x sees (0, g sin φ, g cos φ); az >= 0 and az < 0 branches."""
    phi = math.radians(phi_deg)
    f = ComplementaryFilter()
    q = f.update([0.0, 9.81 * math.sin(phi), 9.81 * math.cos(phi)], [0, 0, 0], 0.02)
    if math.cos(phi) >= 0:  # branch az >= 0: zero z part, q = (cos φ/2, sin φ/2, 0, 0)
        np.testing.assert_allclose(q, [math.cos(phi / 2), math.sin(phi / 2), 0, 0], atol=1e-15)
    else:  # branch az < 0: the w/x-swapped form, which here has a zero y part
        assert q[2] == 0.0
        np.testing.assert_allclose(abs(q[0] * q[1]), abs(math.cos(phi / 2) * math.sin(phi / 2)))
    np.testing.assert_allclose(_gravity_in_sensor(q), [0, math.sin(phi), math.cos(phi)], atol=1e-15)


def test_first_sample_upside_down():
    q = ComplementaryFilter().update([0.0, 0.0, -9.81], [0, 0, 0], 0.02)
    np.testing.assert_array_equal(np.abs(q), [0.0, 1.0, 0.0, 0.0])


@given(
    accel=st.tuples(*[st.floats(-30, 30)] * 3).filter(lambda a: math.hypot(*a) > 1e-3),
)
def test_first_sample_matches_gravity_direction(accel):
    q = ComplementaryFilter().update(accel, [0, 0, 0], 0.02)
    a = np.array(accel)
    np.testing.assert_allclose(np.linalg.norm(q), 1.0, atol=1e-12)
    np.testing.assert_allclose(_gravity_in_sensor(q), a / np.linalg.norm(a), atol=1e-9)


@pytest.mark.parametrize("omega", [(0.0, 0.0, 1.3), (0.4, -0.7, 0.2), (3.0, 1.0, -2.0)])
def test_pure_rotation_integration(omega):
    """gain 0, no bias: n first-order steps, each normalised, turn by n·2·atan(|ω|dt/2)."""
    f = ComplementaryFilter(gain_acc=0.0, bias_estimation=False)
    q_init = f.update([0.0, 0.0, 9.81], [0, 0, 0], DT)
    w = np.array(omega)
    n = 200
    for _ in range(n):
        q = f.update([0.0, 0.0, 9.81], w, DT)
    angle = n * 2 * math.atan(0.5 * DT * np.linalg.norm(w))
    expected = Rotation.from_quat(q_init, scalar_first=True) * Rotation.from_rotvec(
        w / np.linalg.norm(w) * angle
    )
    got = Rotation.from_quat(q, scalar_first=True)
    assert (expected.inv() * got).magnitude() < 1e-12


def _correction_tilt(theta_deg: float, gain: float, accel_scale: float = 1.0, **kw) -> float:
    """Level filter, then one still sample tilted by θ about x: the tilt it moves to."""
    f = ComplementaryFilter(gain_acc=gain, bias_estimation=False, **kw)
    f.update([0.0, 0.0, 9.81], [0, 0, 0], DT)
    th = math.radians(theta_deg)
    q = f.update(accel_scale * 9.81 * np.array([0, math.sin(th), math.cos(th)]), [0, 0, 0], DT)
    assert q[2] == 0.0 and q[3] == 0.0  # stays a pure x rotation
    return 2 * math.atan2(q[1], q[0])


@pytest.mark.parametrize("gain", [0.0, 0.1, 0.5, 1.0])
def test_small_correction_uses_normalised_lerp(gain):
    th = math.radians(20.0)  # delta scalar cos(10°) > 0.9
    half = math.atan2(gain * math.sin(th / 2), (1 - gain) + gain * math.cos(th / 2))
    assert _correction_tilt(20.0, gain) == pytest.approx(2 * half, abs=1e-14)


@pytest.mark.parametrize("gain", [0.0, 0.1, 0.5, 1.0])
def test_large_correction_uses_slerp(gain):
    # delta scalar cos(45°) <= 0.9: the correction is exactly gain·θ
    assert _correction_tilt(90.0, gain) == pytest.approx(gain * math.pi / 2, abs=1e-14)


@pytest.mark.parametrize(("scale", "factor"), [(1.05, 1.0), (1.15, 0.5), (0.88, 0.8), (1.3, 0.0)])
def test_adaptive_gain_factor(scale, factor):
    """factor 1 below 10 % magnitude error, 2 − 10·err up to 20 %, 0 beyond."""
    got = _correction_tilt(20.0, 0.3, accel_scale=scale, adaptive_gain=True)
    assert got == pytest.approx(_correction_tilt(20.0, 0.3 * factor), abs=1e-9)


def test_steady_state_and_bias_update_order():
    """Bias moves by bias_alpha·(ω − bias) in steady state and is used by the same prediction."""
    f = ComplementaryFilter(gain_acc=0.0, bias_alpha=0.5)
    f.update([0.0, 0.0, 9.81], [0, 0, 0], DT)
    w = np.array([0.0, 0.0, 0.1])
    f.update([0.0, 0.0, 9.81], w, DT)  # |ω − ω_prev| = 0.1 > 0.01: not steady
    assert not f.steady_state
    np.testing.assert_array_equal(f.bias, [0, 0, 0])
    yaw_before = 2 * math.atan2(f.orientation[3], f.orientation[0])
    q = f.update([0.0, 0.0, 9.81], w, DT)  # now steady: bias → 0.05, integrates 0.05 rad/s
    assert f.steady_state
    np.testing.assert_allclose(f.bias, [0, 0, 0.05], atol=1e-15)
    yaw_step = 2 * math.atan2(q[3], q[0]) - yaw_before
    assert yaw_step == pytest.approx(2 * math.atan(0.5 * DT * 0.05), abs=1e-14)
    f.update([0.0, 0.0, 9.81 + 0.2], w, DT)  # |a| − 9.81 = 0.2 > 0.1: not steady
    assert not f.steady_state
    f.update([0.0, 0.0, 9.81], w + 0.3, DT)
    f.update([0.0, 0.0, 9.81], w + 0.3, DT)  # |ω − bias| = 0.35 > 0.2: not steady
    assert not f.steady_state
    np.testing.assert_allclose(f.bias, [0, 0, 0.05], atol=1e-15)


def test_no_bias_estimation_keeps_zero_bias_and_no_steady_state():
    f = ComplementaryFilter(bias_estimation=False)
    for _ in range(50):
        f.update([0.0, 0.0, 9.81], [0.01, 0.0, 0.0], DT)
    assert not f.steady_state
    np.testing.assert_array_equal(f.bias, [0, 0, 0])


def test_reset_reinitialises_from_accelerometer():
    f = ComplementaryFilter.from_spec(load_spec().filter)
    for accel, gyro, dt in _mixed_stream(3, 100):
        f.update(accel, gyro, dt)
    f.reset()
    assert not f.initialized and not f.steady_state
    np.testing.assert_array_equal(f.bias, [0, 0, 0])
    q = f.update([0.0, 0.0, 9.81], [1.0, 1.0, 1.0], DT)
    np.testing.assert_array_equal(q, [1.0, 0.0, 0.0, 0.0])


# ---------------------------------------------------------------------------------------
# Bad input: clear errors, state untouched
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["gain_acc", "bias_alpha"])
@pytest.mark.parametrize("value", [-0.01, 1.01, float("nan"), float("inf"), "high", None])
def test_bad_gains_rejected(name, value):
    with pytest.raises(ValueError, match=rf"{name} must be in \[0, 1\]"):
        ComplementaryFilter(**{name: value})


def _snapshot(f: ComplementaryFilter):
    return (f.initialized, f.steady_state, f.orientation.tolist(), f.bias.tolist())


BAD_UPDATES = [
    ({"dt": 0.0}, "dt"),
    ({"dt": -0.02}, "dt"),
    ({"dt": float("nan")}, "dt"),
    ({"dt": float("inf")}, "dt"),
    ({"accel_mps2": [0.0, 0.0]}, "accel_mps2"),
    ({"accel_mps2": [[0.0], [0.0], [9.81]]}, "accel_mps2"),
    ({"accel_mps2": [0.0, float("nan"), 9.81]}, "accel_mps2"),
    ({"accel_mps2": [0.0, 0.0, 0.0]}, "accel_mps2"),
    ({"accel_mps2": [1e200, 0.0, 0.0]}, "accel_mps2"),
    ({"gyro_rps": [0.0, 0.0, float("inf")]}, "gyro_rps"),
    ({"gyro_rps": [0.0, 0.0, 0.0, 0.0]}, "gyro_rps"),
    ({"gyro_rps": "abc"}, "gyro_rps"),
    ({"gyro_rps": [0.0, "x", 0.0]}, "gyro_rps"),
    ({"dt": "soon"}, "dt"),
    ({"dt": None}, "dt"),
]


@pytest.mark.parametrize("warm", [False, True])
@pytest.mark.parametrize(("bad", "field"), BAD_UPDATES)
def test_bad_update_rejected_and_state_unchanged(warm, bad, field):
    f = ComplementaryFilter.from_spec(load_spec().filter)
    if warm:
        for accel, gyro, dt in _mixed_stream(7, 60):
            f.update(accel, gyro, dt)
    before = _snapshot(f)
    args = {"accel_mps2": [0.1, 0.2, 9.8], "gyro_rps": [0.01, 0.02, 0.03], "dt": DT} | bad
    with pytest.raises(ValueError, match=field):
        f.update(**args)
    assert _snapshot(f) == before
    # the filter still works afterwards
    assert np.isfinite(f.update([0.1, 0.2, 9.8], [0.01, 0.02, 0.03], DT)).all()


def test_overflowing_rate_rejected_and_state_unchanged():
    f = ComplementaryFilter()
    f.update([0.0, 0.0, 9.81], [0, 0, 0], DT)
    before = _snapshot(f)
    with pytest.raises(ValueError, match="gyro_rps"):
        f.update([0.0, 0.0, 9.81], [1e300, 1e300, 0.0], 1e10)
    assert _snapshot(f) == before


def test_degenerate_correction_rejected_and_state_unchanged():
    """Measured gravity exactly opposite the prediction: the C++ would produce NaN."""
    f = ComplementaryFilter(bias_estimation=False)
    f.update([0.0, 0.0, 9.81], [0, 0, 0], DT)
    before = _snapshot(f)
    with pytest.raises(ValueError, match="degenerate"):
        f.update([0.0, 0.0, -9.81], [0, 0, 0], DT)
    assert _snapshot(f) == before


# ---------------------------------------------------------------------------------------
# Tilt accuracy against ground truth (synthetic IMU streams, docs/hardware.md §3 noise)
# ---------------------------------------------------------------------------------------
def _imu_from_trajectory(rots: Rotation, lin_acc_world: np.ndarray | None, seed: int):
    """Ideal sampled IMU for sensor orientations ``rots`` (sensor in world) at 50 Hz.

    Gyro k = mean body rate over (k−1, k] (what the filter's integration step assumes) plus
    bias and white noise; accel = Rᵀ(a_lin + g e_z) plus white noise.
    """
    rng = np.random.default_rng(seed)
    n = len(rots)
    rel = rots[:-1].inv() * rots[1:]
    gyro = np.vstack([np.zeros(3), rel.as_rotvec() / DT])
    gyro += GYRO_BIAS + rng.normal(0.0, GYRO_SIGMA, (n, 3))
    f_world = np.tile([0.0, 0.0, G_STD], (n, 1))
    if lin_acc_world is not None:
        f_world = f_world + lin_acc_world
    accel = rots.inv().apply(f_world) + rng.normal(0.0, ACCEL_SIGMA, (n, 3))
    return accel, gyro


def _tilt_errors_deg(rots: Rotation, accel, gyro, **params) -> tuple[np.ndarray, object]:
    f = ComplementaryFilter.from_spec(load_spec().filter)
    if params:
        f = ComplementaryFilter(**params)
    true_g = rots.inv().apply([0.0, 0.0, 1.0])
    err = np.empty(len(rots))
    for k in range(len(rots)):
        q = f.update(accel[k], gyro[k], DT)
        c = float(np.clip(_gravity_in_sensor(q) @ true_g[k], -1.0, 1.0))
        err[k] = math.degrees(math.acos(c))
    return err, f


def _times(seconds: float) -> np.ndarray:
    return np.arange(int(seconds * RATE_HZ)) * DT


def _still(seconds: float = 30.0) -> Rotation:
    return Rotation.from_euler("xyz", [20.0, -12.0, 40.0], degrees=True) * Rotation.identity(
        len(_times(seconds))
    )


def test_still_with_bias_converges():
    rots = _still()
    accel, gyro = _imu_from_trajectory(rots, None, seed=1)
    err, f = _tilt_errors_deg(rots, accel, gyro)
    assert f.steady_state
    np.testing.assert_allclose(f.bias, GYRO_BIAS, atol=math.radians(0.1))
    assert err.max() < 1.0
    assert err[-500:].max() < 0.2


def test_bias_estimation_reduces_still_tilt_error():
    rots = _still()
    accel, gyro = _imu_from_trajectory(rots, None, seed=2)
    spec = load_spec().filter
    common = dict(gain_acc=spec.gain_acc, bias_alpha=spec.bias_alpha, adaptive_gain=True)
    with_est, _ = _tilt_errors_deg(rots, accel, gyro, bias_estimation=True, **common)
    without, _ = _tilt_errors_deg(rots, accel, gyro, bias_estimation=False, **common)
    assert with_est[-500:].mean() < 0.3 * without[-500:].mean()


def test_slow_rotation_tracks_tilt():
    """Pitch/roll swings of ±25° at 0.2/0.13 Hz (≈ 30°/s peak) with a slow yaw, after 5 s still."""
    t = _times(40.0)
    s = np.clip(t - 5.0, 0.0, None)
    euler = np.column_stack(
        [
            25.0 * np.sin(2 * np.pi * 0.2 * s),
            25.0 * np.sin(2 * np.pi * 0.13 * s),
            10.0 * s,
        ]
    )
    rots = Rotation.from_euler("xyz", euler, degrees=True)
    accel, gyro = _imu_from_trajectory(rots, None, seed=3)
    err, _ = _tilt_errors_deg(rots, accel, gyro)
    assert err.max() < 1.0
    assert np.sqrt(np.mean(err**2)) < 0.3


def test_vibration_tracks_tilt():
    """VIBRATE_ROLL-like shaking: ±0.1 rad at 8 Hz about the tool axis (sensor x) plus
    ±2 m/s² linear vibration at 10 Hz, on a tool pitched 30° down, after 5 s still."""
    t = _times(25.0)
    on = (t > 5.0).astype(float)
    base = Rotation.from_euler("y", 30.0, degrees=True)
    roll = on * 0.1 * np.sin(2 * np.pi * 8.0 * t)
    rots = base * Rotation.from_rotvec(np.outer(roll, [1.0, 0.0, 0.0]))
    lin = on[:, None] * 2.0 * np.outer(np.sin(2 * np.pi * 10.0 * t), [0.6, 0.0, 0.8])
    accel, gyro = _imu_from_trajectory(rots, lin, seed=4)
    err, _ = _tilt_errors_deg(rots, accel, gyro)
    assert err.max() < 2.5
    assert np.sqrt(np.mean(err**2)) < 1.5


def test_twirl_about_tool_axis_tracks_tilt():
    """TWIRL: 3 turns at 3 rad/s about the tool axis (sensor x), the tool pitched 30° down,
    1 s ramps, after 5 s still to learn the bias."""
    t = _times(17.0)
    full = (3 * 2 * np.pi - 3.0) / 3.0  # the two 1 s ramps turn 1.5 rad each
    rate = np.interp(t, [0, 5, 6, 6 + full, 7 + full, 17], [0, 0, 3.0, 3.0, 0, 0])
    angle = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * DT)])
    base = Rotation.from_euler("y", 30.0, degrees=True)
    rots = base * Rotation.from_rotvec(np.outer(angle, [1.0, 0.0, 0.0]))
    accel, gyro = _imu_from_trajectory(rots, None, seed=5)
    err, f = _tilt_errors_deg(rots, accel, gyro)
    assert angle[-1] == pytest.approx(3 * 2 * np.pi, abs=0.05)
    assert err.max() < 1.0
    assert np.sqrt(np.mean(err**2)) < 0.3
    # the twirl must not corrupt the bias estimate (not steady while turning)
    np.testing.assert_allclose(f.bias, GYRO_BIAS, atol=math.radians(0.2))
