"""The simulated wrist: motors, IMU and F/T twin sharing one deterministic world.

``SimWrist`` integrates commanded joint velocities through a first-order motor lag
(exact discretisation), the motors' velocity-limit registers (``spec.wrist.max_velocity``)
and the joint position limits (pitch ``spec.wrist.pitch_limits``, roll within
``±spec.wrist.roll_turn_budget`` turns — the cable wind-up budget, docs/hardware.md §3).
Driving a joint into a limit faster than ``hard_stop_velocity`` raises the OVERLOAD hardware
error bit and drops that motor's torque, as a real XC430 does on a hard stop.

The IMU is mounted on the tool base F0 (``R_base_imu`` = R_F0←imu, the IMU axes expressed in
F0, identity by default; ``ToolRuntime`` takes the same matrix under the same name). It
samples at ``spec.imu.rate_hz``: specific force ``R_world←imuᵀ (g ẑ + a_base)`` (m/s²) and
angular rate ``R_world←imuᵀ ω_base + bias`` (rad/s), plus white noise at the spec's densities
(σ = density·√rate, the discrete-time equivalent of a white-noise density). The base pose
is driven by ``set_base_motion(fn)`` with ``fn(t) -> (R_world←F0, ω_world[, a_world])``.

Time advances only in ``step(dt)``; stamps are simulation seconds (use ``sim.clock`` as the
runtime clock), so closed-loop tests run as fast as the CPU allows and are reproducible
with a ``seed``.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from collections.abc import Callable, Sequence
from typing import Generic, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.spec import Spec
from articutool.tool import kinematics
from articutool.tool.drivers.base import (
    JOINTS,
    DriverError,
    FTDriver,
    FTSample,
    HardwareError,
    ImuDriver,
    ImuSample,
    validate_position_command,
)
from articutool.tool.drivers.motor_model import ModelMotorDriver, MotorModel, MotorPlant

__all__ = [
    "BaseMotion",
    "QueuedFTDriver",
    "QueuedImuDriver",
    "SampleQueue",
    "SimFTDriver",
    "SimImuDriver",
    "SimMotorDriver",
    "SimWrist",
    "axis_angle_rotation",
    "constant_rate_motion",
    "imu_noise_sigmas",
]

BaseMotion = Callable[[float], Sequence[ArrayLike]]
_MAX_SUBSTEP = 0.002  # s; resolution of limit contact and position-mode tracking
_QUEUE_LEN = 256  # samples kept for a driver that is not being read
_S = TypeVar("_S")


def imu_noise_sigmas(spec: Spec) -> tuple[float, float]:
    """Per-sample white-noise σ of the accelerometer (m/s²) and gyro (rad/s) at the IMU rate:
    the datasheet density × √rate, the discrete-time equivalent of a noise density."""
    rate = spec.imu.rate_hz
    accel = spec.imu.accel_noise_ug_rthz * 1e-6 * spec.imu.gravity * math.sqrt(rate)
    return accel, math.radians(spec.imu.gyro_noise_dps_rthz) * math.sqrt(rate)


def axis_angle_rotation(axis: ArrayLike, angle: float) -> NDArray[np.float64]:
    """Rodrigues' formula: rotation by ``angle`` about unit-normalised ``axis``."""
    a = np.asarray(axis, dtype=np.float64)
    n = np.linalg.norm(a)
    if not np.isfinite(a).all() or n == 0.0:
        raise ValueError(f"axis must be a finite non-zero 3-vector; got {axis!r}")
    x, y, z = a / n
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)


