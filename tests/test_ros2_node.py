"""``articutool ros2`` on a real ROS 2 graph: three processes.

The real tool (``articutool tool`` on the simulated drivers, paired, loopback TLS), the node
(``articutool ros2``, forwarding over the paired link), and this test process as a plain
rclpy client written here (rclpy's own Client/ActionClient/Subscription, none of our code),
on a DDS domain of its own restricted to localhost. The client uses the interfaces as ADA's
Articutool behaviours do (``personalrobotics/ada_feeding``, ``behaviors/articutool/``): the
upstream names with no namespace, ``CallSetOrientationControl``'s request fields (offsets
sent as ``math.radians``, the identity quaternion), ``ExecuteNamedPrimitive``'s goals and
cancels, ``TriggerArticutoolCalibration``'s empty request. The refusals a ROS 2 client gets
are compared with what the link client gets for the same bad requests.

Skipped where rclpy or the built ``articutool_interfaces`` are unavailable (``make`` builds
the package on CPython 3.11 x86-64 only).
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from articutool.link import messages as m
from articutool.link.client import ArticutoolClient
from articutool.link.config import load_config
from articutool.link.pairing import pair
from conftest import free_port, ros_domain_id, wait_until

_why = "rclpy and the built articutool_interfaces (make; CPython 3.11 on x86_64 only)"
rclpy = pytest.importorskip("rclpy", reason=_why)
pytest.importorskip("articutool_interfaces.action", reason=_why)

from action_msgs.msg import GoalStatus  # noqa: E402
from articutool_interfaces.action import ExecuteArticutoolPrimitive  # noqa: E402
from articutool_interfaces.msg import ImuCalibrationStatus  # noqa: E402
from articutool_interfaces.srv import SetOrientationControl, TriggerCalibration  # noqa: E402
from builtin_interfaces.msg import Duration  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import Quaternion  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter_client import AsyncParameterClient  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile  # noqa: E402
from sensor_msgs.msg import BatteryState, Imu, JointState  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

SRC = Path(__file__).resolve().parent.parent / "src"
TOOL = f"wrist_{os.getpid()}"
# ADA's default names (no namespace); the random domain keeps other runs on this host apart.
SOC = "/articutool/set_orientation_control"
PRIMITIVE = "/orientation_control/execute_primitive"
CALIBRATION = "/orientation_calibration_service/trigger_calibration"
DOMAIN = ros_domain_id()  # away from others' default domain 0 and other workers


def _env(domain: int) -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=str(SRC), ROS_DOMAIN_ID=str(domain),
                ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")


ENV = _env(DOMAIN)


def _articutool(*args: str, env: dict[str, str] = ENV, **kw: Any) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "articutool", *args], env=env, text=True,
                            **kw)


def _start_node(pc_cfg: Path, port: int, log: Path, *ros_args: str,
                env: dict[str, str] = ENV) -> subprocess.Popen[str]:
    with log.open("a") as err:
        node = _articutool("ros2", "--link-config", str(pc_cfg), "--connect",
                           f"tls/127.0.0.1:{port}", *(("--ros-args", *ros_args) if ros_args
                                                       else ()),
                           env=env, stdout=subprocess.PIPE, stderr=err)
    assert node.stdout is not None
    line = node.stdout.readline()  # the node prints one line once it serves
    assert "serving" in line, (line, log.read_text())
    return node


class Graph:
    """The processes, the link's refusals and the plain rclpy client's node."""

    def __init__(self, folder: Path, domain: int = DOMAIN) -> None:
        self.env = _env(domain)
        pair(folder, TOOL, ["pc_1"])
        self.port = free_port()
        self.pc_cfg = folder / "pc_1" / "link.toml"
        self.tool = _articutool("tool", "--no-level", "--link-config",
                                str(folder / TOOL / "link.toml"), "--listen",
                                f"tls/127.0.0.1:{self.port}", env=self.env,
                                stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.link_cfg = load_config(self.pc_cfg).replace(
            connect=(f"tls/127.0.0.1:{self.port}",), listen=())
        # What the link itself answers to the bad requests the ROS 2 client will send.
        with ArticutoolClient(self.link_cfg) as c:
            assert c.wait_for_tool(30), "the tool was not heard"
            self.link_refusals = {
                "offset": c.set_mode("leveling", 500.0, 0.0),
                "nan": _refusal(lambda: c.set_mode("leveling", math.nan, 0.0)),
                "mode": _refusal(lambda: c.set_mode(7)),
                "params": c.run_primitive("TWIRL_CW", [1.0]).to_dict(),
                "unknown": c.run_primitive("NO_SUCH_PRIMITIVE", []).to_dict(),
                "clear": c.clear_fault(),
            }
        self.log = folder / "node.log"
        # parameters the ROS 2 way: -p overrides the flag's --wait 10
        self.node_proc = _start_node(self.pc_cfg, self.port, self.log, "-p", "wait_s:=30",
                                     "-p", "offset_units:=degrees", env=self.env)
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=domain)
        self.node = rclpy.create_node("plain_test_client", context=self.ctx)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self.received: dict[str, list[Any]] = {"js": [], "imu": [], "health": [], "battery": []}
        self.received["status"] = []
        for key, cls, name in (("js", JointState, "/articutool/joint_states"),
                               ("imu", Imu, "/articutool/imu_data_and_orientation"),
                               ("health", DiagnosticArray, "/articutool/health"),
                               ("battery", BatteryState, "/articutool/battery")):
            self.node.create_subscription(cls, name, self.received[key].append, 10)
        self.node.create_subscription(
            ImuCalibrationStatus, "/orientation_calibration_service/status",
            self.received["status"].append,
            QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.soc = self.node.create_client(SetOrientationControl, SOC)
        self.soc_mode = self.node.create_client(
            SetOrientationControl, "/orientation_control/set_orientation_control_mode")
        self.calibration = self.node.create_client(TriggerCalibration, CALIBRATION)
        self.clear = self.node.create_client(Trigger, "/articutool/clear_fault")
        self.stop = self.node.create_client(Trigger, "/articutool/stop")
        self.action = ActionClient(self.node, ExecuteArticutoolPrimitive, PRIMITIVE)
        self.traj_pub = self.node.create_publisher(JointTrajectory,
                                                   "/articutool/joint_trajectory", 10)
        for c in (self.soc, self.soc_mode, self.calibration, self.clear, self.stop):
            assert c.wait_for_service(timeout_sec=30), c.srv_name
        assert self.action.wait_for_server(timeout_sec=30)

    def wait(self, future: Any, timeout: float = 30.0) -> Any:
        self.executor.spin_until_future_complete(future, timeout_sec=timeout)
        assert future.done(), "no answer in time"
        return future.result()

    def spin_until(self, cond: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
            if cond():
                return True
        return False

    def set_mode(self, mode: int, pitch: float = 0.0, roll: float = 0.0,
                 client: Any = None) -> Any:
        """As ADA's CallSetOrientationControl fills the request (offsets as given here)."""
        req = SetOrientationControl.Request(control_mode=mode, pitch_offset=pitch,
                                            roll_offset=roll)
        req.target_orientation_robot_base = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
        return self.wait((client or self.soc).call_async(req))

    def send_goal(self, name: str, params: list[float],
                  feedback: list[Any] | None = None) -> Any:
        cb = None if feedback is None else (lambda f: feedback.append(f.feedback))
        handle = self.wait(self.action.send_goal_async(
            ExecuteArticutoolPrimitive.Goal(primitive_name=name, parameters=params),
            feedback_callback=cb))
        assert handle.accepted
        return handle

    def close(self) -> None:
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)
        for p in (self.node_proc, self.tool):
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
                try:
                    p.wait(20)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()


