"""The goals ``articutool ros2``'s two actions forward (``ExecuteArticutoolPrimitive`` and
``FollowJointTrajectory``), in one table: at most ``max_goals`` run at once across both (more
are rejected), a goal is known from its acceptance on (so a cancel that arrives before its
execute callback starts counts), and a cancel is marked on the goal it names.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Forwarded", "GoalTable"]


@dataclass
class Forwarded:
    """A ROS 2 goal being forwarded: ``done`` once its execute callback has its result."""

    done: threading.Event = field(default_factory=threading.Event)
    cancel_requested: bool = False


class GoalTable:
    """The forwarded goals, by UUID (the link goal's id), accepted and not yet ended."""

    def __init__(self, max_goals: int) -> None:
        from rclpy.action import CancelResponse, GoalResponse
        self.max_goals = max_goals
        self.goal_ok, self.goal_no = GoalResponse.ACCEPT, GoalResponse.REJECT
        self.cancel_ok, self.cancel_no = CancelResponse.ACCEPT, CancelResponse.REJECT
        self._lock = threading.Lock()
        self._running: dict[bytes, Forwarded] = {}

    def on_goal(self, _goal: Any) -> Any:
        """An action's goal callback: reject while ``max_goals`` goals run."""
        with self._lock:
            busy = len(self._running) >= self.max_goals
        return self.goal_no if busy else self.goal_ok

    def on_accepted(self, goal_handle: Any) -> None:
        """An action's accepted callback: known from here on, then executed."""
        with self._lock:
            self._running[bytes(goal_handle.goal_id.uuid)] = Forwarded()
        goal_handle.execute()

    def action_server(self, side: Any, action_type: Any, name: str, execute: Any,
                      cancel: Any) -> Any:
        """An rclpy ActionServer on ``side`` (a :class:`~articutool.ros2.serving.Side`) whose
        goals this table admits, with ``execute`` and the ``cancel`` callback; every request
        queue of the side's depth."""
        from rclpy.action import ActionServer
        q = side.qos
        return ActionServer(side.node, action_type, name, execute, goal_callback=self.on_goal,
                            handle_accepted_callback=self.on_accepted, cancel_callback=cancel,
                            goal_service_qos_profile=q, result_service_qos_profile=q,
                            cancel_service_qos_profile=q, callback_group=side.group)

    def track(self, gid: bytes) -> Forwarded:
        """The entry of goal ``gid`` (made if the accepted callback did not)."""
        with self._lock:
            return self._running.setdefault(gid, Forwarded())

    def end(self, gid: bytes, fwd: Forwarded) -> None:
        """Goal ``gid`` has its result: done, and no longer cancellable or counted."""
        fwd.done.set()
        with self._lock:
            self._running.pop(gid, None)

    def request_cancel(self, gid: bytes) -> tuple[Forwarded | None, bool]:
        """Mark a cancel of ``gid``: (its entry, whether this is its first cancel), or
        (None, False) when no goal of that id runs (the cancel is to be rejected)."""
        with self._lock:
            fwd = self._running.get(gid)
            if fwd is None or fwd.done.is_set():
                return None, False
            first, fwd.cancel_requested = not fwd.cancel_requested, True
        return fwd, first

    def active(self) -> list[bytes]:
        """The ids of the goals still running."""
        with self._lock:
            return list(self._running)
