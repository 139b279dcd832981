"""Interoperability with real ROS 2: rclpy and the message packages from PyPI.

Every standard message type the link sends or receives is serialised by our encoder and
deserialised by ROS 2 (``rclpy.serialization``, rmw_fastrtps_cpp typesupport), and the other
way round; our RIHS01 type hashes are compared with the ``hash_string`` of ROS 2's installed
interface descriptions (``share/<pkg>/<kind>/<Name>.json``). Our own
``articutool_interfaces`` types are checked against the built package in
``test_ros2_interfaces.py``.

The ROS 2 wheels are the ``ros`` extra (CPython 3.11 on x86_64, installed by ``make``);
elsewhere this module is skipped, saying so.
"""

from __future__ import annotations

import json
import math
import platform
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from articutool.link import cdr
from articutool.link import messages as m
from articutool.tool.api import Mode, ToolState
from articutool.trajectory import JointTrajectory

rclpy_ser = pytest.importorskip(
    "rclpy.serialization",
    reason=f"the ROS 2 wheels (extra 'ros') exist for CPython 3.11 on x86_64 only; this is "
           f"{platform.python_implementation()} {platform.python_version()} on "
           f"{platform.machine()}, or the extra is not installed")

from action_msgs.msg import GoalStatusArray  # noqa: E402
from action_msgs.srv import CancelGoal  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from sensor_msgs.msg import BatteryState, Imu, JointState  # noqa: E402
from std_msgs.msg import Header  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from trajectory_msgs.msg import JointTrajectory as RosJointTrajectory  # noqa: E402


def _state() -> ToolState:
    return ToolState(stamp=1.0, mode=Mode.LEVELING, joint_names=("pitch", "roll"),
                     position=(0.1, -0.25), velocity=(0.5, 0.0),
                     orientation_wxyz=(0.9, 0.1, -0.2, 0.3), angular_velocity=(0.01, 0.02, 0.03),
                     linear_acceleration=(0.1, 0.2, 9.81), battery_voltage=11.9,
                     loop_period_mean=0.02, loop_jitter=0.0004, loop_overruns=1,
                     fault="", extra={"imu_stale": 0.0})


def _trajectory(n: int) -> JointTrajectory:
    t = np.linspace(0.0, 1.5, n) if n > 1 else np.array([1.25])
    pos = np.stack([0.1 * np.sin(t), 0.2 * t], axis=1)
    vel = np.stack([0.1 * np.cos(t), np.full_like(t, 0.2)], axis=1)
    return JointTrajectory(("pitch", "roll"), t, pos, vel)


T0 = 1_700_000_000.25
# (our type name, ROS 2 class, our message)
CASES: list[tuple[str, Any, Any]] = [
    (cdr.JOINT_STATE, JointState, m.joint_state_msg(_state(), T0)),
    (cdr.IMU, Imu, m.imu_msg(_state(), T0)),
    (cdr.DIAGNOSTIC_ARRAY, DiagnosticArray, m.health_msg(_state(), T0, {"decode_errors": 3})),
    (cdr.BATTERY_STATE, BatteryState, m.battery_msg(_state(), T0)),
    (cdr.HEADER, Header, m.heartbeat_msg(T0, "pc-1")),
    (cdr.JOINT_TRAJECTORY, RosJointTrajectory, m.trajectory_msg(_trajectory(1), T0)),
    (cdr.JOINT_TRAJECTORY, RosJointTrajectory, m.trajectory_msg(_trajectory(7), 0.0)),
    (cdr.GOAL_STATUS_ARRAY, GoalStatusArray,
     m.status_array([(bytes(range(16)), T0, m.GoalStatus.EXECUTING),
                     (bytes(16), T0 + 1, m.GoalStatus.ABORTED)])),
    (f"{cdr.CANCEL_GOAL}_Request", CancelGoal.Request, m.cancel_request(bytes(range(16)))),
    (f"{cdr.CANCEL_GOAL}_Response", CancelGoal.Response,
     m.cancel_response(0, [(bytes(range(16)), T0)])),
    (f"{cdr.TRIGGER}_Request", Trigger.Request, m.trigger_request()),
    (f"{cdr.TRIGGER}_Response", Trigger.Response, m.trigger_response(False, "no fault to clear")),
]
IDS = [f"{t.split('/')[-1]}-{i}" for i, (t, _, _) in enumerate(CASES)]