def _refusal(fn: Callable[[], Any]) -> str:
    try:
        fn()
    except ValueError as err:
        return str(err)
    raise AssertionError("the link client accepted a bad request")


@pytest.fixture(scope="module")
def graph(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Graph]:
    g = Graph(tmp_path_factory.mktemp("ros2-pair"))
    try:
        yield g
    finally:
        g.close()


def test_the_service_sets_the_mode_on_the_tool(graph: Graph) -> None:
    resp = graph.set_mode(SetOrientationControl.Request.MODE_LEVELING)
    assert resp.success, resp.message
    assert graph.spin_until(lambda: _health(graph).get("mode") == "LEVELING", 10)
    resp = graph.set_mode(SetOrientationControl.Request.MODE_DISABLED)
    assert resp.success, resp.message
    assert graph.spin_until(lambda: _health(graph).get("mode") == "DISABLED", 10)


def test_bad_requests_get_the_links_refusals(graph: Graph) -> None:
    ref = graph.link_refusals
    resp = graph.set_mode(1, pitch=500.0)
    assert (resp.success, resp.message) == ref["offset"]
    assert not ref["offset"][0] and "pitch_offset" in resp.message
    resp = graph.set_mode(1, pitch=math.nan)
    assert (resp.success, resp.message) == (False, ref["nan"])
    resp = graph.set_mode(7)
    assert (resp.success, resp.message) == (False, ref["mode"])
    for key, name, params in (("params", "TWIRL_CW", [1.0]),
                              ("unknown", "NO_SUCH_PRIMITIVE", [])):
        handle = graph.send_goal(name, params)
        res = graph.wait(handle.get_result_async())
        assert res.status == GoalStatus.STATUS_ABORTED
        assert (res.result.success, res.result.message) == (False, ref[key]["message"])
    resp = graph.wait(graph.clear.call_async(Trigger.Request()))
    assert (resp.success, resp.message) == ref["clear"]


