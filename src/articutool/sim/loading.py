"""Placing a load on the utensil by hand (the thesis' Exp. 2b/2c protocol): pure geometry.

The world holds a parked supply of the food (``FeedingWorld.make(load_g=…)``);
:class:`~articutool.sim.placement.LoadPlacement` (``world.placement.place``) puts the load on
the utensil the way a scoop leaves it:

- **rigid pieces** are deposited one at a time at :func:`deposit_spot` — a random spot over
  the whole dish (a fork: over its tines), each lowered onto whatever is under that spot
  (the dish, or pieces already there) and let go just above it, until the utensil holds the
  load. A heap built so, over the whole dish, is bounded by the pieces' angle of repose as a
  lifted scoop's heap is: a piece that lands on a slope steeper than the pieces allow rolls
  down or off, and what the utensil keeps is what a scoop would keep. Nothing is stacked on
  one spot (a tower no hand builds);
- **particles** fill the dish from its floor up (:func:`pour_lattice`): a liquid levels
  itself in the dish whatever scooped it.
"""

from __future__ import annotations

import math

import numpy as np

from articutool.food.dish import spoon_dish
from articutool.spec import UtensilSpec

__all__ = ["DEPOSIT_CLEARANCE_M", "deposit_spot", "dish_surface_height", "dish_volume_m3",
           "max_load_g", "pour_lattice"]

# A deposited piece is let go this far above what is under it (m): a hand lowers a piece onto
# the heap and lets go; 2 mm is a numerical choice, small against a piece's 5-8 mm thickness.
DEPOSIT_CLEARANCE_M = 0.002


def dish_surface_height(u: UtensilSpec, y: float, z: float) -> float:
    """Height (m) of a spoon dish's inner surface above its floor at (``y``, ``z``) in the
    utensil frame (``z`` along the dish from its centre): 0 on the floor, rising along the
    45° walls to the dish's depth at the rim; ``inf`` outside the rim. A fork has no dish: 0."""
    if u.physics.kind != "spoon":
        return 0.0
    zc, a, b, a0, b0, depth = spoon_dish(u)
    dz, dy = z - zc, y

    def outside(h: float) -> float:  # > 0 where the point is outside the ellipse at height h
        s = h / depth if depth else 1.0
        return (dz / (a0 + (a - a0) * s)) ** 2 + (dy / (b0 + (b - b0) * s)) ** 2 - 1.0

    if outside(0.0) <= 0.0:
        return 0.0
    if outside(depth) > 0.0:
        return math.inf
    lo, hi = 0.0, depth
    for _ in range(40):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if outside(mid) > 0.0 else (lo, mid)
    return hi


def deposit_spot(u: UtensilSpec, footprint: float, rng: np.random.Generator
                 ) -> tuple[float, float]:
    """A spot (y, z) in the utensil frame over which a piece of radius ``footprint`` (seen
    from above) is deposited: uniform over the dish's rim ellipse shrunk by half the
    footprint (the piece's centre over the dish, its edge may overhang the slope), or over a
    fork's tines."""
    ph = u.physics
    if ph.kind == "spoon":
        zc, a, b, *_ = spoon_dish(u)
        ea, eb = max(a - footprint / 2, 1e-4), max(b - footprint / 2, 1e-4)
    else:
        assert ph.tine_length is not None and ph.tines and ph.tine_pitch
        zc = u.tip_z - ph.tine_length / 2
        ea, eb = ph.tine_length / 2, (ph.tines - 1) * ph.tine_pitch / 2 + 1e-4
    rho, phi = math.sqrt(float(rng.uniform())), float(rng.uniform(0.0, 2.0 * math.pi))
    return eb * rho * math.sin(phi), zc + ea * rho * math.cos(phi)


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


def dish_volume_m3(u: UtensilSpec) -> float:
    """Volume (m³) a spoon's dish holds filled level to its rim (its hydrostatic level
    capacity, :class:`articutool.food.hydrostatics.Hydrostatics`); 0 for a fork."""
    if u.physics.kind != "spoon":
        return 0.0
    from articutool.food.hydrostatics import Hydrostatics

    return float(Hydrostatics(spoon_dish(u)).level_capacity)


def max_load_g(u: UtensilSpec, kind: str, density: float,
               angle_of_repose_deg: float | None = None) -> float:
    """The most a utensil can hold of a food (g), a physical bound for refusing a load:

    - a liquid (no surface tension in our model) at most fills the dish level to its rim
      (:func:`dish_volume_m3` × density): more runs over (a fork holds none);
    - rigid pieces at most fill the dish and a heap over its rim (or a fork's tines) no
      steeper than their angle of repose — bounded by the rim's area × half its smaller
      semi-axis × tan(repose) — as solid kernel (packing 1: no heap is denser);
    - strands: no bound (they hang)."""
    if kind == "liquid":
        return dish_volume_m3(u) * density * 1000.0
    if kind != "granular" or angle_of_repose_deg is None:
        return math.inf
    slope = math.tan(math.radians(angle_of_repose_deg))
    if u.physics.kind == "spoon":
        _, a, b, *_ = spoon_dish(u)
        area, half = math.pi * a * b, min(a, b)
        base = dish_volume_m3(u)
    else:
        ph = u.physics
        assert ph.tine_length is not None and ph.tines and ph.tine_pitch
        width = (ph.tines - 1) * ph.tine_pitch + 2 * (ph.tine_radius or 0.0)
        area, half, base = ph.tine_length * width, width / 2, 0.0
    return (base + area * half / 2 * slope) * density * 1000.0
