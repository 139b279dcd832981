"""``articutool ros2``: the Articutool on a ROS 2 graph under the upstream tool's names,
forwarded over the paired link, plus plan-then-verify as a service.

An rclpy node on the PC that ADA's Articutool behaviours (``personalrobotics/ada_feeding``)
and any ROS 2 stack use like the upstream tool nodes (``personalrobotics/articutool_ros2``),
while the wrist itself trusts only the paired PC: every command is forwarded by an
:class:`~articutool.link.client.ArticutoolClient` (signed commands, lease, heartbeat) and
the replies are the tool's own. Names: :mod:`articutool.ros2.names` (upstream names exactly
with an empty namespace).

- ``SetOrientationControl`` on ADA's name and on the upstream node's: offsets in radians by
  default, what ADA's ``CallSetOrientationControl`` sends (``math.radians`` of its inputs), or
  in degrees as the upstream ``.srv`` says with ``offset_units="degrees"``; the unit in force
  is logged at start. MODE_FULL_ORIENTATION (2) forwards ``target_orientation_robot_base``;
  the other modes ignore it. DISABLED is a stop (below).
- ``articutool/stop`` (``std_srvs/Trigger``): DISABLED on the tool, which aborts any
  primitive or trajectory. Stops and the primitive action (its cancels are stops) live on a
  second node with its own executor thread; stop requests from every source share one stop
  thread (:class:`~articutool.ros2.lanes.StopLane`); ordinary requests run on a bounded work
  lane and are refused at once when it is full. No flood of other calls holds a stop back.
- ``ExecuteArticutoolPrimitive``: a goal's UUID is the link goal's, so a ROS 2 cancel
  reaches the tool's goal; a cancel is accepted at once and forwarded once rclpy has marked
  the goal CANCELING (the tool's CANCELED result then never reaches the goal first, which
  would end it ABORTED and drop the cancel). At most ``max_goals`` goals run at once; more
  are rejected.
- ``TriggerCalibration``: answered without calibrating anything, and saying so: the wrist
  levels against gravity alone (the controller is yaw-invariant and the filter leaves yaw
  unobserved), so there is no yaw offset to compute; ``ImuCalibrationStatus`` says
  ``is_yaw_calibrated: false`` (latched).
- Telemetry: joint states under the ROS 2 joint names (``joint_names``, upstream's
  ``atool_joint1``/``atool_joint2`` by default, for [pitch, roll]), IMU, health and battery
  as the tool sent them (well-formed messages only); ``/joint_states`` and upstream's raw and
  calibrated IMU topics: :mod:`articutool.ros2.wrist_topics`.
- ``switch_controller`` and ``list_controllers``: :mod:`articutool.ros2.controllers`.
- ``VerifyTrajectory``: :mod:`articutool.ros2.verify_service`, on its own lane.

The services of the main node (not rclpy's parameter services; the stop is on the safety node)
take all their waiting requests, up to a batch, each time the executor calls them
(:mod:`articutool.ros2.intake`), and request queues are ``queue_depth`` (5 000) deep, so a flood
of bad calls is answered rather than dropped by DDS (docs/ros2.md).

Callbacks never raise into the executor: a request the client refuses (bad numbers, a silent
tool) is answered ``success=false`` with the message ``articutool client`` prints.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.client import ArticutoolClient, LinkError, parse_mode
from articutool.ros2 import wrist_topics
from articutool.ros2.admission import mode_refusal, primitive_refusal
from articutool.ros2.controllers import ControllerBook
from articutool.ros2.intake import create_draining_service
from articutool.ros2.lanes import StopLane, WorkLane
from articutool.ros2.names import resolve
from articutool.tool.api import Mode
from articutool.tool.telemetry import reported_limits

__all__ = ["ArticutoolRos2Node", "NodeSettings"]

_log = logging.getLogger(__name__)

CALIBRATION_MESSAGE = (
    "nothing to calibrate: this wrist levels against gravity alone (its controller is "
    "yaw-invariant and its filter leaves yaw unobserved), so no yaw offset is computed or "
    "applied; computed_offset_jacobase_to_filterworld is the identity")


_LIMITS_TTL = 1.0  # s between reads of the connected tool's reported joint limits


@dataclass(frozen=True)
class NodeSettings:
    """How the node names and reads things (the ROS 2 parameters of ``articutool ros2``)."""

    namespace: str = ""
    joint_names: tuple[str, str] = ("atool_joint1", "atool_joint2")
    offset_units: str = "radians"  # ADA's; the upstream .srv says degrees
    republish_joint_states: bool = True
    verifier: Any = None  # articutool.ros2.verify_service.Verifier, or None: no service
    queue_depth: int = 5000  # DDS history of every service and action request queue
    max_goals: int = 4


@dataclass
class _Forwarded:
    """A ROS 2 goal this node forwards: ``done`` once its execute callback has its result."""

    done: threading.Event = field(default_factory=threading.Event)
    cancel_requested: bool = False


class ArticutoolRos2Node:
    """The rclpy nodes forwarding the Articutool API to ``client``'s tool.

    ``client`` None serves only ``VerifyTrajectory`` (no tool). rclpy must be initialised
    (``context``); :attr:`node` (parameters, ordinary services, telemetry) and
    :attr:`safety_node` (stop, primitive action) each need an executor of their own.
    """

    def __init__(self, client: ArticutoolClient | None, settings: NodeSettings | None = None,
                 context: Any = None, node: Any = None) -> None:
        from rclpy.callback_groups import ReentrantCallbackGroup
        from rclpy.node import Node
        from rclpy.qos import QoSProfile

        self.client = client
        self.settings = s = settings or NodeSettings()
        if s.offset_units not in ("degrees", "radians"):
            raise ValueError(f"offset_units must be 'degrees' or 'radians'; got "
                             f"{s.offset_units!r}")
        self.names = resolve(s.namespace)
        self.node = node if node is not None else Node("articutool_ros2", context=context)
        self.node.get_logger().info(
            f"SetOrientationControl offsets are read in {s.offset_units.upper()} "
            f"(offset_units={s.offset_units}; ADA's CallSetOrientationControl sends radians, "
            "the upstream .srv says degrees)")
        self._qos = QoSProfile(depth=s.queue_depth)
        self.counters = {"forwarded": 0, "dropped": 0, "trajectories": 0, "busy": 0,
                         "stops": 0}
        # Reentrant: a coroutine callback awaiting a lane holds a mutually exclusive group (the
        # node's default) until it ends, which would serialise every request and keep the
        # lanes' wake-up guard condition out of the wait set.
        self._group = ReentrantCallbackGroup()
        self._wake_main = self.node.create_guard_condition(lambda: None,
                                                           callback_group=self._group)
        self._work = WorkLane("ros2-work", threads=2, capacity=16)
        self._verify_lane = WorkLane("ros2-verify", threads=1, capacity=4)
        self.safety_node = None
        self._forward: list[Any] = []
        self._action = None
        if s.verifier is not None:
            from articutool_interfaces.srv import VerifyTrajectory
            create_draining_service(self.node, VerifyTrajectory, self.names["verify_trajectory"],
                                    self._start_verify, qos_profile=self._qos,
                                    callback_group=self._group)
        if client is None:
            return
        self._stops = StopLane(self._stop_tool)
        # No parameter services (it has no parameters): fewer entities for its executor to
        # wait on, so the stop service and the actions' requests are taken sooner.
        self.safety_node = Node(f"{self.node.get_name()}_stop", context=context,
                                namespace=self.node.get_namespace(),
                                start_parameter_services=False)
        self._safety_group = ReentrantCallbackGroup()
        self._wake_safety = self.safety_node.create_guard_condition(
            lambda: None, callback_group=self._safety_group)
        self._lock = threading.Lock()
        self._limits, self._limits_at = None, -math.inf
        self._running: dict[bytes, _Forwarded] = {}  # accepted, result not yet sent
        self._setup_services()
        self._setup_action()
        self._setup_telemetry()
        self._setup_trajectory_path()

    # ------------------------------------------------------------------- set-up --
    def _setup_services(self) -> None:
        from articutool_interfaces.srv import SetOrientationControl, TriggerCalibration
        from std_srvs.srv import Trigger

        n, q, g = self.names, self._qos, self._group
        for key in ("set_orientation_control", "set_orientation_control_mode"):
            create_draining_service(self.node, SetOrientationControl, n[key],
                                    self._start_set_mode, qos_profile=q, callback_group=g)
        create_draining_service(self.node, Trigger, n["clear_fault"], self._start_clear_fault,
                                qos_profile=q, callback_group=g)
        create_draining_service(self.node, TriggerCalibration, n["trigger_calibration"],
                                self._on_calibration, qos_profile=q, callback_group=g)
        self.safety_node.create_service(Trigger, n["stop"], self._on_stop, qos_profile=q,
                                        callback_group=self._safety_group)

    def _setup_action(self) -> None:
        from action_msgs.msg import GoalStatus
        from articutool_interfaces.action import ExecuteArticutoolPrimitive
        from rclpy.action import ActionServer, CancelResponse, GoalResponse

        self._action_type = ExecuteArticutoolPrimitive
        self._terminal = {GoalStatus.STATUS_SUCCEEDED, GoalStatus.STATUS_CANCELED,
                          GoalStatus.STATUS_ABORTED}
        self._cancel_ok, self._cancel_no = CancelResponse.ACCEPT, CancelResponse.REJECT
        self._goal_ok, self._goal_no = GoalResponse.ACCEPT, GoalResponse.REJECT
        q = self._qos
        self._action = ActionServer(
            self.safety_node, ExecuteArticutoolPrimitive, self.names["execute_primitive"],
            self._execute, goal_callback=self._on_goal,
            handle_accepted_callback=self._on_accepted,
            cancel_callback=self._on_cancel_request, goal_service_qos_profile=q,
            result_service_qos_profile=q, cancel_service_qos_profile=q,
            callback_group=self._safety_group)

    def _setup_telemetry(self) -> None:
        from articutool_interfaces.msg import ImuCalibrationStatus
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from sensor_msgs.msg import BatteryState, Imu, JointState
        from trajectory_msgs.msg import JointTrajectory

        assert self.client is not None
        n, c = self.names, self.client
        qos = QoSProfile(depth=10)  # reliable, volatile: matches ROS 2's default subscribers
        self.node.create_subscription(JointTrajectory, n["joint_trajectory"],
                                      self._on_trajectory, qos, raw=True,
                                      callback_group=self._group)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        status_pub = self.node.create_publisher(ImuCalibrationStatus, n["calibration_status"],
                                                latched)
        status = ImuCalibrationStatus(is_yaw_calibrated=False)
        status.header.stamp = self.node.get_clock().now().to_msg()
        status_pub.publish(status)
        for ep, cls, key, convert in (
                (c.names.joint_states, JointState, "joint_states", self._rename_joints),
                (c.names.imu, Imu, "imu", None), (c.names.health, DiagnosticArray, "health", None),
                (c.names.battery, BatteryState, "battery", None)):
            pub = self.node.create_publisher(cls, n[key], qos)
            self._forward.append(c.transport.subscribe(ep, self._forwarder(pub, ep.type,
                                                                           convert)))
        self._forward += wrist_topics.setup(self.node, c, n, self.settings.joint_names,
                                            self.settings.republish_joint_states, self.counters)

    # ------------------------------------------------------------------ telemetry --
    def _rename_joints(self, msg: Any) -> bytes:
        """The tool's [pitch, roll] joint state under the ROS 2 joint names."""
        msg.name = list(self.settings.joint_names)
        return cdr.encode(msg, cdr.JOINT_STATE)

    def _forwarder(self, pub: Any, typename: str, convert: Any) -> Any:
        def on_data(data: bytes) -> None:
            try:  # only well-formed messages of the right type reach the ROS 2 graph
                msg = cdr.decode(data, typename)
                pub.publish(convert(msg) if convert is not None else bytes(data))
                self.counters["forwarded"] += 1
            except Exception as err:  # malformed payload, or rclpy shutting down
                self.counters["dropped"] += 1
                _log.debug("telemetry not forwarded: %s", err)
        return on_data

    def current_wrist(self) -> tuple[float, float] | None:
        """The tool's last joint positions [pitch, roll] (None without a tool or telemetry)."""
        st = self.client.latest_state() if self.client is not None else None
        return None if st is None else (float(st.position[0]), float(st.position[1]))

    # ------------------------------------------------------------------- services --
    def _start_set_mode(self, request: Any, response: Any) -> Any:
        """The response when the node answers at once (a refusal, a busy lane), else the
        coroutine that awaits the tool (:mod:`articutool.ros2.intake`)."""
        mode = int(request.control_mode)
        scale = (180.0 / math.pi) if self.settings.offset_units == "radians" else 1.0
        pitch, roll = float(request.pitch_offset) * scale, float(request.roll_offset) * scale
        assert self.client is not None
        client = self.client
        t = request.target_orientation_robot_base
        target = (float(t.x), float(t.y), float(t.z), float(t.w))
        try:  # refused here, as the link client would, without waiting for a lane
            m.soc_request(parse_mode(mode), pitch, roll, target)
        except ValueError as err:
            response.success, response.message = False, str(err)
            return response
        # as the connected tool would (its reported limits): no link round trip
        refusal = mode_refusal(mode, pitch, roll, self._tool_limits())
        if refusal is not None:
            response.success, response.message = False, refusal
            return response
        if mode == Mode.DISABLED:  # every DISABLED is a stop
            future = self._stops.submit(self._wake_main)
        else:
            future = self._submit(lambda: client.set_mode(mode, pitch, roll, target))
        return self._finish(future, response, "set_orientation_control")

    async def _finish(self, future: Any, response: Any, what: str) -> Any:
        response.success, response.message = await self._outcome(future, what)
        return response

    def _tool_limits(self) -> Any:
        """The connected tool's joint limits as it reports them, read at most every
        ``_LIMITS_TTL`` s (a state is rebuilt from telemetry on each read)."""
        now = time.monotonic()
        if now - self._limits_at > _LIMITS_TTL:
            assert self.client is not None
            self._limits, self._limits_at = reported_limits(self.client.latest_state()), now
        return self._limits

    async def _on_stop(self, _request: Any, response: Any) -> Any:
        future = self._stops.submit(self._wake_safety)
        response.success, response.message = await self._outcome(future, "stop")
        return response

    def _stop_tool(self) -> tuple[bool, str]:
        assert self.client is not None
        self.counters["stops"] += 1
        return self.client.set_mode(Mode.DISABLED)

    def _start_clear_fault(self, _request: Any, response: Any) -> Any:
        assert self.client is not None
        return self._finish(self._submit(self.client.clear_fault), response, "clear_fault")

    def _on_calibration(self, _request: Any, response: Any) -> Any:
        response.success, response.message = True, CALIBRATION_MESSAGE
        q = response.computed_offset_jacobase_to_filterworld
        q.x, q.y, q.z, q.w = 0.0, 0.0, 0.0, 1.0
        return response

    def _submit(self, fn: Any, lane: WorkLane | None = None) -> Any:
        future = (lane or self._work).submit(fn, self._wake_main)
        if future is None:
            self.counters["busy"] += 1
        return future

    async def _outcome(self, future: Any, what: str) -> tuple[bool, str]:
        if future is None:
            return False, "refused: busy (too many requests waiting for the tool); try again"
        try:
            ok, msg = await future
            return bool(ok), str(msg)
        except (ValueError, LinkError) as err:
            return False, str(err)
        except Exception as err:  # never into the executor
            _log.exception("%s failed", what)
            return False, f"internal error: {type(err).__name__}: {err}"

    def _start_verify(self, request: Any, response: Any) -> Any:
        verifier = self.settings.verifier
        wrist = self.current_wrist()
        future = self._submit(lambda: verifier.answer(request, wrist), self._verify_lane)
        if future is None:
            return _fill_verify(response, {
                "feasible": False, "reason": "busy", "first_failure_time": -1.0,
                "message": "refused: busy (verifications waiting); try again",
                "velocity_margin": math.nan, "predicted_spill_g": math.nan})
        return self._finish_verify(future, response)

    async def _finish_verify(self, future: Any, response: Any) -> Any:
        try:
            out = await future
        except Exception as err:
            _log.exception("verify_trajectory failed")
            out = {"feasible": False, "reason": "error", "first_failure_time": -1.0,
                   "message": f"internal error: {type(err).__name__}: {err}",
                   "velocity_margin": math.nan, "predicted_spill_g": math.nan}
        return _fill_verify(response, out)

    def _on_trajectory(self, data: bytes) -> None:
        """A ROS 2 wrist trajectory (serialised) → the tool; header.stamp 0 = start now.
        Joint names may be the ROS 2 names (``joint_names``) or the tool's own."""
        assert self.client is not None
        try:
            msg = cdr.decode(data, cdr.JOINT_TRAJECTORY)
            ros = list(self.settings.joint_names)
            state = self.client.latest_state()
            if sorted(msg.joint_names) == sorted(ros) and state is not None:
                tool = list(state.joint_names)
                msg.joint_names = [tool[ros.index(str(j))] for j in msg.joint_names]
            traj = m.trajectory_from_msg(msg)
            stamp = m.stamp_to_time(msg.header.stamp)
            self.client.follow_trajectory(traj, start_at=stamp if stamp > 0 else None)
            self.counters["trajectories"] += 1
        except Exception as err:  # a topic has no reply: say why it was not sent
            self.node.get_logger().warning(f"joint_trajectory not forwarded: {err}")

    # --------------------------------------------------------------------- action --
    def _on_goal(self, _goal: Any) -> Any:
        with self._lock:
            busy = len(self._running) >= self.settings.max_goals
        return self._goal_no if busy else self._goal_ok

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
        assert self.client is not None
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

    async def _execute(self, goal_handle: Any) -> Any:
        from rclpy.task import Future
        A = self._action_type
        gid = bytes(goal_handle.goal_id.uuid)
        goal = goal_handle.request
        assert self.client is not None
        client = self.client

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
        refusal = primitive_refusal(goal.primitive_name)  # no thread, no link round trip
        if refusal is not None:
            fwd.done.set()
            with self._lock:
                self._running.pop(gid, None)
            goal_handle.abort()
            return A.Result(success=False, message=refusal, final_joint_values=[])
        if goal_handle.is_cancel_requested:  # cancelled before it was sent: never start it
            fwd.done.set()
            with self._lock:
                self._running.pop(gid, None)
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

        future: Future = Future()
        wake = self._wake_safety
        threading.Thread(target=lambda: (future.set_result(run()), wake.trigger()),
                         name="ros2-goal", daemon=True).start()
        try:
            ok, msg, joints, status = await future
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

    # ------------------------------------------------------- the trajectory path --
    def _setup_trajectory_path(self) -> None:
        """ADA's trajectory path: FollowJointTrajectory and the controller switch, when their
        interface packages are installed (``make`` builds them where they are not)."""
        try:
            from control_msgs.action import FollowJointTrajectory
            from controller_manager_msgs.srv import ListControllers, SwitchController
        except ImportError as err:
            self.node.get_logger().warning(f"trajectory path not served: {err}")
            return
        from rclpy.action import ActionServer

        n, q = self.names, self._qos
        self._fjt_type = FollowJointTrajectory
        self._fjt = ActionServer(
            self.safety_node, FollowJointTrajectory, n["follow_joint_trajectory"],
            self._execute_fjt, goal_callback=self._on_goal,
            handle_accepted_callback=self._on_accepted, cancel_callback=self._on_cancel_fjt,
            goal_service_qos_profile=q, result_service_qos_profile=q,
            cancel_service_qos_profile=q, callback_group=self._safety_group)
        self._controllers = ControllerBook(self.settings.joint_names)
        create_draining_service(self.node, SwitchController, n["switch_controller"],
                                self._on_switch_controller, qos_profile=q,
                                callback_group=self._group)
        create_draining_service(self.node, ListControllers, n["list_controllers"],
                                self._on_list_controllers, qos_profile=q,
                                callback_group=self._group)

    def _on_switch_controller(self, request: Any, response: Any) -> Any:
        """The wrist picks its control law per command (a trajectory, a primitive, a mode), so
        a switch changes only what ``list_controllers`` answers, with ros2_control's
        strictness (:class:`~articutool.ros2.controllers.ControllerBook`)."""
        activate = [str(c) for c in (*request.activate_controllers,
                                     *getattr(request, "start_controllers", []))]
        deactivate = [str(c) for c in (*request.deactivate_controllers,
                                       *getattr(request, "stop_controllers", []))]
        response.ok, text = self._controllers.switch(activate, deactivate,
                                                     int(request.strictness))
        if hasattr(response, "message"):
            response.message = text
        return response

    def _on_list_controllers(self, _request: Any, response: Any) -> Any:
        from controller_manager_msgs.msg import ControllerState
        response.controller = [ControllerState(**c) for c in self._controllers.listed()]
        return response

    def _on_cancel_fjt(self, goal_handle: Any) -> Any:
        gid = bytes(goal_handle.goal_id.uuid)
        with self._lock:
            fwd = self._running.get(gid)
            if fwd is None or fwd.done.is_set():
                return self._cancel_no
            fwd.cancel_requested = True
        return self._cancel_ok

    async def _execute_fjt(self, goal_handle: Any) -> Any:
        """Forward the trajectory, report progress from the tool's joint states, and end
        SUCCESSFUL when the wrist is at the last point (within the goal tolerance, 0.05 rad
        where none is given) by the end plus ``goal_time_tolerance`` (0.5 s if zero)."""
        from rclpy.task import Future
        F = self._fjt_type
        gid = bytes(goal_handle.goal_id.uuid)
        assert self.client is not None
        client = self.client
        with self._lock:
            fwd = self._running.setdefault(gid, _Forwarded())

        def finish(code: int, text: str, how: str) -> Any:
            fwd.done.set()
            with self._lock:
                self._running.pop(gid, None)
            getattr(goal_handle, how)()
            return F.Result(error_code=code, error_string=text)

        try:
            traj, tol, slack = self._fjt_goal(goal_handle.request)
        except ValueError as err:
            code = F.Result.INVALID_JOINTS if "joint" in str(err) else F.Result.INVALID_GOAL
            return finish(code, str(err), "abort")
        stamp = goal_handle.request.trajectory.header.stamp
        start_at = float(stamp.sec) + float(stamp.nanosec) * 1e-9 or None

        def run() -> str:
            """'' when the trajectory ran to its end, else why not."""
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
                    if not taken and now > t0 + 0.5:
                        return (f"the tool did not take the trajectory (its mode is "
                                f"{st.mode.name}; it refuses positions outside the wrist "
                                "limits, velocities above them, or a first point far from "
                                "the present joints)")
                    if taken and st.mode is not Mode.TRAJECTORY:
                        return f"the tool left the trajectory (now {st.mode.name})"
                    self._fjt_feedback(goal_handle, traj, now - t0, st.position)
                    if now >= end and np.all(np.abs(np.subtract(
                            st.position, traj.positions[-1])) <= tol):
                        return ""
                time.sleep(0.05)
            return "goal tolerance"

        future: Future = Future()
        wake = self._wake_safety
        threading.Thread(target=lambda: (future.set_result(run()), wake.trigger()),
                         name="ros2-trajectory", daemon=True).start()
        why = await future
        if why == "":
            return finish(F.Result.SUCCESSFUL, "", "succeed")
        if why == "cancelled":
            stop = self._stops.submit(self._wake_safety)
            _, msg = await self._outcome(stop, "stop")
            return finish(F.Result.SUCCESSFUL, f"cancelled; stop: {msg}", "canceled")
        if why == "goal tolerance":
            st = client.latest_state()
            at = None if st is None else [round(float(v), 4) for v in st.position]
            return finish(F.Result.GOAL_TOLERANCE_VIOLATED,
                          f"the wrist is at {at}, not within {list(tol)} rad of the last point "
                          f"{[round(float(v), 4) for v in traj.positions[-1]]}", "abort")
        return finish(F.Result.INVALID_GOAL, why, "abort")

    def _fjt_goal(self, goal: Any) -> tuple[Any, np.ndarray, float]:
        """(trajectory in the tool's joint order, per-joint goal tolerance, time slack)."""
        from articutool.ros2.verify_service import BadRequestError, trajectory_from_ros
        if len(goal.multi_dof_trajectory.points):
            raise ValueError("multi_dof_trajectory is not supported by a 2-joint wrist")
        st = self.client.latest_state() if self.client is not None else None
        if st is None:
            raise ValueError("no joint state from the tool yet")
        ros, tool = list(self.settings.joint_names), list(st.joint_names)
        try:
            traj = trajectory_from_ros(goal.trajectory, "trajectory")
        except BadRequestError as err:
            raise ValueError(str(err)) from None
        names = [tool[ros.index(j)] if j in ros else j for j in traj.joint_names]
        if sorted(names) != sorted(tool):
            raise ValueError(f"trajectory.joint_names must be the wrist's joints {ros} (or "
                             f"{tool}) in any order; got {list(traj.joint_names)}")
        from articutool.trajectory import JointTrajectory
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

    def _fjt_feedback(self, goal_handle: Any, traj: Any, t: float, actual: Any) -> None:
        from trajectory_msgs.msg import JointTrajectoryPoint
        q, v = traj.sample(t)
        fb = self._fjt_type.Feedback(joint_names=list(self.settings.joint_names))
        fb.desired = JointTrajectoryPoint(positions=[float(x) for x in q],
                                          velocities=[float(x) for x in v])
        fb.actual = JointTrajectoryPoint(positions=[float(x) for x in actual])
        fb.error = JointTrajectoryPoint(positions=[float(a - d) for a, d in zip(actual, q,
                                                                                strict=True)])
        try:
            goal_handle.publish_feedback(fb)
        except Exception as err:  # the goal ended meanwhile
            _log.debug("feedback dropped: %s", err)

    # ------------------------------------------------------------------ shutdown --
    def cancel_all(self) -> None:
        """Cancel every goal this node forwarded that is still running (on shutdown)."""
        if self.client is None:
            return
        with self._lock:
            active = list(self._running)
        for gid in active:
            try:
                self.client.cancel(gid)
            except LinkError as err:
                _log.warning("could not cancel goal %s: %s", gid.hex(), err)

    def destroy(self) -> None:
        """Stop forwarding and destroy the nodes (the client is the caller's to close)."""
        for h in self._forward:
            h.close()
        if self._action is not None:
            self._action.destroy()
        if getattr(self, "_fjt", None) is not None:
            self._fjt.destroy()
        self._work.close()
        self._verify_lane.close()
        if self.client is not None:
            self._stops.close()
        if self.safety_node is not None:
            self.safety_node.destroy_node()
        self.node.destroy_node()


def _ros_trajectory(traj: Any, out: Any) -> Any:
    """articutool JointTrajectory → the given ``trajectory_msgs/JointTrajectory`` message."""
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectoryPoint

    out.joint_names = list(traj.joint_names)
    pts = []
    for t, q, v in zip(traj.times, traj.positions, traj.velocities, strict=True):
        sec = math.floor(t)
        pts.append(JointTrajectoryPoint(
            positions=np.asarray(q, dtype=float).tolist(),
            velocities=np.asarray(v, dtype=float).tolist(),
            time_from_start=Duration(sec=int(sec),
                                     nanosec=min(round((t - sec) * 1e9), 999_999_999))))
    out.points = pts
    return out


def _fill_verify(response: Any, out: dict[str, Any]) -> Any:
    """A VerifyTrajectory response from the verifier's answer."""
    for key in ("feasible", "reason", "message", "first_failure_time", "velocity_margin",
                "samples_checked", "spill_checked", "predicted_spill_g",
                "max_required_velocity"):
        if key in out:
            setattr(response, key, out[key])
    wt = out.get("wrist_trajectory")
    if wt is not None:
        response.wrist_trajectory = _ros_trajectory(wt, response.wrist_trajectory)
    return response
