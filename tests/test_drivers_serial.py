"""IMU (OpenLog Artemis CSV) and F/T (Resense HEX21 frames) drivers on pseudo-terminals.

The real drivers open the pty's slave path through pyserial; the test writes real byte
streams — clean, garbage, short, corrupt and split — into the master side.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from articutool.tool.drivers.base import DriverError
from articutool.tool.drivers.ft import (
    FRAME_LEN,
    FramePlausibility,
    ResenseFTDriver,
    encode_frame,
)
from articutool.tool.drivers.imu import OpenLogImuDriver, parse_openlog_line
from conftest import packaged_spec

SPEC = packaged_spec()
G = SPEC.imu.gravity
HEADER = b"rtcDate,rtcTime,aX,aY,aZ,gX,gY,gZ,mX,mY,mZ,imu_degC,output_Hz,\r\n"


@pytest.fixture
def pty() -> Iterator[tuple[int, str]]:
    master, slave = os.openpty()
    yield master, os.ttyname(slave)
    os.close(slave)
    os.close(master)


def collect(read_all: Callable[[], list], done: Callable[[list], bool], wait: float = 5.0) -> list:
    """Poll a non-blocking driver until ``done`` (pty delivery is asynchronous). The deadline
    only bounds a failing test; nothing about timing is asserted."""
    got: list = []
    deadline = time.monotonic() + wait
    while True:
        got += read_all()
        if done(got) or time.monotonic() > deadline:
            return got
        time.sleep(0.002)


def imu_line(acc_mg: tuple[float, float, float], gyro_dps: tuple[float, float, float]) -> bytes:
    f = [*acc_mg, *gyro_dps, -28.5, 16.2, -38.1, 27.83, 49.998]
    return ("01/07/2000,00:03:18.45," + ",".join(f"{v:.3f}" for v in f) + ",\r\n").encode()


# ------------------------------------------------------------------------------ IMU ------
@pytest.fixture
def imu(pty: tuple[int, str]) -> Iterator[tuple[OpenLogImuDriver, int]]:
    master, path = pty
    t = iter(range(10**9))
    drv = OpenLogImuDriver(SPEC, port=path, clock=lambda: float(next(t)))
    drv.open()
    yield drv, master
    drv.close()


def test_imu_units_and_header(imu: tuple[OpenLogImuDriver, int]) -> None:
    drv, master = imu
    os.write(master, HEADER + imu_line((-12.7, 4.88, 1005.37), (0.15, -0.53, 90.0)))
    got = collect(drv.read_all, lambda g: len(g) >= 1)
    assert len(got) == 1
    s = got[0]
    np.testing.assert_allclose(s.accel, np.array([-12.7, 4.88, 1005.37]) * G / 1000.0)
    np.testing.assert_allclose(s.gyro, np.radians([0.15, -0.53, 90.0]))
    assert s.temperature == pytest.approx(27.83)
    assert drv.lines_ok == 1 and drv.lines_bad == 1  # the header is skipped and counted


def test_imu_garbage_short_and_corrupt_lines_are_skipped_and_counted(
    imu: tuple[OpenLogImuDriver, int],
) -> None:
    drv, master = imu
    good = [((i, -i, 1000.0 + i), (0.1 * i, 0.0, -0.1 * i)) for i in range(6)]
    full = imu_line(*good[0])
    bad_lines = [
        b"\x00\xff\xfe\x80garbage\xc3\x28\r\n",  # non-ASCII noise
        b"01/07/2000,00:03:18.45,1.0,2.0\r\n",  # short
        full[: len(full) // 2] + b"\r\n",  # truncated
        full.replace(b"1000.000", b"10x0.000"),  # non-numeric
        full.replace(b"1000.000", b"nan"),  # NaN
        full.replace(b"1000.000", b"inf"),
        full.replace(b"1000.000", b"99999.0"),  # beyond ±16 g: corruption
        b"3.67,3.42,1009.77,0.53,-0.15,-0.09,-6.60,40.35,-40.65,29.15,49.821,7,8,\r\n",
        b"1,2,3,4,5,6,7,8,9,10,11,12,13,14,15,16\r\n",  # too many fields
        b"Menu: press any key\r\n",
    ]
    stream = HEADER
    for k, (acc, gyro) in enumerate(good):
        stream += imu_line(acc, gyro)
        stream += b"".join(bad_lines[k :: len(good)])
    os.write(master, stream)
    got = collect(drv.read_all, lambda g: len(g) >= len(good))
    assert len(got) == len(good)
    for s, (acc, gyro) in zip(got, good, strict=True):
        np.testing.assert_allclose(s.accel, np.array(acc) * G / 1000.0, atol=1e-9)
        np.testing.assert_allclose(s.gyro, np.radians(gyro), atol=1e-9)
    assert drv.lines_ok == len(good)
    assert drv.lines_bad == len(bad_lines) + 1  # + header


def test_imu_partial_lines_across_reads(imu: tuple[OpenLogImuDriver, int]) -> None:
    drv, master = imu
    line = imu_line((1.0, 2.0, 3.0), (4.0, 5.0, 6.0))
    os.write(master, line[:17])
    assert collect(drv.read_all, lambda g: False, wait=0.05) == []
    os.write(master, line[17:40])
    assert collect(drv.read_all, lambda g: False, wait=0.05) == []
    os.write(master, line[40:] + line[:5])
    got = collect(drv.read_all, lambda g: len(g) >= 1)
    assert len(got) == 1 and drv.lines_bad == 0
    np.testing.assert_allclose(got[0].accel, np.array([1.0, 2.0, 3.0]) * G / 1000.0)


def test_imu_runaway_garbage_without_newline_is_dropped(
    imu: tuple[OpenLogImuDriver, int],
) -> None:
    drv, master = imu
    os.write(master, bytes(range(14, 250)) * 4)  # ~1 kB, no newline
    collect(drv.read_all, lambda g: drv.lines_bad >= 1)
    assert drv.lines_bad == 1
    os.write(master, b"\n" + imu_line((0.0, 0.0, 1000.0), (0.0, 0.0, 0.0)))
    got = collect(drv.read_all, lambda g: len(g) >= 1)
    assert len(got) == 1
    assert got[0].accel[2] == pytest.approx(G)


def test_imu_read_returns_newest(imu: tuple[OpenLogImuDriver, int]) -> None:
    drv, master = imu
    os.write(master, b"".join(imu_line((0, 0, 1000.0), (k, 0, 0)) for k in range(5)))
    collect(lambda: [], lambda g: False, wait=0.05)
    s = collect(lambda: [x] if (x := drv.read()) else [], lambda g: len(g) >= 1)
    assert s[-1].gyro[0] == pytest.approx(math.radians(4))
    assert drv.read() is None


def test_imu_open_errors() -> None:
    drv = OpenLogImuDriver(SPEC, port="/dev/definitely-not-a-port")
    with pytest.raises(DriverError, match="not open"):
        drv.read()
    with pytest.raises(DriverError, match="cannot open IMU port"):
        drv.open()


@given(st.text(max_size=200))
def test_parse_never_raises(text: str) -> None:
    r = parse_openlog_line(text, G)
    assert r is None or (np.isfinite(r[0]).all() and np.isfinite(r[1]).all())


@given(
    st.lists(st.floats(-16000, 16000), min_size=3, max_size=3),
    st.lists(st.floats(-2000, 2000), min_size=3, max_size=3),
)
def test_parse_roundtrip(acc: list[float], gyro: list[float]) -> None:
    line = "01/07/2000,00:03:18.45," + ",".join(repr(v) for v in [*acc, *gyro]) + ",1,2,3,25,50,"
    r = parse_openlog_line(line, G)
    assert r is not None
    np.testing.assert_allclose(r[0], np.array(acc) * G / 1000.0)
    np.testing.assert_allclose(r[1], np.radians(gyro))


# ------------------------------------------------------------------------------- F/T -----
def ft_frames(
    n: int, seed: int = 0, fz: float = 1.5, temp: float = 31.2, force_noise: float = 0.3
) -> list[tuple]:
    """Realistic frames: small noisy forces/moments, a slowly drifting temperature."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        f = rng.normal(0, force_noise, 3) + [0.2, -0.4, fz]
        m = rng.normal(0, 0.01, 3)
        t = temp + 0.001 * k + rng.normal(0, 0.02)
        # float32 round trip so expected values compare exactly
        out.append(tuple(float(np.float32(x)) for x in (*f, *m, t)))
    return out


