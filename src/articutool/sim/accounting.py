"""Where the food is: pure classification of food items from the contacts they make.

An item (a pecan piece, a water particle, a noodle strand) is, at each accounting step:

- on a **surface** it touches and not on the utensil — its scene object's ``place``: back in
  the ``container`` (bowl or plate), on the ``table`` (a non-critical spill), or ``critical``
  (the user, wheelchair, floor); if it touches several, the least severe wins (an item on the
  bowl's rim that also touches the table is still in the bowl);
- on the **utensil** if it touches the utensil, whatever else it touches: an item the utensil
  holds has not left it (a noodle strand hanging from the fork onto the plate is carried by
  the fork, and its weight is shared as a scale under the fork would read it,
  :meth:`articutool.sim.weighing.Weighing.carried_g`);
- otherwise what it rests on: through item-item contacts it takes the place of the items
  holding it. The places spread from every classified item at once, one contact hop at a
  time: an item takes the place of its nearest classified neighbours (fewest hops), and among
  those the least severe (container, table, critical, then utensil); its surface is the
  lowest surface index among those neighbours with that place. Each hop reads only what
  the hops before it decided, so the result (the fixed point where no unclassified item
  touches a classified one) is a function of the contact graph alone: neither the order in
  which MuJoCo lists the contacts nor the direction of a pair can change it (thesis §5's
  outcome classes rest on it; a single pass that reads its own earlier decisions depends on
  the order in 15 % of random graphs). A heap on a spoon counts as on the spoon and a heap in
  the bowl as in the bowl;
- **airborne** when it touches nothing that is classified (falling, or flung);
- **eaten** once it entered the mouth region (the world removes it).

Sleeping items (MuJoCo islands at rest) keep their previous class, and items resting on them
inherit it: their contacts are not recomputed while they sleep, and they cannot move.

**Spilled** and **eaten** mean one thing everywhere (every experiment, every bite record):

- an item **spills** when it stays on a spill place (the table, or the user, wheelchair or
  floor) for ``world.spill_dwell_s`` of simulated time (``data/physics.toml``), counted
  while it touches spill places (a bounce in the air pauses the count, landing back on the
  utensil or in a container resets it). One tick of contact — a piece grazing the table's
  edge as the spoon passes, or a class the contact graph gives for one step — is not food
  on the table; food that landed stays there far longer. The event carries the time it
  first touched the spill place. :class:`SpillTracker` implements it;
- the **spilled mass** of a run or a bite (:func:`spilled_by_place`) counts each item once,
  at the worst place it reached: a piece that lands on the table and rolls to the floor is
  0.92 g of critical spill, not 0.92 g table + 0.92 g critical; an item is counted in the
  interval in which it first spilled;
- an item is **eaten** once, when it enters the mouth region or is on the utensil when the
  user takes the bite (pieces, particles and noodle strands alike); the world removes it,
  so it is never on the utensil, nor eaten, again. **Delivered** (:func:`delivered_g`) is
  what is on the utensil at the end plus what was eaten during the interval;
- in **transport** (from the moment the loaded utensil starts to move towards the user: Exp.
  2b and 2c, and a bite's ``resting``, ``staging`` and ``present`` stages) anything that
  leaves the utensil is **spilled wherever it lands** (:func:`transport_spill`), a container
  included: a loss into the bowl or the plate is reported apart (place ``container``) but is
  a loss all the same. Only a shedding primitive, before transport and over the food's
  container, **sheds** (what it moves into the container is shed, not spilled).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
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
    "TRANSPORT_PLACES",
    "UTENSIL",
    "SpillEvent",
    "SpillTracker",
    "classify_items",
    "delivered_g",
    "spilled_by_place",
    "transport_spill",
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
        (codes, surface) — each item's class and, for items on a surface or resting on items
        on one, the surface's index (else −1).
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
        pick = c == best[items]  # of those, the lowest surface index (order-free)
        low = np.full(n_items, len(surface_codes), dtype=np.int64)
        np.minimum.at(low, items[pick], surf[pick])
        where[on] = low[on]
    if item_utensil.size:  # held by the utensil, whatever else it touches
        codes[item_utensil] = UTENSIL
        where[item_utensil] = -1
    keep = asleep | (previous == EATEN)
    codes[keep] = previous[keep]
    where[keep] = previous_where[keep]
    if item_item.size:
        # Both directions of every pair; each hop reads only the classes known before it, so
        # the result is the same for any order or direction of the pairs.
        src = np.concatenate([item_item[:, 0], item_item[:, 1]])
        dst = np.concatenate([item_item[:, 1], item_item[:, 0]])
        n_surf = len(surface_codes)
        for _ in range(n_items):
            take = (codes[dst] == AIRBORNE) & ~keep[dst] & (_RANK[codes[src]] < 99)
            if not take.any():
                break
            s, t = src[take], dst[take]
            rank = np.full(n_items, 99, dtype=np.int64)
            np.minimum.at(rank, t, _RANK[codes[s]])
            best = rank[t] == _RANK[codes[s]]  # the pairs that carry each item's best place
            surf = np.full(n_items, n_surf, dtype=np.int64)
            np.minimum.at(surf, t[best], np.where(where[s[best]] >= 0, where[s[best]], n_surf))
            got = rank < 99
            codes[got] = _BY_RANK[rank[got]]
            where[got] = np.where(surf[got] < n_surf, surf[got], -1)
    return codes, where


class SpillTracker:
    """Spill events from the classes of successive accounting steps (see module doc).

    An item's spill time at level L (table, then critical) grows by the step while its class
    is at least L, pauses while it is airborne (a bounce) and restarts when it is back on the
    utensil, in a container, or (for critical) on the table. Once it reaches ``dwell_s`` the
    item spills at L — once per level, each a worse place than any before — with the time it
    first touched the spill place.

    Args:
        n_items: number of food items.
        dwell_s: simulated time an item must stay on spill places to count (s, ≥ 0).
    """

    def __init__(self, n_items: int, dwell_s: float) -> None:
        if not dwell_s >= 0:
            raise ValueError(f"dwell_s must be >= 0 s; got {dwell_s}")
        self.dwell_s = dwell_s
        self._time = np.zeros((2, n_items))  # time on spill places at level table, critical
        self._since = np.full((2, n_items), np.nan)  # when that stay began
        self._where = np.full((2, n_items), -1, dtype=np.int64)  # first spill surface seen
        self.worst = np.zeros(n_items, dtype=np.int64)  # worst spill class counted

    def forget(self, items: NDArray[np.int64]) -> None:
        """Clear these items' history (an item reused as a new one)."""
        self._time[:, items] = 0.0
        self._since[:, items] = np.nan
        self._where[:, items] = -1
        self.worst[items] = 0

    def update(self, t: float, dt: float, codes: NDArray[np.int64], where: NDArray[np.int64],
               active: NDArray[np.bool_]) -> list[tuple[int, int, int, float]]:
        """Advance by one accounting step of ``dt`` s ending at ``t`` with the items'
        ``codes`` and surfaces ``where``; ``active``: items in the world. Returns the new
        spills as ``(item, class, surface index or −1, time it began)``."""
        out: list[tuple[int, int, int, float]] = []
        # Critical first: an item that lands straight on the floor is one critical event.
        for row, level in ((1, CRITICAL), (0, TABLE)):
            on = active & (codes >= level) & (codes <= CRITICAL)
            reset = (codes != AIRBORNE) & ~on
            start = on & np.isnan(self._since[row])
            self._since[row, start] = t
            self._where[row, start] = where[start]
            self._time[row, on] += dt
            self._time[row, reset] = 0.0
            self._since[row, reset] = np.nan
            self._where[row, reset] = -1
            new = on & (self._time[row] >= self.dwell_s - 1e-9) & (self.worst < level)
            for k in np.flatnonzero(new):
                w = int(where[k]) if where[k] >= 0 else int(self._where[row, k])
                out.append((int(k), level, w, float(self._since[row, k])))
            self.worst[new] = level
        out.sort(key=lambda e: (e[3], e[0], e[1]))
        return out


