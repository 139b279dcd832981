"""Per-sample cost of the complementary filter (runs at 50 Hz on the tool's Raspberry Pi).

``ComplementaryFilter.update`` uses Python floats. ``_NumpyFilter`` is the same predict/correct
step written with small NumPy arrays (no input validation), kept here only to justify that choice
by measurement; it is checked against the real filter so the comparison stays honest.

Run: ``.venv/bin/python -m pytest benchmarks/test_bench_filter.py --benchmark-only``
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from articutool.spec import load_spec
from articutool.tool.filter import ComplementaryFilter

DT = 0.02
ACCEL = np.array([0.8, -1.9, 9.6])
GYRO = np.array([0.05, -0.03, 0.02])


def _warm_filter() -> ComplementaryFilter:
    f = ComplementaryFilter.from_spec(load_spec().filter)
    for _ in range(10):
        f.update(ACCEL, GYRO, DT)
    return f


class _NumpyFilter:
    """Array formulation of the same step (inverse-orientation state, adaptive gain, bias)."""

    def __init__(self, gain_acc: float, bias_alpha: float) -> None:
        self.gain_acc, self.bias_alpha = gain_acc, bias_alpha
        self.q = np.array([1.0, 0.0, 0.0, 0.0])
        self.bias = np.zeros(3)
        self.prev = np.zeros(3)

    def init(self, accel: np.ndarray) -> None:
        u = accel / np.linalg.norm(accel)
        w = math.sqrt((u[2] + 1) * 0.5)  # az >= 0 branch only (benchmark input)
        self.q = np.array([w, -u[1] / (2 * w), u[0] / (2 * w), 0.0])

    def update(self, accel: np.ndarray, gyro: np.ndarray, dt: float) -> np.ndarray:
        norm = np.linalg.norm(accel)
        if (
            abs(norm - 9.81) <= 0.1
            and (np.abs(gyro - self.prev) <= 0.01).all()
            and (np.abs(gyro - self.bias) <= 0.2).all()
        ):
            self.bias = self.bias + self.bias_alpha * (gyro - self.bias)
        self.prev = gyro
        rx, ry, rz = gyro - self.bias
        omega = np.array([[0, rx, ry, rz], [-rx, 0, rz, -ry], [-ry, -rz, 0, rx], [-rz, ry, -rx, 0]])
        p = self.q + 0.5 * dt * (omega @ self.q)
        p /= np.linalg.norm(p)
        w, x, y, z = p
        rot = np.array(
            [
                [w * w + x * x - y * y - z * z, 2 * (x * y + w * z), 2 * (x * z - w * y)],
                [2 * (x * y - w * z), w * w - x * x + y * y - z * z, 2 * (y * z + w * x)],
                [2 * (x * z + w * y), 2 * (y * z - w * x), w * w - x * x - y * y + z * z],
            ]
        )
        g = rot @ (accel / norm)
        d0 = math.sqrt((g[2] + 1) * 0.5)
        d = np.array([d0, -g[1] / (2 * d0), g[0] / (2 * d0), 0.0])
        err = abs(norm - 9.81) / 9.81
        factor = 1.0 if err < 0.1 else (-10.0 * err + 2.0 if err < 0.2 else 0.0)
        gain = factor * self.gain_acc
        if d0 <= 0.9:
            angle = math.acos(d0)
            a, b = math.sin(angle * (1 - gain)) / math.sin(angle), math.sin(angle * gain)
            d = b / math.sin(angle) * d
            d[0] += a
        else:
            d = gain * d
            d[0] += 1.0 - gain
        d /= np.linalg.norm(d)
        pw, pv = p[0], p[1:]
        dw, dv = d[0], d[1:]
        r = np.concatenate([[pw * dw - pv @ dv], pw * dv + dw * pv + np.cross(pv, dv)])
        self.q = r / np.linalg.norm(r)
        return self.q * np.array([1.0, -1.0, -1.0, -1.0])


def test_numpy_variant_matches_filter():
    spec = load_spec().filter
    f = ComplementaryFilter.from_spec(spec)
    g = _NumpyFilter(spec.gain_acc, spec.bias_alpha)
    f.update(ACCEL, GYRO, DT)
    g.init(ACCEL)
    rng = np.random.default_rng(0)
    for _ in range(200):
        a = ACCEL + rng.normal(0, 0.3, 3)
        w = GYRO + rng.normal(0, 0.5, 3)
        np.testing.assert_allclose(f.update(a, w, DT), g.update(a, w, DT), atol=1e-12)


def test_bench_update_python_floats(benchmark):
    f = _warm_filter()
    q = benchmark(f.update, ACCEL, GYRO, DT)
    assert np.isfinite(q).all()


def test_bench_update_from_lists(benchmark):
    """Driver-shaped input (plain lists/tuples) skips nothing but the array wrapper."""
    f = _warm_filter()
    q = benchmark(f.update, ACCEL.tolist(), GYRO.tolist(), DT)
    assert np.isfinite(q).all()


def test_bench_update_numpy_variant(benchmark):
    spec = load_spec().filter
    g = _NumpyFilter(spec.gain_acc, spec.bias_alpha)
    g.init(ACCEL)
    q = benchmark(g.update, ACCEL, GYRO, DT)
    assert np.isfinite(q).all()


@pytest.mark.parametrize("n", [500])
def test_bench_stream_of_samples(benchmark, n):
    """10 s of 50 Hz samples through a fresh filter (includes the initialisation)."""
    rng = np.random.default_rng(1)
    accel = ACCEL + rng.normal(0, 0.01, (n, 3))
    gyro = GYRO + rng.normal(0, 0.001, (n, 3))
    spec = load_spec().filter

    def run() -> np.ndarray:
        f = ComplementaryFilter.from_spec(spec)
        for k in range(n):
            q = f.update(accel[k], gyro[k], DT)
        return q

    assert np.isfinite(benchmark(run)).all()
