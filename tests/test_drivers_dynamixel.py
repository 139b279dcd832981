"""The Dynamixel driver against a fake protocol-2.0 bus on a pseudo-terminal.

The real ``DynamixelDriver`` (and the real ``dynamixel_sdk`` PortHandler/pyserial underneath)
opens the pty's slave path; a thread on the master side plays two XC430s with a register
file each. The fake computes its own CRC-16 (bitwise, poly 0x8005) so a packet-building bug
in either side would show up as a timeout or a CRC mismatch.
"""

from __future__ import annotations

import math
import os
import select
import threading
import time
import tomllib
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from articutool.dynamixel_units import (
    bus_watchdog_units,
    rad_s_to_velocity_units,
    rad_to_ticks,
    ticks_to_rad,
    to_signed32,
    to_unsigned32,
    turns_lost_in_reboot,
    velocity_limit_units,
    velocity_units_to_rad_s,
)
from articutool.spec import SpecError, default_spec_path, parse_spec
from articutool.tool.api import Mode
from articutool.tool.drivers.base import DriverError, HardwareError
from articutool.tool.drivers.dynamixel import (
    ADDR_BUS_WATCHDOG,
    ADDR_GOAL_POSITION,
    ADDR_GOAL_VELOCITY,
    ADDR_HARDWARE_ERROR_STATUS,
    ADDR_MAX_POSITION_LIMIT,
    ADDR_MIN_POSITION_LIMIT,
    ADDR_OPERATING_MODE,
    ADDR_PRESENT_INPUT_VOLTAGE,
    ADDR_PRESENT_POSITION,
    ADDR_PRESENT_TEMPERATURE,
    ADDR_PRESENT_VELOCITY,
    ADDR_TORQUE_ENABLE,
    ADDR_VELOCITY_LIMIT,
    DynamixelDriver,
)
from articutool.tool.drivers.sim import SimWrist
from articutool.tool.runtime import ToolRuntime
from conftest import packaged_spec, wait_until

SPEC = packaged_spec()
M = SPEC.motors
IDS = (M.pitch_id, M.roll_id)
RAD_PER_UNIT = M.velocity_unit_rpm * 2 * math.pi / 60  # independent of the driver's helper
RAD_PER_TICK = 2 * math.pi / M.ticks_per_rev
MODEL = 1160  # what the fake answers to PING; the driver only records it
# Reply timeout headroom (2 × this + 2 ms): the fake answers within a few ms, but on 2 shared
# cores at load 25 a niced test process can wait more than 0.2 s for the CPU. Tests that expect
# a timeout pay it, so it is not larger.
LATENCY_MS = 250.0
WATCHDOG_UNIT_S = 0.020  # Bus Watchdog (98) unit, ROBOTIS e-manual (X-series control table)
GOAL_REGISTERS = range(100, 120)  # Goal PWM .. Goal Position: read-only after a watchdog stop
# The driver under test gets a longer bus watchdog than the spec's 0.1 s, so that a loaded
# test machine pausing between two calls does not trip it in tests about something else.
BUS_SPEC = SPEC.model_copy(
    update={"motors": SPEC.motors.model_copy(update={"bus_watchdog_s": 1.0})}
)


# ----------------------------------------------------------------- fake protocol 2.0 bus --
def crc16(data: bytes) -> int:
    """CRC-16/BUYPASS (poly 0x8005, init 0), bit by bit, as the protocol 2.0 spec defines."""
    crc = 0
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    out = bytearray()
    for b in body:
        out.append(b)
        if len(out) >= 3 and out[-3:] == b"\xff\xff\xfd":
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes) -> bytes:
    out = bytearray()
    i = 0
    while i < len(body):
        out.append(body[i])
        if (
            len(out) >= 3
            and out[-3:] == b"\xff\xff\xfd"
            and i + 1 < len(body)
            and (body[i + 1] == 0xFD)
        ):
            i += 1  # drop the stuffed byte
        i += 1
    return bytes(out)


