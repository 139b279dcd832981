"""Placing a load on the utensil by hand (the thesis' Exp. 2b/2c protocol): pure geometry.

The world holds a parked load (``FeedingWorld(load_g=…)``); :meth:`FeedingWorld.place_load`
puts it on the utensil: rigid pieces dropped one by one from just above the dish (or the
tines) at :func:`drop_points`, particles on the lattice of :func:`pour_lattice` that fills
the dish from its floor up, as a poured liquid.
"""

from __future__ import annotations

import numpy as np

from articutool.food.dish import spoon_dish
from articutool.spec import UtensilSpec

__all__ = ["drop_points", "pour_lattice"]


def drop_points(u: UtensilSpec, piece_extent: float, n: int,
                seed: int) -> list[tuple[float, float, float]]:
    """Where ``n`` rigid pieces are dropped (utensil frame): just above the dish centre (or
    the tines' middle), scattered ±4 mm with the world's ``seed``."""
    ph = u.physics
    if ph.kind == "spoon":
        zc, *_, depth = spoon_dish(u)
    else:
        assert ph.tine_length is not None
        zc, depth = u.tip_z - ph.tine_length / 2, 0.0
    rng = np.random.default_rng(seed + 7)
    lift = depth + 0.6 * piece_extent  # clear of the dish for the largest piece
    out = []
    for _ in range(n):
        dy, dz = rng.uniform(-0.004, 0.004, 2)
        out.append((u.tip_x + lift, float(dy), float(zc + dz)))
    return out


def pour_lattice(u: UtensilSpec, cell: float) -> list[tuple[float, float, float]]:
    """Particle centres (utensil frame, particles of size ``cell``) filling the dish from its
    floor up, then heaped above its rim until the heap closes: every place a poured liquid
    can be put (none on a fork)."""
    if u.physics.kind != "spoon":
        return []
    zc, a, b, a0, b0, depth = spoon_dish(u)
    pts: list[tuple[float, float, float]] = []
    for layer in range(41):
        h = cell / 2 + layer * cell  # centre height above the floor
        # The dish widens with height (45° walls); above the rim the heap narrows.
        grow = min(h / depth, 1.0) - max(h - depth, 0.0) / depth if depth else 0.0
        al, bl = a0 + (a - a0) * grow - cell / 2, b0 + (b - b0) * grow - cell / 2
        if al < 0 and bl < 0 and layer > 0:
            break
        ni, nj = int(max(al, 0.0) / cell), int(max(bl, 0.0) / cell)
        pts += [(u.tip_x + h, j * cell, zc + i * cell)
                for i in range(-ni, ni + 1) for j in range(-nj, nj + 1)]
    return pts
