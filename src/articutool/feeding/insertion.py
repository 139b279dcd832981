"""Where the utensil goes during an acquisition: tip waypoints from a strategy and the food's
container (pure; thesis §4.3.1 and §4.4, "above-food" pose, insertion, extraction).

The utensil points along a horizontal ``heading`` tipped ``pitch_down`` below the horizon
(:func:`articutool.sim.scenes.tip_target` turns a waypoint into a pose). Positions are in the
arm base frame, relative to the centre of the container's inner floor ``floor``.

- **scoop** (and **dip**, a scoop without drag): from above, down steeply behind the food,
  into it at ``depth_m`` above the floor, dragged ``drag_m`` through it along the heading
  (centred on the container), then out.
- **skewer**: straight down at the container's centre to ``depth_m``, then out.
- **out**: up 4 cm while turning towards ``extract_pitch_down_deg``, then to 7.5 cm above the
  floor at that pitch (0: the arm levels the utensil; otherwise the wrist levels it after,
  a tool-only motion, §4.3.1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.feeding.strategies import Strategy

__all__ = ["PHASES", "TipWaypoint", "acquisition_waypoints"]

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


def _wp(p: NDArray[np.float64], pitch_deg: float, speed: float) -> TipWaypoint:
    return TipWaypoint((float(p[0]), float(p[1]), float(p[2])), math.radians(pitch_deg), speed)


def acquisition_waypoints(strategy: Strategy, floor: ArrayLike,
                          heading: ArrayLike) -> dict[str, list[TipWaypoint]]:
    """The three phases' waypoints: ``above`` (the above-food pose, reached by a free arm
    motion), ``into`` (from the above-food pose into the food) and ``out`` (from the food's
    end point out); each phase starts where the previous one ended."""
    c = np.asarray(floor, dtype=float)
    h = np.asarray(heading, dtype=float)
    h = h / np.linalg.norm(h)
    app, ins = strategy.approach, strategy.insertion
    a, e = ins.pitch_down_deg, ins.extract_pitch_down_deg
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
    out = [last, _wp(top + _Z * 0.04, (a + e) / 2, _SPEED["out"]),
           _wp(top + _Z * 0.075, e, _SPEED["out"])]
    return {"above": [above], "into": into, "out": out}