def spilled_by_place(events: Sequence[SpillEvent], since: int = 0) -> dict[str, float]:
    """Spilled grams by place (``table``, ``critical``) of the items whose first spill event
    is at index ``since`` or later: each item once, at the worst place it reached (see module
    doc; a table-then-floor item is a critical spill only)."""
    first_before = {e.item for e in events[:since]}
    worst: dict[int, SpillEvent] = {}
    for e in events[since:]:
        if e.item in first_before:
            continue
        if e.item not in worst or PLACE_CODES[e.place] > PLACE_CODES[worst[e.item].place]:
            worst[e.item] = e
    out = {"table": 0.0, "critical": 0.0}
    for e in worst.values():
        out[e.place] += e.mass_g
    return out


def delivered_g(before: Mapping[str, float], after: Mapping[str, float]) -> float:
    """Delivered grams between two mass snapshots (``masses_g`` dicts): on the utensil at
    ``after`` plus what was eaten in between (see module doc)."""
    return float(after["utensil"] + after["eaten"] - before["eaten"])


# Where a transported item that left the utensil ended, by severity (``transport_spill``).
TRANSPORT_PLACES = ("airborne", "container", "table", "critical")
_TRANSPORT_RANK = {AIRBORNE: 0, CONTAINER: 1, TABLE: 2, CRITICAL: 3}


def transport_spill(start: NDArray[np.int64], now: NDArray[np.int64],
                    item_g: NDArray[np.float64], events: Sequence[SpillEvent],
                    since: int = 0) -> dict[str, float]:
    """Grams spilled in a transport, by place (see module doc): every item that was on the
    utensil when the transport began (``start``, the classes then: ``item_classes()``) and
    is neither on it nor eaten now (``now``) is spilled at the worst place it reached —
    where it is now, or a table or critical place it stayed on meanwhile (``events[since:]``)
    — ``container`` included; ``airborne`` if it has not landed yet. Items not on the
    utensil at the start count only through their spill events (food knocked from the
    table to the floor), once each, at the worst place, as :func:`spilled_by_place`."""
    start, now = np.asarray(start), np.asarray(now)
    if start.shape != now.shape or start.shape != np.shape(item_g):
        raise ValueError("start, now and item_g must have one entry per item")
    worst: dict[int, int] = {}
    carried = start == UTENSIL
    for k in np.flatnonzero(carried & (now != UTENSIL) & (now != EATEN)):
        worst[int(k)] = int(now[k]) if int(now[k]) in _TRANSPORT_RANK else AIRBORNE
    first_before = {e.item for e in events[:since]}
    for e in events[since:]:
        code = PLACE_CODES[e.place]
        if carried[e.item] and now[e.item] in (UTENSIL, EATEN):
            continue  # it landed back on the utensil (or was eaten): not lost
        if not carried[e.item] and e.item in first_before:
            continue  # spilled before the transport
        if e.item not in worst or _TRANSPORT_RANK[code] > _TRANSPORT_RANK[worst[e.item]]:
            worst[e.item] = code
    out = dict.fromkeys(TRANSPORT_PLACES, 0.0)
    for k, code in worst.items():
        out[CLASS_NAMES[code]] += float(item_g[k])
    return out