class FakeBus:
    """Two X-series motors: register files, PING/READ/WRITE/SYNC_WRITE/SYNC_READ/REBOOT.

    An ideal motor: Present Velocity follows Goal Velocity while torque is on; Present
    Position is set by the test. Bus Watchdog (98), as the e-manual describes it: with torque
    on and 98 = 1..127, no instruction packet for 98 × 20 ms stops the motor and sets 98 to
    -1; Goal registers then refuse writes (Data Range Error) until 98 is written 0. Writing 0
    lets the motor follow its (old) goal again, the pessimistic reading. REBOOT resets RAM
    and the multi-turn count (Present Position comes back within one turn). ``deaf`` cuts
    the bus: packets from the host are lost, as with an unplugged cable.
    """

    def __init__(self, master_fd: int) -> None:
        self.fd = master_fd
        self.regs = {i: bytearray(700) for i in IDS}
        for r in self.regs.values():
            r[ADDR_OPERATING_MODE] = 3  # factory default: position mode
            r[ADDR_VELOCITY_LIMIT : ADDR_VELOCITY_LIMIT + 4] = (275).to_bytes(4, "little")
            r[ADDR_MAX_POSITION_LIMIT : ADDR_MAX_POSITION_LIMIT + 4] = (4095).to_bytes(4, "little")
            r[ADDR_PRESENT_INPUT_VOLTAGE : ADDR_PRESENT_INPUT_VOLTAGE + 2] = (120).to_bytes(
                2, "little"
            )
            r[ADDR_PRESENT_TEMPERATURE] = 31
        self.lock = threading.Lock()
        self.writes: list[tuple[str, int, int, bytes]] = []  # (kind, id, addr, data)
        self.instructions: list[int] = []
        self.silent = False
        self.deaf = False
        self.corrupt_crc = False
        self.watchdog_trips = 0
        self.last_packet = {i: time.monotonic() for i in IDS}
        self._buf = bytearray()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    # register helpers
    def get(self, dxl_id: int, addr: int, size: int) -> int:
        with self.lock:
            return int.from_bytes(self.regs[dxl_id][addr : addr + size], "little")

    def set(self, dxl_id: int, addr: int, size: int, value: int) -> None:
        with self.lock:
            self.regs[dxl_id][addr : addr + size] = (value & ((1 << (8 * size)) - 1)).to_bytes(
                size, "little"
            )

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)

    # the motor
    def _follow(self, dxl_id: int) -> None:
        """Present Velocity = Goal Velocity with torque on and no watchdog stop, else 0."""
        r = self.regs[dxl_id]
        moving = r[ADDR_TORQUE_ENABLE] and r[ADDR_BUS_WATCHDOG] != 0xFF
        goal = r[ADDR_GOAL_VELOCITY : ADDR_GOAL_VELOCITY + 4] if moving else bytes(4)
        r[ADDR_PRESENT_VELOCITY : ADDR_PRESENT_VELOCITY + 4] = goal

    def _watchdog(self) -> None:
        now = time.monotonic()
        with self.lock:
            for i, r in self.regs.items():
                wd = r[ADDR_BUS_WATCHDOG]
                quiet = now - self.last_packet[i]
                if r[ADDR_TORQUE_ENABLE] and 1 <= wd <= 127 and quiet > wd * WATCHDOG_UNIT_S:
                    r[ADDR_BUS_WATCHDOG] = 0xFF  # -1: Bus Watchdog Error
                    self.watchdog_trips += 1
                    self._follow(i)

    def _reboot(self, dxl_id: int) -> None:
        r = self.regs[dxl_id]
        ticks = to_signed32(int.from_bytes(r[ADDR_PRESENT_POSITION : ADDR_PRESENT_POSITION + 4],
                                           "little"))
        r[64:ADDR_PRESENT_POSITION] = bytes(ADDR_PRESENT_POSITION - 64)  # RAM to defaults
        r[ADDR_PRESENT_POSITION : ADDR_PRESENT_POSITION + 4] = (ticks % 4096).to_bytes(
            4, "little"
        )  # the multi-turn count is lost

    # protocol
    def _send_status(self, dxl_id: int, err: int, params: bytes = b"") -> None:
        if self.silent:
            return
        if self.regs[dxl_id][ADDR_HARDWARE_ERROR_STATUS]:
            err |= 0x80  # alert bit
        body = stuff(bytes([0x55, err]) + params)
        pkt = bytes([0xFF, 0xFF, 0xFD, 0x00, dxl_id]) + (len(body) + 2).to_bytes(2, "little")
        pkt += body
        crc = crc16(pkt)
        if self.corrupt_crc:
            crc ^= 0x1234
        os.write(self.fd, pkt + crc.to_bytes(2, "little"))

    def _write_reg(self, dxl_id: int, addr: int, data: bytes, kind: str) -> int:
        r = self.regs[dxl_id]
        if addr < 64 and r[ADDR_TORQUE_ENABLE]:
            return 7  # access error: EEPROM locked while torque is on
        if addr in GOAL_REGISTERS and r[ADDR_BUS_WATCHDOG] == 0xFF:
            return 4  # data range error: goals are read-only after a watchdog stop
        if addr == ADDR_GOAL_VELOCITY:
            limit = int.from_bytes(r[ADDR_VELOCITY_LIMIT : ADDR_VELOCITY_LIMIT + 4], "little")
            if abs(to_signed32(int.from_bytes(data, "little"))) > limit:
                return 6  # data limit error: the goal is ignored
        r[addr : addr + len(data)] = data
        if r[ADDR_TORQUE_ENABLE] or addr == ADDR_TORQUE_ENABLE:  # torque off: tests set it
            self._follow(dxl_id)
        self.writes.append((kind, dxl_id, addr, bytes(data)))
        return 0

    def _heard(self, ids: object) -> None:
        now = time.monotonic()
        for i in ids:  # type: ignore[attr-defined]
            if i in self.regs:
                self.last_packet[i] = now

    def _handle(self, dxl_id: int, inst: int, p: bytes) -> None:
        if self.deaf:
            return
        self.instructions.append(inst)
        with self.lock:
            if dxl_id == 0xFE and inst == 0x83:
                n = int.from_bytes(p[2:4], "little")
                self._heard(p[k] for k in range(4, len(p), n + 1))
            elif dxl_id == 0xFE and inst == 0x82:
                self._heard(p[4:])
            else:
                self._heard([dxl_id])
            if inst == 0x01 and dxl_id in self.regs:  # PING
                self._send_status(dxl_id, 0, MODEL.to_bytes(2, "little") + b"\x2d")
            elif inst == 0x02 and dxl_id in self.regs:  # READ
                addr, n = int.from_bytes(p[0:2], "little"), int.from_bytes(p[2:4], "little")
                self._send_status(dxl_id, 0, bytes(self.regs[dxl_id][addr : addr + n]))
            elif inst == 0x03 and dxl_id in self.regs:  # WRITE
                addr = int.from_bytes(p[0:2], "little")
                err = self._write_reg(dxl_id, addr, p[2:], "write")
                self._send_status(dxl_id, err)
            elif inst == 0x08 and dxl_id in self.regs:  # REBOOT
                self._send_status(dxl_id, 0)
                self._reboot(dxl_id)
            elif inst == 0x83 and dxl_id == 0xFE:  # SYNC_WRITE
                addr, n = int.from_bytes(p[0:2], "little"), int.from_bytes(p[2:4], "little")
                for k in range(4, len(p), n + 1):
                    if p[k] in self.regs:
                        self._write_reg(p[k], addr, p[k + 1 : k + 1 + n], "sync")
            elif inst == 0x82 and dxl_id == 0xFE:  # SYNC_READ
                addr, n = int.from_bytes(p[0:2], "little"), int.from_bytes(p[2:4], "little")
                for i in p[4:]:
                    if i in self.regs:
                        self._send_status(i, 0, bytes(self.regs[i][addr : addr + n]))

    def _parse(self) -> None:
        while True:
            start = self._buf.find(b"\xff\xff\xfd\x00")
            if start < 0:
                del self._buf[:-3]
                return
            del self._buf[:start]
            if len(self._buf) < 7:
                return
            total = 7 + int.from_bytes(self._buf[5:7], "little")
            if len(self._buf) < total:
                return
            pkt = bytes(self._buf[:total])
            del self._buf[:total]
            if crc16(pkt[:-2]) != int.from_bytes(pkt[-2:], "little"):
                continue  # a real motor drops a packet with a bad CRC
            body = unstuff(pkt[7:-2])
            self._handle(pkt[4], body[0], body[1:])

    def _run(self) -> None:
        while not self._stop.is_set():
            r, _, _ = select.select([self.fd], [], [], 0.005)
            if r:
                try:
                    self._buf += os.read(self.fd, 4096)
                except OSError:
                    return
                self._parse()
            self._watchdog()


