"""Transport planning API shared by the planners and the Exp. 2a benchmark runner.

Three systems (thesis Ch. 5, Exp. 2a):

* ``decoupled`` — 6-DOF arm path under a loose tool-base orientation constraint, time
  parameterisation, then plan-then-verify (Alg. 2) with the wrist leveling the utensil.
* ``strict6`` — 6-DOF arm with the rigid utensil (wrist locked at 0); tip level within ±tol.
* ``strict8`` — 8-DOF arm + wrist; tip level within ±tol.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from articutool.spec import Spec
from articutool.trajectory import JointTrajectory

__all__ = [
    "PHASES",
    "PLANNERS",
    "SYSTEMS",
    "PlanRequest",
    "PlanResult",
    "TransportTask",
    "plan",
    "validate_request",
]

SYSTEMS = ("decoupled", "strict6", "strict8")
PLANNERS = ("rrtconnect", "rrtstar")
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

    system: str  # "decoupled" | "strict6" | "strict8"
    task: TransportTask
    timeout_s: float = 30.0
    planner: str = "rrtconnect"  # or "rrtstar"
    seed: int = 0
    tolerance_deg: float | None = None  # strict systems: ±tol pitch/roll (default 10)
    wrist_aware_timing: bool = True  # decoupled: wrist velocity limit in time parameterisation
    utensil: str = "spoon"


@dataclass(frozen=True)
class PlanResult:
    """Outcome of one :func:`plan` call."""

    system: str
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
    planner: str = ""  # OMPL's name of the planner that found the path (e.g. "RRTConnect")
    # Wall time (s) per phase, summed over attempts: setup, search, simplify, timing,
    # recheck, verify (see ``PHASES``); what is left of planning_time_s is glue.
    phases: dict[str, float] = field(default_factory=dict)

    def to_record(self) -> dict[str, Any]:
        """JSON-serialisable summary without the trajectories (NaN becomes ``None``)."""

        def num(x: float) -> float | None:
            return None if not math.isfinite(x) else float(x)

        return {
            "system": self.system,
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


def validate_request(request: PlanRequest) -> None:
    """Raise ``ValueError`` naming the field and allowed values for a malformed request."""
    if request.system not in SYSTEMS:
        raise ValueError(f"system must be one of {SYSTEMS}; got {request.system!r}")
    if request.planner not in PLANNERS:
        raise ValueError(f"planner must be one of {PLANNERS}; got {request.planner!r}")
    t = request.timeout_s
    if isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(t) or t <= 0:
        raise ValueError(f"timeout_s must be a finite number > 0 s; got {t!r}")
    if isinstance(request.seed, bool) or not isinstance(request.seed, int) or request.seed < 0:
        raise ValueError(f"seed must be an integer >= 0; got {request.seed!r}")
    tol = request.tolerance_deg
    if tol is not None and (not isinstance(tol, int | float) or not math.isfinite(tol)
                            or not 0 < tol < 90):
        raise ValueError(f"tolerance_deg must be in (0, 90) degrees or None; got {tol!r}")
    task = request.task
    for name, n in (("start", 6), ("goal", 6), ("start_wrist", 2), ("goal_wrist", 2)):
        v = getattr(task, name)
        try:
            vals = [float(x) for x in v]
        except (TypeError, ValueError):
            raise ValueError(f"task.{name} must be {n} numbers (rad); got {v!r}") from None
        if len(vals) != n:
            raise ValueError(f"task.{name} must have {n} joint values (rad); got {len(vals)}")
        if not all(math.isfinite(x) for x in vals):
            raise ValueError(f"task.{name} must be finite (no NaN/inf); got {vals}")


def plan(request: PlanRequest, spec: Spec | None = None) -> PlanResult:
    """Plan one transport task with the requested system.

    Never raises for a planning failure (``success=False`` with a message); raises
    ``ValueError`` for a bad request (unknown system/planner, timeout <= 0, non-finite task).
    Deterministic given ``request.seed`` (up to the wall-clock timeout).
    """
    from articutool.planning.ompl_planner import plan_transport

    validate_request(request)
    if spec is None:
        from articutool.spec import load_spec

        spec = load_spec()
    return plan_transport(request, spec)
