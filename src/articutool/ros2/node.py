"""``articutool ros2``: the Articutool on a ROS 2 graph under the upstream tool's names,
forwarded over the paired link, plus plan-then-verify as a service.

An rclpy node on the PC that ADA's Articutool behaviours (``personalrobotics/ada_feeding``)
and any ROS 2 stack use like the upstream tool nodes (``personalrobotics/articutool_ros2``),
while the wrist itself trusts only the paired PC: every command is forwarded by an
:class:`~articutool.link.client.ArticutoolClient` (signed commands, lease, heartbeat) and
the replies are the tool's own. Names: :mod:`articutool.ros2.names` (upstream names exactly
with an empty namespace).

:class:`ArticutoolRos2Node` composes one server per interface, each given what it needs (the
link client, its settings, the rclpy node it serves on with that node's callback group and
wake-up guard condition, :class:`~articutool.ros2.serving.Side`):

- on the main node: ``SetOrientationControl`` on both names and ``clear_fault``
  (:mod:`~articutool.ros2.orientation_control`), ``TriggerCalibration`` and its status
  (:mod:`~articutool.ros2.calibration`), ``VerifyTrajectory``
  (:mod:`~articutool.ros2.verify_service`), the controller manager's ``switch_controller`` and
  ``list_controllers`` (:mod:`~articutool.ros2.controller_manager`), the ``joint_trajectory``
  topic (:mod:`~articutool.ros2.trajectories`) and the telemetry
  (:mod:`~articutool.ros2.telemetry`);
- on the safety node, with its own executor thread and no parameter services: the stop
  (:mod:`~articutool.ros2.stop_service`, owner of the stop lane every stop goes through),
  ``ExecuteArticutoolPrimitive`` (:mod:`~articutool.ros2.primitive_action`) and
  ``FollowJointTrajectory`` (:mod:`~articutool.ros2.trajectories`), whose cancels are stops;
  the two actions share one goal table (:mod:`~articutool.ros2.goals`).

The main node's services (not rclpy's parameter services) take all their waiting requests, up
to a batch, each time the executor calls them (:mod:`articutool.ros2.intake`), and request
queues are ``queue_depth`` (5 000) deep, so a flood of bad calls is answered rather than
dropped by DDS (docs/ros2.md). Callbacks never raise into the executor: a request the client
refuses (bad numbers, a silent tool) is answered ``success=false`` with the message
``articutool client`` prints.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Any

from articutool.link.client import ArticutoolClient, LinkError
from articutool.ros2.calibration import CalibrationServer
from articutool.ros2.goals import GoalTable
from articutool.ros2.names import resolve
from articutool.ros2.orientation_control import OrientationControlServer
from articutool.ros2.primitive_action import PrimitiveActionServer
from articutool.ros2.serving import Side, latest_wrist
from articutool.ros2.stop_service import StopServer
from articutool.ros2.telemetry import TelemetryServer
from articutool.ros2.trajectories import FollowJointTrajectoryServer, TrajectoryTopic
from articutool.ros2.verify_service import VerifyServer

__all__ = ["ArticutoolRos2Node", "NodeSettings"]

_log = logging.getLogger(__name__)


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


class ArticutoolRos2Node:
    """The rclpy nodes forwarding the Articutool API to ``client``'s tool.

    ``client`` None serves only ``VerifyTrajectory`` (no tool). rclpy must be initialised
    (``context``); :attr:`node` (parameters, ordinary services, telemetry) and
    :attr:`safety_node` (stop, actions) each need an executor of their own.
    """

    def __init__(self, client: ArticutoolClient | None, settings: NodeSettings | None = None,
                 context: Any = None, node: Any = None) -> None:
        from rclpy.node import Node
        from rclpy.qos import QoSProfile

        self.client = client
        self.settings = s = settings or NodeSettings()
        if s.offset_units not in ("degrees", "radians"):
            raise ValueError(f"offset_units must be 'degrees' or 'radians'; got "
                             f"{s.offset_units!r}")
        self.names = n = resolve(s.namespace)
        self.node = node if node is not None else Node("articutool_ros2", context=context)
        self.node.get_logger().info(
            f"SetOrientationControl offsets are read in {s.offset_units.upper()} "
            f"(offset_units={s.offset_units}; ADA's CallSetOrientationControl sends radians, "
            "the upstream .srv says degrees)")
        self.counters = {"forwarded": 0, "dropped": 0, "trajectories": 0, "busy": 0,
                         "stops": 0}
        qos = QoSProfile(depth=s.queue_depth)
        main = Side.of(self.node, qos)
        self.safety_node = None
        self._verify = self._stop = self._modes = self._primitive = None
        self._fjt = self._telemetry = None
        if s.verifier is not None:
            self._verify = VerifyServer(s.verifier, main, n["verify_trajectory"],
                                        self.current_wrist, self.counters)
        if client is None:
            return
        # No parameter services (it has no parameters): fewer entities for its executor to
        # wait on, so the stop service and the actions' requests are taken sooner.
        self.safety_node = Node(f"{self.node.get_name()}_stop", context=context,
                                namespace=self.node.get_namespace(),
                                start_parameter_services=False)
        safety = Side.of(self.safety_node, qos)
        self._goals = GoalTable(s.max_goals)
        self._stop = StopServer(client, safety, n["stop"], self.counters)
        stops = self._stop.lane
        self._modes = OrientationControlServer(client, main, n, s.offset_units, stops,
                                               self.counters)
        CalibrationServer(main, n["trigger_calibration"], n["calibration_status"])
        self._primitive = PrimitiveActionServer(client, safety, n["execute_primitive"],
                                                self._goals, self.node.get_logger())
        TrajectoryTopic(client, main, n["joint_trajectory"], s.joint_names, self.counters)
        self._telemetry = TelemetryServer(self.node, client, n, s.joint_names,
                                          s.republish_joint_states, self.counters)
        missing = _trajectory_path_missing()
        if missing is not None:
            self.node.get_logger().warning(f"trajectory path not served: {missing}")
            return
        from articutool.ros2.controller_manager import ControllerManagerServer
        self._fjt = FollowJointTrajectoryServer(client, safety, n["follow_joint_trajectory"],
                                                self._goals, stops, s.joint_names)
        ControllerManagerServer(main, n, s.joint_names)

    def current_wrist(self) -> tuple[float, float] | None:
        """The tool's last joint positions [pitch, roll] (None without a tool or telemetry)."""
        return latest_wrist(self.client)

    def cancel_all(self) -> None:
        """Cancel every goal this node forwarded that is still running (on shutdown)."""
        if self.client is None:
            return
        for gid in self._goals.active():
            try:
                self.client.cancel(gid)
            except LinkError as err:
                _log.warning("could not cancel goal %s: %s", gid.hex(), err)

    def destroy(self) -> None:
        """Stop forwarding and destroy the nodes (the client is the caller's to close)."""
        if self._telemetry is not None:
            self._telemetry.close()
        for action in (self._primitive, self._fjt):
            if action is not None:
                action.destroy()
        for part in (self._modes, self._verify, self._stop):
            if part is not None:
                part.close()
        if self.safety_node is not None:
            self.safety_node.destroy_node()
        self.node.destroy_node()


def _trajectory_path_missing() -> str | None:
    """Why ADA's trajectory path (FollowJointTrajectory and the controller manager) cannot be
    served, or None: their interface packages are installed (``make`` builds them where they
    are not)."""
    try:
        from control_msgs.action import FollowJointTrajectory  # noqa: F401
        from controller_manager_msgs.srv import ListControllers, SwitchController  # noqa: F401
    except ImportError as err:
        return str(err)
    return None