@pytest.fixture
def bus() -> Iterator[tuple[FakeBus, str]]:
    master, slave = os.openpty()
    fake = FakeBus(master)
    yield fake, os.ttyname(slave)
    fake.close()
    os.close(slave)
    os.close(master)


@pytest.fixture
def driver(bus: tuple[FakeBus, str]) -> Iterator[tuple[DynamixelDriver, FakeBus]]:
    fake, path = bus
    drv = DynamixelDriver(BUS_SPEC, port=path, latency_ms=LATENCY_MS)
    drv.open()
    yield drv, fake
    drv.close()


def sync_goal_velocity_writes(fake: FakeBus) -> list[tuple[int, int]]:
    return [
        (i, to_signed32(int.from_bytes(d, "little")))
        for kind, i, a, d in fake.writes
        if kind == "sync" and a == ADDR_GOAL_VELOCITY
    ]


def present_velocities(fake: FakeBus) -> list[int]:
    return [to_signed32(fake.get(i, ADDR_PRESENT_VELOCITY, 4)) for i in IDS]


# ------------------------------------------------------------------------------- tests --
def test_open_configures_motors_safely(driver: tuple[DynamixelDriver, FakeBus]) -> None:
    drv, fake = driver
    expected_limit = [math.floor(v / RAD_PER_UNIT) for v in SPEC.wrist.max_velocity]
    for i, lim in zip(IDS, expected_limit, strict=True):
        assert fake.get(i, ADDR_VELOCITY_LIMIT, 4) == lim  # the motor enforces the limit
        assert fake.get(i, ADDR_OPERATING_MODE, 1) == 1  # velocity mode
        assert fake.get(i, ADDR_TORQUE_ENABLE, 1) == 0  # torque stays off until asked
        assert fake.get(i, ADDR_GOAL_VELOCITY, 4) == 0
    assert lim * RAD_PER_UNIT <= SPEC.wrist.max_velocity[1]
    assert drv.model_numbers == (MODEL, MODEL)
    assert drv.mode == "velocity"
    assert 0x01 in fake.instructions  # pinged


