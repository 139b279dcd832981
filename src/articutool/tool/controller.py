"""Yaw-invariant leveling controller (thesis §4.2, Algorithm 1; docs/hardware.md §5).

Pure and stateful: :class:`LevelingController` holds only the PID memory (integral and last
error) and the chosen offsets; it reads no sensor and drives no motor. Each 50 Hz tick the
runtime hands it the tool-base orientation in the gravity-aligned world frame and the measured
joints, and gets back a joint velocity command ``[pitch, roll]`` in rad/s.

One tick (Algorithm 1, with the reference tuning of docs/hardware.md §5):

1. ``y_world = R_world←F0 · y(q)``, the tool's up vector (Eq. 4.1) in the world.
2. Error: the axis-angle rotation taking ``y_world`` onto world +z (Alg. 1 lines 8–10). The
   angle is ``atan2(|y × z|, y · z)``, which, unlike ``arccos``, stays accurate near 0 and π.
3. Deadband: below ``deadband`` the command is zero and the integral is reset.
4. PID on the world-frame error vector; integral clamped per component to ±``integral_clamp``;
   derivative of the error (no kick on the first tick after a reset).
5. ``ω_local = R⁻¹ ω_world``; ``q̇ = J⁺(q) (ω_local × y(q))`` (Eqs. 4.6–4.7, via
   :func:`~articutool.tool.kinematics.joint_rates_for_rotation`).
6. Singularity damping: where ``|cos θr|`` < ``damping_threshold`` the pitch command is scaled
   by ``(|cos θr| / damping_threshold) ** damping_power``. The singularity is ``cos θr = 0``,
   where the up vector lies along the pitch axis (F0 y) and pitch no longer moves it.
7. Predictive joint limits: the speed towards a limit is at most ``limit_gain`` × the distance
   left (so a joint slows exponentially, time constant 1/``limit_gain``, and the motors' own
   velocity lag cannot carry it into the stop), and never more than reaches the limit in one
   tick (``q + q̇ dt`` stays inside). A joint already outside its limits may move back in but
   is never driven further out, nor snapped.
8. Per-joint clip to the commandable speed ``spec.wrist.max_velocity``.

**Roll window** (level around the current turn). The up vector depends on roll only modulo
2π, so any roll window as wide as ``spec.wrist.roll_limits`` holds a leveling solution for
every base orientation (with pitch inside its limits). :meth:`LevelingController.engage`
shifts that window by whole turns to centre it on the nearest level configuration (within
half a turn of the present roll), then inside the cable's net-turn budget ``±roll_budget``:
after a twirl the tool levels at the nearest turn, with half a turn of room either way for the
base to roll, instead of being pinned against ``roll_limits``. Before the first ``engage`` the
window is ``roll_limits``.

**Offsets** (hold a chosen tilt). With offsets ``o = (a, b)`` the controller levels the
*virtual* wrist ``q − o``: it drives ``R · y(q − o)`` to world +z, so at rest
``q = q_level + o`` where ``q_level`` is a leveling solution (Eqs. 4.2–4.3) for the current
base. In words: the tool is levelled, then turned a further ``a`` in pitch and ``b`` in roll
about its own joints. Steps 1–6 use ``q − o``; the joint limits (step 7) apply to the
physical ``q``.

**Stall report** (beyond Alg. 1). Alg. 1 is local: from a base tilted 60–120° it
can come to rest with pitch pressed against a limit (or pitch damped away at the roll
singularity) while the tool is still tilted, though a level configuration exists on the other
side of the joint space (reaching it would swing the utensil through large tilts, so the
controller does not go there on its own). :attr:`LevelingController.stalled` says so: the error
has stayed above ``stall_angle`` for ``stall_s`` while the command was below the one Alg. 1
gives at the deadband edge (``kp × deadband``). The same holds when the base pitches so far
that leveling on the present branch would need pitch past its limit (the level configuration
is then on the other branch, half a roll turn away).

**Rate feed-forward** (optional, beyond Alg. 1). Pure feedback lags a base turning at ω by
about ω/Kp (0.84 rad/s / 5 ≈ 10°). If the runtime passes the base's angular velocity in F0
(the bias-corrected gyro, see :meth:`LevelingController.tool_base_rate`), the controller adds
the correction of Eq. 4.5, ``−ω_base``, to ``ω_local`` outside the deadband.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.spec import Spec
from articutool.tool.kinematics import (
    TWO_PI,
    attitude_jacobian,
    joint_rates_for_rotation,
    nearest_attitude_solution,
    nearest_leveling_solution,
    rotation,
    up_vector,
)

__all__ = ["AttitudeController", "LevelingController"]

_Z = np.array([0.0, 0.0, 1.0])
_X = np.array([1.0, 0.0, 0.0])
_TINY = 1e-12


def _check(
    name: str, value: float, lo: float, hi: float = math.inf, lo_open: bool = False
) -> float:
    v = float(value)
    ok = math.isfinite(v) and (v > lo if lo_open else v >= lo) and v <= hi
    if not ok:
        bracket = "(" if lo_open else "["
        raise ValueError(f"{name} must be in {bracket}{lo}, {hi}]; got {value}")
    return v


def _rotation_matrix(R: ArrayLike, name: str) -> NDArray[np.float64]:
    a = np.asarray(R, dtype=np.float64)
    if a.shape != (3, 3):
        raise ValueError(f"{name} must be a 3x3 rotation matrix; got shape {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite (got NaN or inf)")
    return a


class LevelingController:
    """PID leveling of the tool's up vector against gravity (thesis Alg. 1; docs/hardware.md §5).

    Parameters are the reference tuning (``spec.controller``) and the wrist's leveling limits
    and commandable speeds (``spec.wrist``); :meth:`from_spec` reads them. ``R_base_imu`` is
    the fixed mounting rotation of the IMU on the tool base, ``R_F0←imu``: its columns are the
    IMU axes expressed in F0 (identity: the IMU axes are F0's axes). ``roll_budget`` (rad) is
    the net roll either side of zero that :meth:`engage` may shift the roll window to
    (default: the window stays ``limits``); ``limit_gain`` (1/s) bounds the speed towards a
    joint limit (default: only the one-tick prediction). ``stall_angle`` (rad) and ``stall_s``
    (s) define :attr:`stalled` (default: never).
    """

    def __init__(
        self,
        kp: float,
        ki: float,
        kd: float,
        integral_clamp: float,
        deadband: float,
        limits: ArrayLike,
        max_velocity: ArrayLike,
        rcond: float = 1e-3,
        damping_threshold: float = 0.6,
        damping_power: float = 5.0,
        R_base_imu: ArrayLike | None = None,
        roll_budget: float | None = None,
        limit_gain: float = math.inf,
        stall_angle: float = math.inf,
        stall_s: float = 1.0,
    ) -> None:
        self.kp = _check("kp", kp, 0.0)
        self.ki = _check("ki", ki, 0.0)
        self.kd = _check("kd", kd, 0.0)
        self.integral_clamp = _check("integral_clamp", integral_clamp, 0.0)
        self.deadband = _check("deadband", deadband, 0.0, math.pi)
        self.rcond = _check("rcond", rcond, 0.0, 1.0, lo_open=True)
        self.damping_threshold = _check("damping_threshold", damping_threshold, 0.0, 1.0, True)
        self.damping_power = _check("damping_power", damping_power, 0.0, lo_open=True)
        lim = np.array(limits, dtype=np.float64)
        if lim.shape != (2, 2) or not np.isfinite(lim).all() or not (lim[:, 0] < lim[:, 1]).all():
            raise ValueError(
                "limits must be finite [[pitch_lo, pitch_hi], [roll_lo, roll_hi]] with lo < hi; "
                f"got {limits!r}"
            )
        vmax = np.array(max_velocity, dtype=np.float64)
        if vmax.shape != (2,) or not np.isfinite(vmax).all() or not (vmax > 0).all():
            raise ValueError(f"max_velocity must be two finite speeds > 0 rad/s; got {vmax!r}")
        self._lo, self._hi = lim[:, 0].copy(), lim[:, 1].copy()
        self._roll_limits = (float(lim[1, 0]), float(lim[1, 1]))
        self._vmax = vmax
        self.roll_budget = (math.inf if roll_budget is None
                            else _check("roll_budget", roll_budget, 0.0, lo_open=True))
        self.limit_gain = float(limit_gain)
        if not self.limit_gain > 0.0:  # inf: only the one-tick prediction
            raise ValueError(f"limit_gain must be > 0 1/s (inf allowed); got {limit_gain}")
        self.stall_angle = (math.inf if stall_angle == math.inf
                            else _check("stall_angle", stall_angle, 0.0, lo_open=True))
        self.stall_s = _check("stall_s", stall_s, 0.0, lo_open=True)
        if R_base_imu is None:
            self._R_imu_base = np.eye(3)
        else:
            m = _rotation_matrix(R_base_imu, "R_base_imu")
            if not np.allclose(m @ m.T, np.eye(3), atol=1e-6) or np.linalg.det(m) < 0:
                raise ValueError("R_base_imu must be a proper rotation (orthonormal, det +1)")
            self._R_imu_base = m.T.copy()  # R_imu←F0, what Alg. 1 line 6 multiplies by
        self._offsets = np.zeros(2)
        self._integral = np.zeros(3)
        self._last_error: NDArray[np.float64] | None = None
        self._error_angle = math.nan
        self._stall_time = 0.0

    @classmethod
    def from_spec(cls, spec: Spec, R_base_imu: ArrayLike | None = None) -> LevelingController:
        """A controller with the spec's gains (``controller``), limits, speeds and net-turn
        budget (``wrist``)."""
        c = spec.controller
        return cls(
            kp=c.kp,
            ki=c.ki,
            kd=c.kd,
            integral_clamp=c.integral_clamp,
            deadband=c.deadband,
            limits=spec.wrist.limits,
            max_velocity=spec.wrist.velocity_limits,
            rcond=c.pinv_rcond,
            damping_threshold=c.damping_threshold,
            damping_power=c.damping_power,
            R_base_imu=R_base_imu,
            roll_budget=spec.wrist.roll_turn_budget * 2.0 * math.pi,
            limit_gain=c.limit_gain,
            stall_angle=math.radians(c.stall_deg),
            stall_s=c.stall_s,
        )

    # ----------------------------------------------------------------- state --
    @property
    def offsets(self) -> tuple[float, float]:
        """The held tilt ``(pitch_offset, roll_offset)`` in rad (see the module docstring)."""
        return float(self._offsets[0]), float(self._offsets[1])

    @property
    def integral(self) -> NDArray[np.float64]:
        """The PID integral (world frame, rad·s), a copy."""
        return self._integral.copy()

    @property
    def error_angle(self) -> float:
        """Tilt error (rad) seen by the last :meth:`update`; NaN before the first."""
        return self._error_angle

    @property
    def stalled(self) -> bool:
        """True when leveling has stopped short of level (see the module docstring)."""
        return self._stall_time >= self.stall_s

    def set_offsets(self, pitch_offset_rad: float, roll_offset_rad: float) -> None:
        """Hold the tool at the level configuration plus these joint offsets; resets the PID."""
        self._offsets = np.array(
            [
                _check("pitch_offset_rad", pitch_offset_rad, -math.inf),
                _check("roll_offset_rad", roll_offset_rad, -math.inf),
            ]
        )
        self.reset()

    @property
    def roll_window(self) -> tuple[float, float]:
        """The roll range (rad) leveling may use now (see the module docstring)."""
        return float(self._lo[1]), float(self._hi[1])

    def nearest_level(
        self, R_world_tool_base: ArrayLike, q: ArrayLike
    ) -> NDArray[np.float64] | None:
        """The physical joints nearest ``q`` at which the offset tool is level (Eqs. 4.2–4.3):
        pitch inside its limits, roll within half the width of ``roll_limits`` of ``q``'s (half
        a turn with ±π), whatever the budget. None if no such configuration levels it."""
        R = _rotation_matrix(R_world_tool_base, "R_world_tool_base")
        qm = self._joints(q)
        o = self._offsets
        half = 0.5 * (self._roll_limits[1] - self._roll_limits[0])
        lim = np.array([[self._lo[0] - o[0], self._hi[0] - o[0]],
                        [qm[1] - half - o[1], qm[1] + half - o[1]]])
        sol, found = self._nearest(R.T @ _Z, lim, qm - o)
        return sol + o if bool(found) else None

    def engage(self, R_world_tool_base: ArrayLike, q: ArrayLike) -> None:
        """Start leveling from joints ``q`` under the base orientation ``R_world_tool_base``:
        reset the PID and choose the roll window, ``roll_limits`` shifted by the whole turns
        that centre it best on :meth:`nearest_level` (targets modulo 2π), then moved (or
        narrowed) to stay within ``±roll_budget``."""
        qm = self._joints(q)
        target = self.nearest_level(R_world_tool_base, qm)
        lo_rel, hi_rel = self._roll_limits
        aim = float(qm[1] if target is None else target[1])
        lo = lo_rel + TWO_PI * round((aim - 0.5 * (lo_rel + hi_rel)) / TWO_PI)
        hi = lo + (hi_rel - lo_rel)
        if not math.isinf(self.roll_budget):
            b = self.roll_budget
            width = min(hi - lo, 2.0 * b)
            lo = min(max(lo, -b), b - width)
            hi = lo + width
        self._lo[1], self._hi[1] = lo, hi
        self.reset()

    def reset(self) -> None:
        """Forget the integral and the last error (call when leveling is (re)engaged)."""
        self._integral[:] = 0.0
        self._last_error = None
        self._error_angle = math.nan
        self._stall_time = 0.0

    # --------------------------------------------------------------- helpers --
    def tool_base_orientation(self, R_world_imu: ArrayLike) -> NDArray[np.float64]:
        """``R_world←F0 = R_world←imu · R_imu←F0`` (Alg. 1 line 6)."""
        return _rotation_matrix(R_world_imu, "R_world_imu") @ self._R_imu_base

    def tool_base_rate(self, gyro_imu: ArrayLike) -> NDArray[np.float64]:
        """The base's angular velocity in F0 from the (bias-corrected) gyro in the IMU frame."""
        w = np.asarray(gyro_imu, dtype=np.float64)
        if w.shape != (3,) or not np.isfinite(w).all():
            raise ValueError(f"gyro_imu must be 3 finite rates (rad/s); got {gyro_imu!r}")
        return self._R_imu_base.T @ w

    def tilt_error(self, R_world_tool_base: ArrayLike, q: ArrayLike) -> NDArray[np.float64]:
        """World axis-angle error (3,) taking the (offset) up vector to +z (Alg. 1 l. 8–10)."""
        R = _rotation_matrix(R_world_tool_base, "R_world_tool_base")
        qv = self._joints(q)
        return self._error(R @ self._pointing(qv - self._offsets))[0]

    @staticmethod
    def _joints(q: ArrayLike) -> NDArray[np.float64]:
        a = np.asarray(q, dtype=np.float64)
        if a.shape != (2,) or not np.isfinite(a).all():
            raise ValueError(f"q must be two finite joint angles [pitch, roll]; got {q!r}")
        return a

    @staticmethod
    def _error(y_world: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
        # y × z = (y1, −y0, 0): written out, np.cross costs ~15 µs.
        y0, y1, y2 = y_world.tolist()
        s = math.hypot(y0, y1)
        angle = math.atan2(s, y2)
        if s > _TINY:
            k = angle / s
            return np.array([y1 * k, -y0 * k, 0.0]), angle
        if y2 > 0.0:
            return np.zeros(3), 0.0
        return _X * math.pi, math.pi  # upside down: any horizontal axis will do

    # ------------------------------------------- what is pointed up (hooks) --
    # Leveling points the tip's up vector (Eq. 4.1) at world +z; AttitudeController
    # overrides these four to point another tip-frame vector there.
    @staticmethod
    def _pointing(qv: NDArray[np.float64]) -> NDArray[np.float64]:
        """The tip vector driven to world +z, in F0."""
        return up_vector(qv)

    def _rates(self, qv: NDArray[np.float64], omega_local: NDArray[np.float64],
               pointing: NDArray[np.float64]) -> NDArray[np.float64]:
        """Joint rates that turn :meth:`_pointing` by ``omega_local`` (F0)."""
        return joint_rates_for_rotation(qv, omega_local, self.rcond)

    @staticmethod
    def _pitch_measure(qv: NDArray[np.float64], pointing: NDArray[np.float64]) -> float:
        """How much pitch still moves the pointed vector: |pitch column| (``|cos θr|``)."""
        return abs(math.cos(float(qv[1])))

    @staticmethod
    def _nearest(v: NDArray[np.float64], limits: NDArray[np.float64],
                 q_ref: NDArray[np.float64]) -> tuple[NDArray[np.float64], np.bool_]:
        """The configuration within ``limits`` nearest ``q_ref`` pointing along ``v`` (F0)."""
        return nearest_leveling_solution(v, limits, q_ref)

    # ---------------------------------------------------------------- update --
    def update(
        self,
        R_world_tool_base: ArrayLike,
        q: ArrayLike,
        dt: float,
        base_rate: ArrayLike | None = None,
    ) -> NDArray[np.float64]:
        """One tick of Algorithm 1: the joint velocity command ``[pitch, roll]`` (rad/s).

        ``R_world_tool_base`` (3, 3) is ``R_world←F0``; ``q`` (2,) the measured joints; ``dt``
        the tick length (s). ``base_rate`` (optional, (3,), rad/s in F0) enables the rate
        feed-forward. Non-finite input or ``dt <= 0`` raises ``ValueError`` (state unchanged).
        """
        R = _rotation_matrix(R_world_tool_base, "R_world_tool_base")
        qm = self._joints(q)
        dt = float(dt)
        if not (math.isfinite(dt) and dt > 0.0):
            raise ValueError(f"dt must be a finite number > 0 s; got {dt}")
        ff = None
        if base_rate is not None:
            ff = np.asarray(base_rate, dtype=np.float64)
            if ff.shape != (3,) or not np.isfinite(ff).all():
                raise ValueError(f"base_rate must be 3 finite rates (rad/s); got {base_rate!r}")

        qv = qm - self._offsets  # the virtual wrist that is levelled
        y_local = self._pointing(qv)
        err, angle = self._error(R @ y_local)
        self._error_angle = angle
        if angle < self.deadband:
            self._integral[:] = 0.0
            self._last_error = err
            self._stall_time = 0.0
            return np.zeros(2)

        integral = self._integral
        integral += err * dt
        np.clip(integral, -self.integral_clamp, self.integral_clamp, out=integral)
        last = self._last_error
        self._last_error = err
        omega_world = self.kp * err + self.ki * integral
        if last is not None and self.kd > 0.0:
            omega_world += (self.kd / dt) * (err - last)

        omega_local = R.T @ omega_world
        if ff is not None:
            omega_local -= ff  # Eq. 4.5: cancel the base's own rotation
        qdot = self._rates(qv, omega_local, y_local)

        c = self._pitch_measure(qv, y_local)
        if c < self.damping_threshold:
            qdot[0] *= (c / self.damping_threshold) ** self.damping_power

        # Predictive limits; the bounds widen to q itself so a joint outside is never yanked.
        # Approaching a limit at k × the distance left lets the motors' lagging velocity loop
        # stop short of it (arriving at full speed in one tick overshoots into the stop).
        lo = np.minimum(self._lo, qm)
        hi = np.maximum(self._hi, qm)
        k = min(self.limit_gain, 1.0 / dt)
        qdot = np.clip(qdot, k * (lo - qm), k * (hi - qm))
        np.clip(qdot, -self._vmax, self._vmax, out=qdot)
        idle = math.hypot(float(qdot[0]), float(qdot[1])) < self.kp * self.deadband
        self._stall_time = self._stall_time + dt if angle > self.stall_angle and idle else 0.0
        return qdot


class AttitudeController(LevelingController):
    """Hold a commanded utensil attitude against gravity: Alg. 1 with the tip-frame vector
    ``g`` (the world vertical as the target orientation sees it) in place of the up vector.

    A target orientation ``R_base←tip`` given in a gravity-aligned base (z up) fixes two of
    the tip's three degrees of freedom through gravity, ``g = R⊤ ẑ``; the third, the heading
    about the vertical, needs a heading reference the wrist does not have (its filter leaves
    yaw unobserved) and follows the arm. Two joints control exactly those two: the same PID,
    gyro feed-forward, predictive limits, roll window and stall report as leveling, with the
    joint rates from the pseudo-inverse of :func:`~articutool.tool.kinematics.attitude_jacobian`
    and the command damped along its weakest direction (leveling's pitch damping, where that
    direction is pitch). Leveling is the case ``g = ŷ``. Offsets are not used (zero).
    """

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self._g = np.array([0.0, 1.0, 0.0])

    @property
    def target_vector(self) -> NDArray[np.float64]:
        """The tip-frame vector held vertical (unit), a copy."""
        return self._g.copy()

    def set_target(self, g: ArrayLike) -> None:
        """Hold the tip-frame vector ``g`` vertical; resets the PID."""
        v = np.asarray(g, dtype=np.float64)
        n = float(np.linalg.norm(v)) if v.shape == (3,) and np.isfinite(v).all() else 0.0
        if n < 1e-9:
            raise ValueError(f"target vector must be 3 finite numbers, not all zero; got {g!r}")
        self._g = v / n
        self.reset()

    def _pointing(self, qv: NDArray[np.float64]) -> NDArray[np.float64]:  # type: ignore[override]
        return rotation(qv) @ self._g

    def _rates(self, qv: NDArray[np.float64], omega_local: NDArray[np.float64],
               pointing: NDArray[np.float64]) -> NDArray[np.float64]:
        """``J⁺ (ω × a)``, its component along the weakest joint direction damped as
        leveling damps pitch: by ``(σ_min / damping_threshold) ** damping_power`` where the
        smallest singular value ``σ_min`` is below the threshold. The weak direction is where
        the two joints move the vector almost alike (both columns nearly parallel, as at the
        nearest attitude to an unreachable target) or one barely moves it; undamped, the
        pseudo-inverse turns a small error there into full-speed chatter."""
        J = attitude_jacobian(qv, self._g)
        u, sv, vt = np.linalg.svd(J, full_matrices=False)
        v = np.cross(omega_local, pointing)
        keep = sv > self.rcond * sv[0]
        coeff = np.divide(u.T @ v, sv, out=np.zeros(2), where=keep)
        smin = float(sv[-1])
        if smin < self.damping_threshold:
            coeff[-1] *= (smin / self.damping_threshold) ** self.damping_power
        return vt.T @ coeff

    @staticmethod
    def _pitch_measure(qv: NDArray[np.float64], pointing: NDArray[np.float64]) -> float:
        return 1.0  # the damping is in _rates, along the weakest direction

    def _nearest(self, v: NDArray[np.float64], limits: NDArray[np.float64],  # type: ignore[override]
                 q_ref: NDArray[np.float64]) -> tuple[NDArray[np.float64], np.bool_]:
        return nearest_attitude_solution(self._g, v, limits, q_ref)
