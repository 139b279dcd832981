"""The pitch/roll motor pair: two Dynamixel XC430-W250-T on one U2D2, protocol 2.0.

Uses ``dynamixel_sdk`` (``PortHandler``, ``PacketHandler(2.0)``, ``GroupSyncWrite`` and the
packet handler's sync-read primitives). Control-table addresses are those of the X-series
(docs/hardware.md §3), checked against the ROBOTIS e-manual control table for the XC430-W250
family (EEPROM 0–63, RAM 64+). Units: velocity 0.229 rev/min per unit, position 4096 ticks
per revolution, present values signed 32-bit two's complement, input voltage 0.1 V.

Safety choices:
- ``open()`` leaves torque off, velocity mode, zero goal velocity, and writes the Velocity
  Limit register (44) from ``spec.wrist.max_velocity`` so the motors enforce the limit even
  if the host misbehaves. EEPROM registers are written only when they differ (flash wear).
- Commands that are non-finite or above the limit raise ``ValueError`` and send nothing
  (the motor would reject an over-limit Goal Velocity and keep its previous goal).
- ``enable_torque(True)`` arms the Bus Watchdog (register 98) with ``spec.motors.bus_watchdog_s``:
  a motor that hears no packet for that long stops itself (host hung, cable cut). It then
  refuses goal writes until the watchdog is cleared; ``read()`` raises ``DriverError`` (the
  runtime faults) and the next ``stop()`` clears it with torque off, so the old goal never
  resumes, and re-arms it.
- ``stop()`` writes the no-motion goal and reads it back; it raises ``DriverError`` when the
  motors do not confirm it (the watchdog then stops them within ``bus_watchdog_s``).
- The multi-turn count survives a reboot (``clear_errors``): a rebooted X-series motor reports
  its position within one turn again, so the driver keeps the lost whole turns as an offset.

One file on purpose: it is one class implementing ``MotorDriver`` over
``dynamixel_sdk``, and its register I/O and the safety sequences above (open, stop with its
read-back, the watchdog's arming and clearing, the reboot with the turn offset) share the
port, the registers' cached state and the error handling. The SDK-free register units are
``articutool/dynamixel_units.py``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
from dynamixel_sdk import (
    COMM_SUCCESS,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
)
from numpy.typing import ArrayLike, NDArray

from articutool.dynamixel_units import (
    bus_watchdog_units,
    position_limit_ticks,
    rad_s_to_velocity_units,
    rad_to_ticks,
    ticks_to_rad,
    to_signed32,
    to_unsigned32,
    turns_lost_in_reboot,
    velocity_limit_units,
    velocity_units_to_rad_s,
)
from articutool.spec import Spec
from articutool.tool.drivers.base import (
    JOINTS,
    DriverError,
    MotorDriver,
    MotorMode,
    MotorState,
    validate_position_command,
    validate_velocity_command,
)

__all__ = [
    "ADDR_BUS_WATCHDOG",
    "ADDR_GOAL_POSITION",
    "ADDR_GOAL_VELOCITY",
    "ADDR_HARDWARE_ERROR_STATUS",
    "ADDR_MAX_POSITION_LIMIT",
    "ADDR_MIN_POSITION_LIMIT",
    "ADDR_OPERATING_MODE",
    "ADDR_PRESENT_INPUT_VOLTAGE",
    "ADDR_PRESENT_POSITION",
    "ADDR_PRESENT_TEMPERATURE",
    "ADDR_PRESENT_VELOCITY",
    "ADDR_TORQUE_ENABLE",
    "ADDR_VELOCITY_LIMIT",
    "OPERATING_MODE_POSITION",
    "OPERATING_MODE_VELOCITY",
    "DynamixelDriver",
]

# --- X-series control table (protocol 2.0), address: size in bytes ------------------------
ADDR_OPERATING_MODE = 11  # 1 B, EEPROM
ADDR_VELOCITY_LIMIT = 44  # 4 B, EEPROM, 0..1023 units
ADDR_MAX_POSITION_LIMIT = 48  # 4 B, EEPROM, 0..4095 ticks
ADDR_MIN_POSITION_LIMIT = 52  # 4 B, EEPROM
ADDR_TORQUE_ENABLE = 64  # 1 B
ADDR_HARDWARE_ERROR_STATUS = 70  # 1 B
ADDR_BUS_WATCHDOG = 98  # 1 B, signed: 0 off/clear, 1..127 × 20 ms, -1 expired (e-manual)
ADDR_GOAL_VELOCITY = 104  # 4 B, signed
ADDR_GOAL_POSITION = 116  # 4 B
ADDR_PRESENT_VELOCITY = 128  # 4 B, signed
ADDR_PRESENT_POSITION = 132  # 4 B, signed
ADDR_PRESENT_INPUT_VOLTAGE = 144  # 2 B, 0.1 V
ADDR_PRESENT_TEMPERATURE = 146  # 1 B, °C
# One sync read covers Bus Watchdog .. Present Temperature (goals included).
_STATUS_START = ADDR_BUS_WATCHDOG
_STATUS_LEN = ADDR_PRESENT_TEMPERATURE + 1 - ADDR_BUS_WATCHDOG  # 49 bytes
# stop() reads back Bus Watchdog .. Goal Position.
_GOALS_LEN = ADDR_GOAL_POSITION + 4 - ADDR_BUS_WATCHDOG

OPERATING_MODE_VELOCITY = 1
OPERATING_MODE_POSITION = 3  # single-turn; Min/Max Position Limit registers apply
_ERRBIT_ALERT = 0x80  # status-packet error byte: "check Hardware Error Status"
_WATCHDOG_EXPIRED = 0xFF  # -1 as the register's one byte


def _le_bytes(value: int, size: int) -> list[int]:
    return [(value >> (8 * k)) & 0xFF for k in range(size)]


def _from_le(data: list[int] | bytes, start: int, size: int) -> int:
    return int.from_bytes(bytes(data[start : start + size]), "little")


class _Port(PortHandler):
    """``PortHandler`` whose status-packet timeout uses a configurable USB latency.

    The SDK waits ``2 × LATENCY_TIMER + 2`` ms (its module constant, 16 ms: the FTDI default
    of the U2D2) plus transmission time. A U2D2 set to 1 ms latency can use a shorter wait;
    a loaded test machine a longer one.
    """

    def __init__(self, port_name: str, latency_ms: float) -> None:
        super().__init__(port_name)
        self.latency_ms = latency_ms

    def setPacketTimeout(self, packet_length: int) -> None:
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = self.tx_time_per_byte * packet_length + 2.0 * self.latency_ms + 2.0


class DynamixelDriver(MotorDriver):
    """Real XC430 pair (IDs ``spec.motors.pitch_id`` / ``roll_id``) on a U2D2.

    ``port`` overrides ``spec.motors.port``; ``clock`` stamps reads (monotonic seconds);
    ``latency_ms`` is the USB-serial latency the reply timeout allows for (see ``_Port``).
    """

    def __init__(
        self,
        spec: Spec,
        port: str | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
        latency_ms: float = 16.0,
    ) -> None:
        if not (math.isfinite(latency_ms) and latency_ms > 0):
            raise ValueError(f"latency_ms must be > 0; got {latency_ms}")
        self._latency_ms = float(latency_ms)
        m = spec.motors
        if m.protocol != 2.0:
            raise ValueError(f"motors.protocol must be 2.0 for the X-series; got {m.protocol}")
        self.port_name = port if port is not None else m.port
        self._baud = m.baudrate
        self._ids = (m.pitch_id, m.roll_id)
        self._clock = clock
        self._unit_rpm = m.velocity_unit_rpm
        self._volt_unit = m.voltage_unit_v
        self._tpr = m.ticks_per_rev
        self._zero = np.array(m.zero_ticks, dtype=np.int64)
        self._vel_limits = spec.wrist.velocity_limits
        self._vel_limit_units = velocity_limit_units(self._vel_limits, self._unit_rpm)
        self._pos_limit_ticks = position_limit_ticks(spec.wrist.limits, self._zero, self._tpr)
        # Position commands are checked against what the registers will actually allow.
        self._pos_limits = ticks_to_rad(self._pos_limit_ticks, self._zero[:, None], self._tpr)
        self._watchdog_s = m.bus_watchdog_s
        self._watchdog_units = bus_watchdog_units(m.bus_watchdog_s)
        # Whole turns (ticks) each motor lost in reboots; added to what it reports.
        self._turn_offset = np.zeros(2, dtype=np.int64)
        self._port: PortHandler | None = None
        self._ph = PacketHandler(2.0)
        self._mode: MotorMode = "velocity"
        self._torque = False
        self._last_ticks: NDArray[np.int64] | None = None  # raw, as the motors report them
        self.model_numbers: tuple[int, int] = (0, 0)

    # --- low-level helpers ---------------------------------------------------------------
    def _require_open(self) -> PortHandler:
        if self._port is None:
            raise DriverError(f"motor port {self.port_name} is not open")
        return self._port

    def _check(self, i: int, result: int, error: int, what: str) -> None:
        who = f"{JOINTS[i]} motor (ID {self._ids[i]})"
        if result != COMM_SUCCESS:
            raise DriverError(f"{who}: {self._ph.getTxRxResult(result)} ({what})")
        if error & ~_ERRBIT_ALERT & 0xFF:
            raise DriverError(f"{who}: {self._ph.getRxPacketError(error)} ({what})")

    def _write(self, i: int, addr: int, size: int, value: int, what: str) -> None:
        port = self._require_open()
        res, err = self._ph.writeTxRx(port, self._ids[i], addr, size, _le_bytes(value, size))
        self._check(i, res, err, f"writing {what}")

    def _read(self, i: int, addr: int, size: int, what: str) -> int:
        port = self._require_open()
        data, res, err = self._ph.readTxRx(port, self._ids[i], addr, size)
        self._check(i, res, err, f"reading {what}")
        return _from_le(data, 0, size)

    def _ensure(self, i: int, addr: int, size: int, value: int, what: str) -> None:
        """Write an EEPROM register only if it differs (limits flash wear)."""
        if self._read(i, addr, size, what) != value & ((1 << (8 * size)) - 1):
            self._write(i, addr, size, value, what)

    def _sync_write(self, addr: int, size: int, values: list[int], what: str) -> None:
        port = self._require_open()
        gsw = GroupSyncWrite(port, self._ph, addr, size)
        for dxl_id, v in zip(self._ids, values, strict=True):
            gsw.addParam(dxl_id, _le_bytes(v, size))
        res = gsw.txPacket()
        if res != COMM_SUCCESS:
            raise DriverError(f"sync write of {what}: {self._ph.getTxRxResult(res)}")

    def _sync_read(self, start: int, length: int, what: str) -> tuple[list[list[int]], list[bool]]:
        """One sync read of ``length`` bytes from ``start`` on both motors: the rows and each
        motor's alert bit."""
        port = self._require_open()
        res = self._ph.syncReadTx(port, start, length, list(self._ids), 2, False)
        if res != COMM_SUCCESS:
            raise DriverError(f"sync read of {what}: {self._ph.getTxRxResult(res)}")
        rows: list[list[int]] = []
        alerts: list[bool] = []
        for i, dxl_id in enumerate(self._ids):
            data, res, err = self._ph.readRx(port, dxl_id, length)
            self._check(i, res, err, f"sync read of {what}")
            if len(data) != length:
                raise DriverError(
                    f"{JOINTS[i]} motor (ID {dxl_id}): {len(data)} status bytes, expected {length}"
                )
            rows.append(data)
            alerts.append(bool(err & _ERRBIT_ALERT))
        return rows, alerts

    def _set_torque(self, on: bool) -> None:
        for i in range(2):
            self._write(i, ADDR_TORQUE_ENABLE, 1, int(on), "Torque Enable")
        self._torque = on

    def _hold_targets(self) -> None:
        """Goal that causes no motion in the current mode: zero velocity or present position."""
        if self._mode == "velocity":
            self._sync_write(ADDR_GOAL_VELOCITY, 4, [0, 0], "Goal Velocity")
        else:
            ticks = [
                to_signed32(self._read(i, ADDR_PRESENT_POSITION, 4, "Present Position"))
                for i in range(2)
            ]
            self._sync_write(
                ADDR_GOAL_POSITION, 4, [to_unsigned32(t) for t in ticks], "Goal Position"
            )

    # --- MotorDriver -----------------------------------------------------------------------
    @property
    def mode(self) -> MotorMode:
        """The current operating mode."""
        return self._mode

    @property
    def torque_enabled(self) -> bool:
        """Whether torque was last switched on by this driver."""
        return self._torque

    def open(self) -> None:
        """Open the port, ping both IDs, torque off, velocity mode, write Velocity Limit."""
        if self._port is not None:
            return
        port = _Port(self.port_name, self._latency_ms)
        try:
            ok = port.openPort() and port.setBaudRate(self._baud)
        except Exception as e:  # pyserial raises SerialException/OSError
            raise DriverError(f"cannot open motor port {self.port_name}: {e}") from e
        if not ok:
            raise DriverError(f"cannot open motor port {self.port_name} at {self._baud} baud")
        self._port = port
        try:
            models = []
            for i, dxl_id in enumerate(self._ids):
                model, res, err = self._ph.ping(port, dxl_id)
                self._check(i, res, err, "ping")
                models.append(model)
            self.model_numbers = (models[0], models[1])
            self._set_torque(False)
            for i in range(2):
                self._ensure(i, ADDR_OPERATING_MODE, 1, OPERATING_MODE_VELOCITY, "Operating Mode")
                self._ensure(
                    i, ADDR_VELOCITY_LIMIT, 4, int(self._vel_limit_units[i]), "Velocity Limit"
                )
            self._mode = "velocity"
            self._sync_write(ADDR_GOAL_VELOCITY, 4, [0, 0], "Goal Velocity")
        except Exception:
            self._close_port()
            raise

    def _close_port(self) -> None:
        if self._port is not None:
            try:
                self._port.closePort()
            finally:
                self._port = None

    def close(self) -> None:
        """Stop, torque off, close the port; then raise ``DriverError`` if the stop or the
        torque off failed (the port is closed either way)."""
        if self._port is None:
            return
        errors = []
        try:
            self.stop()
        except DriverError as e:
            errors.append(str(e))
        try:
            self._set_torque(False)
        except Exception as e:
            errors.append(f"torque off failed: {e}")
        try:
            self._close_port()
        except Exception as e:
            errors.append(f"closing port: {e}")
        if errors:
            raise DriverError("; ".join(errors))

    def enable_torque(self, on: bool) -> None:
        """Torque on (after setting a no-motion goal), then arm the bus watchdog; or off."""
        self._require_open()
        if on:
            self._hold_targets()
        self._set_torque(bool(on))
        if on:  # the watchdog watches only while torque is on; a reboot clears it
            for i in range(2):
                self._write(i, ADDR_BUS_WATCHDOG, 1, self._watchdog_units, "Bus Watchdog")

    def set_mode(self, mode: MotorMode) -> None:
        """Stop, torque off, write Operating Mode (and position limits), restore torque."""
        if mode not in ("velocity", "position"):
            raise ValueError(f"mode must be 'velocity' or 'position'; got {mode!r}")
        self._require_open()
        was_on = self._torque
        self.stop()
        self._set_torque(False)  # EEPROM registers are writable only with torque off
        for i in range(2):
            if mode == "position":
                lo, hi = (int(t) for t in self._pos_limit_ticks[i])
                self._ensure(i, ADDR_MIN_POSITION_LIMIT, 4, lo, "Min Position Limit")
                self._ensure(i, ADDR_MAX_POSITION_LIMIT, 4, hi, "Max Position Limit")
            value = OPERATING_MODE_POSITION if mode == "position" else OPERATING_MODE_VELOCITY
            self._write(i, ADDR_OPERATING_MODE, 1, value, "Operating Mode")
        self._mode = mode
        if was_on:
            self.enable_torque(True)

    def set_velocity(self, qd: ArrayLike) -> None:
        """Sync-write Goal Velocity (rad/s → 0.229 rev/min units); refuses bad input."""
        a = validate_velocity_command(qd, self._vel_limits)
        self._require_open()
        if self._mode != "velocity":
            raise DriverError("set_velocity needs velocity mode (call set_mode('velocity'))")
        # Rounding may land one unit past the floor-rounded register limit: quantisation only.
        units = np.clip(
            rad_s_to_velocity_units(a, self._unit_rpm),
            -self._vel_limit_units,
            self._vel_limit_units,
        )
        self._sync_write(
            ADDR_GOAL_VELOCITY, 4, [to_unsigned32(int(u)) for u in units], "Goal Velocity"
        )

    def set_position(self, q: ArrayLike) -> None:
        """Sync-write Goal Position (rad → ticks) within the position-limit registers."""
        a = validate_position_command(q, self._pos_limits)
        self._require_open()
        if self._mode != "position":
            raise DriverError("set_position needs position mode (call set_mode('position'))")
        for i in np.flatnonzero(self._turn_offset):
            # Single-turn goals are in the motor's own count, which a reboot moved by whole
            # turns: the same goal would be a different joint angle.
            raise DriverError(
                f"set_position: the {JOINTS[i]} motor was rebooted "
                f"{int(self._turn_offset[i]) // self._tpr:+d} turns away from its single-turn "
                "range; position mode cannot reach it (use velocity mode)"
            )
        ticks = rad_to_ticks(a, self._zero, self._tpr)
        ticks = np.clip(ticks, self._pos_limit_ticks[:, 0], self._pos_limit_ticks[:, 1])
        self._sync_write(
            ADDR_GOAL_POSITION, 4, [to_unsigned32(int(t)) for t in ticks], "Goal Position"
        )

    def read(self) -> MotorState:
        """One sync read of Bus Watchdog..Present Temperature; Hardware Error Status is read
        only for a motor whose status packet carries the alert bit. Raises ``DriverError``
        when a motor's bus watchdog has stopped it (the next ``stop()`` clears that)."""
        rows, alerts = self._sync_read(_STATUS_START, _STATUS_LEN, "present values")
        hw = tuple(
            self._read(i, ADDR_HARDWARE_ERROR_STATUS, 1, "Hardware Error Status")
            if alerts[i]
            else 0
            for i in range(2)
        )

        def field(row: list[int], addr: int, size: int) -> int:
            return _from_le(row, addr - _STATUS_START, size)

        ticks = np.array([to_signed32(field(r, ADDR_PRESENT_POSITION, 4)) for r in rows])
        self._last_ticks = ticks
        expired = [JOINTS[i] for i, r in enumerate(rows)
                   if field(r, ADDR_BUS_WATCHDOG, 1) == _WATCHDOG_EXPIRED]
        if expired:
            raise DriverError(
                f"bus watchdog expired on the {' and '.join(expired)} motor: no packet for "
                f"{self._watchdog_s:g} s (spec.motors.bus_watchdog_s), the motors stopped "
                "themselves; stop() clears it"
            )
        vel_units = [to_signed32(field(r, ADDR_PRESENT_VELOCITY, 4)) for r in rows]
        volts = [field(r, ADDR_PRESENT_INPUT_VOLTAGE, 2) * self._volt_unit for r in rows]
        temps = [float(field(r, ADDR_PRESENT_TEMPERATURE, 1)) for r in rows]
        return MotorState(
            position=ticks_to_rad(ticks + self._turn_offset, self._zero, self._tpr),
            velocity=velocity_units_to_rad_s(vel_units, self._unit_rpm),
            hardware_error=(int(hw[0]), int(hw[1])),
            input_voltage=min(volts),
            temperature=max(temps),
            stamp=self._clock(),
        )

    def _stop_goals(self) -> tuple[int, list[int]] | None:
        """The no-motion goal register and values: zero velocity, or hold the last read
        position; None in position mode before any read."""
        if self._mode == "velocity":
            return ADDR_GOAL_VELOCITY, [0, 0]
        if self._last_ticks is None:
            return None
        return ADDR_GOAL_POSITION, [to_unsigned32(int(t)) for t in self._last_ticks]

    def _clear_watchdog(self) -> None:
        """Clear an expired bus watchdog without resuming the old goal: torque off (the motor
        cannot move), clear, no-motion goal, then torque on and re-arm if it was on."""
        was_on = self._torque
        self._set_torque(False)
        for i in range(2):
            self._write(i, ADDR_BUS_WATCHDOG, 1, 0, "Bus Watchdog")
        if was_on:
            self.enable_torque(True)
        else:
            self._hold_targets()

    def stop(self) -> None:
        """Zero Goal Velocity (velocity mode) or hold the last read position (position mode),
        and read the goals back; clears an expired bus watchdog (see ``_clear_watchdog``).

        Raises ``DriverError`` when the goal cannot be sent or the motors do not confirm it:
        they may still be moving, until their watchdog stops them. Does nothing before
        ``open()``. Clears the SDK's port-busy flag first, since a transaction interrupted by
        an exception leaves it set.
        """
        port = self._port
        if port is None:
            return
        port.is_using = False
        goals = self._stop_goals()
        if goals is None:
            return
        addr, values = goals
        try:
            self._sync_write(addr, 4, values, "stop goal")
            rows, _ = self._sync_read(ADDR_BUS_WATCHDOG, _GOALS_LEN, "goals")
            if any(r[0] == _WATCHDOG_EXPIRED for r in rows):
                self._clear_watchdog()
                rows, _ = self._sync_read(ADDR_BUS_WATCHDOG, _GOALS_LEN, "goals")
            for i, r in enumerate(rows):
                held = _from_le(r, addr - ADDR_BUS_WATCHDOG, 4)
                if held != values[i]:
                    raise DriverError(
                        f"{JOINTS[i]} motor (ID {self._ids[i]}) holds goal {to_signed32(held)} "
                        f"at register {addr}, not the stop goal {to_signed32(values[i])}"
                    )
        except Exception as e:  # DriverError, or pyserial's errors from a vanished port
            raise DriverError(
                f"stop not confirmed: {e}; the motors may keep their last goal until their "
                f"bus watchdog stops them ({self._watchdog_s:g} s after the last packet)"
            ) from e

    def clear_errors(self) -> None:
        """Reboot each motor whose Hardware Error Status is non-zero; torque comes back off.

        The reboot loses the motor's multi-turn count; the whole turns it lost are kept in the
        driver's turn offset, so the reported roll (and the cable budget) stays true.
        """
        port = self._require_open()
        for i, dxl_id in enumerate(self._ids):
            if self._read(i, ADDR_HARDWARE_ERROR_STATUS, 1, "Hardware Error Status"):
                before = to_signed32(self._read(i, ADDR_PRESENT_POSITION, 4, "Present Position"))
                before += int(self._turn_offset[i])
                res, err = self._ph.reboot(port, dxl_id)
                self._check(i, res, err, "reboot")
                self._torque = False
                self._wait_for_boot(i)
                after = to_signed32(self._read(i, ADDR_PRESENT_POSITION, 4, "Present Position"))
                self._turn_offset[i] = turns_lost_in_reboot(before, after, self._tpr)

    def _wait_for_boot(self, i: int, attempts: int = 10) -> None:
        """After REBOOT the motor is silent while it boots; ping it until it answers (each
        ping times out after 2 × latency + 2 ms: ~0.35 s in all at 16 ms)."""
        port = self._require_open()
        res = COMM_SUCCESS
        for _ in range(attempts):
            _, res, _ = self._ph.ping(port, self._ids[i])
            if res == COMM_SUCCESS:
                return
        self._check(i, res, 0, "ping after reboot")