def test_open_skips_eeprom_writes_when_already_set(bus: tuple[FakeBus, str]) -> None:
    fake, path = bus
    with DynamixelDriver(SPEC, port=path, latency_ms=LATENCY_MS):
        pass
    n_writes = sum(1 for k, _, a, _ in fake.writes if k == "write" and a < 64)
    with DynamixelDriver(SPEC, port=path, latency_ms=LATENCY_MS):
        pass
    assert n_writes > 0
    assert sum(1 for k, _, a, _ in fake.writes if k == "write" and a < 64) == n_writes


def test_velocity_command_unit_conversion(driver: tuple[DynamixelDriver, FakeBus]) -> None:
    drv, fake = driver
    drv.enable_torque(True)
    assert all(fake.get(i, ADDR_TORQUE_ENABLE, 1) == 1 for i in IDS)
    qd = np.array([1.0, -2.5])
    drv.set_velocity(qd)
    drv.read()  # a round trip: the (unanswered) sync write has been processed
    got = [to_signed32(fake.get(i, ADDR_GOAL_VELOCITY, 4)) for i in IDS]
    assert got == [round(v / RAD_PER_UNIT) for v in qd]  # 0.229 rev/min per unit
    state = drv.read()  # the fake's ideal motor reports its goal as present velocity
    np.testing.assert_allclose(state.velocity, qd, atol=RAD_PER_UNIT / 2)


def test_command_at_the_limit_is_accepted_and_stays_within_the_register(
    driver: tuple[DynamixelDriver, FakeBus],
) -> None:
    drv, fake = driver
    drv.enable_torque(True)
    vmax = np.array(SPEC.wrist.max_velocity)
    drv.set_velocity(-vmax)
    drv.read()
    for i in IDS:
        limit = fake.get(i, ADDR_VELOCITY_LIMIT, 4)
        assert to_signed32(fake.get(i, ADDR_GOAL_VELOCITY, 4)) == -limit


@pytest.mark.parametrize(
    "bad",
    [[math.nan, 0.0], [0.0, math.inf], [0.0, -math.inf], [0.0, 100.0], [1.0], "fast"],
)
def test_bad_velocity_commands_are_refused_and_nothing_is_sent(
    driver: tuple[DynamixelDriver, FakeBus], bad: object
) -> None:
    drv, fake = driver
    drv.enable_torque(True)
    drv.set_velocity([0.5, 0.5])
    drv.read()  # round trip: the sync write above has been processed
    before = len(sync_goal_velocity_writes(fake))
    with pytest.raises(ValueError, match=r"qd"):
        drv.set_velocity(bad)  # type: ignore[arg-type]
    drv.read()  # a full round trip: every earlier byte has been processed
    assert len(sync_goal_velocity_writes(fake)) == before
    assert [to_signed32(fake.get(i, ADDR_GOAL_VELOCITY, 4)) for i in IDS] == [
        round(0.5 / RAD_PER_UNIT)
    ] * 2


