"""The goal table of the ``ExecuteArticutoolPrimitive`` action (thesis §3.2.2, §4.5).

Goals are identified by their goal id, never by comparing primitive statuses: the server is
the only caller of ``start_primitive`` on its ``ToolAPI``, so after it starts goal G every
status the tool reports is G's, until it starts the next goal. The table remembers the
running goal (``active``), finished goals for late ``get_result`` calls (the last
``keep``), and the ``get_result`` callers waiting for a goal to end.

Pure state with no lock of its own: ``ToolServer`` (``link/server.py``) holds its lock around
every call.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field

from articutool.link import messages as m
from articutool.link.transport import Responder
from articutool.tool.api import PrimitiveStatus

__all__ = ["Goal", "GoalTable"]


@dataclass
class Goal:
    """One action goal: its id, primitive, acceptance time, status and (once ended) result."""

    goal_id: bytes
    name: str
    accepted_at: float  # wall clock, for GoalInfo.stamp
    status: int
    cancel_requested: bool = False
    result: m.PrimitiveResult | None = None
    waiters: list[Responder] = field(default_factory=list)


class GoalTable:
    """Goals by id, oldest first, and the one running (``active``)."""

    def __init__(self, keep: int = 32) -> None:
        self.keep = keep  # finished goals remembered for late get_result calls
        self._goals: OrderedDict[bytes, Goal] = OrderedDict()
        self.active: Goal | None = None

    def __contains__(self, goal_id: bytes) -> bool:
        return goal_id in self._goals

    def get(self, goal_id: bytes) -> Goal | None:
        """The goal with ``goal_id``, or None (unknown or forgotten)."""
        return self._goals.get(goal_id)

    def remember(self, goal: Goal) -> None:
        """Record ``goal``, forgetting the oldest finished goals beyond ``keep``."""
        self._goals[goal.goal_id] = goal
        done = [k for k, g in self._goals.items() if g.result is not None]
        for k in done[:max(0, len(self._goals) - self.keep)]:  # never a running goal
            del self._goals[k]

    def statuses(self) -> list[tuple[bytes, float, int]]:
        """(goal id, accepted at, status) of every goal remembered, for the status array."""
        return [(g.goal_id, g.accepted_at, g.status) for g in self._goals.values()]

    def settle(self, read_status: Callable[[], PrimitiveStatus | None]
               ) -> tuple[list[Responder], m.PrimitiveResult] | PrimitiveStatus | None:
        """Read the tool's status for the active goal (``read_status`` is called only when
        one runs). If the goal ended, record its result and return its waiters with it (the
        caller answers them); if it runs, return the status (for feedback); else None."""
        goal = self.active
        if goal is None:
            return None
        st = read_status()
        if st is None:
            return None
        if not st.done:
            return st
        if st.success:
            status = m.GoalStatus.SUCCEEDED
        else:
            status = m.GoalStatus.CANCELED if goal.cancel_requested else m.GoalStatus.ABORTED
        final = tuple(st.final_joint_values) or tuple(st.current_joint_values)
        result = m.PrimitiveResult(bool(st.success), st.message, final, status)
        goal.result, goal.status = result, status
        waiters, goal.waiters = goal.waiters, []
        self.active = None
        return waiters, result
