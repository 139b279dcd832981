"""The small, synchronous driver interface the 50 Hz tool runtime is written against.

Three device kinds (docs/hardware.md §3): the Dynamixel pitch/roll motor pair, the OpenLog
Artemis IMU and the Resense HEX21 force/torque sensor. Every method returns promptly (no
call waits for more than one bus transaction), so the runtime loop can call them each tick.
Each real driver has a simulated twin in ``articutool.tool.drivers.sim`` with the same API.

Joint order everywhere is [pitch, roll]; angles in rad, rates in rad/s, stamps in seconds of a
monotonic clock (the simulated twins use the simulation clock).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from enum import IntFlag
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "JOINTS",
    "DriverError",
    "FTDriver",
    "FTSample",
    "HardwareError",
    "ImuDriver",
    "ImuSample",
    "MotorDriver",
    "MotorMode",
    "MotorState",
    "validate_position_command",
    "validate_velocity_command",
]

JOINTS = ("pitch", "roll")
MotorMode = Literal["velocity", "position"]


class DriverError(RuntimeError):
    """A device did not answer, answered garbage, or is not open."""


class HardwareError(IntFlag):
    """Bits of the Dynamixel X-series Hardware Error Status register (address 70).

    From the ROBOTIS e-manual (X-series control table, "Hardware Error Status"). With the
    default Shutdown register the motor drops torque when OVERHEATING, ELECTRICAL_SHOCK or
    OVERLOAD is set, until it is rebooted.
    """

    INPUT_VOLTAGE = 0x01
    OVERHEATING = 0x04
    MOTOR_ENCODER = 0x08
    ELECTRICAL_SHOCK = 0x10
    OVERLOAD = 0x20


@dataclass(frozen=True)
class MotorState:
    """One read of both motors.

    ``hardware_error`` holds the Hardware Error Status bitfield of each motor ([pitch, roll]);
    ``input_voltage`` is the lower of the two motors' input voltages (the battery, V) and
    ``temperature`` the hotter of the two (°C).
    """

    position: NDArray[np.float64]  # (2,) rad
    velocity: NDArray[np.float64]  # (2,) rad/s
    hardware_error: tuple[int, int]
    input_voltage: float
    temperature: float
    stamp: float

    @property
    def has_hardware_error(self) -> bool:
        """True when either motor reports a hardware error."""
        return any(self.hardware_error)

    def describe_errors(self) -> str:
        """Human-readable hardware errors, e.g. ``"roll: OVERLOAD"``; empty when healthy."""
        parts = []
        for joint, bits in zip(JOINTS, self.hardware_error, strict=True):
            if bits:
                names = [f.name for f in HardwareError if bits & f]
                unknown = bits & ~sum(HardwareError)
                if unknown:
                    names.append(f"0x{unknown:02x}")
                parts.append(f"{joint}: {'|'.join(str(n) for n in names)}")
        return "; ".join(parts)


@dataclass(frozen=True)
class ImuSample:
    """One IMU reading in the sensor frame: specific force (m/s²) and angular rate (rad/s)."""

    accel: NDArray[np.float64]  # (3,)
    gyro: NDArray[np.float64]  # (3,)
    stamp: float
    temperature: float = math.nan  # °C, if the stream carries it


@dataclass(frozen=True)
class FTSample:
    """One force/torque reading (tare offset already subtracted)."""

    force: NDArray[np.float64]  # (3,) N
    torque: NDArray[np.float64]  # (3,) N·m
    temperature: float  # °C
    stamp: float


def _as_joint_vector(x: ArrayLike, name: str) -> NDArray[np.float64]:
    try:
        a = np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be 2 numbers [pitch, roll]; got {x!r}") from None
    if a.shape != (2,):
        raise ValueError(f"{name} must have shape (2,) as [pitch, roll]; got shape {a.shape}")
    for joint, v in zip(JOINTS, a, strict=True):
        if not math.isfinite(v):
            raise ValueError(f"{name}[{joint}] must be finite; got {v}")
    return a


def validate_velocity_command(qd: ArrayLike, limits: ArrayLike) -> NDArray[np.float64]:
    """Check a joint velocity command against ``|qd| ≤ limits`` (rad/s); return it as (2,).

    Refuses (``ValueError`` naming the joint and the allowed range) instead of clipping: a
    command the motors would reject must not silently become a different motion.
    """
    a = _as_joint_vector(qd, "qd")
    lim = np.asarray(limits, dtype=np.float64)
    for joint, v, m in zip(JOINTS, a, lim, strict=True):
        if abs(v) > m * (1.0 + 1e-9):
            raise ValueError(f"qd[{joint}] = {v:.6g} rad/s is outside [{-m:.6g}, {m:.6g}] rad/s")
    return a


def validate_position_command(q: ArrayLike, limits: ArrayLike) -> NDArray[np.float64]:
    """Check a joint position command against ``limits`` ((2, 2) rows [lo, hi]); return (2,)."""
    a = _as_joint_vector(q, "q")
    lim = np.asarray(limits, dtype=np.float64)
    for joint, v, (lo, hi) in zip(JOINTS, a, lim, strict=True):
        if not lo - 1e-9 <= v <= hi + 1e-9:
            raise ValueError(f"q[{joint}] = {v:.6g} rad is outside [{lo:.6g}, {hi:.6g}] rad")
    return a


class MotorDriver(ABC):
    """The pitch/roll motor pair.

    After ``open()`` the motors are in velocity mode with torque off and zero goal velocity;
    the motors' own velocity-limit registers hold ``spec.wrist.max_velocity``.
    """

    @abstractmethod
    def open(self) -> None:
        """Connect, check both motors answer, torque off, velocity mode, write limits."""

    @abstractmethod
    def close(self) -> None:
        """Stop, torque off (best effort) and release the port. Safe to call twice."""

    @abstractmethod
    def enable_torque(self, on: bool) -> None:
        """Switch both motors' torque on or off (goal velocity is zeroed first)."""

    @abstractmethod
    def set_mode(self, mode: MotorMode) -> None:
        """Switch operating mode (``"velocity"`` or ``"position"``); stops the motors first."""

    @property
    @abstractmethod
    def mode(self) -> MotorMode:
        """The current operating mode."""

    @abstractmethod
    def set_velocity(self, qd: ArrayLike) -> None:
        """Command joint velocities (rad/s, [pitch, roll]) in velocity mode.

        Non-finite or over-limit values raise ``ValueError`` and nothing is sent.
        """

    @abstractmethod
    def set_position(self, q: ArrayLike) -> None:
        """Command joint positions (rad) in position mode; out-of-range raises ``ValueError``."""

    @abstractmethod
    def read(self) -> MotorState:
        """Present position, velocity, hardware errors, input voltage and temperature."""

    @abstractmethod
    def stop(self) -> None:
        """Zero velocity (or hold position); does nothing before ``open()``.

        Raises ``DriverError`` when the motors may still be moving (the stop could not be sent
        or was not confirmed): the caller must treat that as a fault, not as stopped.
        """

    @abstractmethod
    def clear_errors(self) -> None:
        """Reboot motors that report a hardware error (torque comes back off). The reported
        joint positions stay continuous across the reboot (whole roll turns included)."""

    def __enter__(self) -> MotorDriver:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _StreamDriver(ABC):
    @abstractmethod
    def open(self) -> None:
        """Open the stream."""

    @abstractmethod
    def close(self) -> None:
        """Close the stream. Safe to call twice."""

    def __enter__(self) -> _StreamDriver:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class ImuDriver(_StreamDriver):
    """An IMU stream. ``lines_ok``/``lines_bad`` count parsed and skipped records."""

    lines_ok: int
    lines_bad: int

    @abstractmethod
    def read_all(self) -> list[ImuSample]:
        """Every complete sample received since the last call, oldest first (never blocks)."""

    def read(self) -> ImuSample | None:
        """The newest complete sample since the last call, or None if none arrived."""
        samples = self.read_all()
        return samples[-1] if samples else None


