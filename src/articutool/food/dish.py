"""A spoon's dish as the spec describes it: one definition for every model built from it.

``UtensilSpec.physics.bowl = [length, width, depth]`` gives the inner rim (an ellipse of
semi-axes ``a = length/2`` along the utensil's z axis and ``b = width/2`` across it) and the
depth. The walls slope at 45°: the floor ellipse has semi-axes ``a0 = max(a − depth, a/4)``
and ``b0 = max(b − depth, b/4)`` (a quarter of the rim at least, so a shallow-and-narrow dish
keeps a floor), and the cross-section at height ``h`` above the floor is the ellipse whose
semi-axes run linearly from the floor's to the rim's. The floor's inner surface lies at the
utensil frame's ``x = tip_x``, the opening faces +x (the wrist's up vector), the dish centre
is at ``z = tip_z − a`` (its far rim end is the tip).

The physics world (``articutool.sim.world_spec``) builds its collision dish from this, the loader
pours into it, and ``articutool.food.hydrostatics`` integrates it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.spec import UtensilSpec

__all__ = ["Dish", "spoon_dish"]


class Dish(NamedTuple):
    """A spoon's dish (m) in the utensil frame; unpacks as ``zc, a, b, a0, b0, depth``.

    ``zc``: centre along z; ``a``, ``b``: rim semi-axes along z (the dish's length) and y
    (its width); ``a0``, ``b0``: floor semi-axes; ``depth``: floor to rim plane.
    """

    zc: float
    a: float
    b: float
    a0: float
    b0: float
    depth: float

    def semi_axes(self, h: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Semi-axes (along z, along y) of the cross-section ``h`` above the floor."""
        s = np.asarray(h, dtype=float) / self.depth
        return self.a0 + (self.a - self.a0) * s, self.b0 + (self.b - self.b0) * s

    def level_volume(self, h: ArrayLike) -> NDArray[np.float64]:
        """Volume (m³) of the dish below the height ``h`` (0 ≤ h ≤ depth), dish level:
        π ∫₀ʰ A(x) B(x) dx with A, B linear in x — a cubic, integrated exactly."""
        h = np.asarray(h, dtype=float)
        da, db = (self.a - self.a0) / self.depth, (self.b - self.b0) / self.depth
        return np.pi * (self.a0 * self.b0 * h + (self.a0 * db + self.b0 * da) * h ** 2 / 2
                        + da * db * h ** 3 / 3)


def spoon_dish(u: UtensilSpec) -> Dish:
    """The dish of a spoon (``u.physics.kind == "spoon"``); ``ValueError`` for a fork."""
    if u.physics.bowl is None:
        raise ValueError(f"a {u.physics.kind} has no dish")
    length, width, depth = u.physics.bowl
    a, b = length / 2, width / 2
    return Dish(u.tip_z - a, a, b, max(a - depth, 0.25 * a), max(b - depth, 0.25 * b), depth)
