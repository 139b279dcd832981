"""``articutool ros2``: the Articutool's API on a ROS 2 graph, forwarded over the paired link.

An rclpy node on the PC (thesis §3.2.2's three command modalities and the tool's telemetry)
that a ROS 2 stack (MoveIt, a behaviour tree, ADA) uses like the original onboard node, while
the wrist itself only trusts the paired PC: every request is forwarded by an
:class:`~articutool.link.client.ArticutoolClient` (signed commands, lease, heartbeat), and the
replies are the tool's own. Names (``<id>`` is the tool's identity)::

    /articutool/<id>/set_orientation_control  articutool_interfaces/srv/SetOrientationControl
    /articutool/<id>/execute_primitive        articutool_interfaces/action/
                                                ExecuteArticutoolPrimitive
    /articutool/<id>/clear_fault              std_srvs/srv/Trigger
    /articutool/<id>/joint_trajectory         trajectory_msgs/msg/JointTrajectory  (in)
    /articutool/<id>/joint_states, imu/data, health, battery                        (out)

Telemetry is forwarded as the CDR bytes the tool sent (rclpy publishes serialised messages
as they are), so ROS 2 subscribers see exactly the link's messages. A ROS 2 goal's UUID is
the link goal's UUID, so a ROS 2 cancel reaches the tool's goal. A ROS 2 cancel of a goal
this node runs is accepted at once and forwarded to the tool only once rclpy has marked the
goal CANCELING: the tool's CANCELED result can then never reach the goal before the cancel
does (it would end the goal ABORTED and rclpy would drop the accepted cancel). Services and
goals never
raise into the executor: a request the client refuses (bad numbers, a silent tool) is
answered ``success=false`` with the same message ``articutool client`` prints.
"""

from __future__ import annotations

import logging
import re
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.client import ArticutoolClient, LinkError

__all__ = ["ROS_NAME_TOKEN", "ArticutoolRos2Node", "check_ros_token"]

_log = logging.getLogger(__name__)

# A ROS 2 name token (rcl's validate_topic_name): letters, digits, underscores, no leading
# digit; node names follow the same rule.
ROS_NAME_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def check_ros_token(value: str, field: str) -> str:
    """``value`` if it can be one token of a ROS 2 name, else ValueError naming ``field``."""
    if not ROS_NAME_TOKEN.fullmatch(value or "") or "__" in value:
        raise ValueError(f"{field} must be a ROS 2 name token (letters, digits and single "
                         f"underscores, not starting with a digit); got {value!r}")
    return value


@dataclass
class _Forwarded:
    """A ROS 2 goal this node forwards: ``done`` once its execute callback has its result."""

    done: threading.Event = field(default_factory=threading.Event)
    cancel_requested: bool = False


