"""The one model of the simulated XC430 pair's command logic (thesis §3.2, the tool's motors).

Both simulated worlds — the kinematic :class:`articutool.tool.drivers.sim.SimWrist` and the
MuJoCo :class:`articutool.sim.world.FeedingWorld` — drive their joints through the same
:class:`MotorModel` (modes, torque, goals, hardware-error bits) and expose it to the runtime
through the same :class:`ModelMotorDriver`; only the plant (how the joints move, where a
hard stop is) differs.

Dynamixel semantics, as the real driver (:mod:`articutool.tool.drivers.dynamixel`) meets
them on the motor: per the ROBOTIS X-series e-manual (XC430-W240, "Shutdown" register 63,
default 52 = 0x34, and "Hardware Error Status" register 70), a motor whose error is one of
the Shutdown bits — OVERHEATING, ELECTRICAL_SHOCK, OVERLOAD — drops Torque Enable and will
not take torque again until it is rebooted (``clear_errors``). An error outside the Shutdown
register (INPUT_VOLTAGE, MOTOR_ENCODER with the default value) is reported in the status but
does not block torque.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.tool.drivers.base import (
    DriverError,
    HardwareError,
    MotorDriver,
    MotorMode,
    MotorState,
    validate_position_command,
    validate_velocity_command,
)

__all__ = ["SHUTDOWN_BITS", "ModelMotorDriver", "MotorModel", "MotorPlant"]

# The default Shutdown register (52) of the X series: these errors drop torque until reboot.
SHUTDOWN_BITS = HardwareError.OVERHEATING | HardwareError.ELECTRICAL_SHOCK | HardwareError.OVERLOAD


class MotorModel:
    """Command state of the two motors: mode, torque, goals, Hardware Error Status bits.

    ``velocity_limits`` (rad/s, the Velocity Limit registers) clip every servo target;
    ``position_limits`` ((2, 2) rad) bound position goals; ``position_gain`` (1/s) is the
    position-mode tracking gain. Pure state; the caller serialises access.
    """

    def __init__(self, velocity_limits: ArrayLike, position_limits: ArrayLike,
                 position_gain: float) -> None:
        self.velocity_limits = np.asarray(velocity_limits, dtype=np.float64)
        self.position_limits = np.asarray(position_limits, dtype=np.float64)
        self.position_gain = float(position_gain)
        self.mode: MotorMode = "velocity"
        self.torque = np.zeros(2, dtype=bool)
        self.cmd_vel = np.zeros(2)
        self.cmd_pos = np.zeros(2)
        self.hw = [0, 0]

    def in_shutdown(self, i: int) -> bool:
        """True when motor ``i`` holds a Shutdown error (torque stays off until reboot)."""
        return bool(self.hw[i] & SHUTDOWN_BITS)

    def reset(self) -> None:
        """Torque off, velocity mode, zero goal (what opening the bus leaves)."""
        self.torque[:] = False
        self.mode = "velocity"
        self.cmd_vel = np.zeros(2)

    def hold(self, q: ArrayLike) -> None:
        """No-motion goal: zero velocity, position goal at the present angles ``q``."""
        self.cmd_vel = np.zeros(2)
        self.cmd_pos = np.asarray(q, dtype=np.float64).copy()

    def enable_torque(self, on: bool, q: ArrayLike) -> None:
        """No-motion goal first, then torque on or off; a motor in shutdown stays off."""
        self.hold(q)
        for i in range(2):
            self.torque[i] = bool(on) and not self.in_shutdown(i)

    def set_mode(self, mode: MotorMode, q: ArrayLike) -> None:
        """Stop at ``q``, switch mode; torque stays as it was."""
        if mode not in ("velocity", "position"):
            raise ValueError(f"mode must be 'velocity' or 'position'; got {mode!r}")
        self.hold(q)
        self.mode = mode

    def set_velocity(self, qd: ArrayLike) -> None:
        """Velocity goal; non-finite or over-limit raises ``ValueError``, wrong mode
        ``DriverError``."""
        a = validate_velocity_command(qd, self.velocity_limits)
        if self.mode != "velocity":
            raise DriverError("set_velocity needs velocity mode (call set_mode('velocity'))")
        self.cmd_vel = a.copy()

    def set_position(self, q: ArrayLike) -> None:
        """Position goal within ``position_limits``; wrong mode raises ``DriverError``."""
        a = validate_position_command(q, self.position_limits)
        if self.mode != "position":
            raise DriverError("set_position needs position mode (call set_mode('position'))")
        self.cmd_pos = a.copy()

    def raise_error(self, i: int, bits: int) -> None:
        """Set error bits on motor ``i``; a Shutdown bit drops its torque."""
        self.hw[i] |= int(bits)
        if int(bits) & SHUTDOWN_BITS:
            self.torque[i] = False

    def reboot(self) -> None:
        """Clear the errors of each motor that has any; its torque comes back off."""
        for i in range(2):
            if self.hw[i]:
                self.hw[i] = 0
                self.torque[i] = False
                self.cmd_vel[i] = 0.0

    def velocity_targets(self, q: ArrayLike) -> NDArray[np.float64]:
        """The servo velocity targets at joint angles ``q`` (0 where torque is off)."""
        vmax = self.velocity_limits
        if self.mode == "velocity":
            target = self.cmd_vel.copy()
        else:
            target = self.position_gain * (self.cmd_pos - np.asarray(q, dtype=np.float64))
        return np.where(self.torque, np.clip(target, -vmax, vmax), 0.0)


@dataclass(frozen=True)
class MotorPlant:
    """What a motor driver reads from a simulated world: present joint angles and rates
    (rad, rad/s), input voltage (V), temperature (°C) and the time stamp (s)."""

    position: Callable[[], NDArray[np.float64]]
    velocity: Callable[[], NDArray[np.float64]]
    input_voltage: Callable[[], float]
    temperature: Callable[[], float]
    stamp: Callable[[], float]


class ModelMotorDriver(MotorDriver):
    """The twin of ``DynamixelDriver`` over a :class:`MotorModel` and a :class:`MotorPlant`:
    same checks, same state machine. ``lock`` is the world's (its stepping thread reads the
    model while the runtime commands it)."""

    def __init__(self, model: MotorModel, plant: MotorPlant,
                 lock: threading.RLock | None = None) -> None:
        self.model = model
        self.plant = plant
        self._lock = lock if lock is not None else threading.RLock()
        self._open = False
        self.last_error = ""

    def _require_open(self) -> None:
        if not self._open:
            raise DriverError("simulated motors are not open")

    @property
    def mode(self) -> MotorMode:
        """The current operating mode."""
        return self.model.mode

    @property
    def torque_enabled(self) -> bool:
        """True when both motors hold torque."""
        return bool(self.model.torque.all())

    def open(self) -> None:
        """Torque off, velocity mode, zero goal."""
        with self._lock:
            self.model.reset()
        self._open = True

    def close(self) -> None:
        """Stop and torque off."""
        if self._open:
            self.stop()
            with self._lock:
                self.model.torque[:] = False
            self._open = False

    def enable_torque(self, on: bool) -> None:
        """Torque on (no-motion goal first) or off; a motor in shutdown stays off."""
        self._require_open()
        with self._lock:
            self.model.enable_torque(on, self.plant.position())

    def set_mode(self, mode: MotorMode) -> None:
        """Stop, switch mode, keep torque as it was."""
        if mode not in ("velocity", "position"):
            raise ValueError(f"mode must be 'velocity' or 'position'; got {mode!r}")
        self._require_open()
        with self._lock:
            self.model.set_mode(mode, self.plant.position())

    def set_velocity(self, qd: ArrayLike) -> None:
        """Command joint velocities; non-finite or over-limit input raises ``ValueError``."""
        validate_velocity_command(qd, self.model.velocity_limits)
        self._require_open()
        with self._lock:
            self.model.set_velocity(qd)

    def set_position(self, q: ArrayLike) -> None:
        """Command joint positions within ``spec.wrist`` limits (single-turn, as the motors)."""
        validate_position_command(q, self.model.position_limits)
        self._require_open()
        with self._lock:
            self.model.set_position(q)

    def read(self) -> MotorState:
        """Present state of the simulated motors (stamped with simulation time)."""
        self._require_open()
        p = self.plant
        with self._lock:
            return MotorState(
                position=p.position(),
                velocity=p.velocity(),
                hardware_error=(self.model.hw[0], self.model.hw[1]),
                input_voltage=p.input_voltage(),
                temperature=p.temperature(),
                stamp=p.stamp(),
            )

    def stop(self) -> None:
        """Zero velocity / hold position. Never raises."""
        with self._lock:
            self.model.hold(self.plant.position())

    def clear_errors(self) -> None:
        """Reboot: clear hardware errors; torque comes back off."""
        self._require_open()
        with self._lock:
            self.model.reboot()

    def inject_hardware_error(self, joint: int, bits: int = HardwareError.OVERLOAD) -> None:
        """Fault injection: raise error bits on one motor (a Shutdown bit drops its torque)."""
        with self._lock:
            self.model.raise_error(joint, bits)
