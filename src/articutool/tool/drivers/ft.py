"""Resense HEX21 6-axis force/torque sensor over USB serial (docs/hardware.md §3).

The stream is 28-byte frames of 7 little-endian float32 — Fx, Fy, Fz (N), Mx, My, Mz (N·m),
temperature (°C) — at ≈ 100 Hz and 2 Mbaud, with no header or checksum. Frame alignment is
therefore found from the values themselves.

Alignment heuristic (``FramePlausibility``):
- a frame is *plausible* when all 7 floats are finite, ``|F| ≤ force_max``,
  ``|M| ≤ torque_max``, the temperature lies in ``temperature_range``, and no channel holds a
  denormal-looking magnitude (0 < |x| < 1e-12, typical of misaligned bytes);
- to *lock*, all 28 byte offsets are tried over ``lock_frames`` consecutive frames; an offset
  qualifies when every frame is plausible and the temperature changes by at most
  ``max_temperature_step`` between frames; if several qualify, the one whose temperature
  channel is steadiest wins;
- once locked, frames are taken 28 bytes at a time while they stay plausible and the
  temperature stays continuous with the previous frame; a failing frame is counted in
  ``frames_bad`` and the search restarts one byte later.

Why whole-field shifts cannot lock: with the default bounds a temperature (≥ 10 °C) can
never pass as a moment (≤ 5 N·m) and a moment can never pass as a temperature, and every
shift by 1–6 fields puts either the temperature into a moment slot or a moment into the
temperature slot. Byte shifts that are not whole fields mix the bytes of neighbouring floats,
which rarely yields four consecutive plausible frames with a steady temperature. The bounds
are constructor parameters for a sensor with a different range.
"""

from __future__ import annotations

import math
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import serial

from articutool.spec import Spec
from articutool.tool.drivers.base import FTDriver, FTSample
from articutool.tool.drivers.serial_port import open_nonblocking, read_available

__all__ = [
    "FRAME_LEN",
    "FramePlausibility",
    "ResenseFTDriver",
    "decode_frame",
    "encode_frame",
]

FRAME_LEN = 28
_FRAME = struct.Struct("<7f")


def decode_frame(b: bytes | bytearray | memoryview) -> tuple[float, ...]:
    """28 bytes → (Fx, Fy, Fz, Mx, My, Mz, T)."""
    return _FRAME.unpack(b)


def encode_frame(values: tuple[float, ...] | list[float]) -> bytes:
    """(Fx, Fy, Fz, Mx, My, Mz, T) → 28 bytes, as the sensor sends them."""
    return _FRAME.pack(*values)


@dataclass(frozen=True)
class FramePlausibility:
    """Bounds that recognise a correctly aligned frame (see the module docstring)."""

    force_max: float = 200.0  # N
    torque_max: float = 5.0  # N·m
    temperature_range: tuple[float, float] = (10.0, 80.0)  # °C
    max_temperature_step: float = 0.5  # °C between consecutive frames (100 Hz)
    lock_frames: int = 4

    def __post_init__(self) -> None:
        lo, hi = self.temperature_range
        if not (self.force_max > 0 and self.torque_max > 0 and lo < hi):
            raise ValueError("force_max and torque_max must be > 0 and temperature lo < hi")
        if self.max_temperature_step <= 0 or self.lock_frames < 2:
            raise ValueError("max_temperature_step must be > 0 and lock_frames >= 2")

    def plausible(self, v: tuple[float, ...]) -> bool:
        """Whether one decoded frame looks like a real reading."""
        if not all(math.isfinite(x) for x in v):
            return False
        if any(0.0 < abs(x) < 1e-12 for x in v):
            return False
        if any(abs(x) > self.force_max for x in v[0:3]):
            return False
        if any(abs(x) > self.torque_max for x in v[3:6]):
            return False
        lo, hi = self.temperature_range
        return lo <= v[6] <= hi


class ResenseFTDriver(FTDriver):
    """The HEX21 on ``port`` (default ``spec.ft.port``) at ``spec.ft.baudrate``.

    Counters: ``frames_ok``, ``frames_bad`` (rejected frames and abandoned 28-byte stretches
    while searching), ``bytes_skipped``.
    """

    def __init__(
        self,
        spec: Spec,
        port: str | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
        plausibility: FramePlausibility | None = None,
    ) -> None:
        super().__init__(spec.ft.tare_samples)
        self.port_name = port if port is not None else spec.ft.port
        self._baud = spec.ft.baudrate
        self._clock = clock
        self.plausibility = plausibility if plausibility is not None else FramePlausibility()
        self._ser: serial.Serial | None = None
        self._buf = bytearray()
        self._locked = False
        self._last_temp = math.nan
        self.frames_ok = 0
        self.frames_bad = 0
        self.bytes_skipped = 0

    @property
    def locked(self) -> bool:
        """Whether the frame alignment is currently known."""
        return self._locked

    def open(self) -> None:
        """Open the port non-blocking; alignment is searched afresh."""
        if self._ser is not None:
            return
        self._ser = open_nonblocking(self.port_name, self._baud, "F/T")
        self._buf.clear()
        self._locked = False

    def close(self) -> None:
        """Close the port."""
        if self._ser is not None:
            try:
                self._ser.close()
            finally:
                self._ser = None

    def _find_alignment(self) -> int | None:
        """Best byte offset in [0, 28) that passes the lock test, or None.

        Needs ``lock_frames`` frames plus 27 bytes buffered so every offset can be judged.
        """
        p = self.plausibility
        best: tuple[float, int] | None = None
        for off in range(FRAME_LEN):
            frames = []
            for k in range(p.lock_frames):
                start = off + k * FRAME_LEN
                v = decode_frame(self._buf[start : start + FRAME_LEN])
                if not p.plausible(v):
                    break
                frames.append(v)
            else:
                temps = np.array([f[6] for f in frames])
                steps = np.abs(np.diff(temps))
                if steps.max() <= p.max_temperature_step:
                    score = float(steps.sum())
                    if best is None or score < best[0]:
                        best = (score, off)
        return None if best is None else best[1]

    def _read_raw(self) -> list[FTSample]:
        self._buf += read_available(self._ser, self.port_name, "F/T")
        p = self.plausibility
        out: list[FTSample] = []
        now = self._clock()
        need = p.lock_frames * FRAME_LEN + FRAME_LEN - 1
        while True:
            if not self._locked:
                if len(self._buf) < need:
                    break
                off = self._find_alignment()
                if off is None:  # nothing in this stretch lines up: drop it
                    del self._buf[:FRAME_LEN]
                    self.bytes_skipped += FRAME_LEN
                    self.frames_bad += 1
                    continue
                if off:
                    del self._buf[:off]
                    self.bytes_skipped += off
                self._locked = True
                self._last_temp = math.nan
            if len(self._buf) < FRAME_LEN:
                break
            v = decode_frame(self._buf[:FRAME_LEN])
            continuous = math.isnan(self._last_temp) or (
                abs(v[6] - self._last_temp) <= p.max_temperature_step
            )
            if not (p.plausible(v) and continuous):
                self.frames_bad += 1
                self._locked = False
                del self._buf[:1]
                self.bytes_skipped += 1
                continue
            del self._buf[:FRAME_LEN]
            self._last_temp = v[6]
            self.frames_ok += 1
            out.append(
                FTSample(
                    force=np.array(v[0:3], dtype=np.float64),
                    torque=np.array(v[3:6], dtype=np.float64),
                    temperature=float(v[6]),
                    stamp=now,
                )
            )
        return out
