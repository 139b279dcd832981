"""ADA's Articutool call sequences against ``articutool ros2``, on a real ROS 2 graph.

ADA's five Articutool behaviours (``personalrobotics/ada_feeding``,
``ada_feeding/ada_feeding/behaviors/articutool/``) are transcribed below as plain rclpy calls:
the names, types, field values, units and order each behaviour's ``setup``/``update``/
``terminate`` use (docs/ros2.md lists them with the upstream file), none of ADA's code.
They run, in the order ADA's acquisition idioms build them (``get_articutool_move_into_sequence``,
``get_post_acquisition_leveling_sequence``, ``get_post_retract_primitive_sequence``), from this
test process against two more: the node (``articutool ros2`` with its defaults, as an ADA
workspace would start it) and the real tool on the simulated drivers behind the paired link.
Covered: modes 0, 1 (ADA's radians offsets) and 2 (a target quaternion), the upstream
registry's every primitive, the trajectory path, the cancels, calibration, ``/joint_states``,
upstream's IMU topics and ``list_controllers``.

Skipped where rclpy or the built interface packages are unavailable (``make``).
"""

from __future__ import annotations

import math
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from articutool.link.messages import stamp_to_time
from articutool.link.pairing import pair
from conftest import free_port

_why = "rclpy and the built interface packages (make; CPython 3.11 on x86_64 only)"
rclpy = pytest.importorskip("rclpy", reason=_why)
pytest.importorskip("articutool_interfaces.action", reason=_why)
pytest.importorskip("controller_manager_msgs.srv", reason=_why)

from action_msgs.msg import GoalStatus  # noqa: E402
from articutool_interfaces.action import ExecuteArticutoolPrimitive  # noqa: E402
from articutool_interfaces.srv import SetOrientationControl, TriggerCalibration  # noqa: E402
from builtin_interfaces.msg import Duration  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from controller_manager_msgs.srv import ListControllers, SwitchController  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import Quaternion  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.duration import Duration as RclpyDuration  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.qos import (  # noqa: E402
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_services_default,
)
from sensor_msgs.msg import Imu, JointState  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from test_ros2_node import DOMAIN, Graph, _articutool, _start_node  # noqa: E402

TOOL = "wrist_ada"
JOINTS = ["atool_joint1", "atool_joint2"]

# ---- ADA's behaviours, transcribed (ada_feeding/ada_feeding/behaviors/articutool/) ----------
# call_set_orientation_control.py, CallSetOrientationControl
SOC_NAME, SOC_WAIT_S = "/articutool/set_orientation_control", 1.0
# switch_articutool_controllers.py, SwitchArticutoolControllers
SWITCH_NAME, SWITCH_WAIT_S = "/articutool/controller_manager/switch_controller", 2.0
# execute_named_primitive.py, ExecuteNamedPrimitive
PRIMITIVE_NAME, PRIMITIVE_WAIT_S = "/orientation_control/execute_primitive", 2.0
# execute_articutool_trajectory.py, ExecuteArticutoolTrajectory (waits 0.01 s per tick)
FJT_NAME = "/articutool/joint_trajectory_controller/follow_joint_trajectory"
# trigger_articutool_calibration.py, TriggerArticutoolCalibration
CALIBRATION_NAME, CALIBRATION_WAIT_S, CALIBRATION_CALL_S = (
    "/orientation_calibration_service/trigger_calibration", 2.0, 10.0)
# What the upstream tool registers (articutool_control/orientation_control.py), with
# parameters in upstream's meanings and units, short enough for a test.
REGISTRY = {
    "TWIRL_CW": [1.0, 4.0],  # rotations, rad/s
    "TWIRL_CCW": [1.0, 4.0],
    "VIBRATE_ROLL": [4.0, 0.05, 0.5],  # Hz, rad, s
    "DEPOSIT_BITE": [45.0, 2.0, 0.3],  # deg, rad/s, s
    "SETTLE_TOSS": [20.0, 1.5, 3.0],  # deg, rad/s, rad/s
    "NOODLE_SHED": [20.0, 1.5, 0.2, 4.0, 3.0, 0.5],  # deg, rad/s, s, Hz, deg, s
    "HOMING": [3.0],  # rad/s
}


