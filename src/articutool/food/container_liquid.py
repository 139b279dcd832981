"""A liquid's open cylindrical container (the scene's bowl) as a closed boundary mesh, and a
fill of particles on a lattice inside it.

The container is the scene's :class:`~articutool.arm.scene.Cylinder` with a
``container_wall``: the geometry MuJoCo collides with (a floor and a wall of that thickness),
here in the cylinder's own frame (centred on the origin, axis along z). The mesh is a solid:
the profile outer floor → outer wall → rim → inner wall → inner floor turned about z, with
normals out of the solid (into the liquid on the inside).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["container_boundary_mesh", "container_fill"]


def container_boundary_mesh(radius: float, length: float, wall: float, segments: int = 96
                            ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """(vertices (m), faces) of the open container of outer ``radius``, height ``length`` and
    ``wall`` thickness, centred on the origin (see the module doc)."""
    if not (0 < wall < radius and 2 * wall < length and segments >= 8):
        raise ValueError(f"need 0 < wall < radius, 2·wall < length, segments >= 8; got "
                         f"{radius}, {length}, {wall}, {segments}")
    h = length / 2.0
    ri = radius - wall
    prof = [(radius, -h), (radius, h), (ri, h), (ri, -h + wall)]
    phi = 2.0 * math.pi * np.arange(segments) / segments
    verts = [np.array([[0.0, 0.0, -h]])]
    for rr, z in prof:
        verts.append(np.column_stack([rr * np.cos(phi), rr * np.sin(phi), np.full(segments, z)]))
    verts.append(np.array([[0.0, 0.0, -h + wall]]))
    v = np.concatenate(verts)
    n = segments
    bottom, top = 0, len(v) - 1
    f: list[tuple[int, int, int]] = [(bottom, 1 + (k + 1) % n, 1 + k) for k in range(n)]
    for i in range(len(prof) - 1):
        lo, hi = 1 + i * n, 1 + (i + 1) * n
        for k in range(n):
            k1 = (k + 1) % n
            f += [(lo + k, lo + k1, hi + k1), (lo + k, hi + k1, hi + k)]
    last = 1 + (len(prof) - 1) * n
    f += [(top, last + k, last + (k + 1) % n) for k in range(n)]
    return v, np.asarray(f, dtype=np.int64)


def container_fill(inner_radius: float, floor_z: float, count: int, radius: float
                   ) -> NDArray[np.float64]:
    """``count`` particle centres (m, the container's frame: axis along z through the origin)
    on a cubic lattice of pitch ``2·radius``, each particle's cube inside the inner wall with
    half a radius to spare, layer by layer from ``1.5·radius`` above the inner floor at
    ``floor_z``."""
    if not (radius > 0 and count >= 1 and inner_radius > 2 * radius):
        raise ValueError(f"need radius > 0, count >= 1 and an inner radius above 2 radii; "
                         f"got {radius}, {count}, {inner_radius}")
    d = 2.0 * radius
    k = int(inner_radius / d) + 1
    g = np.arange(-k, k + 1) * d
    xx, yy = np.meshgrid(g, g, indexing="ij")
    ring = np.hypot(np.abs(xx) + radius, np.abs(yy) + radius) <= inner_radius - 0.5 * radius
    layer = np.column_stack([xx[ring], yy[ring]])
    layers = math.ceil(count / len(layer))
    z = floor_z + 1.5 * radius + d * np.arange(layers)
    pts = np.concatenate([np.column_stack([layer, np.full(len(layer), zk)]) for zk in z])
    return pts[:count]
