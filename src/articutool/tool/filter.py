"""Orientation filter: the Valenti et al. (2015) gyro + accelerometer complementary filter.

Thesis §4.2; behaviour and parameters in docs/hardware.md §4. The arithmetic follows the ROS
``imu_complementary_filter`` library (CCNYRoboticsLab/imu_tools, ``complementary_filter.cpp``,
after PR #234, which set the LERP/SLERP threshold to the paper's 0.9) step by step, in the same
order of floating-point operations, so that for the same inputs and parameters the output agrees
with that implementation to rounding (tests/test_filter.py checks bit-identical results against a
literal transcription of the C++; a C++ build that contracts to FMA, e.g. GCC on aarch64, may
differ in the last ulp):

1. First sample: the state is set from the accelerometer alone (no prediction; ``dt`` unused).
2. Bias (if enabled): the steady-state test compares ``| |a| − 9.81 |`` with 0.1 m/s², each
   ``|ω − ω_prev|`` with 0.01 rad/s and each ``|ω − bias|`` with 0.2 rad/s; if steady, bias moves
   toward ω by ``bias_alpha``. ``ω_prev`` is then updated. This runs *before* the prediction,
   which therefore already uses the updated bias.
3. Predict: first-order integration of ``ω − bias`` over ``dt``, normalised.
4. Correct: the normalised acceleration, rotated into the world by the predicted state, gives
   the predicted gravity; the tilt-only delta quaternion taking it to +z is scaled by the gain
   (adaptive if enabled) with normalised LERP when its scalar part exceeds 0.9, SLERP otherwise,
   composed onto the prediction and normalised.

Like the C++, the state is the *inverse* orientation (world w.r.t. sensor). :meth:`update`
returns what the ROS node publishes: its conjugate, the Hamilton quaternion ``(w, x, y, z)`` of
the sensor frame in the gravity-aligned world frame (yaw is unobserved and drifts freely).

The ROS node itself drops the very first IMU message (it only stores its time stamp) and hands
the second one to the library, which initialises on it; this module is the library, so its first
:meth:`update` initialises. Pure Python floats are used on purpose: at this size scalar math is
about ten times faster than small NumPy arrays (see ``benchmarks/test_bench_filter.py``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from articutool.spec import FilterSpec

__all__ = ["ComplementaryFilter"]

# Constants of the reference implementation (it compares |a| with 9.81, not 9.80665).
GRAVITY = 9.81
ANGULAR_VELOCITY_THRESHOLD = 0.2  # rad/s, |ω − bias| for steady state
ACCELERATION_THRESHOLD = 0.1  # m/s², | |a| − g | for steady state
DELTA_ANGULAR_VELOCITY_THRESHOLD = 0.01  # rad/s, |ω − ω_prev| for steady state
INTERPOLATION_THRESHOLD = 0.9  # delta scalar part above which LERP replaces SLERP
# Adaptive gain: factor 1 below 10 % magnitude error, linear down to 0 at 20 %. The line is
# built exactly as the C++ builds it (slope then intercept) to reproduce its rounding.
_ERR1 = 0.1
_ERR2 = 0.2
_SLOPE = 1.0 / (_ERR1 - _ERR2)
_INTERCEPT = 1.0 - _SLOPE * _ERR1


def _vec3(v: ArrayLike | Sequence[float], name: str) -> tuple[float, float, float]:
    """Three finite Python floats from a length-3 vector, or ValueError naming ``name``."""
    try:
        a = np.asarray(v, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name} must be three numbers; got {v!r}") from e
    if a.shape != (3,):
        raise ValueError(f"{name} must have shape (3,); got {a.shape}")
    x, y, z = a.tolist()
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise ValueError(f"{name} must be finite; got {a.tolist()}")
    return x, y, z


def _unit_interval(value: float, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not 0.0 <= v <= 1.0:  # also rejects NaN
        raise ValueError(f"{name} must be in [0, 1]; got {value!r}")
    return v


def _adaptive_gain(gain_acc: float, ax: float, ay: float, az: float) -> float:
    """Gain scaled by the acceleration-magnitude error (docs/hardware.md §4, Valenti Eq. 60)."""
    error = abs(math.sqrt(ax * ax + ay * ay + az * az) - GRAVITY) / GRAVITY
    if error < _ERR1:
        factor = 1.0
    elif error < _ERR2:
        factor = _SLOPE * error + _INTERCEPT
    else:
        factor = 0.0
    return factor * gain_acc


class ComplementaryFilter:
    """Gyro + accelerometer attitude filter with adaptive gain and gyro-bias estimation.

    Valenti, Dryanovski & Xiao (2015), as implemented by ROS ``imu_complementary_filter``;
    docs/hardware.md §4. Defaults are the library's; :meth:`from_spec` gives the Articutool's.

    Args:
        gain_acc: accelerometer correction gain in [0, 1].
        bias_alpha: bias low-pass gain in [0, 1], applied only in steady state.
        adaptive_gain: scale ``gain_acc`` down when ``|a|`` departs from gravity.
        bias_estimation: estimate the gyro bias while the sensor is still.
    """

    __slots__ = (
        "_adaptive",
        "_bias",
        "_bias_alpha",
        "_estimate_bias",
        "_gain_acc",
        "_initialized",
        "_prev",
        "_q",
        "_steady",
    )

    def __init__(
        self,
        gain_acc: float = 0.01,
        bias_alpha: float = 0.01,
        adaptive_gain: bool = False,
        bias_estimation: bool = True,
    ) -> None:
        self._gain_acc = _unit_interval(gain_acc, "gain_acc")
        self._bias_alpha = _unit_interval(bias_alpha, "bias_alpha")
        self._adaptive = bool(adaptive_gain)
        self._estimate_bias = bool(bias_estimation)
        self.reset()

    @classmethod
    def from_spec(cls, spec: FilterSpec) -> ComplementaryFilter:
        """A filter configured from ``spec.filter`` (the Articutool's 0.1 / 0.05 / on / on)."""
        return cls(
            gain_acc=spec.gain_acc,
            bias_alpha=spec.bias_alpha,
            adaptive_gain=spec.adaptive_gain,
            bias_estimation=spec.bias_estimation,
        )

    def reset(self) -> None:
        """Forget everything: the next :meth:`update` initialises from its accelerometer."""
        # Internal state: world w.r.t. sensor, (w, x, y, z) — the inverse of the output.
        self._q = (1.0, 0.0, 0.0, 0.0)
        self._bias = (0.0, 0.0, 0.0)
        self._prev = (0.0, 0.0, 0.0)
        self._steady = False
        self._initialized = False

    # ------------------------------------------------------------------ properties --
    @property
    def gain_acc(self) -> float:
        """Accelerometer correction gain."""
        return self._gain_acc

    @property
    def bias_alpha(self) -> float:
        """Bias low-pass gain."""
        return self._bias_alpha

    @property
    def adaptive_gain(self) -> bool:
        """Whether the gain adapts to the acceleration magnitude."""
        return self._adaptive

    @property
    def bias_estimation(self) -> bool:
        """Whether the gyro bias is estimated."""
        return self._estimate_bias

    @property
    def initialized(self) -> bool:
        """True once the first sample has set the orientation."""
        return self._initialized

    @property
    def steady_state(self) -> bool:
        """Steady-state flag of the last update (always False without bias estimation)."""
        return self._steady

    @property
    def bias(self) -> NDArray[np.float64]:
        """Estimated gyro bias (rad/s, sensor frame), shape (3,)."""
        return np.array(self._bias)

    @property
    def orientation(self) -> NDArray[np.float64]:
        """Sensor frame in the world frame, Hamilton (w, x, y, z); identity before the first
        sample."""
        w, x, y, z = self._q
        return np.array((w, -x, -y, -z))

    # ---------------------------------------------------------------------- update --
    def update(
        self,
        accel_mps2: ArrayLike | Sequence[float],
        gyro_rps: ArrayLike | Sequence[float],
        dt: float,
    ) -> NDArray[np.float64]:
        """Fuse one IMU sample and return the orientation (w, x, y, z) of sensor in world.

        Args:
            accel_mps2: specific force in the sensor frame, m/s² (raw, not normalised;
                its magnitude is compared with 9.81), shape (3,), non-zero.
            gyro_rps: angular rate in the sensor frame, rad/s, shape (3,).
            dt: time since the previous sample, s, finite and > 0 (validated always; on the
                first sample it is otherwise unused, as in the C++).

        Raises:
            ValueError: on bad input or a degenerate correction; the state is then unchanged.
        """
        ax, ay, az = _vec3(accel_mps2, "accel_mps2")
        wx, wy, wz = _vec3(gyro_rps, "gyro_rps")
        try:
            dt = float(dt)
        except (TypeError, ValueError) as e:
            raise ValueError(f"dt must be a number of seconds; got {dt!r}") from e
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be finite and > 0 s; got {dt!r}")
        norm = math.sqrt(ax * ax + ay * ay + az * az)
        if not 0.0 < norm < math.inf:
            raise ValueError(f"accel_mps2 magnitude must be non-zero and finite; got {norm!r} m/s²")
        ux, uy, uz = ax / norm, ay / norm, az / norm

        if not self._initialized:
            self._q = _from_gravity(ux, uy, uz)
            self._initialized = True
            return self.orientation

        # --- bias estimation (before the prediction, which uses the new bias) ---
        bx, by, bz = self._bias
        steady = self._steady
        if self._estimate_bias:
            px, py, pz = self._prev
            steady = (
                abs(norm - GRAVITY) <= ACCELERATION_THRESHOLD
                and abs(wx - px) <= DELTA_ANGULAR_VELOCITY_THRESHOLD
                and abs(wy - py) <= DELTA_ANGULAR_VELOCITY_THRESHOLD
                and abs(wz - pz) <= DELTA_ANGULAR_VELOCITY_THRESHOLD
                and abs(wx - bx) <= ANGULAR_VELOCITY_THRESHOLD
                and abs(wy - by) <= ANGULAR_VELOCITY_THRESHOLD
                and abs(wz - bz) <= ANGULAR_VELOCITY_THRESHOLD
            )
            if steady:
                alpha = self._bias_alpha
                bx += alpha * (wx - bx)
                by += alpha * (wy - by)
                bz += alpha * (wz - bz)

        # --- prediction: q̇ = −½ ω ⊗ q for the inverse state, first order ---
        q0, q1, q2, q3 = self._q
        rx, ry, rz = wx - bx, wy - by, wz - bz
        h = 0.5 * dt
        p0 = q0 + h * (rx * q1 + ry * q2 + rz * q3)
        p1 = q1 + h * (-rx * q0 - ry * q3 + rz * q2)
        p2 = q2 + h * (rx * q3 - ry * q0 - rz * q1)
        p3 = q3 + h * (-rx * q2 + ry * q1 - rz * q0)
        n = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2 + p3 * p3)
        if not n < math.inf:  # absurd rate × dt overflowed the integration
            raise ValueError(f"gyro_rps × dt overflowed (gyro_rps={[wx, wy, wz]}, dt={dt})")
        p0, p1, p2, p3 = p0 / n, p1 / n, p2 / n, p3 / n

        # --- correction: predicted gravity = conj(p) applied to the measured direction ---
        # (rotation by the conjugate written with the sign flips folded in; flips are exact)
        s00, s11, s22, s33 = p0 * p0, p1 * p1, p2 * p2, p3 * p3
        gx = (
            (s00 + s11 - s22 - s33) * ux
            + 2 * (p1 * p2 + p0 * p3) * uy
            + 2 * (p1 * p3 - p0 * p2) * uz
        )
        gy = (
            2 * (p1 * p2 - p0 * p3) * ux
            + (s00 - s11 + s22 - s33) * uy
            + 2 * (p2 * p3 + p0 * p1) * uz
        )
        gz = (
            2 * (p1 * p3 + p0 * p2) * ux
            + 2 * (p2 * p3 - p0 * p1) * uy
            + (s00 - s11 - s22 + s33) * uz
        )
        half_cos = (gz + 1) * 0.5
        if not half_cos > 0.0:
            # Predicted gravity exactly opposite to the measurement: the delta is undefined
            # (the C++ would divide by zero and poison its state with NaN from then on).
            raise ValueError("degenerate correction: measured gravity opposite to prediction")
        d0 = math.sqrt(half_cos)
        d1 = -gy / (2.0 * d0)
        d2 = gx / (2.0 * d0)

        gain = _adaptive_gain(self._gain_acc, ax, ay, az) if self._adaptive else self._gain_acc
        if d0 <= INTERPOLATION_THRESHOLD:  # large correction: SLERP toward identity
            angle = math.acos(d0)
            s = math.sin(angle)
            a = math.sin(angle * (1.0 - gain)) / s
            b = math.sin(angle * gain) / s
            d0, d1, d2 = a + b * d0, b * d1, b * d2
        else:  # small correction: normalised LERP
            d0, d1, d2 = (1.0 - gain) + gain * d0, gain * d1, gain * d2
        n = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        d0, d1, d2 = d0 / n, d1 / n, d2 / n

        # q = p ⊗ d (d has no z part)
        r0 = p0 * d0 - p1 * d1 - p2 * d2
        r1 = p0 * d1 + p1 * d0 - p3 * d2
        r2 = p0 * d2 + p2 * d0 + p3 * d1
        r3 = p1 * d2 - p2 * d1 + p3 * d0
        n = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3)

        # commit (nothing above mutated the filter)
        self._q = (r0 / n, r1 / n, r2 / n, r3 / n)
        if self._estimate_bias:
            self._bias = (bx, by, bz)
            self._prev = (wx, wy, wz)
            self._steady = steady
        return np.array((self._q[0], -self._q[1], -self._q[2], -self._q[3]))


def _from_gravity(ux: float, uy: float, uz: float) -> tuple[float, float, float, float]:
    """Inverse-convention state from a unit gravity reading (Valenti Eq. 25), yaw arbitrary.

    Two branches keep the square-root argument away from zero: the z-free form when the
    sensor z axis points up (az >= 0), the w/x-swapped form when it points down.
    """
    if uz >= 0:
        w = math.sqrt((uz + 1) * 0.5)
        return (w, -uy / (2.0 * w), ux / (2.0 * w), 0.0)
    x = math.sqrt((1 - uz) * 0.5)
    return (-uy / (2.0 * x), x, 0.0, ux / (2.0 * x))