class Ada(Graph):
    """The graph: the tool, the node with its defaults, and this process's plain client with
    ADA's calls (``Graph``'s plumbing: ``wait``, ``spin_until``, ``close``)."""

    def __init__(self, folder: Path) -> None:
        pair(folder, TOOL, ["pc_1"])
        port = free_port()
        self.tool = _articutool("tool", "--no-level", "--link-config",
                                str(folder / TOOL / "link.toml"), "--listen",
                                f"tls/127.0.0.1:{port}", stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.log = folder / "node.log"
        # Every behaviour-facing parameter at its default; the link's timeouts widened for a
        # loaded test machine (a 2 s reply bound failed here at load ~15).
        self.node_proc = _start_node(folder / "pc_1" / "link.toml", port, self.log,
                                     "-p", "wait_s:=30", "-p", "call_timeout_s:=10.0",
                                     "-p", "tool_timeout_s:=10.0")
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=DOMAIN)
        self.node = rclpy.create_node("ada_like_client", context=self.ctx)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self.got: dict[str, list[Any]] = {k: [] for k in
                                          ("js", "robot_js", "imu", "raw", "cal", "health")}
        for key, cls, name in (("js", JointState, "/articutool/joint_states"),
                               ("robot_js", JointState, "/joint_states"),
                               ("imu", Imu, "/articutool/imu_data_and_orientation"),
                               ("raw", Imu, "/articutool/imu_data"),
                               ("cal", Imu, "/articutool/imu_data_and_orientation_calibrated"),
                               ("health", DiagnosticArray, "/articutool/health")):
            self.node.create_subscription(cls, name, self.got[key].append, 10)
        # setup() of each behaviour: its client, as ADA creates it
        self.soc = self.node.create_client(SetOrientationControl, SOC_NAME)
        self.switch = self.node.create_client(SwitchController, SWITCH_NAME)
        self.primitive = ActionClient(self.node, ExecuteArticutoolPrimitive, PRIMITIVE_NAME)
        self.fjt = ActionClient(
            self.node, FollowJointTrajectory, FJT_NAME,
            goal_service_qos_profile=qos_profile_services_default,
            result_service_qos_profile=qos_profile_services_default,
            cancel_service_qos_profile=qos_profile_services_default,
            feedback_sub_qos_profile=QoSProfile(reliability=ReliabilityPolicy.RELIABLE,
                                                history=HistoryPolicy.KEEP_LAST, depth=10),
            status_sub_qos_profile=QoSProfile(reliability=ReliabilityPolicy.RELIABLE,
                                              durability=DurabilityPolicy.TRANSIENT_LOCAL,
                                              history=HistoryPolicy.KEEP_LAST, depth=1))
        self.calibration = self.node.create_client(TriggerCalibration, CALIBRATION_NAME)
        self.spin_until(lambda: self.soc.service_is_ready() and len(self.got["health"]) > 0, 30)

    def health(self) -> dict[str, str]:
        h = self.got["health"]
        return {kv.key: kv.value for kv in h[-1].status[0].values} if h else {}

    def settle(self, s: float = 0.3) -> list[float]:
        """The wrist's joints after ``s`` s of rest, from a joint state the tool stamped after
        them (a loaded host delivers the states late: the last one received may be older)."""
        self.spin_until(lambda: False, s)
        t = time.time()
        js = self.got["js"]
        assert self.spin_until(lambda: bool(js) and stamp_to_time(js[-1].header.stamp) >= t,
                               30), \
            "no joint state stamped after the wait"
        return list(js[-1].position)

    # -- CallSetOrientationControl.update --
    def call_set_orientation_control(self, control_mode: int, pitch_offset_deg: float = 0.0,
                                     roll_offset_deg: float = 0.0,
                                     target_xyzw: tuple[float, ...] | None = None) -> Any:
        R = SetOrientationControl.Request
        assert control_mode in [R.MODE_DISABLED, R.MODE_LEVELING, R.MODE_FULL_ORIENTATION]
        assert self.soc.wait_for_service(timeout_sec=SOC_WAIT_S)
        req = R()
        req.control_mode = int(control_mode)
        if req.control_mode == R.MODE_LEVELING:
            req.pitch_offset = float(math.radians(pitch_offset_deg))
            req.roll_offset = float(math.radians(roll_offset_deg))
            req.target_orientation_robot_base = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
        elif req.control_mode == R.MODE_FULL_ORIENTATION:
            assert target_xyzw is not None
            x, y, z, w = target_xyzw
            req.target_orientation_robot_base = Quaternion(x=float(x), y=float(y),
                                                           z=float(z), w=float(w))
            req.pitch_offset = 0.0
            req.roll_offset = 0.0
        else:
            req.pitch_offset = 0.0
            req.roll_offset = 0.0
            req.target_orientation_robot_base = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
        return self.wait(self.soc.call_async(req))

    # -- SwitchArticutoolControllers.update --
    def switch_articutool_controllers(self, activate: list[str], deactivate: list[str],
                                      strictness: int = SwitchController.Request.BEST_EFFORT
                                      ) -> Any:
        assert self.switch.wait_for_service(timeout_sec=SWITCH_WAIT_S)
        req = SwitchController.Request()
        req.activate_controllers = activate
        req.deactivate_controllers = deactivate
        req.strictness = strictness
        req.activate_asap = False
        req.timeout = RclpyDuration(seconds=5.0).to_msg()
        return self.wait(self.switch.call_async(req))

    # -- ExecuteNamedPrimitive.update (and terminate's cancel_goal_async) --
    def execute_named_primitive(self, name: str, params: list[float],
                                cancel_after_s: float | None = None) -> Any:
        if not name or name.upper() == "NONE":
            return None  # ADA succeeds without a call
        assert self.primitive.wait_for_server(timeout_sec=PRIMITIVE_WAIT_S)
        goal = ExecuteArticutoolPrimitive.Goal()
        goal.primitive_name = name
        goal.parameters = [float(p) for p in params]
        handle = self.wait(self.primitive.send_goal_async(goal))
        assert handle.accepted
        result = handle.get_result_async()
        if cancel_after_s is not None:
            self.spin_until(lambda: False, cancel_after_s)
            handle.cancel_goal_async()
        return self.wait(result, 60)

    # -- ExecuteArticutoolTrajectory.update (and terminate's cancel_goal_async) --
    def execute_articutool_trajectory(self, trajectory: JointTrajectory,
                                      cancel_after_s: float | None = None) -> tuple[int, Any]:
        if not trajectory.points:
            return FollowJointTrajectory.Result.SUCCESSFUL, None
        assert self.spin_until(lambda: self.fjt.wait_for_server(timeout_sec=0.01), 10)
        goal = FollowJointTrajectory.Goal()
        goal.trajectory = trajectory
        handle = self.wait(self.fjt.send_goal_async(goal))
        assert handle.accepted
        result = handle.get_result_async()
        if cancel_after_s is not None:  # once the tool follows it: the trajectory (a topic)
            # and the stop (a service) travel apart, so a stop may overtake it (docs/ros2.md)
            assert self.spin_until(lambda: self.health().get("mode") == "TRAJECTORY", 10)
            self.spin_until(lambda: False, cancel_after_s)
            assert handle.status in (GoalStatus.STATUS_ACCEPTED, GoalStatus.STATUS_EXECUTING)
            handle.cancel_goal_async()
        res = self.wait(result, 30)
        return res.result.error_code, res

    # -- TriggerArticutoolCalibration.update --
    def trigger_articutool_calibration(self) -> Any:
        assert self.calibration.wait_for_service(timeout_sec=CALIBRATION_WAIT_S)
        return self.wait(self.calibration.call_async(TriggerCalibration.Request()),
                         CALIBRATION_CALL_S)


