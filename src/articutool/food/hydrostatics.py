"""Hydrostatics of a liquid in a spoon's dish: what it holds level, tilted, and after a tilt
history.

A liquid at rest in an accelerating dish has a plane free surface normal to the apparent
gravity ``g − a`` (the dish's acceleration ``a`` subtracted from gravity, both in the dish
frame). The liquid occupies the dish below that plane. It can rise no higher than the lowest
point of the rim along the surface normal: the dish's *capacity* for a surface normal ``n`` is
the volume of the dish below the plane ``n·p = min_rim n·p``. A volume ``V`` in the dish keeps
``min(V, capacity(n))``; the rest runs over the rim. Spilled liquid does not come back, so
along a tilt history the retained volume is the running minimum of the capacities
(quasi-static: no inertia of the liquid, no surface tension — the meniscus a real spoon pins
at its rim is worth a few degrees, the capillary length of water being 2.7 mm). The liquid's
own inertia (slosh) is ``articutool.food.slosh``, which tilts the surface this module turns
into spilled volume.

Frame: the dish frame has its origin at the floor's centre and the utensil frame's axes —
``x`` the dish normal (out of the opening), ``y`` across the dish, ``z`` along it towards the
tip. A *tilt* ``θ`` is the angle between the surface normal and ``x``; its *direction* ``φ``
says which side is low: ``φ = 0`` the tip (``+z``) low ("over the tip"), ``φ = π/2`` the
``+y`` side low ("sideways"); the up vector is ``(cos θ, −sin θ sin φ, −sin θ cos φ)``.

The dish is the one in :mod:`articutool.food.dish` (the geometry the physics world is built
from). Its cross-section at height ``x`` is an ellipse whose semi-axes are linear in ``x``, so
the volume below a plane is a one-dimensional integral of elliptic segment areas; the plane
meets the section's boundary where a quadratic in ``x`` vanishes, and Gauss–Legendre
quadrature between those roots integrates it to ~1e-6 relative. Volumes in m³; multiply by a
density for a mass.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.food.dish import Dish

__all__ = [
    "SIDE",
    "TIP",
    "Hydrostatics",
    "tilt_direction",
    "up_vector",
]

TIP = 0.0  # direction of a tilt over the tip (rad)
SIDE = 0.5 * math.pi  # direction of a sideways tilt (rad)

_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)
_TABLE_TILT_STEP = math.radians(0.25)
_TABLE_DIR_STEP = math.radians(2.5)


def up_vector(tilt: ArrayLike, direction: ArrayLike = TIP) -> NDArray[np.float64]:
    """Unit surface normal (dish frame) of a tilt ``θ`` towards ``φ`` (rad), shape (..., 3)."""
    t, d = np.broadcast_arrays(np.asarray(tilt, dtype=float), np.asarray(direction, dtype=float))
    s = np.sin(t)
    return np.stack([np.cos(t), -s * np.sin(d), -s * np.cos(d)], axis=-1)


def tilt_direction(up: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Tilt ``θ`` ∈ [0, π] and direction ``φ`` ∈ (−π, π] (rad) of surface normals (..., 3)
    (any length; the inverse of :func:`up_vector`)."""
    u = np.asarray(up, dtype=float)
    horiz = np.hypot(u[..., 1], u[..., 2])
    return np.arctan2(horiz, u[..., 0]), np.arctan2(-u[..., 1], -u[..., 2])


def _normalise_up(up: ArrayLike) -> NDArray[np.float64]:
    u = np.asarray(up, dtype=float)
    if u.shape[-1:] != (3,):
        raise ValueError(f"a direction is a 3-vector; got shape {u.shape}")
    n = np.linalg.norm(u, axis=-1, keepdims=True)
    if not np.all(np.isfinite(u)) or np.any(n < 1e-12):
        raise ValueError("a surface normal (or apparent gravity) must be finite and non-zero")
    return u / n