def test_read_converts_signed_present_values(driver: tuple[DynamixelDriver, FakeBus]) -> None:
    drv, fake = driver
    zero = M.zero_ticks
    fake.set(IDS[0], ADDR_PRESENT_POSITION, 4, zero[0] - 1000)
    fake.set(IDS[1], ADDR_PRESENT_POSITION, 4, zero[1] - 3 * 4096 - 17)  # multi-turn, < 0
    fake.set(IDS[0], ADDR_PRESENT_VELOCITY, 4, -40)
    fake.set(IDS[1], ADDR_PRESENT_VELOCITY, 4, 7)
    fake.set(IDS[0], ADDR_PRESENT_INPUT_VOLTAGE, 2, 118)
    fake.set(IDS[1], ADDR_PRESENT_TEMPERATURE, 1, 44)
    s = drv.read()
    np.testing.assert_allclose(s.position, [-1000 * RAD_PER_TICK, (-3 * 4096 - 17) * RAD_PER_TICK])
    np.testing.assert_allclose(s.velocity, [-40 * RAD_PER_UNIT, 7 * RAD_PER_UNIT])
    assert s.input_voltage == pytest.approx(11.8)
    assert s.temperature == 44
    assert s.hardware_error == (0, 0)
    assert not s.has_hardware_error


def test_hardware_error_is_reported_and_cleared_by_reboot(
    driver: tuple[DynamixelDriver, FakeBus],
) -> None:
    drv, fake = driver
    fake.set(IDS[1], ADDR_HARDWARE_ERROR_STATUS, 1, int(HardwareError.OVERLOAD))
    s = drv.read()
    assert s.hardware_error == (0, int(HardwareError.OVERLOAD))
    assert s.has_hardware_error
    assert "roll" in s.describe_errors() and "OVERLOAD" in s.describe_errors()
    drv.clear_errors()
    assert 0x08 in fake.instructions
    assert drv.read().hardware_error == (0, 0)
    assert not drv.torque_enabled


def test_position_mode_writes_limits_and_ticks(driver: tuple[DynamixelDriver, FakeBus]) -> None:
    drv, fake = driver
    drv.enable_torque(True)
    drv.set_mode("position")
    zero = np.array(M.zero_ticks)
    lim = np.array(SPEC.wrist.limits)
    for k, i in enumerate(IDS):
        assert fake.get(i, ADDR_OPERATING_MODE, 1) == 3
        lo = min(max(round(lim[k, 0] / RAD_PER_TICK) + zero[k], 0), 4095)
        hi = min(max(round(lim[k, 1] / RAD_PER_TICK) + zero[k], 0), 4095)
        assert fake.get(i, ADDR_MIN_POSITION_LIMIT, 4) == lo
        assert fake.get(i, ADDR_MAX_POSITION_LIMIT, 4) == hi
        assert fake.get(i, ADDR_TORQUE_ENABLE, 1) == 1  # torque restored
    drv.set_position([0.3, -1.0])
    drv.read()
    assert [fake.get(i, ADDR_GOAL_POSITION, 4) for i in IDS] == [
        round(0.3 / RAD_PER_TICK) + zero[0],
        round(-1.0 / RAD_PER_TICK) + zero[1],
    ]
    with pytest.raises(ValueError, match=r"q\[pitch\]"):
        drv.set_position([3.0, 0.0])
    with pytest.raises(DriverError, match="velocity mode"):
        drv.set_velocity([0.1, 0.1])
    drv.set_mode("velocity")
    assert fake.get(IDS[0], ADDR_OPERATING_MODE, 1) == 1


def test_silent_bus_raises_driver_error_and_stop_is_still_safe(
    driver: tuple[DynamixelDriver, FakeBus],
) -> None:
    drv, fake = driver
    drv.enable_torque(True)
    drv.set_velocity([1.0, 1.0])
    fake.silent = True
    with pytest.raises(DriverError, match="pitch motor"):
        drv.read()
    with pytest.raises(DriverError, match="stop"):
        drv.stop()  # the motors cannot confirm it
    fake.silent = False
    drv.stop()  # confirmed now (clearing the watchdog if the silence let it expire)
    drv.read()
    assert [fake.get(i, ADDR_GOAL_VELOCITY, 4) for i in IDS] == [0, 0]
    assert present_velocities(fake) == [0, 0]