@pytest.fixture(scope="module")
def ada(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ada]:
    g = Ada(tmp_path_factory.mktemp("ros2-ada"))
    try:
        yield g
    finally:
        g.close()


def _moveit_trajectory(q0: list[float], target: list[float], seconds: float) -> JointTrajectory:
    """As MoveIt plans for the 'articutool' group: starts at the present joints at t = 0."""
    mid = [(a + b) / 2 for a, b in zip(q0, target, strict=True)]
    v = [2 * (b - a) / seconds for a, b in zip(q0, target, strict=True)]
    sec = [0.0, seconds / 2, seconds]

    def at(t: float) -> Duration:
        return Duration(sec=int(t), nanosec=round((t % 1) * 1e9))
    return JointTrajectory(joint_names=JOINTS, points=[
        JointTrajectoryPoint(positions=p, velocities=vel, time_from_start=at(t))
        for p, vel, t in ((q0, [0.0, 0.0], sec[0]), (mid, v, sec[1]),
                          (target, [0.0, 0.0], sec[2]))])


def test_the_node_says_which_offset_unit_is_in_force(ada: Ada) -> None:
    assert "offsets are read in RADIANS" in ada.log.read_text()


def test_move_into_sequence_disables_switches_to_velocity_and_twirls(ada: Ada) -> None:
    resp = ada.call_set_orientation_control(SetOrientationControl.Request.MODE_DISABLED)
    assert resp.success, resp.message
    assert ada.switch_articutool_controllers(["velocity_controller"],
                                             ["joint_trajectory_controller"]).ok
    roll0 = ada.settle()[1]
    res = ada.execute_named_primitive("TWIRL_CW", [2.0, 4.0])  # ±2 turns
    assert res.status == GoalStatus.STATUS_SUCCEEDED and res.result.success, res.result.message
    assert res.result.final_joint_values[1] == pytest.approx(roll0 + 4 * math.pi, abs=0.05)
    assert ada.execute_named_primitive("NONE", []) is None
    res = ada.execute_named_primitive("TWIRL_CCW", [2.0, 4.0])
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message