class Hydrostatics:
    """A dish's hydrostatics: level capacity, fill height, capacity and spill at any tilt.

    Directions are *up* vectors of the free surface (the surface normal, pointing out of the
    liquid). From an apparent gravity ``g_app = g − a`` (dish frame) the up vector is
    ``−g_app``; the ``*_g`` methods take ``g_app`` directly. Everything is vectorised over
    leading axes.
    """

    def __init__(self, dish: Dish) -> None:
        if not (dish.depth > 0 and dish.a > 0 and dish.b > 0 and 0 < dish.a0 <= dish.a
                and 0 < dish.b0 <= dish.b):
            raise ValueError(f"not a dish: {dish}")
        self.dish = dish

    # ------------------------------------------------------------------ level liquid --
    @cached_property
    def level_capacity(self) -> float:
        """Volume (m³) the level dish holds to its rim."""
        return float(self.dish.level_volume(self.dish.depth))

    def fill_height(self, volume: float) -> float:
        """Height (m) of a level liquid of ``volume`` (m³) above the floor; ``ValueError``
        outside [0, level capacity]."""
        v = float(volume)
        if not (0.0 <= v <= self.level_capacity):
            raise ValueError(f"volume {v * 1e6:.4g} mL outside [0, "
                             f"{self.level_capacity * 1e6:.4g}] mL (the level capacity)")
        lo, hi = 0.0, self.dish.depth
        for _ in range(60):  # the level volume is increasing in the height
            mid = 0.5 * (lo + hi)
            if self.dish.level_volume(mid) < v:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)

    # ------------------------------------------------------------- the volume below --
    def volume_below(self, up: ArrayLike, level: ArrayLike) -> NDArray[np.float64]:
        """Volume (m³) of the dish where ``n·p ≤ level`` (``n`` the unit ``up`` vector,
        ``p`` from the floor's centre, m)."""
        n = _normalise_up(up)
        c = np.asarray(level, dtype=float)
        n, c = np.broadcast_arrays(n, c[..., None])
        c = c[..., 0]
        d = self.dish
        al, be = (d.a - d.a0) / d.depth, (d.b - d.b0) / d.depth
        nx, ny, nz = n[..., 0], n[..., 1], n[..., 2]
        # The plane meets a section's boundary where (c − nx·x)² = (ny·B)² + (nz·A)²,
        # a quadratic q2·x² + q1·x + q0 = 0; between its roots the integrand is smooth.
        q2 = nx ** 2 - (ny * be) ** 2 - (nz * al) ** 2
        q1 = -2.0 * c * nx - 2.0 * ny ** 2 * d.b0 * be - 2.0 * nz ** 2 * d.a0 * al
        q0 = c ** 2 - (ny * d.b0) ** 2 - (nz * d.a0) ** 2
        with np.errstate(invalid="ignore", divide="ignore"):
            disc = q1 ** 2 - 4.0 * q2 * q0
            sq = np.sqrt(np.where(disc >= 0, disc, np.nan))
            # stable roots; a vanishing q2 leaves the linear root −q0/q1
            qq = -0.5 * (q1 + np.copysign(sq, q1))
            r1 = np.where(np.abs(q2) > 1e-15, qq / q2, -q0 / q1)
            r2 = q0 / qq
        roots = np.stack([r1, r2], axis=-1)
        roots = np.where(np.isfinite(roots), np.clip(roots, 0.0, d.depth), 0.0)
        edges = np.sort(np.concatenate(
            [np.zeros(c.shape + (1,)), roots, np.full(c.shape + (1,), d.depth)], axis=-1),
            axis=-1)
        lo, hi = edges[..., :-1, None], edges[..., 1:, None]  # (..., 3, 1)
        x = 0.5 * (hi + lo) + 0.5 * (hi - lo) * _GL_X  # (..., 3, K)
        A, B = d.semi_axes(x)
        m = np.hypot(ny[..., None, None] * B, nz[..., None, None] * A)
        rhs = c[..., None, None] - nx[..., None, None] * x
        # a level section (m = 0) is all below the plane or all above it
        s = np.clip(np.where(m > 0, rhs / np.where(m > 0, m, 1.0),
                             np.where(rhs >= 0, 1.0, -1.0)), -1.0, 1.0)
        seg = np.pi - np.arccos(s) + s * np.sqrt(1.0 - s * s)  # unit disc below s
        area = A * B * seg
        vol = np.sum(0.5 * (hi - lo)[..., 0] * np.sum(area * _GL_W, axis=-1), axis=-1)
        return np.maximum(vol, 0.0)  # never below zero by rounding

    def rim_level(self, up: ArrayLike) -> NDArray[np.float64]:
        """``min over the rim of n·p``: the highest surface level before liquid runs out."""
        n = _normalise_up(up)
        d = self.dish
        return n[..., 0] * d.depth - np.hypot(n[..., 1] * d.b, n[..., 2] * d.a)

    # ------------------------------------------------------------- capacity and spill --
    def capacity(self, up: ArrayLike) -> NDArray[np.float64]:
        """Volume (m³) the dish holds with its liquid's surface normal ``up`` (dish frame)."""
        return self.volume_below(up, self.rim_level(up))

    def capacity_at(self, tilt: ArrayLike, direction: ArrayLike = TIP) -> NDArray[np.float64]:
        """Capacity (m³) at a tilt ``θ`` towards ``φ`` (rad)."""
        return self.capacity(up_vector(tilt, direction))

    def retained(self, volume: ArrayLike, up: ArrayLike) -> NDArray[np.float64]:
        """What a ``volume`` (m³) keeps under a surface normal ``up``: ``min(V, capacity)``."""
        return np.minimum(np.asarray(volume, dtype=float), self.capacity(up))

    def spilled(self, volume: ArrayLike, up: ArrayLike) -> NDArray[np.float64]:
        """What runs over the rim (m³) when a ``volume`` at rest is tilted to ``up``."""
        v = np.asarray(volume, dtype=float)
        return v - np.minimum(v, self.capacity(up))

    def retained_g(self, volume: ArrayLike, g_app: ArrayLike) -> NDArray[np.float64]:
        """:meth:`retained` under an apparent gravity ``g − a`` (dish frame, any units)."""
        return self.retained(volume, -np.asarray(g_app, dtype=float))

    def spilled_g(self, volume: ArrayLike, g_app: ArrayLike) -> NDArray[np.float64]:
        """:meth:`spilled` under an apparent gravity ``g − a`` (dish frame, any units)."""
        return self.spilled(volume, -np.asarray(g_app, dtype=float))

    def retained_history(self, volume: float, up: ArrayLike,
                         fast: bool = False) -> NDArray[np.float64]:
        """Volume (m³) in the dish after each surface normal of a history ``up`` (N, 3):
        the running minimum of the capacities, capped by the initial ``volume`` (spilled
        liquid does not return). ``fast`` interpolates the capacity table
        (:meth:`capacity_fast`, ~1e-9 m³ off) instead of integrating every sample."""
        u = _normalise_up(up)
        cap = self.capacity_fast(*tilt_direction(u)) if fast else self.capacity(u)
        return np.minimum(float(volume), np.minimum.accumulate(np.atleast_1d(cap)))

    def onset_tilt(self, volume: float, direction: ArrayLike = TIP) -> NDArray[np.float64]:
        """Smallest tilt (rad) towards ``direction`` at which a ``volume`` starts to spill
        (bisection: the capacity falls as the tilt grows). 0 for a volume at or above the
        level capacity."""
        v = float(volume)
        d = np.asarray(direction, dtype=float)
        lo, hi = np.zeros(d.shape), np.full(d.shape, math.pi)
        if v >= self.level_capacity:
            return lo
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            holds = self.capacity_at(mid, d) >= v
            lo, hi = np.where(holds, mid, lo), np.where(holds, hi, mid)
        return 0.5 * (lo + hi)

    # ------------------------------------------------------- tabulated, for speed --
    @cached_property
    def _table(self) -> NDArray[np.float64]:
        # Capacity on a (tilt, direction) grid: tilts 0..π, directions 0..π/2 (the dish is
        # symmetric about both its axes, so |φ| folded into [0, π/2] covers every direction).
        tilts = np.arange(0.0, math.pi + 0.5 * _TABLE_TILT_STEP, _TABLE_TILT_STEP)
        dirs = np.arange(0.0, 0.5 * math.pi + 0.5 * _TABLE_DIR_STEP, _TABLE_DIR_STEP)
        T, D = np.meshgrid(tilts, dirs, indexing="ij")
        return self.capacity_at(T, D)

    def capacity_fast(self, tilt: ArrayLike, direction: ArrayLike = TIP) -> NDArray[np.float64]:
        """Capacity (m³) interpolated bilinearly in a table of tilt (0.25° steps) × direction
        (2.5° steps) built once per dish (~0.2 s): a few µs for a whole trajectory, within
        ~1e-9 m³ (1 mg of water) of :meth:`capacity_at`."""
        table = self._table
        t = np.clip(np.asarray(tilt, dtype=float), 0.0, math.pi) / _TABLE_TILT_STEP
        p = np.abs(np.asarray(direction, dtype=float))
        p = np.where(p > 0.5 * math.pi, math.pi - p, p) / _TABLE_DIR_STEP
        t, p = np.broadcast_arrays(t, p)
        i = np.minimum(t.astype(int), table.shape[0] - 2)
        j = np.minimum(p.astype(int), table.shape[1] - 2)
        ft, fp = t - i, p - j
        return ((1 - ft) * ((1 - fp) * table[i, j] + fp * table[i, j + 1])
                + ft * ((1 - fp) * table[i + 1, j] + fp * table[i + 1, j + 1]))
