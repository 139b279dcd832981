"""SparkFun OpenLog Artemis (ICM-20948) IMU: CSV lines over USB serial (docs/hardware.md §3).

Each data line has 13 comma-separated fields (the logger usually adds a trailing comma):
``rtcDate, rtcTime, aX, aY, aZ (milli-g), gX, gY, gZ (deg/s), mX, mY, mZ (µT), imu_degC,
output_Hz``. Acceleration becomes m/s² with ``spec.imu.gravity`` per g, rates become rad/s.

Reads never block (serial timeout 0): bytes are buffered and only complete lines are parsed.
Header lines, menus, garbage, short or corrupt lines, non-numeric or non-finite fields and
values beyond the ICM-20948 full-scale ranges are skipped and counted in ``lines_bad``;
nothing on the wire can raise, only a lost serial device does (``DriverError``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import serial

from articutool.spec import Spec
from articutool.tool.drivers.base import ImuDriver, ImuSample
from articutool.tool.drivers.serial_port import open_nonblocking, read_available

__all__ = [
    "ACCEL_FULL_SCALE_MG",
    "GYRO_FULL_SCALE_DPS",
    "N_FIELDS",
    "OpenLogImuDriver",
    "parse_openlog_line",
]

N_FIELDS = 13
# ICM-20948 maximum full-scale ranges (datasheet): a reading beyond them is corruption.
ACCEL_FULL_SCALE_MG = 16000.0
GYRO_FULL_SCALE_DPS = 2000.0
_MAX_LINE = 512  # bytes without a newline before the buffer is declared garbage


def parse_openlog_line(line: str, gravity: float) -> tuple[np.ndarray, np.ndarray, float] | None:
    """Parse one OpenLog Artemis CSV line into (accel m/s² (3,), gyro rad/s (3,), temp °C).

    Returns None for anything that is not a complete, plausible data line. The date and time
    fields are checked for shape only (``/`` and ``:``), which rejects a fragment whose
    columns are shifted.
    """
    fields = line.strip().split(",")
    if fields and fields[-1].strip() == "":
        fields.pop()  # the logger's trailing comma
    if len(fields) != N_FIELDS:
        return None
    if "/" not in fields[0] or ":" not in fields[1]:
        return None
    try:
        values = [float(f) for f in fields[2:]]
    except ValueError:
        return None
    if not all(math.isfinite(v) for v in values):
        return None
    accel_mg, gyro_dps = values[0:3], values[3:6]
    if any(abs(a) > ACCEL_FULL_SCALE_MG for a in accel_mg):
        return None
    if any(abs(g) > GYRO_FULL_SCALE_DPS for g in gyro_dps):
        return None
    accel = np.array(accel_mg) * (gravity / 1000.0)
    gyro = np.radians(np.array(gyro_dps))
    return accel, gyro, values[9]


class OpenLogImuDriver(ImuDriver):
    """The OpenLog Artemis on ``port`` (default ``spec.imu.port``) at ``spec.imu.baudrate``.

    Samples are stamped with ``clock()`` when their line is read (the logger's own RTC is
    not trusted for timing).
    """

    def __init__(
        self,
        spec: Spec,
        port: str | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.port_name = port if port is not None else spec.imu.port
        self._baud = spec.imu.baudrate
        self._gravity = spec.imu.gravity
        self._clock = clock
        self._ser: serial.Serial | None = None
        self._buf = bytearray()
        self.lines_ok = 0
        self.lines_bad = 0

    def open(self) -> None:
        """Open the port non-blocking and drop anything buffered before now."""
        if self._ser is not None:
            return
        self._ser = open_nonblocking(self.port_name, self._baud, "IMU")
        self._buf.clear()

    def close(self) -> None:
        """Close the port."""
        if self._ser is not None:
            try:
                self._ser.close()
            finally:
                self._ser = None

    def read_all(self) -> list[ImuSample]:
        """Every complete line received since the last call, parsed, oldest first."""
        self._buf += read_available(self._ser, self.port_name, "IMU")
        *lines, tail = self._buf.split(b"\n")
        if len(tail) > _MAX_LINE:
            self.lines_bad += 1
            tail = b""
        self._buf = bytearray(tail)
        out: list[ImuSample] = []
        now = self._clock() if lines else 0.0
        for raw in lines:
            raw = raw.strip()
            if not raw:
                continue
            try:
                parsed = parse_openlog_line(raw.decode("ascii"), self._gravity)
            except UnicodeDecodeError:
                parsed = None
            if parsed is None:
                self.lines_bad += 1
                continue
            accel, gyro, temp = parsed
            self.lines_ok += 1
            out.append(ImuSample(accel=accel, gyro=gyro, stamp=now, temperature=temp))
        return out