def test_post_acquisition_leveling_sequence_runs_a_moveit_style_trajectory(ada: Ada) -> None:
    assert ada.call_set_orientation_control(SetOrientationControl.Request.MODE_DISABLED).success
    assert ada.execute_named_primitive("HOMING", [3.0]).result.success
    assert ada.switch_articutool_controllers(["joint_trajectory_controller"],
                                             ["velocity_controller"]).ok
    q0 = ada.settle()
    code, res = ada.execute_articutool_trajectory(_moveit_trajectory(q0, [-0.3, 0.4], 1.5))
    assert code == FollowJointTrajectory.Result.SUCCESSFUL, res.result.error_string
    assert res.status == GoalStatus.STATUS_SUCCEEDED
    np.testing.assert_allclose(ada.settle(), [-0.3, 0.4], atol=0.05)  # on its last point
    assert ada.execute_articutool_trajectory(JointTrajectory())[0] == 0  # ADA: trivially


def test_a_trajectory_the_tool_refuses_ends_invalid_and_moves_nothing(ada: Ada) -> None:
    # A MoveIt-style trajectory whose first point (t = 0) is 0.4 rad from the wrist: the tool
    # refuses it (no motion), and the action says so once the tool's own telemetry has gone on
    # without taking it, however late a loaded PC reads that telemetry.
    assert ada.call_set_orientation_control(SetOrientationControl.Request.MODE_DISABLED).success
    assert ada.switch_articutool_controllers(["joint_trajectory_controller"],
                                             ["velocity_controller"]).ok
    q0 = ada.settle()
    far = [q0[0] + 0.4, q0[1]]
    code, res = ada.execute_articutool_trajectory(_moveit_trajectory(far, q0, 1.5))
    assert code == FollowJointTrajectory.Result.INVALID_GOAL, res.result.error_string
    assert "did not take the trajectory" in res.result.error_string
    np.testing.assert_allclose(ada.settle(), q0, atol=0.02)  # nothing moved


