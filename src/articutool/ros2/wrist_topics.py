"""The wrist where ADA and MoveIt read it: the topics the upstream Articutool's helper nodes
publish besides the tool's own, made by ``articutool ros2`` from the tool's telemetry.

- ``/joint_states`` (``sensor_msgs/JointState``): the wrist's joint states under the ROS 2
  joint names, as upstream's ``articutool_system`` ``joint_state_republisher`` copies
  ``/articutool/joint_states`` there (ADA's ``GetJointStates`` and MoveIt's joint state
  monitor read it); on unless the parameter ``republish_joint_states`` is false. Reliable,
  keep-last 1, as upstream's.
- ``/articutool/imu_data`` (``sensor_msgs/Imu``, upstream's IMU driver topic): acceleration and
  angular velocity with ``orientation_covariance[0] = -1`` (no orientation: the REP 145
  convention). The angular velocity is the tool's bias-corrected gyro (the link carries no
  other).
- ``/articutool/imu_data_and_orientation_calibrated`` (upstream's calibration node output): the
  filtered orientation with the identity as the robot-base offset, the one
  ``TriggerCalibration`` answers (this wrist has no heading reference to calibrate), as the
  upstream node publishes before a calibration.

Every IMU message carries upstream's frame ``atool_imu_frame`` (the tool stamps it). Only
well-formed messages reach the graph; a malformed one is counted and dropped.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

import numpy as np

from articutool.link import cdr

__all__ = ["forwarder", "renamer", "setup"]

_log = logging.getLogger(__name__)


def _raw_imu(msg: Any) -> bytes:
    msg.orientation.x = msg.orientation.y = msg.orientation.z = 0.0
    msg.orientation.w = 1.0
    msg.orientation_covariance = np.array([-1.0] + [0.0] * 8)
    return cdr.encode(msg, cdr.IMU)


def renamer(joint_names: tuple[str, str]) -> Callable[[Any], bytes]:
    """The tool's [pitch, roll] joint state (decoded) → serialised under ``joint_names``."""
    def renamed(msg: Any) -> bytes:
        msg.name = list(joint_names)
        return cdr.encode(msg, cdr.JOINT_STATE)
    return renamed


def setup(node: Any, client: Any, names: dict[str, str], joint_names: tuple[str, str],
          republish_joint_states: bool, counters: dict[str, int]) -> list[Any]:
    """Create the publishers on ``node`` and subscribe them to ``client``'s telemetry; the
    link subscriptions (to close on shutdown)."""
    from rclpy.qos import QoSProfile
    from sensor_msgs.msg import Imu, JointState

    renamed = renamer(joint_names)

    def calibrated(msg: Any) -> bytes:
        return cdr.encode(msg, cdr.IMU)

    routes: list[tuple[Any, str, Any, str, QoSProfile, Callable[[Any], bytes]]] = [
        (client.names.imu, cdr.IMU, Imu, names["imu_raw"], QoSProfile(depth=10), _raw_imu),
        (client.names.imu, cdr.IMU, Imu, names["imu_calibrated"], QoSProfile(depth=10),
         calibrated),
    ]
    if republish_joint_states:
        routes.append((client.names.joint_states, cdr.JOINT_STATE, JointState,
                       names["robot_joint_states"], QoSProfile(depth=1), renamed))
    return [client.transport.subscribe(ep, forwarder(node.create_publisher(cls, topic, qos),
                                                     typename, convert, counters))
            for ep, typename, cls, topic, qos, convert in routes]


def forwarder(pub: Any, typename: str, convert: Callable[[Any], bytes] | None,
              counters: dict[str, int]) -> Callable[[bytes], None]:
    """A link subscriber that publishes each well-formed ``typename`` message on ``pub``:
    ``convert`` of the decoded message, or the link's bytes as they are when None."""
    def on_data(data: bytes) -> None:
        try:  # only well-formed messages of the right type reach the ROS 2 graph
            msg = cdr.decode(data, typename)
            pub.publish(convert(msg) if convert is not None else bytes(data))
            counters["forwarded"] += 1
        except Exception as err:  # malformed payload, or rclpy shutting down
            counters["dropped"] += 1
            _log.debug("telemetry not forwarded: %s", err)
    return on_data
