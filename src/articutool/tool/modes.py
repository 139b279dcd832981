"""The runtime's mode requests and its LEVELING and FULL_ORIENTATION modes (thesis §4.2, §4.4,
Alg. 1).

``set_mode`` takes DISABLED, LEVELING or FULL_ORIENTATION (PRIMITIVE and TRAJECTORY have their
own calls): :func:`requested_mode` says which, or why not. FULL_ORIENTATION holds a target
utensil orientation given in a gravity-aligned robot base (:func:`attitude_target`: the two
degrees of freedom gravity fixes; the heading follows the arm) with an
:class:`~articutool.tool.controller.AttitudeController` in the same :class:`Leveling` shell, so
it has leveling's safety envelope, faults and stall report; a target no configuration within
the wrist's reach holds is refused with the nearest reachable one. :class:`Leveling` is
LEVELING's part of the runtime: the pitch/roll offsets (degrees, within ``spec.wrist`` limits),
the refusal to start when the nearest level configuration lies beyond the cable's roll budget,
and each tick's command from :class:`~articutool.tool.controller.LevelingController` with the
bias-corrected gyro fed forward (Eq. 4.5) unless ``rate_feedforward=False``. A stall (the
controller at rest short of level) is no fault: the tool keeps leveling and
:attr:`Leveling.stall_target` holds the nearest reachable level configuration (NaN when none is
reachable), which telemetry reports. :class:`~articutool.tool.runtime.ToolRuntime` composes it.
"""

from __future__ import annotations

import logging
import math
import numbers

import numpy as np
from numpy.typing import NDArray

from articutool.rotations import quaternion_to_matrix
from articutool.spec import Spec
from articutool.tool.api import Mode
from articutool.tool.controller import AttitudeController, LevelingController

__all__ = ["Leveling", "attitude_target", "check_offsets", "requested_mode"]

log = logging.getLogger(__name__)

_TWO_PI = 2.0 * math.pi


def requested_mode(mode: Mode | int) -> Mode:
    """The mode a ``set_mode`` call asks for: DISABLED, LEVELING or FULL_ORIENTATION;
    ValueError otherwise."""
    try:
        mode = Mode(int(mode))
    except (TypeError, ValueError):
        raise ValueError(f"mode must be {int(Mode.DISABLED)} (DISABLED), "
                         f"{int(Mode.LEVELING)} (LEVELING) or {int(Mode.FULL_ORIENTATION)} "
                         f"(FULL_ORIENTATION); got {mode!r}") from None
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


def attitude_target(xyzw: object) -> NDArray[np.float64]:
    """The tip-frame vector FULL_ORIENTATION holds vertical for the target orientation
    ``xyzw`` ([x, y, z, w] of ``R_base←tip`` in a gravity-aligned base, z up): ``R⊤ ẑ``.
    A non-unit quaternion is normalised; ValueError naming the field for a zero, non-finite
    or malformed one."""
    try:
        q = np.asarray([float(v) for v in xyzw], dtype=np.float64)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        q = np.full(1, np.nan)
    n = float(np.linalg.norm(q)) if q.shape == (4,) and np.isfinite(q).all() else 0.0
    if n < 1e-6:
        raise ValueError("target_orientation_robot_base must be a quaternion [x, y, z, w] of "
                         f"finite numbers, not all zero; got {xyzw!r}")
    x, y, z, w = q / n
    return quaternion_to_matrix([w, x, y, z])[2]  # the third row: R⊤ ẑ


def _least_angle_to_vertical(R: NDArray[np.float64], g: NDArray[np.float64],
                             pitch_limits: tuple[float, float]) -> float:
    """The least angle (rad) between the tip-frame vector ``g`` and the vertical over the
    wrist's configurations (pitch within ``pitch_limits``, any roll) under the base
    orientation ``R``. With ``w`` the vertical in F0 (``R``'s last row), the height
    ``w · rotation(p, r) g`` is ``sin r (A g₀ + w₁ g₁) + cos r (A g₁ − w₁ g₀) + g₂ B`` with
    ``A = w₀ cos p + w₂ sin p`` and ``B = w₂ cos p − w₀ sin p``, so its maximum over the
    roll is ``√((A² + w₁²)(g₀² + g₁²)) + g₂ B``: a function of the pitch alone, maximised on a
    grid and by golden-section search around the grid's best (NumPy only: the tool's core
    install has no SciPy)."""
    w = np.asarray(R, dtype=float)[2]
    g = np.asarray(g, dtype=float)
    k = math.hypot(g[0], g[1])
    lo, hi = pitch_limits

    def height(p: NDArray[np.float64]) -> NDArray[np.float64]:
        a = w[0] * np.cos(p) + w[2] * np.sin(p)
        b = w[2] * np.cos(p) - w[0] * np.sin(p)
        return k * np.sqrt(a * a + w[1] * w[1]) + g[2] * b

    grid = np.linspace(lo, hi, 721)
    i = int(np.argmax(height(grid)))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    ratio = 0.5 * (math.sqrt(5.0) - 1.0)
    for _ in range(60):
        c, d = b - ratio * (b - a), a + ratio * (b - a)
        if height(np.array(c)) >= height(np.array(d)):
            b = d
        else:
            a = c
    best = max(float(height(np.array(0.5 * (a + b)))), float(height(grid[i])))
    return math.acos(min(1.0, max(-1.0, best)))


class Leveling:
    """LEVELING (or, with an :class:`AttitudeController`, FULL_ORIENTATION): the controller,
    its offsets and the stall report."""

    def __init__(self, spec: Spec, controller: LevelingController, rate_feedforward: bool) -> None:
        self.controller = controller
        self.roll_turn_budget = spec.wrist.roll_turn_budget
        self.pitch_limits = (float(spec.wrist.pitch_limits[0]), float(spec.wrist.pitch_limits[1]))
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
        if target is None and isinstance(self.controller, AttitudeController):
            return self.unreachable(R)  # "" when within the deadband of the target
        if target is None or abs(target[1]) <= b * _TWO_PI + tol:
            return ""
        return (f"refused: leveling from roll {q[1] / _TWO_PI:+.2f} turns needs roll "
                f"{target[1] / _TWO_PI:+.2f} turns, beyond the cable budget of ±{b:g} turns "
                "(spec.wrist.roll_turn_budget); unwind first (HOMING or TWIRL)")

    def unreachable(self, R: NDArray[np.float64]) -> str:
        """Why FULL_ORIENTATION refuses its target under the base orientation ``R`` when no
        configuration within the pitch limits holds it exactly: the nearest reachable
        attitude (the least angle between the held vector and the vertical, pitch within its
        limits, any roll) is more than the deadband from it. "" when within the deadband
        (held as near as the limits allow)."""
        ctrl = self.controller
        angle = _least_angle_to_vertical(R, ctrl.target_vector,  # type: ignore[attr-defined]
                                         self.pitch_limits)
        if angle <= ctrl.deadband:
            return ""
        return ("refused: target orientation out of reach: no wrist configuration within the "
                "pitch limits (spec.wrist.pitch_limits) holds it under the present base "
                f"orientation; the nearest reachable attitude is {math.degrees(angle):.1f}° "
                "from it; nothing moved (refused, not clipped)")

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
