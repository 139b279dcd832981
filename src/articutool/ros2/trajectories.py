"""Wrist trajectories from ROS 2: ADA's trajectory path (``FollowJointTrajectory`` on
``articutool/joint_trajectory_controller/follow_joint_trajectory``) and our
``articutool/joint_trajectory`` topic, both forwarded to the tool's TRAJECTORY mode.

Joint names may be the ROS 2 names (``joint_names``, upstream's ``atool_joint1``/
``atool_joint2`` for [pitch, roll]) or the tool's own, in any order. A
``FollowJointTrajectory`` goal ends SUCCESSFUL when the wrist is within the goal tolerance
(0.05 rad where none is given) of the last point by the end plus ``goal_time_tolerance``
(0.5 s if zero); INVALID_JOINTS or INVALID_GOAL name the field; a goal the tool does not take
ends INVALID_GOAL saying so; a cancel stops the wrist (through the stop lane). The action lives
on the safety node and shares its goal table with the primitive action.
"""

from __future__ import annotations

import logging
import math
import time
from typing import Any

import numpy as np

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.client import LinkError
from articutool.ros2.goals import GoalTable
from articutool.ros2.lanes import StopLane
from articutool.ros2.serving import Side, in_thread, outcome
from articutool.tool.api import Mode

__all__ = ["FollowJointTrajectoryServer", "TrajectoryTopic"]

# How long the tool's own telemetry may show another mode after a trajectory was sent before
# the trajectory counts as refused (s of the tool's clock).
TAKE_WINDOW_S = 1.0

_log = logging.getLogger(__name__)


class FollowJointTrajectoryServer:
    """``control_msgs/FollowJointTrajectory`` on ``side`` (the safety node) for ``client``'s
    tool; a cancel stops the wrist through ``stops``."""

    def __init__(self, client: Any, side: Side, name: str, goals: GoalTable, stops: StopLane,
                 joint_names: tuple[str, str]) -> None:
        from control_msgs.action import FollowJointTrajectory

        self._client, self._side, self._goals, self._stops = client, side, goals, stops
        self._joint_names = joint_names
        self._type = FollowJointTrajectory
        self._server = goals.action_server(side, FollowJointTrajectory, name, self._execute,
                                           self._on_cancel)

    def destroy(self) -> None:
        self._server.destroy()

    def _on_cancel(self, goal_handle: Any) -> Any:
        fwd, _ = self._goals.request_cancel(bytes(goal_handle.goal_id.uuid))
        return self._goals.cancel_no if fwd is None else self._goals.cancel_ok

    async def _execute(self, goal_handle: Any) -> Any:
        """Forward the trajectory, report progress from the tool's joint states, and end
        SUCCESSFUL when the wrist is at the last point (within the goal tolerance, 0.05 rad
        where none is given) by the end plus ``goal_time_tolerance`` (0.5 s if zero)."""
        F = self._type
        gid = bytes(goal_handle.goal_id.uuid)
        client = self._client
        fwd = self._goals.track(gid)

        def finish(code: int, text: str, how: str) -> Any:
            self._goals.end(gid, fwd)
            getattr(goal_handle, how)()
            return F.Result(error_code=code, error_string=text)

        try:
            traj, tol, slack = self._goal(goal_handle.request)
        except ValueError as err:
            code = F.Result.INVALID_JOINTS if "joint" in str(err) else F.Result.INVALID_GOAL
            return finish(code, str(err), "abort")
        stamp = goal_handle.request.trajectory.header.stamp
        start_at = float(stamp.sec) + float(stamp.nanosec) * 1e-9 or None

        def run() -> str:
            """'' when the trajectory ran to its end, else why not."""
            sent = client.latest_tool_time()  # the tool's time before it can have the trajectory
            try:
                client.follow_trajectory(traj, start_at=start_at)
            except (ValueError, LinkError) as err:
                return str(err)
            t0 = time.time() if start_at is None else start_at
            end = t0 + traj.duration
            taken = False
            while time.time() < end + slack:
                if fwd.cancel_requested:
                    return "cancelled"
                st = client.latest_state()
                now = time.time()
                if st is not None and now >= t0:
                    taken = taken or st.mode is Mode.TRAJECTORY
                    # Refused: the tool's own telemetry, a second on from before the trajectory
                    # was sent, still shows another mode (judged on the tool's clock: a loaded
                    # PC reads the tool's states late).
                    tool_now = client.latest_tool_time()
                    waited = math.inf if sent is None or tool_now is None else tool_now - sent
                    if not taken and now > t0 + 0.5 and waited >= TAKE_WINDOW_S:
                        return (f"the tool did not take the trajectory (its mode is "
                                f"{st.mode.name}; it refuses positions outside the wrist "
                                "limits, velocities above them, or a first point far from "
                                "the present joints)")
                    if taken and st.mode is not Mode.TRAJECTORY:
                        return f"the tool left the trajectory (now {st.mode.name})"
                    self._feedback(goal_handle, traj, now - t0, st.position)
                    if now >= end and np.all(np.abs(np.subtract(
                            st.position, traj.positions[-1])) <= tol):
                        return ""
                time.sleep(0.05)
            return "goal tolerance"

        why = await in_thread(run, self._side.wake, "ros2-trajectory")
        if why == "":
            return finish(F.Result.SUCCESSFUL, "", "succeed")
        if why == "cancelled":
            stop = self._stops.submit(self._side.wake)
            _, msg = await outcome(stop, "stop")
            return finish(F.Result.SUCCESSFUL, f"cancelled; stop: {msg}", "canceled")
        if why == "goal tolerance":
            st = client.latest_state()
            at = None if st is None else [round(float(v), 4) for v in st.position]
            return finish(F.Result.GOAL_TOLERANCE_VIOLATED,
                          f"the wrist is at {at}, not within {list(tol)} rad of the last point "
                          f"{[round(float(v), 4) for v in traj.positions[-1]]}", "abort")
        return finish(F.Result.INVALID_GOAL, why, "abort")

    def _goal(self, goal: Any) -> tuple[Any, np.ndarray, float]:
        """(trajectory in the tool's joint order, per-joint goal tolerance, time slack)."""
        from articutool.ros2.verify_service import BadRequestError, trajectory_from_ros
        from articutool.trajectory import JointTrajectory
        if len(goal.multi_dof_trajectory.points):
            raise ValueError("multi_dof_trajectory is not supported by a 2-joint wrist")
        st = self._client.latest_state()
        if st is None:
            raise ValueError("no joint state from the tool yet")
        ros, tool = list(self._joint_names), list(st.joint_names)
        try:
            traj = trajectory_from_ros(goal.trajectory, "trajectory")
        except BadRequestError as err:
            raise ValueError(str(err)) from None
        names = [tool[ros.index(j)] if j in ros else j for j in traj.joint_names]
        if sorted(names) != sorted(tool):
            raise ValueError(f"trajectory.joint_names must be the wrist's joints {ros} (or "
                             f"{tool}) in any order; got {list(traj.joint_names)}")
        traj = JointTrajectory(tuple(names), traj.times, traj.positions,
                               traj.velocities).reordered(tool)
        tol = np.full(2, 0.05)
        for jt in goal.goal_tolerance:
            name = tool[ros.index(jt.name)] if jt.name in ros else jt.name
            if name in tool and jt.position > 0:
                tol[tool.index(name)] = float(jt.position)
        gt = goal.goal_time_tolerance
        slack = float(gt.sec) + float(gt.nanosec) * 1e-9 or 0.5
        return traj, tol, slack

    def _feedback(self, goal_handle: Any, traj: Any, t: float, actual: Any) -> None:
        from trajectory_msgs.msg import JointTrajectoryPoint
        q, v = traj.sample(t)
        fb = self._type.Feedback(joint_names=list(self._joint_names))
        fb.desired = JointTrajectoryPoint(positions=[float(x) for x in q],
                                          velocities=[float(x) for x in v])
        fb.actual = JointTrajectoryPoint(positions=[float(x) for x in actual])
        fb.error = JointTrajectoryPoint(positions=[float(a - d) for a, d in zip(actual, q,
                                                                                strict=True)])
        try:
            goal_handle.publish_feedback(fb)
        except Exception as err:  # the goal ended meanwhile
            _log.debug("feedback dropped: %s", err)


