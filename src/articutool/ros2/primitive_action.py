"""``ExecuteArticutoolPrimitive`` on ``orientation_control/execute_primitive``: a primitive
forwarded to the tool's goal of the same UUID, with its feedback, result and cancel.

A goal's UUID is the link goal's, so a ROS 2 cancel reaches the tool's goal. A cancel is
accepted at once and forwarded once rclpy has marked the goal CANCELING (the tool's CANCELED
result then never reaches the goal first, which would end it ABORTED and drop the cancel). A
primitive name the tool does not know is refused with the tool's own message, without a thread
or a link round trip. The server lives on the safety node (its cancels are stops) and shares
its goal table with ``FollowJointTrajectory`` (:class:`~articutool.ros2.goals.GoalTable`).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Any

from articutool.link import messages as m
from articutool.link.client import LinkError
from articutool.ros2.admission import primitive_refusal
from articutool.ros2.goals import Forwarded, GoalTable
from articutool.ros2.serving import Side, in_thread

__all__ = ["PrimitiveActionServer"]

_log = logging.getLogger(__name__)


class PrimitiveActionServer:
    """The primitive action on ``side`` (the safety node), forwarding to ``client``'s tool;
    a cancel that cannot be forwarded is logged on ``log`` (the main node's logger)."""

    def __init__(self, client: Any, side: Side, name: str, goals: GoalTable,
                 log: Any) -> None:
        from articutool_interfaces.action import ExecuteArticutoolPrimitive

        self._client, self._side, self._goals, self._log = client, side, goals, log
        self._type = ExecuteArticutoolPrimitive
        self._server = goals.action_server(side, ExecuteArticutoolPrimitive, name,
                                           self._execute, self._on_cancel_request)

    def destroy(self) -> None:
        self._server.destroy()

    def _on_cancel_request(self, goal_handle: Any) -> Any:
        """Accept the cancel of a goal this node runs; a thread forwards it to the tool once
        rclpy has marked the goal CANCELING (see :meth:`_forward_cancel`)."""
        gid = bytes(goal_handle.goal_id.uuid)
        fwd, first = self._goals.request_cancel(gid)
        if fwd is None:
            return self._goals.cancel_no
        if first:
            threading.Thread(target=self._forward_cancel, args=(gid, goal_handle, fwd),
                             name="ros2-cancel", daemon=True).start()
        return self._goals.cancel_ok

    def _forward_cancel(self, gid: bytes, goal_handle: Any, fwd: Forwarded) -> None:
        """Cancel ``gid`` on the tool, after rclpy has taken the accepted cancel (the callback
        has returned): forwarding from the callback itself let the tool's CANCELED result
        reach :meth:`_execute` first, which then aborted the goal, and rclpy dropped the
        cancel (``goals_canceling=[]``). A goal whose send_goal has not reached the tool yet
        is unknown there: retried until it runs, or ends, or the link's call bound passes."""
        client, log = self._client, self._log
        bound = client.cfg.call_timeout + client.cfg.tool_timeout
        deadline = time.monotonic() + bound
        while not goal_handle.is_cancel_requested:
            if fwd.done.wait(0.005) or time.monotonic() > deadline:
                return  # ended meanwhile (rclpy then refused the cancel), or never marked
        deadline = time.monotonic() + bound
        while not fwd.done.is_set():
            try:
                if client.cancel(gid):
                    return
            except (ValueError, LinkError) as err:
                log.warning(f"cancel of goal {gid.hex()} not forwarded: {err}")
                return
            if fwd.done.wait(0.05):
                return
            if time.monotonic() > deadline:
                log.warning(f"the tool did not cancel goal {gid.hex()} within {bound:g} s")
                return

    async def _execute(self, goal_handle: Any) -> Any:
        A = self._type
        gid = bytes(goal_handle.goal_id.uuid)
        goal = goal_handle.request
        client = self._client

        def feedback(st: Any) -> None:
            fb = A.Feedback(feedback_string=str(st.feedback),
                            percent_complete=float(st.percent_complete),
                            current_joint_values=[float(v) for v in st.current_joint_values])
            try:
                goal_handle.publish_feedback(fb)
            except Exception as err:  # the goal ended meanwhile
                _log.debug("feedback dropped: %s", err)

        fwd = self._goals.track(gid)
        refusal = primitive_refusal(goal.primitive_name)  # no thread, no link round trip
        if refusal is not None:
            self._goals.end(gid, fwd)
            goal_handle.abort()
            return A.Result(success=False, message=refusal, final_joint_values=[])
        if goal_handle.is_cancel_requested:  # cancelled before it was sent: never start it
            self._goals.end(gid, fwd)
            goal_handle.canceled()
            return A.Result(success=False, message="cancelled before it started",
                            final_joint_values=[])

        def run() -> tuple[bool, str, tuple[float, ...], int]:
            try:
                res = client.run_primitive(str(goal.primitive_name),
                                           [float(v) for v in goal.parameters], feedback,
                                           goal_id=gid)
                return res.success, res.message, res.final_joint_values, res.status
            except (ValueError, LinkError) as err:
                return False, str(err), (), m.GoalStatus.ABORTED
            except Exception as err:
                _log.exception("execute_primitive failed")
                return (False, f"internal error: {type(err).__name__}: {err}", (),
                        m.GoalStatus.ABORTED)

        try:
            ok, msg, joints, status = await in_thread(run, self._side.wake, "ros2-goal")
        finally:
            self._goals.end(gid, fwd)
        if status == m.GoalStatus.CANCELED and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        elif ok:
            goal_handle.succeed()
        else:
            goal_handle.abort()
        return A.Result(success=bool(ok), message=str(msg),
                        final_joint_values=[float(v) for v in joints])
