"""The transport planning request and result types (thesis Ch. 5, Exp. 2a), and the names
of the planners (decoupled, strict6, strict8: the thesis' three Exp. 2a systems), of OMPL's
search algorithms they run and of the phases.

Their own module so that ``planning.api`` (the front door, ``plan``) and the OMPL backend
(``planning.ompl_planner``) both read them without importing each other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from articutool.trajectory import JointTrajectory

__all__ = [
    "ALGORITHMS",
    "PHASES",
    "PLANNERS",
    "PlanRequest",
    "PlanResult",
    "TransportTask",
]

PLANNERS = ("decoupled", "strict6", "strict8")
ALGORITHMS = ("rrtconnect", "rrtstar")
# Phases of one plan() call, in order (PlanResult.phases): building the problem and checking
# the endpoints, the OMPL search, path simplification, time parameterisation, the dense
# re-check of the timed trajectory, and (decoupled) verification.
PHASES = ("setup", "search", "simplify", "timing", "recheck", "verify")


@dataclass(frozen=True)
class TransportTask:
    """One Exp. 2a transport task: level tool at both ends, collision-free."""

    task_id: int
    start: tuple[float, ...]  # 6 arm joints (rad)
    goal: tuple[float, ...]  # 6 arm joints (rad)
    # wrist [pitch, roll] for strict8 (8-DOF start = start + start_wrist)
    start_wrist: tuple[float, float] = (0.0, 0.0)
    goal_wrist: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class PlanRequest:
    """What to plan and how."""

    planner: str  # "decoupled" | "strict6" | "strict8"
    task: TransportTask
    timeout_s: float = 30.0
    algorithm: str = "rrtconnect"  # or "rrtstar"
    seed: int = 0
    tolerance_deg: float | None = None  # strict planners: ±tol pitch/roll (default 10)
    wrist_aware_timing: bool = True  # decoupled: wrist velocity limit in time parameterisation
    utensil: str = "spoon"


@dataclass(frozen=True)
class PlanResult:
    """Outcome of one :func:`plan` call. Its record keeps the benchmark's keys: ``system``
    is the planner, ``planner`` the search algorithm."""

    planner: str
    task_id: int
    success: bool
    planning_time_s: float  # wall time incl. retries, timing and verification
    attempts: int  # planning attempts (decoupled: 1 + replans after failed verification)
    verification_rejections: int  # decoupled: plans the verifier rejected
    path_length: float  # joint-space length of the arm path (rad), nan if failed
    max_tilt_deg: float  # max tool-tip tilt from level along the executed path, nan if failed
    verified: bool | None  # decoupled: final verification outcome; strict: None
    message: str
    trajectory: JointTrajectory | None  # time-parameterised arm (6 or 8 joints)
    wrist_trajectory: JointTrajectory | None  # decoupled: leveling trajectory from the verifier
    algorithm: str = ""  # OMPL's name of the algorithm that found the path (e.g. "RRTConnect")
    # Wall time (s) per phase, summed over attempts: setup, search, simplify, timing,
    # recheck, verify (see ``PHASES``); what is left of planning_time_s is glue.
    phases: dict[str, float] = field(default_factory=dict)

    def to_record(self) -> dict[str, Any]:
        """JSON-serialisable summary without the trajectories (NaN becomes ``None``)."""

        def num(x: float) -> float | None:
            return None if not math.isfinite(x) else float(x)

        return {
            "system": self.planner,
            "task_id": int(self.task_id),
            "success": bool(self.success),
            "planning_time_s": float(self.planning_time_s),
            "attempts": int(self.attempts),
            "verification_rejections": int(self.verification_rejections),
            "path_length": num(self.path_length),
            "max_tilt_deg": num(self.max_tilt_deg),
            "verified": self.verified,
            "message": self.message,
            "duration_s": (
                float(self.trajectory.times[-1]) if self.trajectory is not None else None
            ),
            "phases_s": {k: float(v) for k, v in self.phases.items()},
        }