def as_tuples(samples: list) -> list[tuple]:
    return [(*s.force, *s.torque, s.temperature) for s in samples]


@pytest.fixture
def ft(pty: tuple[int, str]) -> Iterator[tuple[ResenseFTDriver, int]]:
    master, path = pty
    drv = ResenseFTDriver(SPEC, port=path)
    drv.open()
    yield drv, master
    drv.close()


def test_ft_clean_stream(ft: tuple[ResenseFTDriver, int]) -> None:
    drv, master = ft
    frames = ft_frames(30)
    os.write(master, b"".join(encode_frame(f) for f in frames) + encode_frame(frames[0])[:11])
    got = collect(drv.read_all, lambda g: len(g) >= 30)
    assert as_tuples(got) == frames  # the trailing short frame waits in the buffer
    assert drv.frames_ok == 30 and drv.frames_bad == 0 and drv.locked


def test_ft_resyncs_after_garbage_prefix_and_mid_frame_start(
    ft: tuple[ResenseFTDriver, int],
) -> None:
    drv, master = ft
    rng = np.random.default_rng(7)
    frames = ft_frames(40, seed=1)
    garbage = rng.integers(0, 256, 100, dtype=np.uint8).tobytes()
    stream = garbage + b"".join(encode_frame(f) for f in frames)[10:]  # starts mid-frame
    os.write(master, stream)
    got = collect(drv.read_all, lambda g: len(g) >= 39)
    assert as_tuples(got) == frames[1:]
    assert drv.bytes_skipped == 100 + FRAME_LEN - 10
    assert drv.frames_bad >= 1


