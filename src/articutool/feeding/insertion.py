"""Where the utensil goes during an acquisition: tip waypoints from a strategy and the food's
container (pure; thesis §4.3.1 and §4.4, "above-food" pose, insertion, extraction).

The utensil points along a horizontal ``heading`` tipped ``pitch_down`` below the horizon
(:func:`articutool.planning.tip_paths.tip_target` turns a waypoint into a pose). Positions are
in the arm base frame, relative to the centre of the container's inner floor ``floor``.

- **scoop** (and **dip**, a scoop without drag): from above, down steeply behind the food,
  into it at ``depth_m`` above the floor, dragged ``drag_m`` through it along the heading
  (centred on the container), then out.
- **skewer**: straight down at the container's centre to ``depth_m``, then out.
- **sweep** (§4.4's "tilted dip" and "tilted scoop" made by the wrist): down at
  ``pitch_down_deg`` until the dish's lowest point is ``depth_m`` above the floor, then level
  *in the food* while moving ``drag_m`` along the heading, about a pivot that keeps every point
  of the dish's outline at least ``depth_m`` above the floor (heights from the utensil's
  geometry in the spec, :func:`dish_outline`), to ``sweep_to_deg`` (where the handle clears
  the rim behind it), then rise while turning level. The turning segments are marked
  ``wrist``: the Articutool's wrist pitch makes the turn while the arm translates; the rigid
  baseline's arm makes the same tip path.

Every motion is shifted ``offset_m`` along the heading from the container's centre.
- **out**: up 4 cm while turning towards ``extract_pitch_down_deg``, then to 7.5 cm above the
  floor at that pitch (0: the arm levels the utensil; otherwise the wrist levels it after,
  a tool-only motion, §4.3.1); with ``level_height_m`` it turns to that pitch first, still
  in the food at that height, then rises.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.feeding.strategies import Strategy
from articutool.spec import Spec

__all__ = ["PHASES", "TipWaypoint", "acquisition_waypoints", "dish_outline", "lowest_point"]

PHASES = ("above", "into", "out")
_Z = np.array([0.0, 0.0, 1.0])
# Behind the entry point the descent starts, so a steep utensil's handle clears the rim.
_BEHIND_M = 0.02
_PRE_ENTRY_M = 0.04  # height above the floor where the slow descent into the food starts
_SPEED = {"above": 0.15, "descend": 0.06, "into": 0.03, "out": 0.03}


@dataclass(frozen=True)
class TipWaypoint:
    """A tip position (m, arm base frame), its pitch below the horizon (rad) and the tip
    speed (m/s) of the segment that ends here."""

    position: tuple[float, float, float]
    pitch_down: float
    speed: float
    # The pitch change of the segment ending here is the wrist's (Articutool): the arm
    # translates, the wrist turns the utensil.
    wrist: bool = False


def _wp(p: NDArray[np.float64], pitch_deg: float, speed: float,
        wrist: bool = False) -> TipWaypoint:
    return TipWaypoint((float(p[0]), float(p[1]), float(p[2])), math.radians(pitch_deg), speed,
                       wrist)


def dish_outline(spec: Spec, utensil: str) -> list[tuple[float, float]]:
    """Points of the utensil's outline that can touch a floor, as (up, forward) offsets from
    the tip (m): a spoon's dish floor and rim ends (its geometry in the spec,
    :func:`articutool.food.dish.spoon_dish`), a fork's tine ends."""
    from articutool.food.dish import spoon_dish

    u = spec.utensil(utensil)
    if u.physics.kind != "spoon":
        return [(0.0, 0.0)]
    _, a, _, a0, _, depth = spoon_dish(u)
    th = u.physics.thickness
    return [(-th, -a + a0), (-th, -a - a0), (depth, 0.0), (depth, -2 * a)]


def lowest_point(outline: list[tuple[float, float]], pitch_down: float) -> float:
    """Height (m) of the outline's lowest point above the tip, the utensil pitched
    ``pitch_down`` rad down (up axis = heading·sin + z·cos, forward = heading·cos − z·sin)."""
    return min(u * math.cos(pitch_down) - f * math.sin(pitch_down) for u, f in outline)


