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
from typing import Protocol

import numpy as np


class Granular(Protocol):
    """What drawing a piece reads of the food (``articutool.sim.params.Granular``, which
    imports this module for its mean piece mass: so only its shape is named here)."""

    half_fraction: float
    half_width_m: tuple[float, float]
    half_length_ratio: float
    piece_screen_m: tuple[float, float]

__all__ = ["Capsule", "capsule_mass", "draw_piece", "footprint", "pack_layer", "piece_extent"]

Capsule = tuple[tuple[float, float, float], tuple[float, float, float], float]


def draw_piece(food: Granular, rng: np.random.Generator) -> list[Capsule]:
    """One piece's capsules, drawn from ``rng``, in the x-y plane (a piece is flat) and
    centred on the smallest circle about the origin's axis that holds them
    (:func:`footprint`)."""
    if rng.uniform() < food.half_fraction:
        w = float(rng.uniform(*food.half_width_m))
        r, half = w / 4.0, max(food.half_length_ratio * w / 2.0 - w / 4.0, 0.0)
        return [((-half, y, 0.0), (half, y, 0.0), r) for y in (-r, r)]
    s = float(rng.uniform(*food.piece_screen_m))
    r = s / 4.0
    a, b = (float(x) for x in rng.uniform(s / 2.0, s, 2))
    angle = math.radians(float(rng.uniform(60.0, 180.0)))
    # The three points' bounding box centre: a bent piece's joint is not its middle.
    pts = np.array([[0.0, 0.0], [a, 0.0], [b * math.cos(angle), b * math.sin(angle)]])
    c = (pts.min(axis=0) + pts.max(axis=0)) / 2.0
    o, pa, pb = ((float(x), float(y), 0.0) for x, y in pts - c)
    return [(o, pa, r), (o, pb, r)]


def footprint(caps: list[Capsule]) -> float:
    """Radius (m) of the circle about the piece's z axis that holds it seen from above."""
    return max(math.hypot(p[0], p[1]) + r for p0, p1, r in caps for p in (p0, p1))


def pack_layer(radii: list[float], inner: float, rng: np.random.Generator,
               tries: int = 200) -> list[tuple[float, float]]:
    """Centres (x, y) for the first pieces of ``radii`` that fit, lying flat, in a disc of
    radius ``inner`` without their footprints overlapping (random sequential addition:
    each piece takes the first of ``tries`` random spots that is free; the layer is full
    at the first piece that finds none). A bowl filled layer by layer so, a piece at a
    time, starts as a loose pile a few layers deep instead of a tall column."""
    placed: list[tuple[float, float, float]] = []
    for r in radii:
        if r >= inner:
            break
        for _ in range(tries):
            rho = (inner - r) * math.sqrt(float(rng.uniform()))
            phi = float(rng.uniform(0.0, 2.0 * math.pi))
            x, y = rho * math.cos(phi), rho * math.sin(phi)
            if all(math.hypot(x - px, y - py) >= r + pr for px, py, pr in placed):
                placed.append((x, y, r))
                break
        else:
            break
    return [(x, y) for x, y, _ in placed]


def capsule_mass(caps: list[Capsule], density: float) -> float:
    """kg: the capsules' volumes × density (as MuJoCo computes it)."""
    m = 0.0
    for p0, p1, r in caps:
        length = float(np.linalg.norm(np.subtract(p1, p0)))
        m += density * (math.pi * r * r * length + 4.0 / 3.0 * math.pi * r**3)
    return m


def piece_extent(food: Granular) -> float:
    """The largest size a piece can have seen from above (m): twice the largest
    :func:`footprint` (a half: its length; a fragment bent straight: two arms and their
    rounded ends about its middle, 2.5 screen sizes)."""
    return max(food.half_width_m[1] * max(food.half_length_ratio, 1.0),
               2.5 * food.piece_screen_m[1])
