"""The ROS 2 names and types ``articutool ros2`` serves: the upstream Articutool's (those ADA's
behaviours call by default) plus our own, all under one optional namespace.

With the namespace empty every name is exactly the one ADA (``personalrobotics/ada_feeding``,
``ada_feeding/behaviors/articutool/``) and the upstream tool nodes
(``personalrobotics/articutool_ros2``) use; a namespace such as ``wrist_1`` puts every name
under ``/wrist_1/`` for a second tool on the same graph (ADA's behaviours take the name as
an input). Pure.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["ENDPOINTS", "Endpoint", "check_namespace", "resolve"]


@dataclass(frozen=True)
class Endpoint:
    """One name: relative path, kind (service, action, publishes, subscribes), ROS 2 type and
    who uses it upstream ('' for names of ours)."""

    rel: str
    kind: str
    type: str
    upstream: str = ""


ENDPOINTS: dict[str, Endpoint] = {
    "set_orientation_control": Endpoint(
        "articutool/set_orientation_control", "service",
        "articutool_interfaces/srv/SetOrientationControl",
        "ADA CallSetOrientationControl (default name)"),
    "set_orientation_control_mode": Endpoint(
        "orientation_control/set_orientation_control_mode", "service",
        "articutool_interfaces/srv/SetOrientationControl",
        "upstream orientation_control node"),
    "execute_primitive": Endpoint(
        "orientation_control/execute_primitive", "action",
        "articutool_interfaces/action/ExecuteArticutoolPrimitive",
        "ADA ExecuteNamedPrimitive; upstream orientation_control node"),
    "trigger_calibration": Endpoint(
        "orientation_calibration_service/trigger_calibration", "service",
        "articutool_interfaces/srv/TriggerCalibration",
        "ADA TriggerArticutoolCalibration; upstream orientation_calibration_service"),
    "calibration_status": Endpoint(
        "orientation_calibration_service/status", "publishes",
        "articutool_interfaces/msg/ImuCalibrationStatus",
        "upstream orientation_calibration_service"),
    "joint_states": Endpoint(
        "articutool/joint_states", "publishes", "sensor_msgs/msg/JointState",
        "ADA CombineJointStates; upstream joint_state_broadcaster"),
    "imu": Endpoint(
        "articutool/imu_data_and_orientation", "publishes", "sensor_msgs/msg/Imu",
        "upstream orientation filters (read by the upstream controller)"),
    "imu_raw": Endpoint(
        "articutool/imu_data", "publishes", "sensor_msgs/msg/Imu",
        "upstream articutool_imu driver (the filters' input)"),
    "imu_calibrated": Endpoint(
        "articutool/imu_data_and_orientation_calibrated", "publishes", "sensor_msgs/msg/Imu",
        "upstream orientation_calibration_service (read by the upstream controller)"),
    "robot_joint_states": Endpoint(
        "joint_states", "publishes", "sensor_msgs/msg/JointState",
        "ADA GetJointStates, MoveIt; upstream joint_state_republisher"),
    "list_controllers": Endpoint(
        "articutool/controller_manager/list_controllers", "service",
        "controller_manager_msgs/srv/ListControllers",
        "MoveIt's Ros2ControlManager (remapped there upstream); upstream controller_manager"),
    "follow_joint_trajectory": Endpoint(
        "articutool/joint_trajectory_controller/follow_joint_trajectory", "action",
        "control_msgs/action/FollowJointTrajectory",
        "ADA ExecuteArticutoolTrajectory; upstream joint_trajectory_controller"),
    "switch_controller": Endpoint(
        "articutool/controller_manager/switch_controller", "service",
        "controller_manager_msgs/srv/SwitchController",
        "ADA SwitchArticutoolControllers; upstream controller_manager"),
    "stop": Endpoint("articutool/stop", "service", "std_srvs/srv/Trigger"),
    "clear_fault": Endpoint("articutool/clear_fault", "service", "std_srvs/srv/Trigger"),
    "verify_trajectory": Endpoint("articutool/verify_trajectory", "service",
                                  "articutool_interfaces/srv/VerifyTrajectory"),
    "joint_trajectory": Endpoint("articutool/joint_trajectory", "subscribes",
                                 "trajectory_msgs/msg/JointTrajectory"),
    "health": Endpoint("articutool/health", "publishes", "diagnostic_msgs/msg/DiagnosticArray"),
    "battery": Endpoint("articutool/battery", "publishes", "sensor_msgs/msg/BatteryState"),
}

_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def check_namespace(value: str, field: str = "namespace") -> str:
    """``value`` as an absolute namespace prefix ('' or ``/a/b``); ValueError naming
    ``field`` unless it is ROS 2 name tokens separated by ``/``."""
    parts = [p for p in value.strip().strip("/").split("/")] if value.strip("/ ") else []
    for p in parts:
        if not _TOKEN.fullmatch(p) or "__" in p:
            raise ValueError(f"{field} must be ROS 2 name tokens (letters, digits and single "
                             f"underscores, not starting with a digit) separated by '/'; "
                             f"got {value!r}")
    return "".join(f"/{p}" for p in parts)


def resolve(namespace: str = "") -> dict[str, str]:
    """{key: absolute name} with every endpoint under ``namespace`` ('' = the upstream
    names exactly)."""
    ns = check_namespace(namespace)
    return {k: f"{ns}/{e.rel}" for k, e in ENDPOINTS.items()}