def test_torque_on_arms_the_bus_watchdog_from_the_spec(
    driver: tuple[DynamixelDriver, FakeBus],
) -> None:
    drv, fake = driver
    drv.enable_torque(True)
    units = round(BUS_SPEC.motors.bus_watchdog_s / WATCHDOG_UNIT_S)
    assert 1 <= units <= 127
    assert [fake.get(i, ADDR_BUS_WATCHDOG, 1) for i in IDS] == [units, units]


def test_motors_stop_on_their_own_when_the_host_goes_quiet_and_stop_recovers(
    driver: tuple[DynamixelDriver, FakeBus],
) -> None:
    drv, fake = driver
    drv.enable_torque(True)
    drv.set_velocity([1.0, -1.0])
    drv.read()
    assert all(v != 0 for v in present_velocities(fake))
    # The host says nothing: the motors' own watchdog stops them.
    assert wait_until(lambda: fake.watchdog_trips == 2)
    assert present_velocities(fake) == [0, 0]
    with pytest.raises(DriverError, match="watchdog"):
        drv.read()  # the runtime learns of it as a failed read (a fault)
    drv.stop()  # clears the watchdog without resuming the old goal, re-arms it
    assert present_velocities(fake) == [0, 0]
    assert [to_signed32(fake.get(i, ADDR_GOAL_VELOCITY, 4)) for i in IDS] == [0, 0]
    assert all(fake.get(i, ADDR_BUS_WATCHDOG, 1) not in (0, 0xFF) for i in IDS)
    assert all(fake.get(i, ADDR_TORQUE_ENABLE, 1) == 1 for i in IDS)
    drv.read()
    drv.set_velocity([0.5, 0.5])  # commands are accepted again
    drv.read()
    assert present_velocities(fake) == [round(0.5 / RAD_PER_UNIT)] * 2


def test_a_stop_the_motors_never_receive_raises_and_the_watchdog_stops_them(
    driver: tuple[DynamixelDriver, FakeBus],
) -> None:
    drv, fake = driver
    drv.enable_torque(True)
    drv.set_velocity([1.0, 1.0])
    drv.read()
    fake.deaf = True  # the cable is cut: the zero goal never arrives
    with pytest.raises(DriverError, match="stop"):
        drv.stop()
    assert wait_until(lambda: fake.watchdog_trips == 2)
    assert present_velocities(fake) == [0, 0]
    with pytest.raises(DriverError):
        drv.close()  # the failed stop is reported on the way out too; the port is closed
    with pytest.raises(DriverError, match="not open"):
        drv.read()


def test_turn_count_survives_a_reboot(driver: tuple[DynamixelDriver, FakeBus]) -> None:
    drv, fake = driver
    zero = M.zero_ticks[1]
    turns = 2.3
    fake.set(IDS[1], ADDR_PRESENT_POSITION, 4, zero + round(turns * 4096))
    assert drv.read().position[1] / (2 * math.pi) == pytest.approx(turns, abs=1e-3)
    fake.set(IDS[1], ADDR_HARDWARE_ERROR_STATUS, 1, int(HardwareError.OVERLOAD))
    drv.clear_errors()
    # The motor lost its multi-turn count (the fake reports within one turn) ...
    assert 0 <= fake.get(IDS[1], ADDR_PRESENT_POSITION, 4) < 4096
    # ... the driver did not.
    s = drv.read()
    assert s.hardware_error == (0, 0)
    assert s.position[1] / (2 * math.pi) == pytest.approx(turns, abs=1e-3)
    # Later motion keeps counting from there: one more turn is +3.3, beyond the budget.
    raw = to_signed32(fake.get(IDS[1], ADDR_PRESENT_POSITION, 4))
    fake.set(IDS[1], ADDR_PRESENT_POSITION, 4, raw + 4096)
    assert drv.read().position[1] / (2 * math.pi) == pytest.approx(turns + 1, abs=1e-3)
    assert drv.read().position[1] > SPEC.wrist.roll_turn_budget * 2 * math.pi
    # A second reboot keeps the offset too.
    fake.set(IDS[1], ADDR_HARDWARE_ERROR_STATUS, 1, int(HardwareError.OVERHEATING))
    drv.clear_errors()
    assert drv.read().position[1] / (2 * math.pi) == pytest.approx(turns + 1, abs=1e-3)
    # Single-turn position goals would now mean a different angle: refused.
    drv.set_mode("position")
    with pytest.raises(DriverError, match="roll motor was rebooted"):
        drv.set_position([0.0, 0.0])