def _scalar(value: Any, kind: str) -> Any:
    if kind in ("float32", "float"):
        value = float(np.float32(value))
    if isinstance(value, (bytes, bytearray)) and len(value) == 1:  # rclpy's byte/octet
        return value[0]
    if isinstance(value, (float, np.floating)):
        return "nan" if math.isnan(value) else float(value)
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    return str(value)


def _ours(value: Any, node: tuple[Any, Any]) -> Any:
    """A rosbags message field as plain Python, by its declared type (float32 rounded)."""
    kind, desc = int(node[0]), node[1]
    if kind == 1:
        return _scalar(value, desc[0])
    if kind == 2:
        _, fields = cdr.typestore().fielddefs[desc]
        return {f: _ours(getattr(value, f), t) for f, t in fields
                if f != "structure_needs_at_least_one_member"}  # rosidl's placeholder
    return [_ours(v, desc[0]) for v in value]


def _theirs(value: Any) -> Any:
    """An rclpy message as plain Python."""
    if hasattr(value, "get_fields_and_field_types"):
        return {k: _theirs(getattr(value, k)) for k in value.get_fields_and_field_types()}
    if isinstance(value, (list, tuple, np.ndarray)) or type(value).__name__ == "array":
        return [_theirs(v) for v in value]
    if isinstance(value, (bytes, bytearray)) and len(value) != 1:
        return list(value)
    return _scalar(value, "")


@pytest.mark.parametrize(("typename", "ros_cls", "ours"), CASES, ids=IDS)
def test_ros2_decodes_what_we_encode(typename: str, ros_cls: Any, ours: Any) -> None:
    theirs = rclpy_ser.deserialize_message(cdr.encode(ours, typename), ros_cls)
    assert _theirs(theirs) == _ours(ours, (2, typename))


@pytest.mark.parametrize(("typename", "ros_cls", "ours"), CASES, ids=IDS)
def test_we_decode_what_ros2_encodes(typename: str, ros_cls: Any, ours: Any) -> None:
    theirs = rclpy_ser.deserialize_message(cdr.encode(ours, typename), ros_cls)  # a ROS object
    data = rclpy_ser.serialize_message(theirs)  # ROS 2's bytes (with its trailing padding)
    assert _ours(cdr.decode(data, typename), (2, typename)) == _theirs(theirs)


def test_a_ros2_trajectory_reaches_the_tool_as_sent() -> None:
    """The issue's case: a ROS 2 PC's wrist trajectory is accepted and means the same."""
    ros = rclpy_ser.deserialize_message(
        cdr.encode(m.trajectory_msg(_trajectory(20), 0.0), cdr.JOINT_TRAJECTORY),
        RosJointTrajectory)
    data = rclpy_ser.serialize_message(ros)
    assert len(data) > len(cdr.encode(m.trajectory_msg(_trajectory(20), 0.0),
                                     cdr.JOINT_TRAJECTORY))  # ROS 2 pads: the bug's trigger
    traj = m.trajectory_from_msg(cdr.decode(data, cdr.JOINT_TRAJECTORY))
    ref = _trajectory(20)
    assert np.allclose(traj.times, ref.times, atol=1e-9)
    assert np.array_equal(traj.positions, ref.positions)


def _ros_hash(typename: str) -> str:
    pkg, kind, name = typename.split("/")
    path = Path(sys.prefix) / "share" / pkg / kind / f"{name}.json"
    doc = json.loads(path.read_text())
    hashes = {h["type_name"]: h["hash_string"] for h in doc["type_hashes"]}
    return hashes[typename]


@pytest.mark.parametrize("typename", [
    cdr.JOINT_STATE, cdr.HEADER, cdr.JOINT_TRAJECTORY, cdr.IMU, cdr.DIAGNOSTIC_ARRAY,
    cdr.BATTERY_STATE, cdr.GOAL_STATUS_ARRAY, cdr.CANCEL_GOAL, cdr.TRIGGER])
def test_type_hashes_equal_ros2_installed_descriptions(typename: str) -> None:
    assert cdr.type_hash(typename) == _ros_hash(typename)