def test_twirl_through_the_action_with_feedback(graph: Graph) -> None:
    assert graph.set_mode(0).success
    graph.spin_until(lambda: bool(graph.received["js"]), 10)
    roll0 = graph.received["js"][-1].position[1]
    feedback: list[Any] = []
    handle = graph.send_goal("TWIRL_CW", [1.0, 3.0], feedback)
    res = graph.wait(handle.get_result_async(), 60)
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    assert res.result.success
    assert res.result.final_joint_values[1] == pytest.approx(roll0 + 2 * math.pi, abs=0.05)
    assert len(feedback) >= 10
    pct = [f.percent_complete for f in feedback]
    assert pct == sorted(pct) and pct[-1] > 90
    # the joint states the node forwards show the same twirl
    assert graph.spin_until(lambda: abs(graph.received["js"][-1].position[1]
                                        - res.result.final_joint_values[1]) < 0.05, 5)


def test_a_cancelled_goal_stops_the_tool(graph: Graph) -> None:
    assert graph.set_mode(0).success
    feedback: list[Any] = []
    handle = graph.send_goal("TWIRL_CCW", [1.0, 0.5], feedback)  # 12.6 s
    assert graph.spin_until(lambda: len(feedback) >= 5, 10)
    cancel = graph.wait(handle.cancel_goal_async())
    assert len(cancel.goals_canceling) == 1
    res = graph.wait(handle.get_result_async(), 30)
    assert res.status == GoalStatus.STATUS_CANCELED
    assert not res.result.success
    travelled = abs(feedback[-1].current_joint_values[1] - feedback[0].current_joint_values[1])
    assert travelled < math.pi  # far short of the goal's full turn
    # the roll no longer moves once the tool has taken the cancel
    graph.spin_until(lambda: False, 0.5)
    r1 = graph.received["js"][-1].position[1]
    graph.spin_until(lambda: False, 1.0)
    assert graph.received["js"][-1].position[1] == pytest.approx(r1, abs=1e-3)


def test_telemetry_is_forwarded(graph: Graph) -> None:
    streams = ("js", "imu", "health", "battery")
    assert graph.spin_until(lambda: all(len(graph.received[k]) >= 5 for k in streams), 10)
    js = graph.received["js"][-1]  # under the upstream joint names, [pitch, roll]
    assert list(js.name) == ["atool_joint1", "atool_joint2"] and len(js.position) == 2
    q = graph.received["imu"][-1].orientation
    assert math.isclose(q.w**2 + q.x**2 + q.y**2 + q.z**2, 1.0, rel_tol=1e-6)
    assert graph.received["health"][-1].status[0].hardware_id == TOOL
    assert graph.received["battery"][-1].serial_number == TOOL


def test_a_ros2_trajectory_moves_the_wrist(graph: Graph) -> None:
    assert graph.set_mode(0).success
    # the twirls left roll outside the trajectory's joint limits [-pi, pi]: home first
    res = graph.wait(graph.send_goal("HOMING", [2.0]).get_result_async(), 30)
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    graph.spin_until(lambda: False, 0.5)  # take the queued joint states: q0 is the latest
    q0 = list(graph.received["js"][-1].position)
    target = [0.3, q0[1]]
    # the first point 0.3 s in: the tool moves there smoothly if the wrist is still settling
    # (a first point at t = 0 must be within one tick's travel, else the tool refuses it)
    traj = JointTrajectory(joint_names=["atool_joint1", "atool_joint2"], points=[
        JointTrajectoryPoint(positions=q0, velocities=[0.0, 0.0],
                             time_from_start=Duration(sec=0, nanosec=300_000_000)),
        JointTrajectoryPoint(positions=target, velocities=[0.0, 0.0],
                             time_from_start=Duration(sec=1, nanosec=800_000_000))])
    graph.traj_pub.publish(traj)
    assert graph.spin_until(lambda: abs(graph.received["js"][-1].position[0] - 0.3) < 0.02,
                            15), graph.log.read_text()
    assert graph.set_mode(0).success


def test_the_upstream_nodes_mode_service_name_sets_the_mode_too(graph: Graph) -> None:
    resp = graph.set_mode(SetOrientationControl.Request.MODE_LEVELING, client=graph.soc_mode)
    assert resp.success, resp.message
    assert graph.spin_until(lambda: _health(graph).get("mode") == "LEVELING", 10)
    assert graph.set_mode(0, client=graph.soc_mode).success


def test_calibration_is_answered_without_pretending(graph: Graph) -> None:
    """As ADA's TriggerArticutoolCalibration calls it: an empty request; the reply says
    there is nothing to calibrate, the offset is the identity, and the latched status says
    yaw is not referenced."""
    resp = graph.wait(graph.calibration.call_async(TriggerCalibration.Request()))
    assert resp.success and "nothing to calibrate" in resp.message
    q = resp.computed_offset_jacobase_to_filterworld
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)
    assert graph.spin_until(lambda: bool(graph.received["status"]), 10)
    assert graph.received["status"][-1].is_yaw_calibrated is False