def test_post_retract_sequence_runs_a_primitive_then_levels_with_adas_radians(ada: Ada) -> None:
    assert ada.switch_articutool_controllers(["velocity_controller"],
                                             ["joint_trajectory_controller"]).ok
    res = ada.execute_named_primitive("NOODLE_SHED", REGISTRY["NOODLE_SHED"])
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    resp = ada.call_set_orientation_control(SetOrientationControl.Request.MODE_LEVELING)
    assert resp.success, resp.message
    assert ada.spin_until(lambda: ada.health().get("mode") == "LEVELING", 10)
    assert ada.spin_until(lambda: float(ada.health().get("tilt_deg", "99")) < 2.0, 15)
    # ADA's 10° request (sent as math.radians(10)) holds 10°, not 0.17°
    resp = ada.call_set_orientation_control(SetOrientationControl.Request.MODE_LEVELING,
                                            pitch_offset_deg=10.0)
    assert resp.success, resp.message
    assert ada.spin_until(
        lambda: float(ada.health().get("pitch_offset_deg", "nan")) == pytest.approx(10.0,
                                                                                    abs=1e-3), 10)
    assert ada.call_set_orientation_control(SetOrientationControl.Request.MODE_DISABLED).success
    assert ada.spin_until(lambda: ada.health().get("mode") == "DISABLED", 10)


def test_full_orientation_mode_2_holds_a_target_quaternion(ada: Ada) -> None:
    assert SetOrientationControl.Request.MODE_FULL_ORIENTATION == 2
    # the tool's base rests with F0 +x up; the tip of q = (0.3, 0.2) in a z-up base:
    from articutool.rotations import matrix_to_quaternion
    from articutool.tool.drivers.sim import axis_angle_rotation
    from articutool.tool.kinematics import rotation
    R_base = axis_angle_rotation([0.0, 1.0, 0.0], -math.pi / 2)
    w, x, y, z = matrix_to_quaternion(R_base @ rotation([0.3, 0.2]))
    resp = ada.call_set_orientation_control(SetOrientationControl.Request.MODE_FULL_ORIENTATION,
                                            target_xyzw=(x, y, z, w))
    assert resp.success and "FULL_ORIENTATION" in resp.message, resp.message
    assert ada.spin_until(lambda: ada.health().get("mode") == "FULL_ORIENTATION", 10)
    assert ada.spin_until(lambda: float(ada.health().get("leveling_stalled", "1")) == 0.0, 5)
    resp = ada.call_set_orientation_control(SetOrientationControl.Request.MODE_FULL_ORIENTATION,
                                            target_xyzw=(0.0, 0.0, 0.0, 0.0))
    assert not resp.success and "target_orientation_robot_base" in resp.message
    assert ada.call_set_orientation_control(SetOrientationControl.Request.MODE_DISABLED).success
    assert ada.spin_until(lambda: ada.health().get("mode") == "DISABLED", 10)


@pytest.mark.parametrize("name", list(REGISTRY))
def test_every_primitive_of_upstreams_registry_runs(ada: Ada, name: str) -> None:
    assert ada.call_set_orientation_control(SetOrientationControl.Request.MODE_DISABLED).success
    if abs(ada.settle(0.1)[0]) > 0.5:  # SETTLE_TOSS needs room past the start pitch
        assert ada.execute_named_primitive("HOMING", [3.0]).result.success
    res = ada.execute_named_primitive(name, REGISTRY[name])
    assert res.status == GoalStatus.STATUS_SUCCEEDED and res.result.success, res.result.message


def test_adas_cancels_stop_the_wrist(ada: Ada) -> None:
    assert ada.call_set_orientation_control(SetOrientationControl.Request.MODE_DISABLED).success
    res = ada.execute_named_primitive("TWIRL_CW", [1.0, 0.5], cancel_after_s=1.0)  # 12.6 s
    assert res.status == GoalStatus.STATUS_CANCELED and not res.result.success
    r1 = ada.settle(0.5)[1]
    assert ada.settle(1.0)[1] == pytest.approx(r1, abs=1e-3)  # the wrist stopped
    assert ada.execute_named_primitive("HOMING", [3.0]).result.success
    q0 = ada.settle()
    _, res = ada.execute_articutool_trajectory(_moveit_trajectory(q0, [0.5, 1.5], 6.0),
                                                  cancel_after_s=1.0)
    assert res.status == GoalStatus.STATUS_CANCELED, res.result.error_string
    q1 = ada.settle(0.5)
    np.testing.assert_allclose(ada.settle(1.0), q1, atol=1e-3,  # stopped short of the end
                               err_msg=f"{res.result.error_string}; {ada.health()}")
    assert abs(q1[1] - 1.5) > 0.3