class FTDriver(_StreamDriver):
    """A force/torque stream with tare. ``frames_ok``/``frames_bad`` count decoded and
    rejected frames. Subclasses implement ``_read_raw``; taring is shared here."""

    frames_ok: int
    frames_bad: int

    def __init__(self, tare_samples: int) -> None:
        if tare_samples < 1:
            raise ValueError(f"tare_samples must be >= 1; got {tare_samples}")
        self._tare_default = int(tare_samples)
        self._offset = np.zeros(6)
        self._tare_needed = 0
        self._tare_acc: list[NDArray[np.float64]] = []

    @abstractmethod
    def _read_raw(self) -> list[FTSample]:
        """Untared samples received since the last call, oldest first (never blocks)."""

    def read_all(self) -> list[FTSample]:
        """Every complete sample received since the last call, tared, oldest first."""
        out = []
        for s in self._read_raw():
            raw = np.concatenate([s.force, s.torque])
            if self._tare_needed:
                self._tare_acc.append(raw)
                if len(self._tare_acc) >= self._tare_needed:
                    self._offset = np.mean(self._tare_acc, axis=0)
                    self._tare_needed = 0
                    self._tare_acc = []
            w = raw - self._offset
            out.append(FTSample(w[:3], w[3:], s.temperature, s.stamp))
        return out

    def read(self) -> FTSample | None:
        """The newest complete sample since the last call, or None if none arrived."""
        samples = self.read_all()
        return samples[-1] if samples else None

    def tare(self, n: int | None = None) -> None:
        """Average the next ``n`` raw samples (default ``spec.ft.tare_samples``) and subtract
        that offset from every later sample (docs/hardware.md §3). Non-blocking: the new offset
        applies once ``n`` samples have arrived (see ``tare_pending``)."""
        n = self._tare_default if n is None else n
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ValueError(f"tare n must be an integer >= 1; got {n!r}")
        self._tare_needed = int(n)
        self._tare_acc = []

    @property
    def tare_pending(self) -> bool:
        """True while a tare is still collecting samples."""
        return self._tare_needed > 0

    @property
    def offset(self) -> NDArray[np.float64]:
        """The tare offset [Fx, Fy, Fz, Mx, My, Mz] being subtracted."""
        return self._offset.copy()
