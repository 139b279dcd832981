"""Transport planning API shared by the planners and the Exp. 2a benchmark runner.

Three planners (the thesis' three systems, Ch. 5, Exp. 2a):

* ``decoupled`` — 6-DOF arm path under a loose tool-base orientation constraint, time
  parameterisation, then plan-then-verify (Alg. 2) with the wrist leveling the utensil.
* ``strict6`` — 6-DOF arm with the rigid utensil (wrist locked at 0); tip level within ±tol.
* ``strict8`` — 8-DOF arm + wrist; tip level within ±tol.

The request/result types live in ``planning.types``.
"""

from __future__ import annotations

import math

from articutool.planning.types import (
    ALGORITHMS,
    PLANNERS,
    PlanRequest,
    PlanResult,
)
from articutool.spec import Spec

__all__ = ["plan", "validate_request"]


def validate_request(request: PlanRequest) -> None:
    """Raise ``ValueError`` naming the field and allowed values for a malformed request."""
    if request.planner not in PLANNERS:
        raise ValueError(f"planner must be one of {PLANNERS}; got {request.planner!r}")
    if request.algorithm not in ALGORITHMS:
        raise ValueError(f"algorithm must be one of {ALGORITHMS}; got {request.algorithm!r}")
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
    """Plan one transport task with the requested planner.

    Never raises for a planning failure (``success=False`` with a message); raises
    ``ValueError`` for a bad request (unknown planner/algorithm, timeout <= 0, non-finite task).
    Deterministic given ``request.seed`` (up to the wall-clock timeout).
    """
    from articutool.planning.ompl_planner import plan_transport

    validate_request(request)
    if spec is None:
        from articutool.spec import load_spec

        spec = load_spec()
    return plan_transport(request, spec)
