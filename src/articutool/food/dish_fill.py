"""A liquid poured into a spoon's dish as particles: where a particle liquid's load starts.

The dish is :mod:`articutool.food.dish`'s, in the utensil frame (the floor's inner surface at
``x = x0``, the opening towards +x, centred at ``z = zc``). The particles sit on a cubic
lattice of spacing ``2r`` (each stands for a cube of liquid of side ``2r``), at least
``clearance · r`` inside the dish's inner surface along its normal (boundary particles hold a
liquid about 1.4 r off a wall, liquid-notes.md: the pour starts where the liquid settles, not
inside the wall's repulsion), the lowest first (a level surface), and among equals the
nearest the dish's axis. Above the rim the heap narrows at 45°.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from articutool.food.dish import Dish

__all__ = ["CLEARANCE_RADII", "dish_pour"]

CLEARANCE_RADII = 1.5  # a numerical choice (see the module doc)


def dish_pour(dish: Dish, x0: float, radius: float, count: int,
              clearance: float = CLEARANCE_RADII) -> NDArray[np.float64]:
    """``count`` particle centres (utensil frame, (count, 3) m) of radius ``radius`` poured
    into ``dish``; ``ValueError`` when the dish (and a heap over its rim up to one depth)
    cannot take them."""
    if not (radius > 0 and count >= 1 and clearance >= 0):
        raise ValueError(f"radius > 0, count >= 1, clearance >= 0; got {radius}, {count}, "
                         f"{clearance}")
    s = 2.0 * radius
    c = clearance * radius
    slope = math.hypot(1.0, max(dish.a - dish.a0, dish.b - dish.b0) / dish.depth)
    hs = np.arange(c, 2.0 * dish.depth, s)
    ys = s * np.arange(-math.ceil(dish.b / s), math.ceil(dish.b / s) + 1)  # symmetric
    zs = s * np.arange(-math.ceil(dish.a / s), math.ceil(dish.a / s) + 1)
    h, y, z = (g.ravel() for g in np.meshgrid(hs, ys, zs, indexing="ij"))
    A, B = dish.semi_axes(np.clip(h, 0.0, dish.depth))
    over = np.maximum(h - dish.depth, 0.0)
    A, B = A - c * slope - over, B - c * slope - over
    ok = (A > 0) & (B > 0)
    ok[ok] = (z[ok] / A[ok]) ** 2 + (y[ok] / B[ok]) ** 2 <= 1.0
    idx = np.flatnonzero(ok)
    if len(idx) < count:
        raise ValueError(f"the dish takes at most {len(idx)} particles of radius "
                         f"{radius * 1e3:g} mm; {count} asked")
    order = idx[np.lexsort((np.hypot(y[idx], z[idx]), h[idx]))[:count]]
    return np.column_stack([x0 + h[order], y[order], dish.zc + z[order]])
