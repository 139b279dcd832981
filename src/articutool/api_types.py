"""Structural types shared across subsystems (so pure modules need not import Pinocchio)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["ArmKinematics", "JobResult", "OrientationModel"]


class OrientationModel(Protocol):
    """What the verifier needs of an arm model (``articutool.arm.ArmModel`` provides it)."""

    def tool_base_rotations(self, q_arm: ArrayLike) -> NDArray[np.float64]:
        """(..., 6) → (..., 3, 3) rotations of F0 in the arm base frame."""
        ...

    def tool_base_angular_velocity(
        self, q_arm: ArrayLike, qd_arm: ArrayLike
    ) -> NDArray[np.float64]:
        """(..., 6), (..., 6) → (..., 3) angular velocity of F0 in the arm base frame."""
        ...


class ArmKinematics(OrientationModel, Protocol):
    """What the transport simulation needs of an arm model (``ArmModel`` provides it)."""

    def tool_base_pose(self, q_arm: ArrayLike) -> NDArray[np.float64]:
        """(6,) arm configuration → (4, 4) pose of F0 in the arm base frame."""
        ...

    def tool_base_kinematics(
        self, q_arm: ArrayLike, qd_arm: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(..., 6), (..., 6) → rotations (..., 3, 3) and angular velocities (..., 3) of F0."""
        ...


@dataclass(frozen=True)
class JobResult:
    """How a job ended: ``ok``, a message a person understands, its value (a plan), and
    ``wall_s``, the wall time the job's own work took (a plan: the planner's time, not the
    simulated time that passed meanwhile)."""

    ok: bool
    message: str = ""
    value: Any = None
    wall_s: float = 0.0