class ArticutoolRos2Node:
    """The rclpy node forwarding the Articutool API to ``client``'s tool (thesis §3.2.2).

    ``ros_id`` is the ``<id>`` in the ROS 2 names (default: the link's ``tool_id``). rclpy
    must be initialised; callbacks run in ``executor`` threads (one reentrant group, so a
    cancel is served while a goal's execute callback waits for the tool).
    """

    def __init__(self, client: ArticutoolClient, ros_id: str | None = None,
                 context: Any = None) -> None:
        from action_msgs.msg import GoalStatus
        from articutool_interfaces.action import ExecuteArticutoolPrimitive
        from articutool_interfaces.srv import SetOrientationControl
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.action import ActionServer, CancelResponse, GoalResponse
        from rclpy.callback_groups import ReentrantCallbackGroup
        from rclpy.node import Node
        from rclpy.qos import QoSProfile
        from sensor_msgs.msg import BatteryState, Imu, JointState
        from std_srvs.srv import Trigger
        from trajectory_msgs.msg import JointTrajectory

        self.client = client
        self.ros_id = check_ros_token(ros_id or client.cfg.tool_id, "tool id")
        self.prefix = f"/articutool/{self.ros_id}"
        self.node = Node(f"articutool_{self.ros_id}", context=context)
        self._action_type = ExecuteArticutoolPrimitive
        self._terminal = {GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_CANCELED,
                          GoalStatus.STATUS_ABORTED}
        self._lock = threading.Lock()
        self._running: dict[bytes, _Forwarded] = {}  # accepted, result not yet sent
        # Before any callback can run: the telemetry subscriptions below fire at once.
        self.counters = {"forwarded": 0, "dropped": 0, "trajectories": 0}
        self._cancel_ok = CancelResponse.ACCEPT
        self._cancel_no = CancelResponse.REJECT
        group = ReentrantCallbackGroup()
        qos = QoSProfile(depth=10)  # reliable, volatile: matches ROS 2's default subscribers
        p = self.prefix
        self.node.create_service(SetOrientationControl, f"{p}/set_orientation_control",
                                 self._on_set_mode, callback_group=group)
        self.node.create_service(Trigger, f"{p}/clear_fault", self._on_clear_fault,
                                 callback_group=group)
        self._action = ActionServer(
            self.node, ExecuteArticutoolPrimitive, f"{p}/execute_primitive", self._execute,
            goal_callback=lambda _goal: GoalResponse.ACCEPT,
            handle_accepted_callback=self._on_accepted,
            cancel_callback=self._on_cancel_request, callback_group=group)
        self.node.create_subscription(JointTrajectory, f"{p}/joint_trajectory",
                                      self._on_trajectory, qos, callback_group=group, raw=True)
        n = client.names
        self._forward = []
        for ep, cls in ((n.joint_states, JointState), (n.imu, Imu),
                        (n.health, DiagnosticArray), (n.battery, BatteryState)):
            rel = ep.name.rsplit(f"/{client.cfg.tool_id}/", 1)[1]
            pub = self.node.create_publisher(cls, f"{p}/{rel}", qos)
            self._forward.append(client.transport.subscribe(ep, self._forwarder(pub, ep.type)))

    # ------------------------------------------------------------------ telemetry --
    def _forwarder(self, pub: Any, typename: str) -> Any:
        def on_data(data: bytes) -> None:
            try:  # only well-formed messages of the right type reach the ROS 2 graph
                cdr.decode(data, typename)
                pub.publish(bytes(data))
                self.counters["forwarded"] += 1
            except Exception as err:  # malformed payload, or rclpy shutting down
                self.counters["dropped"] += 1
                _log.debug("telemetry not forwarded: %s", err)
        return on_data

    # ------------------------------------------------------------------- services --
    def _on_set_mode(self, request: Any, response: Any) -> Any:
        try:
            ok, msg = self.client.set_mode(int(request.control_mode),
                                           float(request.pitch_offset),
                                           float(request.roll_offset))
        except (ValueError, LinkError) as err:
            ok, msg = False, str(err)
        except Exception as err:  # never into the executor
            _log.exception("set_orientation_control failed")
            ok, msg = False, f"internal error: {type(err).__name__}: {err}"
        response.success, response.message = bool(ok), str(msg)
        return response

    def _on_clear_fault(self, _request: Any, response: Any) -> Any:
        try:
            ok, msg = self.client.clear_fault()
        except LinkError as err:
            ok, msg = False, str(err)
        except Exception as err:
            _log.exception("clear_fault failed")
            ok, msg = False, f"internal error: {type(err).__name__}: {err}"
        response.success, response.message = bool(ok), str(msg)
        return response

    def _on_trajectory(self, data: bytes) -> None:
        """A ROS 2 wrist trajectory (serialised) → the tool; header.stamp 0 = start now."""
        try:
            msg = cdr.decode(data, cdr.JOINT_TRAJECTORY)
            traj = m.trajectory_from_msg(msg)
            stamp = m.stamp_to_time(msg.header.stamp)
            self.client.follow_trajectory(traj, start_at=stamp if stamp > 0 else None)
            self.counters["trajectories"] += 1
        except Exception as err:  # a topic has no reply: say why it was not sent
            self.node.get_logger().warning(f"joint_trajectory not forwarded: {err}")

    # --------------------------------------------------------------------- action --
    def _on_accepted(self, goal_handle: Any) -> None:
        """Known from acceptance on, so a cancel before the execute callback starts counts."""
        with self._lock:
            self._running[bytes(goal_handle.goal_id.uuid)] = _Forwarded()
        goal_handle.execute()

    def _on_cancel_request(self, goal_handle: Any) -> Any:
        """Accept the cancel of a goal this node runs; a thread forwards it to the tool once
        rclpy has marked the goal CANCELING (see :meth:`_forward_cancel`)."""
        gid = bytes(goal_handle.goal_id.uuid)
        with self._lock:
            fwd = self._running.get(gid)
            if fwd is None or fwd.done.is_set():
                return self._cancel_no
            first, fwd.cancel_requested = not fwd.cancel_requested, True
        if first:
            threading.Thread(target=self._forward_cancel, args=(gid, goal_handle, fwd),
                             name="ros2-cancel", daemon=True).start()
        return self._cancel_ok

    def _forward_cancel(self, gid: bytes, goal_handle: Any, fwd: _Forwarded) -> None:
        """Cancel ``gid`` on the tool, after rclpy has taken the accepted cancel (the callback
        has returned): forwarding from the callback itself let the tool's CANCELED result
        reach :meth:`_execute` first, which then aborted the goal, and rclpy dropped the
        cancel (``goals_canceling=[]``). A goal whose send_goal has not reached the tool yet
        is unknown there: retried until it runs, or ends, or the link's call bound passes."""
        bound = self.client.cfg.call_timeout + self.client.cfg.tool_timeout
        deadline = time.monotonic() + bound
        while not goal_handle.is_cancel_requested:
            if fwd.done.wait(0.005) or time.monotonic() > deadline:
                return  # ended meanwhile (rclpy then refused the cancel), or never marked
        deadline = time.monotonic() + bound
        while not fwd.done.is_set():
            try:
                if self.client.cancel(gid):
                    return
            except (ValueError, LinkError) as err:
                self.node.get_logger().warning(f"cancel of goal {gid.hex()} not forwarded: "
                                               f"{err}")
                return
            if fwd.done.wait(0.05):
                return
            if time.monotonic() > deadline:
                self.node.get_logger().warning(
                    f"the tool did not cancel goal {gid.hex()} within {bound:g} s")
                return

    def _execute(self, goal_handle: Any) -> Any:
        A = self._action_type
        gid = bytes(goal_handle.goal_id.uuid)
        goal = goal_handle.request

        def feedback(st: Any) -> None:
            fb = A.Feedback(feedback_string=str(st.feedback),
                            percent_complete=float(st.percent_complete),
                            current_joint_values=[float(v) for v in st.current_joint_values])
            try:
                goal_handle.publish_feedback(fb)
            except Exception as err:  # the goal ended meanwhile
                _log.debug("feedback dropped: %s", err)

        with self._lock:
            fwd = self._running.setdefault(gid, _Forwarded())
        if goal_handle.is_cancel_requested:  # cancelled before it was sent: never start it
            fwd.done.set()
            with self._lock:
                self._running.pop(gid, None)
            goal_handle.canceled()
            return A.Result(success=False, message="cancelled before it started",
                            final_joint_values=[])
        try:
            res = self.client.run_primitive(str(goal.primitive_name),
                                            [float(v) for v in goal.parameters], feedback,
                                            goal_id=gid)
            ok, msg, joints, status = (res.success, res.message, res.final_joint_values,
                                       res.status)
        except (ValueError, LinkError) as err:
            ok, msg, joints, status = False, str(err), (), m.GoalStatus.ABORTED
        except Exception as err:
            _log.exception("execute_primitive failed")
            ok, msg, joints, status = (False, f"internal error: {type(err).__name__}: {err}",
                                       (), m.GoalStatus.ABORTED)
        finally:
            fwd.done.set()
            with self._lock:
                self._running.pop(gid, None)
        if status == m.GoalStatus.CANCELED and goal_handle.is_cancel_requested:
            goal_handle.canceled()
        elif ok:
            goal_handle.succeed()
        else:
            goal_handle.abort()
        return A.Result(success=bool(ok), message=str(msg),
                        final_joint_values=[float(v) for v in joints])

    def cancel_all(self) -> None:
        """Cancel every goal this node forwarded that is still running (on shutdown)."""
        with self._lock:
            active = list(self._running)
        for gid in active:
            try:
                self.client.cancel(gid)
            except LinkError as err:
                _log.warning("could not cancel goal %s: %s", gid.hex(), err)

    def destroy(self) -> None:
        """Stop forwarding and destroy the node (the client is the caller's to close)."""
        for h in self._forward:
            h.close()
        self._action.destroy()
        self.node.destroy_node()
