"""The runtime's mode requests and its LEVELING mode (thesis §4.2, §4.4, Alg. 1).

``set_mode`` takes DISABLED or LEVELING (PRIMITIVE and TRAJECTORY have their own calls):
:func:`requested_mode` says which, or why not. :class:`Leveling` is LEVELING's part of the
runtime: the pitch/roll offsets (degrees, within ``spec.wrist`` limits), the refusal to start
when the nearest level configuration lies beyond the cable's roll budget, and each tick's
command from :class:`~articutool.tool.controller.LevelingController` with the bias-corrected
gyro fed forward (Eq. 4.5) unless ``rate_feedforward=False``. A stall (the controller at
rest short of level) is no fault: the tool keeps leveling and :attr:`Leveling.stall_target`
holds the nearest reachable level configuration (NaN when none is reachable), which
telemetry reports. :class:`~articutool.tool.runtime.ToolRuntime` composes it.
"""

from __future__ import annotations

import logging
import math
import numbers

import numpy as np
from numpy.typing import NDArray

from articutool.spec import Spec
from articutool.tool.api import Mode
from articutool.tool.controller import LevelingController

__all__ = ["Leveling", "check_offsets", "requested_mode"]

log = logging.getLogger(__name__)

_TWO_PI = 2.0 * math.pi


def requested_mode(mode: Mode | int) -> Mode:
    """The mode a ``set_mode`` call asks for: DISABLED or LEVELING; ValueError otherwise."""
    try:
        mode = Mode(int(mode))
    except (TypeError, ValueError):
        raise ValueError(f"mode must be {int(Mode.DISABLED)} (DISABLED) or "
                         f"{int(Mode.LEVELING)} (LEVELING); got {mode!r}") from None
    if mode is Mode.PRIMITIVE:
        raise ValueError("mode PRIMITIVE is entered with start_primitive, not set_mode")
    if mode is Mode.TRAJECTORY:
        raise ValueError("mode TRAJECTORY is entered with follow_trajectory, not set_mode")
    return mode


def check_offsets(
    pitch_deg: float, roll_deg: float, limits: NDArray[np.float64]
) -> tuple[float, float]:
    """The leveling offsets as floats (degrees); ValueError naming the field and its range
    (``limits``: the wrist's joint limits, rad) otherwise."""
    out = []
    for name, v, (lo, hi) in (("pitch_offset_deg", pitch_deg, limits[0]),
                              ("roll_offset_deg", roll_deg, limits[1])):
        lo_d, hi_d = math.degrees(lo), math.degrees(hi)
        ok = isinstance(v, numbers.Real) and not isinstance(v, bool)
        x = float(v) if ok else math.nan
        if not (math.isfinite(x) and lo_d <= x <= hi_d):
            raise ValueError(f"{name} must be a number in [{lo_d:g}, {hi_d:g}] degrees "
                             f"(spec.wrist limits); got {v!r}")
        out.append(x)
    return out[0], out[1]


class Leveling:
    """LEVELING: the controller, its offsets and the stall report."""

    def __init__(self, spec: Spec, controller: LevelingController, rate_feedforward: bool) -> None:
        self.controller = controller
        self.roll_turn_budget = spec.wrist.roll_turn_budget
        self.rate_feedforward = bool(rate_feedforward)
        self.offsets_deg = (0.0, 0.0)
        # While stalled: the nearest reachable level configuration (NaN: none); else None.
        self.stall_target: tuple[float, float] | None = None

    def engage(self, R: NDArray[np.float64], q: NDArray[np.float64],
               offsets_deg: tuple[float, float]) -> str:
        """Start leveling from ``q`` under the base orientation ``R`` with ``offsets_deg``;
        the refusal (offsets unchanged) or ""."""
        ctrl = self.controller
        previous = ctrl.offsets
        ctrl.set_offsets(math.radians(offsets_deg[0]), math.radians(offsets_deg[1]))
        refusal = self.out_of_budget(R, q)
        if refusal:
            ctrl.set_offsets(*previous)
            return refusal
        ctrl.engage(R, q)
        self.offsets_deg = offsets_deg
        return ""

    def out_of_budget(self, R: NDArray[np.float64], q: NDArray[np.float64]) -> str:
        """Why leveling cannot start from ``q`` under the base orientation ``R``, or "".

        The up vector repeats every roll turn, so the nearest level configuration is at most
        half a turn of roll away; leveling is refused only when that one lies beyond the
        cable's net-turn budget (the roll would be pinned against the budget, tilted).
        """
        target = self.controller.nearest_level(R, q)
        b = self.roll_turn_budget
        tol = self.controller.deadband  # pinned that close to the budget is level enough
        if target is None or abs(target[1]) <= b * _TWO_PI + tol:
            return ""
        return (f"refused: leveling from roll {q[1] / _TWO_PI:+.2f} turns needs roll "
                f"{target[1] / _TWO_PI:+.2f} turns, beyond the cable budget of ±{b:g} turns "
                "(spec.wrist.roll_turn_budget); unwind first (HOMING or TWIRL)")

    def command(self, R: NDArray[np.float64], q: NDArray[np.float64],
                gyro_corrected: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
        """One tick's joint velocity command (Alg. 1), updating the stall report."""
        ctrl = self.controller
        rate = ctrl.tool_base_rate(gyro_corrected) if self.rate_feedforward else None
        cmd = ctrl.update(R, q, dt, base_rate=rate)
        if not ctrl.stalled:
            self.stall_target = None
            return cmd
        new = self.stall_target is None
        target = ctrl.nearest_level(R, q)  # where level could be reached now
        self.stall_target = ((math.nan, math.nan) if target is None
                             else (float(target[0]), float(target[1])))
        if new:
            log.warning("leveling stalled at %.1f° of tilt (nearest level configuration: %s)",
                        math.degrees(ctrl.error_angle), self.stall_target)
        return cmd