def _sweep(strategy: Strategy, c: NDArray[np.float64], h: NDArray[np.float64],
           outline: list[tuple[float, float]]) -> dict[str, list[TipWaypoint]]:
    app, ins = strategy.approach, strategy.insertion
    a = ins.pitch_down_deg

    def tip(along: float, pitch_deg: float) -> NDArray[np.float64]:
        # The tip's height that puts the outline's lowest point depth_m above the floor.
        z = ins.depth_m - lowest_point(outline, math.radians(pitch_deg))
        return c + h * along + _Z * z

    start = tip(-ins.drag_m / 2, a)
    back = start - h * _BEHIND_M
    above = _wp(back + _Z * app.height_m, app.pitch_down_deg, _SPEED["above"])
    into = [above, _wp(back + _Z * _PRE_ENTRY_M, a, _SPEED["descend"]),
            _wp(start, a, _SPEED["into"])]
    b = ins.sweep_to_deg
    n = max(2, math.ceil((a - b) / 10.0))  # the pivot, piecewise: ≤ 10° a segment
    for k in range(1, n + 1):
        s = k / n
        p = a + s * (b - a)
        into.append(_wp(tip(-ins.drag_m / 2 + s * ins.drag_m, p), p, _SPEED["into"],
                        wrist=True))
    end = np.array(into[-1].position)
    # Out: rise while turning level (the handle clears the rim as the dish rises).
    out = [into[-1], _wp(np.array([end[0], end[1], c[2]]) + _Z * 0.075, 0.0, _SPEED["out"],
                         wrist=b > 0)]
    return {"above": [above], "into": into, "out": out}


def acquisition_waypoints(strategy: Strategy, floor: ArrayLike, heading: ArrayLike,
                          outline: list[tuple[float, float]] | None = None
                          ) -> dict[str, list[TipWaypoint]]:
    """The three phases' waypoints: ``above`` (the above-food pose, reached by a free arm
    motion), ``into`` (from the above-food pose into the food) and ``out`` (from the food's
    end point out); each phase starts where the previous one ended. ``outline``
    (:func:`dish_outline`) is needed by a ``sweep``."""
    h = np.asarray(heading, dtype=float)
    h = h / np.linalg.norm(h)
    app, ins = strategy.approach, strategy.insertion
    c = np.asarray(floor, dtype=float) + h * ins.offset_m
    a, e = ins.pitch_down_deg, ins.extract_pitch_down_deg
    if ins.motion == "sweep":
        if outline is None:
            raise ValueError("a sweep needs the utensil's outline (dish_outline)")
        return _sweep(strategy, c, h, outline)
    if ins.motion == "skewer":
        start = end = c + _Z * ins.depth_m
        above = _wp(c + _Z * app.height_m, app.pitch_down_deg, _SPEED["above"])
        into = [above, _wp(c + _Z * _PRE_ENTRY_M, a, _SPEED["descend"]),
                _wp(start, a, _SPEED["into"])]
    else:  # scoop, dip (a dip drags 0)
        start = c - h * ins.drag_m / 2 + _Z * ins.depth_m
        end = c + h * ins.drag_m / 2 + _Z * ins.depth_m
        back = start - h * _BEHIND_M
        above = _wp(back + _Z * (app.height_m - ins.depth_m), app.pitch_down_deg,
                    _SPEED["above"])
        into = [above, _wp(back + _Z * (_PRE_ENTRY_M - ins.depth_m), a, _SPEED["descend"]),
                _wp(start, a, _SPEED["into"])]
        if ins.drag_m > 0:
            into.append(_wp(end, a, _SPEED["into"]))
    last = into[-1]
    top = np.array([end[0], end[1], c[2]])
    if ins.level_height_m is not None:  # turn in the food, then rise
        out = [last, _wp(top + _Z * ins.level_height_m, e, _SPEED["into"]),
               _wp(top + _Z * 0.075, e, _SPEED["out"])]
    else:  # rise while turning
        out = [last, _wp(top + _Z * 0.04, (a + e) / 2, _SPEED["out"]),
               _wp(top + _Z * 0.075, e, _SPEED["out"])]
    return {"above": [above], "into": into, "out": out}
