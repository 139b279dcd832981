"""A liquid load in the utensil's frame: the pure mechanics of the coupling (no solver here).

The liquid in a moving dish is simulated in the dish's (the utensil body's) frame, where the
dish is static. A frame whose origin accelerates by ``a`` and turns at ``ω`` (angular
acceleration ``α``) adds to gravity, per particle at ``x`` moving at ``v`` in the frame, the
fictitious accelerations ``−a − α×x − 2ω×v − ω×(ω×x)``: the apparent gravity
``R⊤(g − a)`` (uniform) and the rotation terms (per particle). A translating spoon is exactly a
static dish under ``g − a``.

The liquid's force on the dish follows from momentum: the solver's pressure and viscous
forces between particles are pairwise antisymmetric and cancel, so the boundary's force on
the liquid is ``Σ m (a_i − g_i)`` with ``a_i`` a particle's acceleration and ``g_i`` its
apparent gravity (both in the frame), and the liquid's force on the dish is its negative,
``F = Σ m (g_i − a_i)``; over a control period ``a_i`` is the particle's velocity change over
the period, so ``F`` is the period's mean force (its impulse over the period). The torque
about the frame's origin is ``Σ x_i × m (g_i − a_i)``. The rotation terms and these sums are
:mod:`articutool.sim.sph_scene`'s (``rotating_frame_acceleration``, ``momentum_balance_*``).

A particle leaves the dish when it is outside the rim's ellipse (grown by a margin) seen
along the dish's normal, or below the shell's floor: from then on it is the world's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from articutool.food.dish import Dish

__all__ = ["apparent_gravity", "outside_dish"]


def apparent_gravity(R: NDArray[np.float64], gravity: NDArray[np.float64],
                     accel: NDArray[np.float64]) -> NDArray[np.float64]:
    """``R⊤ (g − a)``: gravity less the frame origin's acceleration (world vectors), in the
    frame whose orientation is ``R`` (world ← frame)."""
    return R.T @ (np.asarray(gravity, dtype=float) - np.asarray(accel, dtype=float))


def outside_dish(x: NDArray[np.float64], dish: Dish, x0: float, margin: float,
                 floor_below: float) -> NDArray[np.bool_]:
    """Which points (utensil frame, (n, 3)) have left the dish: outside the rim's ellipse
    grown by ``margin`` (m) seen along the dish's normal, or more than ``floor_below`` (m)
    below its inner floor."""
    x = np.atleast_2d(x)
    along, across = x[:, 2] - dish.zc, x[:, 1]
    rim = (along / (dish.a + margin)) ** 2 + (across / (dish.b + margin)) ** 2 > 1.0
    return rim | (x[:, 0] < x0 - floor_below)
