"""Where the food is: pure classification of food items from the contacts they make.

An item (a pecan piece, a water particle, a noodle strand) is, at each accounting step:

- on a **surface** it touches — its scene object's ``place``: back in the ``container`` (bowl
  or plate), on the ``table`` (a non-critical spill), or ``critical`` (the user, wheelchair,
  floor); if it touches several, the least severe wins (an item on the bowl's rim that also
  touches the table is still in the bowl);
- on the **utensil** if it touches the utensil and no surface;
- otherwise what it rests on: through item-item contacts it takes the place of the items
  holding it (container, table, critical, then utensil, in that order of precedence), so a
  heap on a spoon counts as on the spoon and a heap in the bowl as in the bowl;
- **airborne** when it touches nothing that is classified (falling, or flung);
- **eaten** once it entered the mouth region (the world removes it).

Sleeping items (MuJoCo islands at rest) keep their previous class: their contacts are not
recomputed while they sleep, and they cannot move.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "AIRBORNE",
    "CLASS_NAMES",
    "CONTAINER",
    "CRITICAL",
    "EATEN",
    "PLACE_CODES",
    "TABLE",
    "UTENSIL",
    "SpillEvent",
    "classify_items",
]

AIRBORNE, UTENSIL, CONTAINER, TABLE, CRITICAL, EATEN = range(6)
CLASS_NAMES = ("airborne", "utensil", "container", "table", "critical", "eaten")
PLACE_CODES = {"container": CONTAINER, "table": TABLE, "critical": CRITICAL}
# Precedence when an item inherits its class from the items it rests on (lower wins).
_RANK = np.array([99, 3, 0, 1, 2, 99])
_BY_RANK = np.array([CONTAINER, TABLE, CRITICAL, UTENSIL])


@dataclass(frozen=True)
class SpillEvent:
    """Food that reached the table (non-critical) or the user, wheelchair or floor."""

    t: float  # s, simulation time
    mass_g: float
    place: str  # "table" or "critical"
    where: str  # the scene object it landed on
    item: int


def classify_items(
    n_items: int,
    item_item: NDArray[np.int64],
    item_utensil: NDArray[np.int64],
    item_surface: NDArray[np.int64],
    surface_codes: NDArray[np.int64],
    previous: NDArray[np.int64],
    previous_where: NDArray[np.int64],
    asleep: NDArray[np.bool_],
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Classify every item (see module doc).

    Args:
        n_items: number of food items.
        item_item: (E, 2) pairs of items in contact.
        item_utensil: (U,) items touching the utensil.
        item_surface: (S, 2) rows [item, surface index] of items touching a surface.
        surface_codes: class code of each surface (``PLACE_CODES`` values).
        previous, previous_where: (n_items,) the result of the last step.
        asleep: (n_items,) items that sleep (keep ``previous``).

    Returns:
        (codes, surface) — each item's class and, for items on a surface, its index (else −1).
    """
    codes = np.full(n_items, AIRBORNE, dtype=np.int64)
    where = np.full(n_items, -1, dtype=np.int64)
    if item_surface.size:
        items, surf = item_surface[:, 0], item_surface[:, 1]
        c = surface_codes[surf]
        best = np.full(n_items, 99, dtype=np.int64)
        np.minimum.at(best, items, c)  # the least severe surface touched
        on = best < 99
        codes[on] = best[on]
        pick = c == best[items]
        where[items[pick]] = surf[pick]
    if item_utensil.size:
        free = codes[item_utensil] == AIRBORNE
        codes[item_utensil[free]] = UTENSIL
    if item_item.size:
        a, b = item_item[:, 0], item_item[:, 1]
        for _ in range(n_items):
            changed = False
            for src, dst in ((a, b), (b, a)):
                take = (codes[dst] == AIRBORNE) & (codes[src] != AIRBORNE) & (codes[src] != EATEN)
                if not take.any():
                    continue
                # Among candidates for the same item, the lowest rank wins.
                cand = np.full(n_items, 99, dtype=np.int64)
                np.minimum.at(cand, dst[take], _RANK[codes[src[take]]])
                got = cand < 99
                codes[got] = _BY_RANK[cand[got]]
                changed = True
            if not changed:
                break
    keep = asleep | (previous == EATEN)
    codes[keep] = previous[keep]
    where[keep] = previous_where[keep]
    return codes, where