class TrajectoryTopic:
    """The ``articutool/joint_trajectory`` subscription on ``side`` (the main node): each
    ``trajectory_msgs/JointTrajectory`` (serialised) → ``client``'s tool; header.stamp 0 =
    start now. A topic has no reply: one that is not sent is logged, saying why."""

    def __init__(self, client: Any, side: Side, name: str, joint_names: tuple[str, str],
                 counters: dict[str, int]) -> None:
        from rclpy.qos import QoSProfile
        from trajectory_msgs.msg import JointTrajectory

        self._client, self._node = client, side.node
        self._joint_names, self._counters = joint_names, counters
        # reliable, volatile: matches ROS 2's default publishers
        side.node.create_subscription(JointTrajectory, name, self._on_trajectory,
                                      QoSProfile(depth=10), raw=True,
                                      callback_group=side.group)

    def _on_trajectory(self, data: bytes) -> None:
        try:
            msg = cdr.decode(data, cdr.JOINT_TRAJECTORY)
            ros = list(self._joint_names)
            state = self._client.latest_state()
            if sorted(msg.joint_names) == sorted(ros) and state is not None:
                tool = list(state.joint_names)
                msg.joint_names = [tool[ros.index(str(j))] for j in msg.joint_names]
            traj = m.trajectory_from_msg(msg)
            stamp = m.stamp_to_time(msg.header.stamp)
            self._client.follow_trajectory(traj, start_at=stamp if stamp > 0 else None)
            self._counters["trajectories"] += 1
        except Exception as err:  # a topic has no reply: say why it was not sent
            self._node.get_logger().warning(f"joint_trajectory not forwarded: {err}")