def constant_rate_motion(
    omega_world: ArrayLike, R0: ArrayLike | None = None
) -> Callable[[float], tuple[NDArray[np.float64], NDArray[np.float64]]]:
    """Base motion rotating at a constant world-frame rate: ``R(t) = exp([ω]× t) R0``."""
    w = np.asarray(omega_world, dtype=np.float64).copy()
    R_init = np.eye(3) if R0 is None else np.asarray(R0, dtype=np.float64).copy()
    speed = float(np.linalg.norm(w))

    def motion(t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        if speed == 0.0:
            return R_init, w
        return axis_angle_rotation(w, speed * t) @ R_init, w

    return motion


def _check_rotation(R: ArrayLike, name: str) -> NDArray[np.float64]:
    a = np.asarray(R, dtype=np.float64)
    if a.shape != (3, 3) or not np.isfinite(a).all():
        raise ValueError(f"{name} must be a finite (3, 3) rotation matrix; got shape {a.shape}")
    if np.abs(a.T @ a - np.eye(3)).max() > 1e-6 or np.linalg.det(a) < 0:
        raise ValueError(f"{name} must be a proper rotation (orthonormal, det +1)")
    return a


def _vec3(v: ArrayLike, name: str) -> NDArray[np.float64]:
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or not np.isfinite(a).all():
        raise ValueError(f"{name} must be a finite 3-vector; got {v!r}")
    return a


class SimWrist:
    """One simulated Articutool: two motors, a base-mounted IMU and a F/T sensor.

    Parameters are simulation choices, not hardware facts: ``motor_lag`` (s, first-order
    time constant), ``gyro_bias`` (rad/s, constant), ``noise`` (False for exact signals),
    ``seed``, ``R_base_imu`` (R_F0←imu), ``hard_stop_velocity`` (rad/s at which hitting a
    limit trips OVERLOAD), ``position_gain`` (1/s, position-mode tracking),
    ``motor_temperature`` (°C), ``ft_offset`` (raw F/T offset [F, M] that tare removes).
    """

    def __init__(
        self,
        spec: Spec,
        *,
        q0: ArrayLike = (0.0, 0.0),
        motor_lag: float = 0.03,
        gyro_bias: ArrayLike = (0.0, 0.0, 0.0),
        noise: bool = True,
        seed: int | None = None,
        R_base_imu: ArrayLike | None = None,
        hard_stop_velocity: float = 0.5,
        position_gain: float = 10.0,
        motor_temperature: float = 35.0,
        ft_offset: ArrayLike = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    ) -> None:
        if not (math.isfinite(motor_lag) and motor_lag >= 0):
            raise ValueError(f"motor_lag must be >= 0 s; got {motor_lag}")
        if not (math.isfinite(hard_stop_velocity) and hard_stop_velocity > 0):
            raise ValueError(f"hard_stop_velocity must be > 0 rad/s; got {hard_stop_velocity}")
        if not (math.isfinite(position_gain) and position_gain > 0):
            raise ValueError(f"position_gain must be > 0 1/s; got {position_gain}")
        self.spec = spec
        w = spec.wrist
        turns = w.roll_turn_budget * 2.0 * math.pi
        self.position_limits = np.array([w.pitch_limits, (-turns, turns)], dtype=np.float64)
        self.velocity_limits = w.velocity_limits
        q = validate_position_command(q0, self.position_limits)
        self._lock = threading.RLock()
        self._t = 0.0
        self._q = q.copy()
        self._qd = np.zeros(2)
        self.motor = MotorModel(self.velocity_limits, w.limits, position_gain)
        self.motor.cmd_pos = q.copy()
        self._tau = float(motor_lag)
        self._hard_stop = float(hard_stop_velocity)
        self._motor_temp = float(motor_temperature)
        self._battery_v0 = spec.motors.supply_v
        self._battery_sag = 0.0
        self._battery_t0 = 0.0
        # IMU
        self._imu_mount = (
            np.eye(3) if R_base_imu is None else _check_rotation(R_base_imu, "R_base_imu")
        )
        self._gyro_bias = _vec3(gyro_bias, "gyro_bias")
        self._noise = bool(noise)
        self._rng = np.random.default_rng(seed)
        g = spec.imu.gravity
        rate = spec.imu.rate_hz
        self._gravity_up = np.array([0.0, 0.0, g])
        self._accel_sigma, self._gyro_sigma = imu_noise_sigmas(spec)
        self._imu_period = 1.0 / rate
        self._next_imu = self._imu_period
        self._imu_stale = False
        self.imu_samples: SampleQueue[ImuSample] = SampleQueue("IMU")
        self.imu_temperature = 30.0
        # F/T
        self._ft_period = 1.0 / spec.ft.rate_hz
        self._next_ft = self._ft_period
        self.ft_samples: SampleQueue[FTSample] = SampleQueue("F/T sensor")
        self._ft_offset = np.asarray(ft_offset, dtype=np.float64).reshape(6)
        self._wrench = np.zeros(6)
        self.ft_noise_sigma = np.repeat([spec.ft.force_noise_n, spec.ft.torque_noise_nm], 3)
        self.ft_temperature = 32.0
        # base
        self._base: BaseMotion = lambda t: (np.eye(3), np.zeros(3))

    # ------------------------------------------------------------------ world accessors --
    @property
    def time(self) -> float:
        """Simulation time (s)."""
        return self._t

    def clock(self) -> float:
        """Simulation time as a clock callable, for the runtime's staleness checks."""
        return self._t

    @property
    def q(self) -> NDArray[np.float64]:
        """True joint positions [pitch, roll] (rad)."""
        return self._q.copy()

    @property
    def qd(self) -> NDArray[np.float64]:
        """True joint velocities (rad/s)."""
        return self._qd.copy()

    def set_joint_positions(self, q: ArrayLike) -> None:
        """Teleport the joints (test setup); velocities are zeroed."""
        with self._lock:
            self._q = validate_position_command(q, self.position_limits).copy()
            self._qd = np.zeros(2)
            self.motor.cmd_pos = self._q.copy()

    def base_state(self, t: float | None = None) -> tuple[NDArray, NDArray, NDArray]:
        """(R_world←F0, ω_world, a_world) of the base at time ``t`` (default now)."""
        out = self._base(self._t if t is None else t)
        if len(out) not in (2, 3):
            raise ValueError("base motion must return (R, omega) or (R, omega, accel)")
        R = _check_rotation(out[0], "base rotation")
        w = _vec3(out[1], "base angular velocity")
        a = _vec3(out[2], "base linear acceleration") if len(out) == 3 else np.zeros(3)
        return R, w, a

    def set_base_motion(self, fn: BaseMotion) -> None:
        """Drive the base: ``fn(t) -> (R_world←F0 (3,3), ω_world (3,)[, a_world (3,)])``."""
        if not callable(fn):
            raise ValueError("base motion must be callable t -> (R, omega[, accel])")
        with self._lock:
            self._base = fn
            self.base_state()  # fail now, not inside step()

    def set_base_pose(
        self, R: ArrayLike, omega_world: ArrayLike = (0, 0, 0), accel_world: ArrayLike = (0, 0, 0)
    ) -> None:
        """Hold the base at a fixed pose (with optional constant rate/acceleration readings)."""
        Rc = _check_rotation(R, "R").copy()
        w, a = _vec3(omega_world, "omega_world").copy(), _vec3(accel_world, "accel_world").copy()
        self.set_base_motion(lambda t: (Rc, w, a))

    def tool_up_world(self) -> NDArray[np.float64]:
        """Ground truth: the utensil's up vector in world, ``R_world←F0 · up_vector(q)``."""
        R, _, _ = self.base_state()
        return R @ kinematics.up_vector(self._q)

    def tilt_error(self) -> float:
        """Ground-truth tilt (rad): the utensil's up vector vs world z (``tilt_from_vertical``)."""
        return float(kinematics.tilt_from_vertical(self.tool_up_world()))

    # ------------------------------------------------------------------ fault injection --
    def set_imu_stale(self, stale: bool = True) -> None:
        """Stop (or resume) IMU samples, as when the USB serial link stalls."""
        self._imu_stale = bool(stale)

    def set_hardware_error(self, joint: int | str, bits: int = HardwareError.OVERLOAD) -> None:
        """Raise hardware-error bits on one motor; shutdown bits drop its torque."""
        i = JOINTS.index(joint) if isinstance(joint, str) else int(joint)
        if i not in (0, 1):
            raise ValueError(f"joint must be 0/1 or one of {JOINTS}; got {joint!r}")
        with self._lock:
            self.motor.raise_error(i, bits)

    def set_motor_temperature(self, celsius: float) -> None:
        """The motors' present temperature (°C), as read back (e.g. an overheated motor)."""
        if not math.isfinite(celsius):
            raise ValueError(f"celsius must be finite; got {celsius}")
        with self._lock:
            self._motor_temp = float(celsius)

    def set_battery(self, voltage: float, sag_v_per_s: float = 0.0) -> None:
        """Battery model for the motors' input voltage: ``voltage − sag·(t − now)``."""
        if not (math.isfinite(voltage) and voltage >= 0):
            raise ValueError(f"voltage must be a finite value >= 0 V; got {voltage}")
        if not (math.isfinite(sag_v_per_s) and sag_v_per_s >= 0):
            raise ValueError(f"sag_v_per_s must be >= 0 V/s; got {sag_v_per_s}")
        with self._lock:
            self._battery_v0, self._battery_sag, self._battery_t0 = voltage, sag_v_per_s, self._t

    def input_voltage(self) -> float:
        """Present motor input voltage (V)."""
        return max(0.0, self._battery_v0 - self._battery_sag * (self._t - self._battery_t0))

    def set_external_wrench(self, force: ArrayLike, torque: ArrayLike = (0, 0, 0)) -> None:
        """The wrench the F/T sensor feels (N, N·m, sensor frame), before its raw offset."""
        self._wrench = np.concatenate([_vec3(force, "force"), _vec3(torque, "torque")])

    # ------------------------------------------------------------------------ dynamics --
    def step(self, dt: float) -> None:
        """Advance the world by ``dt`` seconds, emitting IMU/F-T samples at their rates."""
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a finite number > 0 s; got {dt}")
        with self._lock:
            t_end = self._t + dt
            while self._t < t_end - 1e-12:
                t_next = min(t_end, self._next_imu, self._next_ft, self._t + _MAX_SUBSTEP)
                self._integrate(t_next - self._t)
                self._t = t_next
                if self._t >= self._next_imu - 1e-12:
                    if not self._imu_stale:
                        self.imu_samples.push(self._imu_sample(self._next_imu))
                    self._next_imu += self._imu_period
                if self._t >= self._next_ft - 1e-12:
                    self.ft_samples.push(self._ft_sample(self._next_ft))
                    self._next_ft += self._ft_period

    def _integrate(self, h: float) -> None:
        if h <= 0:
            return
        target = self.motor.velocity_targets(self._q)
        if self._tau > 0:
            a = math.exp(-h / self._tau)
            q_new = self._q + target * h + (self._qd - target) * self._tau * (1.0 - a)
            qd_new = target + (self._qd - target) * a
        else:
            q_new = self._q + target * h
            qd_new = target
        lo, hi = self.position_limits[:, 0], self.position_limits[:, 1]
        for i in range(2):
            if not lo[i] <= q_new[i] <= hi[i]:
                q_new[i] = min(max(q_new[i], lo[i]), hi[i])
                if abs(qd_new[i]) > self._hard_stop or abs(self._qd[i]) > self._hard_stop:
                    self.motor.raise_error(i, HardwareError.OVERLOAD)
                qd_new[i] = 0.0
        self._q, self._qd = q_new, qd_new

    def _imu_sample(self, ts: float) -> ImuSample:
        R, w, a = self.base_state(ts)
        R_wi = R @ self._imu_mount
        accel = R_wi.T @ (self._gravity_up + a)
        gyro = R_wi.T @ w + self._gyro_bias
        if self._noise:
            accel = accel + self._rng.normal(0.0, self._accel_sigma, 3)
            gyro = gyro + self._rng.normal(0.0, self._gyro_sigma, 3)
        return ImuSample(accel=accel, gyro=gyro, stamp=ts, temperature=self.imu_temperature)

    def _ft_sample(self, ts: float) -> FTSample:
        w = self._wrench + self._ft_offset
        if self._noise:
            w = w + self._rng.normal(0.0, 1.0, 6) * self.ft_noise_sigma
        return FTSample(force=w[:3], torque=w[3:], temperature=self.ft_temperature, stamp=ts)

    # ----------------------------------------------------------------- driver plumbing --
    def motor_driver(self) -> SimMotorDriver:
        """A ``MotorDriver`` acting on this world."""
        return SimMotorDriver(self)

    def imu_driver(self) -> SimImuDriver:
        """An ``ImuDriver`` reading this world's IMU."""
        return SimImuDriver(self)

    def ft_driver(self) -> SimFTDriver:
        """An ``FTDriver`` reading this world's F/T sensor."""
        return SimFTDriver(self)


class SimMotorDriver(ModelMotorDriver):
    """The twin of ``DynamixelDriver`` on a :class:`SimWrist`: the shared
    :class:`~articutool.tool.drivers.motor_model.MotorModel` over the kinematic joints."""

    def __init__(self, sim: SimWrist) -> None:
        plant = MotorPlant(position=lambda: sim.q, velocity=lambda: sim.qd,
                           input_voltage=sim.input_voltage,
                           temperature=lambda: sim._motor_temp, stamp=lambda: sim.time)
        super().__init__(sim.motor, plant, sim._lock)
        self.sim = sim


class SampleQueue(Generic[_S]):
    """A simulated sensor's samples as its driver sees them: bounded (a driver that is not
    read keeps the newest), opening drops what came before, reading drains; thread-safe (the
    world steps in one thread while the runtime reads in another)."""

    def __init__(self, what: str, maxlen: int = _QUEUE_LEN) -> None:
        self.what = what
        self._q: deque[_S] = deque(maxlen=maxlen)
        self._lock = threading.Lock()
        self.is_open = False
        self.read_count = 0

    def push(self, sample: _S) -> None:
        """A new sample from the simulated device."""
        with self._lock:
            self._q.append(sample)

    def _drain(self) -> list[_S]:
        with self._lock:
            out = list(self._q)
            self._q.clear()
        return out

    def open(self) -> None:
        """Start receiving (drops samples produced before opening)."""
        self._drain()
        self.is_open = True

    def close(self) -> None:
        """Stop receiving."""
        self.is_open = False

    def read(self) -> list[_S]:
        """Samples since the last read, oldest first; ``DriverError`` when not open."""
        if not self.is_open:
            raise DriverError(f"simulated {self.what} is not open")
        out = self._drain()
        self.read_count += len(out)
        return out


class QueuedImuDriver(ImuDriver):
    """An ``ImuDriver`` reading a :class:`SampleQueue` (the simulated IMUs)."""

    lines_bad = 0

    def __init__(self, samples: SampleQueue[ImuSample]) -> None:
        self.samples = samples

    @property
    def lines_ok(self) -> int:  # type: ignore[override]
        """Samples read so far."""
        return self.samples.read_count

    def open(self) -> None:
        """Start receiving (drops samples produced before opening)."""
        self.samples.open()

    def close(self) -> None:
        """Stop receiving."""
        self.samples.close()

    def read_all(self) -> list[ImuSample]:
        """Samples produced since the last call, oldest first."""
        return self.samples.read()


class QueuedFTDriver(FTDriver):
    """An ``FTDriver`` reading a :class:`SampleQueue` (the simulated F/T sensors)."""

    frames_bad = 0

    def __init__(self, samples: SampleQueue[FTSample], tare_samples: int) -> None:
        super().__init__(tare_samples)
        self.samples = samples

    @property
    def frames_ok(self) -> int:  # type: ignore[override]
        """Frames read so far."""
        return self.samples.read_count

    def open(self) -> None:
        """Start receiving."""
        self.samples.open()

    def close(self) -> None:
        """Stop receiving."""
        self.samples.close()

    def _read_raw(self) -> list[FTSample]:
        return self.samples.read()


class SimImuDriver(QueuedImuDriver):
    """The twin of ``OpenLogImuDriver``: samples synthesised by ``SimWrist.step``."""

    def __init__(self, sim: SimWrist) -> None:
        super().__init__(sim.imu_samples)
        self.sim = sim


class SimFTDriver(QueuedFTDriver):
    """The twin of ``ResenseFTDriver``: raw samples carry ``ft_offset``; tare removes it."""

    def __init__(self, sim: SimWrist) -> None:
        super().__init__(sim.ft_samples, sim.spec.ft.tare_samples)
        self.sim = sim