def test_calibration_is_answered(ada: Ada) -> None:
    resp = ada.trigger_articutool_calibration()
    q = resp.computed_offset_jacobase_to_filterworld
    assert resp.success and "nothing to calibrate" in resp.message
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)


def test_list_controllers_answers_as_ros2_control_after_adas_switches(ada: Ada) -> None:
    lister = ada.node.create_client(ListControllers,
                                    "/articutool/controller_manager/list_controllers")
    assert lister.wait_for_service(timeout_sec=10)
    assert ada.switch_articutool_controllers(["joint_trajectory_controller"],
                                             ["velocity_controller"]).ok
    got = {c.name: c for c in ada.wait(lister.call_async(ListControllers.Request())).controller}
    assert set(got) == {"velocity_controller", "joint_trajectory_controller",
                        "joint_state_broadcaster"}
    jtc = got["joint_trajectory_controller"]
    assert jtc.state == "active" and jtc.type == \
        "joint_trajectory_controller/JointTrajectoryController"
    assert list(jtc.claimed_interfaces) == ["atool_joint1/position", "atool_joint2/position"]
    assert got["velocity_controller"].state == "inactive"
    assert list(got["velocity_controller"].claimed_interfaces) == []
    assert got["joint_state_broadcaster"].state == "active"
    strict = ada.switch_articutool_controllers(["joint_trajectory_controller"], [],
                                               SwitchController.Request.STRICT)
    assert not strict.ok  # already active: ros2_control refuses a STRICT switch
    assert ada.switch_articutool_controllers(["velocity_controller"],
                                             ["joint_trajectory_controller"]).ok


def test_joint_states_and_imu_topics_are_where_ada_and_moveit_read_them(ada: Ada) -> None:
    assert ada.spin_until(lambda: all(len(ada.got[k]) >= 5 for k in
                                      ("js", "robot_js", "imu", "raw", "cal")), 10)
    js, robot = ada.got["js"][-1], ada.got["robot_js"][-1]
    assert list(robot.name) == JOINTS == list(js.name)
    np.testing.assert_allclose(robot.position, js.position, atol=0.02)  # the same wrist
    imu, raw, cal = ada.got["imu"][-1], ada.got["raw"][-1], ada.got["cal"][-1]
    assert {m.header.frame_id for m in (imu, raw, cal)} == {"atool_imu_frame"}
    assert raw.orientation_covariance[0] == -1.0  # no orientation on the raw topic
    assert 9.0 < math.hypot(raw.linear_acceleration.x, raw.linear_acceleration.y,
                            raw.linear_acceleration.z) < 10.6  # gravity, at rest
    q = cal.orientation
    assert math.isclose(q.w**2 + q.x**2 + q.y**2 + q.z**2, 1.0, rel_tol=1e-6)


def test_the_rclpy_facts_behind_adas_bugs() -> None:
    """docs/ros2.md: ADA's ExecuteNamedPrimitive.terminate reads ClientGoalHandle.is_active,
    which rclpy's client goal handle lacks, and ExecuteArticutoolTrajectory.terminate calls
    GoalStatus(status), a message constructor that takes keywords only."""
    from rclpy.action.client import ClientGoalHandle
    from rclpy.action.client import GoalStatus as ClientModuleGoalStatus
    assert not hasattr(ClientGoalHandle, "is_active")
    with pytest.raises(TypeError):
        ClientModuleGoalStatus(GoalStatus.STATUS_EXECUTING)


@pytest.mark.parametrize("republish", [True, False])
def test_the_joint_state_republisher_is_behind_its_parameter(republish: bool) -> None:
    from types import SimpleNamespace

    from articutool.ros2 import wrist_topics
    from articutool.ros2.names import resolve
    topics: list[str] = []
    node = SimpleNamespace(create_publisher=lambda cls, topic, qos: topics.append(topic))
    client = SimpleNamespace(names=SimpleNamespace(imu="imu", joint_states="js"),
                             transport=SimpleNamespace(subscribe=lambda ep, cb: ep))
    wrist_topics.setup(node, client, resolve(""), ("a", "b"), republish, {})
    assert ("/joint_states" in topics) is republish
    assert {"/articutool/imu_data", "/articutool/imu_data_and_orientation_calibrated"} <= set(
        topics)
