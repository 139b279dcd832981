"""A spoon's dish as a closed triangle mesh: the boundary a particle liquid is poured into.

The same dish as :mod:`articutool.food.dish` (the one the physics world collides with and
:mod:`articutool.food.hydrostatics` integrates), in the utensil frame: the floor's inner
surface at ``x = x0`` (the spec's ``tip_x``), the opening towards +x, the dish centred at
``z = zc``. The shell is a solid of the utensil's thickness: its inner surface is the ideal
dish (floor and 45° walls up to the rim), its outer surface the same dish moved down by the
thickness along the walls' normal (√2 × the thickness along x for 45° walls), and a flat lip
at the rim's height joins the two. Normals point out of the solid (into the liquid on the
inner surface).

Each cross-section is a polygon of ``segments`` vertices whose area equals its ellipse's (the
vertices lie on the ellipse scaled by √(θ / sin θ), θ = 2π / segments), so the cavity the
inner surface and the rim plane close holds the dish's level capacity to the quadrature's
accuracy.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from articutool.food.dish import Dish

__all__ = ["dish_boundary_mesh", "dish_cavity_mesh", "mesh_volume"]


def _ring(dish: Dish, h: float, segments: int, scale: float) -> NDArray[np.float64]:
    """The polygon of the cross-section ``h`` above the floor (dish coordinates: along, across,
    up), area-preserving."""
    A, B = dish.semi_axes(h)
    phi = 2.0 * math.pi * np.arange(segments) / segments
    return np.column_stack([scale * A * np.cos(phi), scale * B * np.sin(phi),
                            np.full(segments, h)])


def _band(lo: int, hi: int, n: int, flip: bool) -> list[tuple[int, int, int]]:
    """Triangles joining ring ``lo`` to ring ``hi`` (vertex offsets, ``n`` each)."""
    tris = []
    for k in range(n):
        k1 = (k + 1) % n
        a, b, c, d = lo + k, lo + k1, hi + k1, hi + k
        tris += [(a, b, c), (a, c, d)] if not flip else [(a, c, b), (a, d, c)]
    return tris


def _fan(centre: int, ring: int, n: int, flip: bool) -> list[tuple[int, int, int]]:
    return [(centre, ring + (k + 1) % n, ring + k) if not flip else
            (centre, ring + k, ring + (k + 1) % n) for k in range(n)]


def _to_utensil(p: NDArray[np.float64], f: list[tuple[int, int, int]], dish: Dish, x0: float
                ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    # Dish coordinates (along, across, up from the floor) → utensil frame (x up, y, z along):
    # a reflection, so every triangle's winding is reversed to keep its normal.
    v = np.column_stack([x0 + p[:, 2], p[:, 1], dish.zc + p[:, 0]])
    return v, np.asarray(f, dtype=np.int64)[:, ::-1].copy()


def _check(dish: Dish, segments: int, rings: int) -> float:
    if segments < 8 or rings < 1:
        raise ValueError(f"segments must be >= 8 and rings >= 1; got {segments}, {rings}")
    if not (dish.depth > 0 and 0 < dish.a0 <= dish.a and 0 < dish.b0 <= dish.b):
        raise ValueError(f"not a dish: {dish}")
    th = 2.0 * math.pi / segments
    return math.sqrt(th / math.sin(th))


def dish_cavity_mesh(dish: Dish, x0: float, segments: int = 64, rings: int = 4
                     ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The space the level dish holds (floor, walls, the rim plane as a lid), closed, normals
    outward, in the utensil frame: its volume is the level capacity."""
    scale = _check(dish, segments, rings)
    hs = np.linspace(0.0, dish.depth, rings + 1)
    pts = [np.array([[0.0, 0.0, 0.0]])] + [_ring(dish, h, segments, scale) for h in hs]
    pts.append(np.array([[0.0, 0.0, dish.depth]]))
    v = np.concatenate(pts)
    n, top = segments, len(v) - 1
    f = _fan(0, 1, n, flip=False)  # floor, facing −up
    for i in range(rings):
        f += _band(1 + i * n, 1 + (i + 1) * n, n, flip=False)
    f += _fan(top, 1 + rings * n, n, flip=True)  # the lid, facing +up
    return _to_utensil(v, f, dish, x0)


def dish_boundary_mesh(dish: Dish, x0: float, thickness: float, segments: int = 64,
                       rings: int = 4) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The dish's shell, ``thickness`` thick (m), as a closed triangle mesh in the utensil
    frame (``x0``: the floor's inner surface, the spec's ``tip_x``): (vertices (n, 3) m,
    faces (m, 3) vertex indices, counter-clockwise seen from outside the solid)."""
    scale = _check(dish, segments, rings)
    if not (math.isfinite(thickness) and thickness > 0):
        raise ValueError(f"thickness must be > 0 m; got {thickness}")
    # The outer surface is the inner one moved down by the wall's normal offset.
    slope = math.hypot(1.0, max((dish.a - dish.a0), (dish.b - dish.b0)) / dish.depth)
    drop = thickness * slope
    hs = np.linspace(0.0, dish.depth, rings + 1)
    n = segments
    inner = [_ring(dish, h, n, scale) for h in hs]
    outer = []
    for h in hs:
        r = _ring(dish, h + drop if h == hs[-1] else h, n, scale)  # the lip's outer edge
        r[:, 2] = h - drop if h < hs[-1] else dish.depth
        outer.append(r)
    v = np.concatenate([np.array([[0.0, 0.0, 0.0]]), *inner,
                        np.array([[0.0, 0.0, -drop]]), *outer])
    ci, co = 0, 1 + len(hs) * n
    i0, o0 = 1, co + 1
    f = _fan(ci, i0, n, flip=True)  # the inner floor faces up, into the liquid
    for i in range(rings):
        f += _band(i0 + i * n, i0 + (i + 1) * n, n, flip=True)  # inner walls face inwards
    f += _band(i0 + rings * n, o0 + rings * n, n, flip=True)  # the lip faces up
    for i in range(rings):
        f += _band(o0 + i * n, o0 + (i + 1) * n, n, flip=False)  # outer walls face out
    f += _fan(co, o0, n, flip=False)  # the outer floor faces down
    return _to_utensil(v, f, dish, x0)


def mesh_volume(vertices: NDArray[np.float64], faces: NDArray[np.int64]) -> float:
    """Signed volume (m³) a closed mesh encloses (positive for outward normals)."""
    a, b, c = (vertices[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)