def test_parameters_are_declared_typed_and_readable(graph: Graph) -> None:
    """What ``ros2 param get/describe /articutool_ros2 …`` reads, through rclpy's parameter
    services; ``-p wait_s:=30`` overrode the flag's 10 s."""
    pc = AsyncParameterClient(graph.node, "/articutool_ros2")
    assert pc.wait_for_services(timeout_sec=30)
    names = ["tool_id", "wait_s", "namespace", "offset_units", "joint_names",
             "call_timeout_s", "tool_timeout_s", "link_config", "utensil"]
    got = graph.wait(pc.get_parameters(names)).values
    values = dict(zip(names, got, strict=True))
    assert values["tool_id"].string_value == TOOL
    assert values["wait_s"].double_value == 30.0
    assert values["namespace"].string_value == ""
    assert values["offset_units"].string_value == "degrees"
    assert list(values["joint_names"].string_array_value) == ["atool_joint1", "atool_joint2"]
    assert values["call_timeout_s"].double_value > 0
    desc = {d.name: d for d in graph.wait(pc.describe_parameters(names)).descriptors}
    rng = desc["wait_s"].floating_point_range[0]
    assert (rng.from_value, rng.to_value) == (0.0, 3600.0)
    assert all(d.read_only for d in desc.values())
    res = graph.wait(pc.set_parameters([rclpy.parameter.Parameter("wait_s", value=5.0)]))
    assert not res.results[0].successful  # read-only: they configure how the node started


def test_stop_ends_a_running_primitive(graph: Graph) -> None:
    assert graph.set_mode(0).success
    feedback: list[Any] = []
    handle = graph.send_goal("TWIRL_CCW", [1.0, 0.5], feedback)
    assert graph.spin_until(lambda: len(feedback) >= 3, 10)
    resp = graph.wait(graph.stop.call_async(Trigger.Request()))
    assert resp.success, resp.message
    res = graph.wait(handle.get_result_async(), 30)
    assert res.status in (GoalStatus.STATUS_ABORTED, GoalStatus.STATUS_CANCELED)
    assert not res.result.success
    graph.spin_until(lambda: False, 0.5)
    r1 = graph.received["js"][-1].position[1]
    graph.spin_until(lambda: False, 1.0)
    assert graph.received["js"][-1].position[1] == pytest.approx(r1, abs=1e-3)


@pytest.fixture
def flooded_graph(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Graph]:
    """A node and tool of the flood test's own: after a long flood on a loaded machine
    rmw_fastrtps may stop answering a client it answered before ("failed to send response
    (timeout)", reproduced with a bare rclpy server), which must not reach the other tests'
    shared node (docs/ros2.md)."""
    g = Graph(tmp_path_factory.mktemp("ros2-flood"), domain=ros_domain_id(1))
    try:
        yield g
    finally:
        g.close()


