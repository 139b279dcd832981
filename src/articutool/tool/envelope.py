"""The runtime's joint safety envelope and its limit-fault recovery (thesis §4.4,
docs/hardware.md §6).

The envelope is pitch ``spec.wrist.pitch_limits`` and roll ``±spec.wrist.roll_turn_budget``
turns (the cable), each widened by the distance one tick covers at the commandable speed
(``max_velocity / rate``: one tick of overshoot). A measured joint outside it is a limit
fault in any mode. The per-mode limits (leveling's ``roll_limits``, trajectory validation,
the primitives' budget) are tighter and enforced by the mode itself.

Clearing a limit fault arms a recovery for each joint still outside: while it is out,
commands that drive it further out fault again and commands that bring it back are allowed.
Pure state and arithmetic; :class:`~articutool.tool.runtime.ToolRuntime` composes it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from articutool.spec import Spec

__all__ = ["SafetyEnvelope"]


class SafetyEnvelope:
    """The envelope's bounds (``bounds[j] = (lo, hi)``, rad) and the per-joint recovery."""

    def __init__(self, spec: Spec) -> None:
        w = spec.wrist
        self.joint_names: tuple[str, str] = (w.joint_names[0], w.joint_names[1])
        turns = w.roll_turn_budget * 2.0 * math.pi
        tol = w.velocity_limits * w.period  # one tick of travel at the commandable speed
        self.bounds = np.array(
            [[w.pitch_limits[0] - tol[0], w.pitch_limits[1] + tol[0]],
             [-turns - tol[1], turns + tol[1]]]
        )
        self.recovering = np.zeros(2, dtype=bool)

    def outside(self, q: NDArray[np.float64]) -> list[int]:
        """The joints of ``q`` outside the envelope."""
        env = self.bounds
        return [j for j in (0, 1) if not env[j, 0] <= q[j] <= env[j, 1]]

    def message(self, q: NDArray[np.float64], joints: list[int]) -> str:
        """The fault message for ``joints`` of ``q`` outside the envelope."""
        parts = []
        for j in joints:
            lo, hi = self.bounds[j]
            parts.append(f"{self.joint_names[j]} = {q[j]:.4f} rad outside the safety envelope "
                         f"[{lo:.4f}, {hi:.4f}] rad")
        return "joint limit violation: " + "; ".join(parts)

    def check(self, q: NDArray[np.float64]) -> tuple[list[int], str]:
        """The tick's check: the joints outside, and a fault message when one of them is not
        recovering (empty otherwise). Joints back inside end their recovery."""
        outside = self.outside(q)
        if outside and not all(self.recovering[j] for j in outside):
            return outside, self.message(q, outside)
        self.recovering[[j for j in (0, 1) if j not in outside]] = False
        return outside, ""

    def arm_recovery(self, q: NDArray[np.float64]) -> None:
        """A limit fault is cleared at ``q``: the joints outside may move back in."""
        for j in self.outside(q):
            self.recovering[j] = True

    def drives_further_out(
        self, q: NDArray[np.float64], cmd: NDArray[np.float64], outside: list[int]
    ) -> str:
        """The fault message when ``cmd`` drives a recovering joint further out, else ""."""
        for j in outside:
            lo, hi = self.bounds[j]
            if (q[j] > hi and cmd[j] > 0.0) or (q[j] < lo and cmd[j] < 0.0):
                return self.message(q, [j])
        return ""