def test_runtime_keeps_the_cable_budget_across_a_motor_reboot(bus: tuple[FakeBus, str]) -> None:
    """The runtime on the real driver: roll at +2.3 turns, OVERLOAD, clear_fault reboots the
    motor (which forgets its turns); the roll still reads +2.3 turns and one more turn, which
    would pass the ±3-turn cable budget, is refused."""
    fake, path = bus
    fake.set(IDS[0], ADDR_PRESENT_POSITION, 4, M.zero_ticks[0])
    fake.set(IDS[1], ADDR_PRESENT_POSITION, 4, M.zero_ticks[1] + round(2.3 * 4096))
    sim = SimWrist(BUS_SPEC, seed=0)  # only its IMU stream; the joints are the fake bus's
    rt = ToolRuntime(BUS_SPEC, DynamixelDriver(BUS_SPEC, port=path, latency_ms=LATENCY_MS),
                     sim.imu_driver(), clock=sim.clock)
    rt.open()
    try:
        t = 0.0
        for _ in range(3):
            t += BUS_SPEC.wrist.period
            st = rt.tick(t)
        assert st.position[1] / (2 * math.pi) == pytest.approx(2.3, abs=1e-3)
        fake.set(IDS[1], ADDR_HARDWARE_ERROR_STATUS, 1, int(HardwareError.OVERLOAD))
        t += BUS_SPEC.wrist.period
        assert "OVERLOAD" in rt.tick(t).fault
        assert rt.clear_fault()[0]
        for _ in range(2):
            t += BUS_SPEC.wrist.period
            st = rt.tick(t)  # the first tick reboots the motor
        assert 0x08 in fake.instructions
        assert 0 <= fake.get(IDS[1], ADDR_PRESENT_POSITION, 4) < 4096  # the motor forgot
        assert rt.set_mode(Mode.DISABLED) == (True, "DISABLED (cleared fault: motor hardware "
                                              "error: roll: OVERLOAD)")
        assert st.position[1] / (2 * math.pi) == pytest.approx(2.3, abs=1e-3)
        ok, msg = rt.start_primitive("TWIRL_CW", [1.0, 2.0])
        assert not ok and "cable budget" in msg
        assert rt.start_primitive("TWIRL_CW", [0.5, 2.0])[0]  # within the budget: allowed
    finally:
        rt.close()


def test_runtime_on_a_cut_bus_faults_the_watchdog_stops_and_it_recovers_without_motion(
    bus: tuple[FakeBus, str],
) -> None:
    fake, path = bus
    for i, z in zip(IDS, M.zero_ticks, strict=True):
        fake.set(i, ADDR_PRESENT_POSITION, 4, z)
    sim = SimWrist(BUS_SPEC, seed=0)  # only its IMU stream; the joints are the fake bus's
    rt = ToolRuntime(BUS_SPEC, DynamixelDriver(BUS_SPEC, port=path, latency_ms=LATENCY_MS),
                     sim.imu_driver(), clock=sim.clock)
    rt.open()
    try:
        t = 0.0

        def tick():  # type: ignore[no-untyped-def]
            nonlocal t
            t += BUS_SPEC.wrist.period
            return rt.tick(t)

        tick()
        assert rt.start_primitive("TWIRL_CW", [0.5, 1.0])[0]
        st = tick()
        written = st.extra["command_roll"]
        assert written > 0.5
        assert wait_until(lambda: present_velocities(fake)[1] > 0)  # the sync write landed
        fake.deaf = True  # the cable is cut
        st = tick()
        assert "motor read failed" in st.fault and st.mode is Mode.DISABLED
        assert st.extra["motor_stop_failures"] >= 1
        assert st.extra["command_roll"] == written  # what the motors last got, not a wish
        assert not rt.motors_stopped
        assert wait_until(lambda: fake.watchdog_trips == 2)  # they stop themselves
        assert present_velocities(fake) == [0, 0]
        fake.deaf = False  # reconnected
        st = tick()  # the read reports the watchdog stop; the stop clears it
        assert "motor read failed" in st.fault  # the first cause is kept
        assert rt.motors_stopped and st.extra["command_roll"] == 0.0
        tick()
        assert rt.set_mode(Mode.DISABLED)[0] and rt.fault == ""
        tick()
        assert present_velocities(fake) == [0, 0]  # the old goal never resumed
        assert all(fake.get(i, ADDR_BUS_WATCHDOG, 1) not in (0, 0xFF) for i in IDS)
    finally:
        rt.close()