def test_ft_rejects_corrupt_frames_and_relocks(ft: tuple[ResenseFTDriver, int]) -> None:
    drv, master = ft
    frames = ft_frames(60, seed=2)
    nan_frame = (math.nan, *frames[20][1:])
    hot_frame = (*frames[40][:6], 79.0)  # a temperature jump: not a real reading
    parts = [encode_frame(f) for f in frames]
    stream = (
        b"".join(parts[:10])
        + b"\x13\x37\xff\x00\x42"  # inserted garbage
        + b"".join(parts[10:20])
        + encode_frame(nan_frame)
        + b"".join(parts[20:40])
        + encode_frame(hot_frame)
        + parts[40][:13]  # a short (truncated) frame
        + b"".join(parts[40:])
    )
    os.write(master, stream)
    got = collect(drv.read_all, lambda g: len(g) >= 60)
    assert as_tuples(got) == frames
    assert drv.frames_bad >= 4


def test_ft_field_shift_cannot_lock_even_when_a_force_looks_like_a_temperature(
    ft: tuple[ResenseFTDriver, int],
) -> None:
    drv, master = ft
    # Fz ≈ 24 N, steadier than the temperature itself: temperature-like in every respect
    frames = ft_frames(30, seed=3, fz=24.0, temp=25.0, force_noise=0.005)
    stream = b"".join(encode_frame(f) for f in frames)
    os.write(master, stream[8:])  # cut two whole fields: a float-aligned wrong start
    got = collect(drv.read_all, lambda g: len(g) >= 29)
    assert as_tuples(got) == frames[1:]


def test_ft_tare(ft: tuple[ResenseFTDriver, int]) -> None:
    drv, master = ft
    frames = ft_frames(30, seed=4)
    drv.tare(10)
    assert drv.tare_pending
    os.write(master, b"".join(encode_frame(f) for f in frames))
    got = collect(drv.read_all, lambda g: len(g) >= 30)
    assert not drv.tare_pending
    raw = np.array(frames)[:, :6]
    offset = raw[:10].mean(axis=0)
    np.testing.assert_allclose(drv.offset, offset)
    np.testing.assert_allclose(np.array(as_tuples(got))[9:, :6], raw[9:] - offset, atol=1e-12)
    np.testing.assert_allclose(np.array(as_tuples(got))[:9, :6], raw[:9])  # before the tare
    assert [s.temperature for s in got] == [f[6] for f in frames]  # temperature is not tared
    for bad in (0, -3, 1.5, True):
        with pytest.raises(ValueError, match="tare n"):
            drv.tare(bad)  # type: ignore[arg-type]


def test_ft_pure_noise_never_locks(ft: tuple[ResenseFTDriver, int]) -> None:
    drv, master = ft
    noise = np.random.default_rng(11).integers(0, 256, 4000, dtype=np.uint8).tobytes()
    os.write(master, noise)
    collect(drv.read_all, lambda g: drv.bytes_skipped >= 3800)
    assert drv.frames_ok == 0 and not drv.locked


def test_ft_plausibility_bounds_are_validated() -> None:
    with pytest.raises(ValueError):
        FramePlausibility(temperature_range=(50.0, 10.0))
    with pytest.raises(ValueError):
        FramePlausibility(lock_frames=1)
    drv = ResenseFTDriver(SPEC, port="/dev/definitely-not-a-port")
    with pytest.raises(DriverError, match="cannot open F/T port"):
        drv.open()