def test_stops_and_cancels_are_all_answered_under_a_flood(flooded_graph: Graph) -> None:
    """Another process floods the node's services with 1 000 bad calls/s (mode 7, a 500°
    offset, NaN, calibration) while this client stops the wrist and
    cancels goals: every stop and every cancel is answered (the flood's own calls may be
    refused as busy). A flood of the action's own goals and cancels is measured by
    benchmarks/bench_ros2_stops.py: it shares the action's queues with a client's cancels."""
    graph = flooded_graph
    flooder = subprocess.Popen([sys.executable, str(Path(__file__).parent / "ros2_flooder.py"),
                                "--rate", "1000", "--seconds", "60",
                                "--kinds", "mode,offset,nan,calibration"], env=graph.env, text=True,
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    assert flooder.stdout is not None
    assert flooder.stdout.readline().strip() == "READY"
    try:
        graph.spin_until(lambda: False, 1.0)  # the flood is on
        answers = []
        for _ in range(20):  # one after another, each awaited, as ADA's behaviours call
            answers.append(graph.wait(graph.stop.call_async(Trigger.Request()), 10))
        assert all(a.success for a in answers), [a.message for a in answers]
        cancelled = 0
        for _ in range(3):
            feedback: list[Any] = []
            handle = graph.send_goal("TWIRL_CW", [1.0, 0.5], feedback)
            assert graph.spin_until(lambda fb=feedback: len(fb) >= 2, 20)
            cancel = graph.wait(handle.cancel_goal_async(), 20)
            assert len(cancel.goals_canceling) == 1
            res = graph.wait(handle.get_result_async(), 30)
            cancelled += res.status == GoalStatus.STATUS_CANCELED
        assert cancelled == 3
    finally:
        out, _ = flooder.communicate(input="", timeout=60)
    sent = out.split()  # SENT n ANSWERED n seconds (its rate: bench_ros2_stops.py)
    assert sent[0] == "SENT" and 0 < int(sent[3]) <= int(sent[1]), out


@pytest.mark.floods
def test_every_call_of_a_1000_per_s_flood_is_answered(flooded_graph: Graph) -> None:
    """3 000 bad calls at 1 000/s (every kind the flooder sends: mode 7, a 500° offset, NaN,
    unknown primitives, cancels of unknown goals, calibrations, empty verifications), and
    during it a burst of 300 cancels and 5 stops from this client: every one is answered
    (a refusal is an answer), however slowly the loaded host lets the node take them, and the
    next DISABLED on set_orientation_control after the flood is answered too. Counts only:
    the flooder takes its replies with deep queues, so a reply it loses is not counted
    against the node (docs/ros2.md)."""
    from action_msgs.srv import CancelGoal
    graph = flooded_graph
    flooder = subprocess.Popen([sys.executable, str(Path(__file__).parent / "ros2_flooder.py"),
                                "--rate", "1000", "--count", "3000", "--depth", "1000",
                                "--grace", "240"], env=graph.env, text=True,
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    assert flooder.stdout is not None
    assert flooder.stdout.readline().strip() == "READY"
    try:
        cancel = graph.node.create_client(CancelGoal, f"{PRIMITIVE}/_action/cancel_goal",
                                          qos_profile=QoSProfile(depth=1000))
        assert cancel.wait_for_service(timeout_sec=30)
        graph.spin_until(lambda: False, 0.5)  # the flood is on
        burst = []
        for _ in range(300):
            req = CancelGoal.Request()
            req.goal_info.goal_id.uuid = list(os.urandom(16))
            burst.append(cancel.call_async(req))
        stops = [graph.stop.call_async(Trigger.Request()) for _ in range(5)]
        graph.spin_until(lambda: all(f.done() for f in (*burst, *stops)), 240)
        assert sum(f.done() for f in burst) == len(burst)
        assert all(f.done() and f.result().success for f in stops)
    except BaseException:
        flooder.communicate(timeout=300)  # closing its stdin ends the flood
        raise
    # Its count sent and answered, stdin kept open: on a quiet host the burst is answered
    # before the 3 s flood has all been sent, and closing stdin would cut the flood short.
    flooder.wait(timeout=300)
    out = flooder.stdout.read()
    sent = out.split()  # SENT n ANSWERED n seconds
    assert sent[0] == "SENT" and int(sent[1]) == 3000 and int(sent[3]) == 3000, out
    assert graph.set_mode(0).success


def test_adas_trajectory_path_moves_the_wrist(graph: Graph) -> None:
    """As ADA's SwitchArticutoolControllers then ExecuteArticutoolTrajectory do: switch to the
    joint_trajectory_controller (BEST_EFFORT), send a FollowJointTrajectory goal in the
    upstream joint names, get SUCCESSFUL with the wrist at the last point."""
    from control_msgs.action import FollowJointTrajectory
    from controller_manager_msgs.srv import SwitchController
    switch = graph.node.create_client(SwitchController,
                                      "/articutool/controller_manager/switch_controller")
    assert switch.wait_for_service(timeout_sec=30)
    req = SwitchController.Request(activate_controllers=["joint_trajectory_controller"],
                                   deactivate_controllers=["velocity_controller"],
                                   strictness=SwitchController.Request.BEST_EFFORT)
    assert graph.wait(switch.call_async(req)).ok
    bad = SwitchController.Request(activate_controllers=["no_such_controller"],
                                   strictness=SwitchController.Request.STRICT)
    assert not graph.wait(switch.call_async(bad)).ok
    fjt = ActionClient(graph.node, FollowJointTrajectory,
                       "/articutool/joint_trajectory_controller/follow_joint_trajectory")
    assert fjt.wait_for_server(timeout_sec=30)
    assert graph.set_mode(0).success
    res = graph.wait(graph.send_goal("HOMING", [2.0]).get_result_async(), 30)
    assert res.status == GoalStatus.STATUS_SUCCEEDED, res.result.message
    graph.spin_until(lambda: False, 0.3)
    q0 = list(graph.received["js"][-1].position)
    goal = FollowJointTrajectory.Goal()
    goal.trajectory = JointTrajectory(joint_names=["atool_joint2", "atool_joint1"], points=[
        JointTrajectoryPoint(positions=[q0[1], q0[0]], velocities=[0.0, 0.0],
                             time_from_start=Duration(sec=0, nanosec=300_000_000)),
        JointTrajectoryPoint(positions=[q0[1], -0.25], velocities=[0.0, 0.0],
                             time_from_start=Duration(sec=1, nanosec=500_000_000))])
    feedback: list[Any] = []
    handle = graph.wait(fjt.send_goal_async(goal, feedback_callback=lambda f: feedback.append(
        f.feedback)))
    assert handle.accepted
    res = graph.wait(handle.get_result_async(), 30)
    assert res.result.error_code == FollowJointTrajectory.Result.SUCCESSFUL, \
        res.result.error_string
    assert res.status == GoalStatus.STATUS_SUCCEEDED and feedback
    assert list(feedback[-1].joint_names) == ["atool_joint1", "atool_joint2"]
    # The result and the joint states travel on different topics: the states published after
    # the node judged the wrist at the last point may reach this client after the result.
    assert graph.spin_until(lambda: abs(graph.received["js"][-1].position[0] + 0.25) <= 0.05,
                            10), graph.received["js"][-1].position
    wrong = FollowJointTrajectory.Goal()
    wrong.trajectory = JointTrajectory(joint_names=["j2n6s200_joint_1", "atool_joint1"],
                                       points=goal.trajectory.points)
    handle = graph.wait(fjt.send_goal_async(wrong))
    res = graph.wait(handle.get_result_async(), 30)
    assert res.result.error_code == FollowJointTrajectory.Result.INVALID_JOINTS
    assert "atool_joint1" in res.result.error_string
    assert graph.set_mode(0).success


def test_sigint_mid_goal_cancels_it_and_exits_0(graph: Graph) -> None:
    """Runs last: it stops the module's node."""
    assert graph.set_mode(0).success
    feedback: list[Any] = []
    graph.send_goal("TWIRL_CW", [1.0, 0.5], feedback)
    assert graph.spin_until(lambda: len(feedback) >= 3, 10)
    graph.node_proc.send_signal(signal.SIGINT)
    out, _ = graph.node_proc.communicate(timeout=30)
    assert graph.node_proc.returncode == 0
    assert "cancelling forwarded goals" in out
    with ArticutoolClient(graph.link_cfg) as c:  # reads telemetry only
        assert c.wait_for_tool(10)
        s1 = c.latest_state()
        assert s1 is not None
        assert wait_until(lambda: c.latest_state().stamp >= s1.stamp + 1.0, 10.0)
        s2 = c.latest_state()
    assert s1 is not None and s2 is not None
    assert s2.position[1] == pytest.approx(s1.position[1], abs=1e-3)


def test_sigterm_stops_an_idle_node(graph: Graph) -> None:
    node = _start_node(graph.pc_cfg, graph.port, graph.log)
    node.send_signal(signal.SIGTERM)
    out, _ = node.communicate(timeout=30)
    assert node.returncode == 0, graph.log.read_text()
    assert "stopping" in out


@pytest.mark.parametrize(("args", "field"), [
    (["--ros-namespace", "a b"], "--ros-namespace"),
    (["--ros-namespace", "9lives"], "--ros-namespace"),
    (["--ros-args", "-p", "wait_s:=-1.0"], "wait_s"),
    (["--ros-args", "-p", "wait_s:=soon"], "wait_s"),
    (["--ros-args", "-p", "offset_units:=furlongs"], "offset_units"),
    (["--ros-args", "-p", "joint_names:=[a]"], "joint_names"),
    (["--ros-args", "-p", "namespace:=a b"], "namespace"),
    (["--ros-args", "-p", "utensil:=ladle"], "utensil"),
    (["--ros-args", "-p", "republish_joint_states:=maybe"], "republish_joint_states"),
    (["--ros-args", "-p", "tool_idd:=x"], "tool_idd"),
    (["--connect", "tcp/nowhere"], "connect"),
    (["--wait", "-1"], "--wait"),
    (["--wait", "1e300"], "--wait"),  # bounded like the client's: a huge wait would hang
])
def test_bad_input_exits_2_naming_the_field(args: list[str], field: str) -> None:
    p = _articutool("ros2", *args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 2, (out, err)
    assert field in err and "Traceback" not in err


def _health(graph: Graph) -> dict[str, str]:
    if not graph.received["health"]:
        return {}
    return {kv.key: kv.value for kv in graph.received["health"][-1].status[0].values}



def test_no_tool_heard_exits_1_saying_so() -> None:
    p = _articutool("ros2", "--connect", f"tcp/127.0.0.1:{free_port()}", "--wait", "1",
                    stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 1, (out, err)
    assert "no Articutool heard within 1 s" in err and "serving" not in out


class _ResultBeforeCancelReply:
    """A link client for which the tool's CANCELED result arrives before the reply to the
    cancel that caused it: the link promises no order between the replies to two calls (the
    tick answers get_result, the link-io thread the cancel), and on a loaded host the result
    may win."""

    def __init__(self) -> None:
        from articutool.link.config import LinkConfig
        from articutool.link.memory_transport import MemoryBus, MemoryTransport
        from articutool.link.transport import Names
        self.cfg = LinkConfig()
        self.names = Names(self.cfg.namespace, self.cfg.tool_id)
        self.transport = MemoryTransport(MemoryBus())
        self.running = threading.Event()
        self.cancelled = threading.Event()
        self.cancels: list[bytes | None] = []

    def run_primitive(self, name: str, params: list[float], feedback_cb: Any = None,
                      timeout: float | None = None, goal_id: bytes | None = None) -> Any:
        self.running.set()
        if not self.cancelled.wait(30):
            return m.PrimitiveResult(True, "done", (0.0, 0.0), m.GoalStatus.SUCCEEDED)
        return m.PrimitiveResult(False, "cancelled", (0.0, 0.0), m.GoalStatus.CANCELED)

    def cancel(self, goal_id: bytes | None = None) -> bool:
        self.cancels.append(goal_id)
        self.cancelled.set()  # the tool cancels and its result goes out ...
        time.sleep(0.3)  # ... before the cancel's own reply arrives
        return True


def test_a_cancel_whose_result_arrives_before_its_reply_still_cancels() -> None:
    """The node, in process, with a client whose tool result beats the cancel's reply: the
    ROS 2 cancel is accepted and the goal ends CANCELED (not ABORTED with the cancel answering
    goals_canceling=[])."""
    from rclpy.executors import MultiThreadedExecutor

    from articutool.ros2.node import ArticutoolRos2Node, NodeSettings
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN)
    fake = _ResultBeforeCancelReply()
    ns = f"race_{os.getpid()}"
    server = ArticutoolRos2Node(fake, NodeSettings(namespace=ns),  # type: ignore[arg-type]
                                context=ctx)
    server_exec = MultiThreadedExecutor(num_threads=4, context=ctx)
    server_exec.add_node(server.node)
    server_exec.add_node(server.safety_node)
    spinner = threading.Thread(target=server_exec.spin, daemon=True)
    spinner.start()
    node = rclpy.create_node("plain_race_client", context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    try:
        action = ActionClient(node, ExecuteArticutoolPrimitive, f"/{ns}{PRIMITIVE}")
        assert action.wait_for_server(timeout_sec=30)

        def wait(future: Any) -> Any:
            ex.spin_until_future_complete(future, timeout_sec=30)
            assert future.done(), "no answer in time"
            return future.result()
        handle = wait(action.send_goal_async(ExecuteArticutoolPrimitive.Goal(
            primitive_name="TWIRL_CW", parameters=[1.0, 0.5])))
        assert handle.accepted and fake.running.wait(10)
        cancel = wait(handle.cancel_goal_async())
        assert len(cancel.goals_canceling) == 1
        res = wait(handle.get_result_async())
        assert res.status == GoalStatus.STATUS_CANCELED
        assert fake.cancels == [bytes(handle.goal_id.uuid)]
    finally:
        server_exec.shutdown(timeout_sec=2.0)
        server.destroy()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


class _RecordingClient(_ResultBeforeCancelReply):
    """Records the offsets the node forwards (degrees, the link's unit)."""

    def __init__(self) -> None:
        super().__init__()
        self.modes: list[tuple[int, float, float]] = []

    def set_mode(self, mode: int, pitch: float = 0.0, roll: float = 0.0,
                 target: tuple[float, ...] = (0.0, 0.0, 0.0, 1.0)) -> tuple[bool, str]:
        self.modes.append((int(mode), pitch, roll))
        return True, "LEVELING"

    def latest_state(self) -> None:
        return None


def _leveling_in_process(fake: Any, settings: Any, pitch: float, roll: float = 0.0) -> Any:
    """The node, in process, serving ``fake`` (a link client) with ``settings``: the reply to
    one LEVELING request with these offsets (the request's units) from a plain client."""
    from rclpy.executors import MultiThreadedExecutor

    from articutool.ros2.node import ArticutoolRos2Node
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN)
    server = ArticutoolRos2Node(fake, settings, context=ctx)
    server_exec = MultiThreadedExecutor(num_threads=2, context=ctx)
    server_exec.add_node(server.node)
    threading.Thread(target=server_exec.spin, daemon=True).start()
    node = rclpy.create_node("plain_leveling_client", context=ctx)
    try:
        cli = node.create_client(SetOrientationControl, f"/{settings.namespace}{SOC}")
        assert cli.wait_for_service(timeout_sec=30)
        req = SetOrientationControl.Request(control_mode=1, pitch_offset=float(pitch),
                                            roll_offset=float(roll))
        req.target_orientation_robot_base = Quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
        future = cli.call_async(req)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.spin_until_future_complete(future, timeout_sec=30)
        assert future.done(), "no answer in time"
        return future.result()
    finally:
        server_exec.shutdown(timeout_sec=2.0)
        server.destroy()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


@pytest.mark.parametrize(("units", "expected_deg"), [("degrees", math.radians(10.0)),
                                                     ("radians", 10.0)])
def test_offset_units_read_what_ada_sends(units: str, expected_deg: float) -> None:
    """ADA's CallSetOrientationControl sends math.radians(pitch_offset_deg). Read as degrees
    (the upstream .srv's unit) a 10° request levels 0.17° off; with offset_units=radians (the
    default) it levels the 10° ADA meant."""
    from articutool.ros2.node import NodeSettings
    fake = _RecordingClient()
    settings = NodeSettings(namespace=f"units_{units}_{os.getpid()}", offset_units=units)
    reply = _leveling_in_process(fake, settings, math.radians(10.0), math.radians(-5.0))
    assert reply.success
    (mode, pitch, roll), = fake.modes
    assert mode == 1
    assert pitch == pytest.approx(expected_deg, rel=1e-5)
    assert roll == pytest.approx(-expected_deg / 2, rel=1e-5)
    assert NodeSettings().offset_units == "radians"  # ADA's unit is the default


class _ToolWithLimits(_RecordingClient):
    """A link client whose tool reports joint limits (rad) other than the packaged spec's, as
    a tool built from another spec file does (``pitch_limit_low``… in its health)."""

    def __init__(self, limits: tuple[tuple[float, float], tuple[float, float]] | None) -> None:
        super().__init__()
        self.limits = limits

    def latest_state(self) -> Any:  # type: ignore[override]
        from articutool.tool.api import Mode, ToolState
        from articutool.tool.telemetry import LIMIT_KEYS
        extra = {} if self.limits is None else {
            k: float(v) for keys, bounds in zip(LIMIT_KEYS, self.limits, strict=True)
            for k, v in zip(keys, bounds, strict=True)}
        return ToolState(stamp=0.0, mode=Mode.DISABLED, joint_names=("pitch", "roll"),
                         position=(0.0, 0.0), velocity=(0.0, 0.0),
                         orientation_wxyz=(1.0, 0.0, 0.0, 0.0),
                         angular_velocity=(0.0, 0.0, 0.0),
                         linear_acceleration=(0.0, 0.0, 0.0), fault="", battery_voltage=12.0,
                         loop_period_mean=0.02, loop_jitter=0.0, loop_overruns=0, extra=extra)


@pytest.mark.parametrize(("limits_deg", "pitch_deg", "forwarded", "words"), [
    (((-120, 120), (-180, 180)), 100.0, True, ()),  # beyond the packaged ±90°, within its own
    (((-30, 30), (-180, 180)), 45.0, False, ("pitch_offset_deg", "[-30, 30]")),
    (None, 100.0, True, ()),  # limits not reported: the tool checks
])
def test_offsets_are_admitted_against_the_connected_tools_limits(
        limits_deg: Any, pitch_deg: float, forwarded: bool, words: tuple[str, ...]) -> None:
    """The node's pre-check of LEVELING offsets uses the limits the connected tool reports:
    a request within that tool's limits reaches it even when the packaged spec's are
    narrower, and one outside them is refused by the node with the tool's message and never
    forwarded."""
    from articutool.ros2.node import NodeSettings
    limits = None if limits_deg is None else tuple(
        (math.radians(lo), math.radians(hi)) for lo, hi in limits_deg)
    fake = _ToolWithLimits(limits)  # type: ignore[arg-type]
    ns = f"limits_{len(words)}_{int(pitch_deg)}_{limits is None:d}_{os.getpid()}"
    reply = _leveling_in_process(fake, NodeSettings(namespace=ns), math.radians(pitch_deg))
    assert reply.success is forwarded, reply.message
    assert [round(p, 3) for _, p, _ in fake.modes] == ([pitch_deg] if forwarded else [])
    for w in words:
        assert w in reply.message


def test_every_name_is_served_with_its_type_on_its_node() -> None:
    """Every name of :data:`articutool.ros2.names.ENDPOINTS` is on the graph with its type and
    kind, the stop and both actions on the safety node (its own executor thread), every other
    service, publisher and subscription on the main node; the calibration status is latched.
    The node is built in process around a link client stand-in."""
    from rclpy.action import get_action_server_names_and_types_by_node

    from articutool.ros2.names import ENDPOINTS, resolve
    from articutool.ros2.node import ArticutoolRos2Node, NodeSettings
    from articutool.ros2.verify_service import Verifier
    from articutool.spec import load_spec
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=DOMAIN)
    ns = f"graph_{os.getpid()}"
    settings = NodeSettings(namespace=ns, verifier=Verifier(load_spec(), "spoon",
                                                            ("atool_joint1", "atool_joint2")))
    server = ArticutoolRos2Node(_RecordingClient(), settings,  # type: ignore[arg-type]
                                context=ctx)
    try:
        names = resolve(ns)
        main, safety = server.node, server.safety_node
        assert safety is not None
        safe_keys = {"stop", "execute_primitive", "follow_joint_trajectory"}

        def served(node: Any) -> dict[str, set[tuple[str, str]]]:
            at = (node.get_name(), node.get_namespace())
            return {
                "service": {(n, t) for n, ts in node.get_service_names_and_types_by_node(*at)
                            for t in ts},
                "action": {(n, t) for n, ts in get_action_server_names_and_types_by_node(
                    node, *at) for t in ts},
                "publishes": {(n, t) for n, ts in node.get_publisher_names_and_types_by_node(
                    *at) for t in ts},
                "subscribes": {(n, t) for n, ts in
                               node.get_subscriber_names_and_types_by_node(*at) for t in ts}}
        def wrong() -> list[tuple[str, str]]:
            """(name key, what is wrong) for every endpoint not where and as it should be."""
            on = {"main": served(main), "safety": served(safety)}
            out = []
            for key, ep in ENDPOINTS.items():
                where = "safety" if key in safe_keys else "main"
                other = "main" if where == "safety" else "safety"
                if (names[key], ep.type) not in on[where][ep.kind]:
                    out.append((key, f"not a {ep.kind} {ep.type} on the {where} node"))
                if any(n == names[key] for n, _ in on[other][ep.kind]):
                    out.append((key, f"also on the {other} node"))
            return out
        wait_until(lambda: not wrong(), 10.0)  # the graph cache may lag the entities
        assert wrong() == []
        status, = main.get_publishers_info_by_topic(names["calibration_status"])
        assert status.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
    finally:
        server.destroy()
        rclpy.try_shutdown(context=ctx)
