"""Irregular granular pieces as compounds of capsules (pure; thesis §5.1's pecans).

A piece is a list of capsules ``(p0, p1, radius)`` in its own frame, drawn from the food's
size and shape distribution (``data/physics.toml`` cites its sources):

- a *half* of width ``w`` (drawn in ``half_width_m``): the kernel's two lobes, two parallel
  capsules of radius w/4 side by side (w wide, w/2 thick) and ``half_length_ratio``·w long;
- a *broken piece* of screen size ``s`` (drawn in ``piece_screen_m``: the round openings it
  passes and is held on): two capsules of radius s/4 (s/2 thick) joined at one end at an
  angle in [60°, 180°], arms s/2..s long — a bent, irregular fragment that does not roll.

MuJoCo weighs each capsule by the food's density (``mass = ρ·volume``, the joint of a broken
piece counted twice: a few % of its volume).
"""

from __future__ import annotations

import math

import numpy as np

from articutool.sim.params import Granular

__all__ = ["Capsule", "bound_radius", "capsule_mass", "draw_piece", "piece_extent"]

Capsule = tuple[tuple[float, float, float], tuple[float, float, float], float]


def draw_piece(food: Granular, rng: np.random.Generator) -> list[Capsule]:
    """One piece's capsules (centred near the origin), drawn from ``rng``."""
    if rng.uniform() < food.half_fraction:
        w = float(rng.uniform(*food.half_width_m))
        r, half = w / 4.0, max(food.half_length_ratio * w / 2.0 - w / 4.0, 0.0)
        return [((-half, y, 0.0), (half, y, 0.0), r) for y in (-r, r)]
    s = float(rng.uniform(*food.piece_screen_m))
    r = s / 4.0
    a, b = (float(x) for x in rng.uniform(s / 2.0, s, 2))
    angle = math.radians(float(rng.uniform(60.0, 180.0)))
    tip_b = (b * math.cos(angle), b * math.sin(angle), 0.0)
    return [((0.0, 0.0, 0.0), (a, 0.0, 0.0), r), ((0.0, 0.0, 0.0), tip_b, r)]


def capsule_mass(caps: list[Capsule], density: float) -> float:
    """kg: the capsules' volumes × density (as MuJoCo computes it)."""
    m = 0.0
    for p0, p1, r in caps:
        length = float(np.linalg.norm(np.subtract(p1, p0)))
        m += density * (math.pi * r * r * length + 4.0 / 3.0 * math.pi * r**3)
    return m


def piece_extent(food: Granular) -> float:
    """The largest size a piece can have (m): the lattice cell that keeps pieces apart."""
    w = food.half_width_m[1] * max(food.half_length_ratio, 1.0)
    return max(w, 2.0 * food.piece_screen_m[1])


def bound_radius(food: Granular) -> float:
    """Radius (m) of a sphere about the piece's origin that holds any piece in any
    orientation: lattice points twice this apart never start two pieces overlapping."""
    w = food.half_width_m[1]
    half = math.hypot(max(food.half_length_ratio * w / 2.0 - w / 4.0, 0.0), w / 4.0) + w / 4.0
    return max(half, 1.25 * food.piece_screen_m[1])