def test_corrupt_status_packets_raise_driver_error(
    driver: tuple[DynamixelDriver, FakeBus],
) -> None:
    drv, fake = driver
    fake.corrupt_crc = True
    with pytest.raises(DriverError, match=r"[Ii]ncorrect status packet"):
        drv.read()
    fake.corrupt_crc = False
    assert drv.read().input_voltage == pytest.approx(12.0)


def test_missing_port_and_not_open_are_clear_errors(tmp_path: object) -> None:
    drv = DynamixelDriver(SPEC, port="/dev/definitely-not-a-port")
    with pytest.raises(DriverError, match="cannot open motor port"):
        drv.open()
    with pytest.raises(DriverError, match="not open"):
        drv.read()
    drv.stop()  # safe before open
    drv.close()


def test_missing_motor_fails_open(bus: tuple[FakeBus, str]) -> None:
    fake, path = bus
    del fake.regs[IDS[1]]
    drv = DynamixelDriver(SPEC, port=path, latency_ms=LATENCY_MS)
    with pytest.raises(DriverError, match=r"roll motor \(ID 2\).*ping"):
        drv.open()


# -------------------------------------------------------------- pure conversion helpers --
@given(st.integers(-(2**31), 2**31 - 1))
def test_signed32_roundtrip(x: int) -> None:
    u = to_unsigned32(x)
    assert 0 <= u < 2**32
    assert to_signed32(u) == x


@given(st.floats(-6.8, 6.8))
def test_velocity_units_roundtrip_within_half_a_unit(v: float) -> None:
    back = velocity_units_to_rad_s(
        rad_s_to_velocity_units(v, M.velocity_unit_rpm), M.velocity_unit_rpm
    )
    assert abs(float(back) - v) <= RAD_PER_UNIT / 2 + 1e-12


@given(st.floats(-40.0, 40.0))
def test_ticks_roundtrip_within_half_a_tick(q: float) -> None:
    t = rad_to_ticks(q, M.zero_ticks[0], M.ticks_per_rev)
    assert (
        abs(float(ticks_to_rad(t, M.zero_ticks[0], M.ticks_per_rev)) - q)
        <= RAD_PER_TICK / 2 + 1e-12
    )


def test_velocity_limit_never_exceeds_spec_and_rejects_out_of_register() -> None:
    units = velocity_limit_units(SPEC.wrist.max_velocity, M.velocity_unit_rpm)
    assert (units * RAD_PER_UNIT <= np.array(SPEC.wrist.max_velocity)).all()
    assert ((units + 1) * RAD_PER_UNIT > np.array(SPEC.wrist.max_velocity)).all()
    with pytest.raises(ValueError, match=r"1\.\.1023"):
        velocity_limit_units([100.0, 1.0], M.velocity_unit_rpm)


def test_bus_watchdog_timeout_fits_the_register_and_outlasts_a_late_tick() -> None:
    units = bus_watchdog_units(SPEC.motors.bus_watchdog_s)
    assert units * WATCHDOG_UNIT_S == pytest.approx(SPEC.motors.bus_watchdog_s)
    for bad in (0.0, 0.01, 0.03, 2.56, math.nan):
        with pytest.raises(ValueError, match="bus watchdog"):
            bus_watchdog_units(bad)
    data = tomllib.loads(default_spec_path().read_text())
    data["motors"]["bus_watchdog_s"] = SPEC.wrist.period  # one late tick would stop the motors
    with pytest.raises(SpecError, match=r"motors\.bus_watchdog_s.*two loop periods"):
        parse_spec(data)
    for bad in (0.05, 3.0):  # the register cannot hold it
        data["motors"]["bus_watchdog_s"] = bad
        with pytest.raises(SpecError, match=r"motors\.bus_watchdog_s.*0\.02 s in \[0\.02, 2\.54\]"):
            parse_spec(data)


@given(st.integers(-50_000, 50_000), st.integers(0, 4095), st.integers(-1000, 1000))
def test_turns_lost_in_reboot_restores_the_unwrapped_position(
    before: int, zero: int, moved: int
) -> None:
    tpr = M.ticks_per_rev
    after = (before + moved) % tpr  # the motor reboots within one turn, the joint moved a bit
    offset = turns_lost_in_reboot(before, after, tpr)
    assert offset % tpr == 0
    assert after + offset == before + moved
