"""``TriggerCalibration`` on ``orientation_calibration_service/trigger_calibration`` and the
latched ``ImuCalibrationStatus`` on ``orientation_calibration_service/status``: answered
without calibrating anything, and saying so.

The upstream calibration computes the yaw between its IMU filter's world frame and the robot
base. This wrist levels against gravity alone (the controller is yaw-invariant and the filter
leaves yaw unobserved), so there is no yaw offset to compute: the service answers
``success: true``, :data:`CALIBRATION_MESSAGE` and the identity, and the status says
``is_yaw_calibrated: false``.
"""

from __future__ import annotations

from typing import Any

from articutool.ros2.intake import create_draining_service
from articutool.ros2.serving import Side

__all__ = ["CALIBRATION_MESSAGE", "CalibrationServer"]

CALIBRATION_MESSAGE = (
    "nothing to calibrate: this wrist levels against gravity alone (its controller is "
    "yaw-invariant and its filter leaves yaw unobserved), so no yaw offset is computed or "
    "applied; computed_offset_jacobase_to_filterworld is the identity")


class CalibrationServer:
    """The calibration service and its latched status on ``side`` (the main node)."""

    def __init__(self, side: Side, service: str, status_topic: str) -> None:
        from articutool_interfaces.msg import ImuCalibrationStatus
        from articutool_interfaces.srv import TriggerCalibration
        from rclpy.qos import DurabilityPolicy, QoSProfile

        create_draining_service(side.node, TriggerCalibration, service, self._on_calibration,
                                qos_profile=side.qos, callback_group=side.group)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        pub = side.node.create_publisher(ImuCalibrationStatus, status_topic, latched)
        status = ImuCalibrationStatus(is_yaw_calibrated=False)
        status.header.stamp = side.node.get_clock().now().to_msg()
        pub.publish(status)

    @staticmethod
    def _on_calibration(_request: Any, response: Any) -> Any:
        response.success, response.message = True, CALIBRATION_MESSAGE
        q = response.computed_offset_jacobase_to_filterworld
        q.x, q.y, q.z, q.w = 0.0, 0.0, 0.0, 1.0
        return response
