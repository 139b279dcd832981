"""Opening the tool's USB serial sensors (shared by the IMU and F/T drivers)."""

from __future__ import annotations

import serial

from articutool.tool.drivers.base import DriverError

__all__ = ["open_nonblocking", "read_available"]


def open_nonblocking(port: str, baudrate: int, what: str) -> serial.Serial:
    """Open ``port`` with reads that never block and drop whatever was buffered before now.

    A missing or busy port raises :class:`DriverError` naming the device (``what``).
    """
    try:
        ser = serial.Serial(port, baudrate, timeout=0)
        ser.reset_input_buffer()
    except (serial.SerialException, OSError) as e:
        raise DriverError(f"cannot open {what} port {port}: {e}") from e
    return ser


def read_available(ser: serial.Serial | None, port: str, what: str) -> bytes:
    """Every byte waiting on ``ser`` without blocking; I/O errors raise :class:`DriverError`."""
    if ser is None:
        raise DriverError(f"{what} port {port} is not open")
    try:
        n = ser.in_waiting
        return ser.read(n) if n else b""
    except (serial.SerialException, OSError) as e:
        raise DriverError(f"{what} port {port}: {e}") from e
