"""Plan-then-verify as a ROS 2 service: ``VerifyTrajectory`` answered by ``articutool ros2
--verify-only`` in its own process to a plain rclpy client (two processes), and the request
checks that refuse what cannot be verified (never "assumed feasible", unlike ADA's path
checks, which call an empty trajectory feasible and sample 10 points)."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from articutool.ros2.verify_service import Verifier
from conftest import ros_domain_id

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SRC = Path(__file__).resolve().parent.parent / "src"


@pytest.fixture(scope="module")
def verifier(spec: Any) -> Verifier:
    return Verifier(spec, "spoon", ("atool_joint1", "atool_joint2"))


def _dur(t: float) -> SimpleNamespace:
    sec = math.floor(t)
    return SimpleNamespace(sec=sec, nanosec=round((t - sec) * 1e9))


def _example(name: str, order: list[int] | None = None) -> SimpleNamespace:
    """A packaged arm trajectory as a stand-in of the ROS 2 message (joints reordered)."""
    d = json.loads((EXAMPLES / name).read_text())
    idx = order or list(range(len(d["joint_names"])))
    pts = [SimpleNamespace(positions=[p["positions"][i] for i in idx],
                           velocities=[p["velocities"][i] for i in idx],
                           time_from_start=_dur(p["time_from_start"])) for p in d["points"]]
    return SimpleNamespace(joint_names=[d["joint_names"][i] for i in idx], points=pts)


def _req(traj: Any, **kw: Any) -> SimpleNamespace:
    base = {"trajectory": traj, "utensil": "", "max_step_deg": 0.0, "wrist_start": [],
            "food": "", "load_g": 0.0}
    base.update(kw)
    return SimpleNamespace(**base)


def test_a_feasible_plan_returns_the_wrist_trajectory_under_ros_names(verifier: Verifier) -> None:
    out = verifier.answer(_req(_example("transport_feasible.json")))
    assert out["feasible"] and out["reason"] == "ok", out["message"]
    assert out["first_failure_time"] == -1.0
    assert 0.0 < out["velocity_margin"] < 1.0
    wt = out["wrist_trajectory"]
    assert wt.joint_names == ("atool_joint1", "atool_joint2")
    assert len(wt) == out["samples_checked"] > 200  # dense, not 10 samples


def test_joint_order_does_not_matter(verifier: Verifier) -> None:
    a = verifier.answer(_req(_example("transport_feasible.json")))
    b = verifier.answer(_req(_example("transport_feasible.json", [5, 3, 1, 0, 2, 4])))
    assert (a["feasible"], a["samples_checked"]) == (b["feasible"], b["samples_checked"])
    assert a["velocity_margin"] == pytest.approx(b["velocity_margin"], abs=1e-12)
    np.testing.assert_allclose(a["wrist_trajectory"].positions,
                               b["wrist_trajectory"].positions, atol=1e-12)


def test_a_flip_fails_with_its_time(verifier: Verifier) -> None:
    traj = _example("transport_flip.json")
    out = verifier.answer(_req(traj))
    assert not out["feasible"] and out["reason"] == "discontinuity"
    end = traj.points[-1].time_from_start
    assert 0 < out["first_failure_time"] < end.sec + end.nanosec * 1e-9


def _bad(verifier: Verifier, **kw: Any) -> str:
    traj = kw.pop("traj", None) or _example("transport_feasible.json")
    out = verifier.answer(_req(traj, **kw))
    assert not out["feasible"] and out["reason"] == "bad_request", out
    assert out["wrist_trajectory"] is None
    return str(out["message"])


def test_bad_requests_are_refused_naming_the_field(verifier: Verifier) -> None:
    t = _example("transport_feasible.json")
    empty = SimpleNamespace(joint_names=t.joint_names, points=[])
    assert "trajectory.points is empty" in _bad(verifier, traj=empty)
    nan = _example("transport_feasible.json")
    nan.points[7].positions[2] = math.nan
    assert "trajectory.points[7]" in _bad(verifier, traj=nan)
    back = _example("transport_feasible.json")
    back.points[5].time_from_start = _dur(0.0)
    assert "time_from_start must increase strictly" in _bad(verifier, traj=back)
    unknown = _example("transport_feasible.json")
    unknown.joint_names[0] = "elbow"
    msg = _bad(verifier, traj=unknown)
    assert "trajectory.joint_names" in msg and "elbow" in msg and "j2n6s200_joint_1" in msg
    short = _example("transport_feasible.json")
    short.points[3].positions = short.points[3].positions[:5]
    assert "trajectory.points[3].positions" in _bad(verifier, traj=short)
    assert "utensil" in _bad(verifier, utensil="ladle")
    assert "max_step_deg" in _bad(verifier, max_step_deg=90.0)
    assert "max_step_deg" in _bad(verifier, max_step_deg=math.inf)
    assert "wrist_start" in _bad(verifier, wrist_start=[0.0, 0.0, 0.0])
    assert "load_g" in _bad(verifier, load_g=-1.0)
    assert "load_g" in _bad(verifier, load_g=math.nan)
    assert "food" in _bad(verifier, food="", load_g=5.0)


def test_a_load_is_judged_as_the_verify_cli_judges_it(verifier: Verifier, spec: Any) -> None:
    from articutool.arm.model import ArmModel
    from articutool.food.definitions import load_food_definitions
    from articutool.food.loads import food_load
    from articutool.trajectory import JointTrajectory
    from articutool.verify.verifier import verify_trajectory

    out = verifier.answer(_req(_example("transport_feasible.json"), food="water", load_g=8.0,
                               utensil="soup_spoon"))
    load = food_load(load_food_definitions()["water"], 8.0)
    rep = verify_trajectory(JointTrajectory.load(EXAMPLES / "transport_feasible.json"),
                            ArmModel(spec, "soup_spoon"), spec, utensil="soup_spoon",
                            load=load)
    assert out["spill_checked"] and rep.food is not None
    assert out["predicted_spill_g"] == rep.food.prediction.spilled_g
    assert out["feasible"] == rep.feasible and out["reason"] == rep.reason
    # A load the model cannot judge is refused naming the field, never verified without it.
    assert "food" in _bad(verifier, food="soup", load_g=5.0)
    assert "16.79" in _bad(verifier, food="water", load_g=30.0, utensil="soup_spoon")


# ------------------------------------------------------------ two processes --
_why = "rclpy and the built articutool_interfaces (make; CPython 3.11 on x86_64 only)"


@pytest.fixture(scope="module")
def verify_node() -> Iterator[tuple[Any, Any, Any]]:
    rclpy = pytest.importorskip("rclpy", reason=_why)
    pytest.importorskip("articutool_interfaces.srv", reason=_why)
    from articutool_interfaces.srv import VerifyTrajectory
    from rclpy.executors import SingleThreadedExecutor

    domain = ros_domain_id(salt=1)
    env = dict(os.environ, PYTHONPATH=str(SRC), ROS_DOMAIN_ID=str(domain),
               ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    proc = subprocess.Popen([sys.executable, "-m", "articutool", "ros2", "--verify-only",
                             "--ros-args", "-p", "utensil:=spoon"], env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None
    assert "serving" in proc.stdout.readline()
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    node = rclpy.create_node("plain_verify_client", context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    client = node.create_client(VerifyTrajectory, "/articutool/verify_trajectory")
    assert client.wait_for_service(timeout_sec=30)
    try:
        yield client, ex, VerifyTrajectory
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=30)


def _ros_request(V: Any, name: str, order: list[int] | None = None, **kw: Any) -> Any:
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    ex = _example(name, order)
    traj = JointTrajectory(joint_names=list(ex.joint_names), points=[
        JointTrajectoryPoint(positions=list(p.positions), velocities=list(p.velocities),
                             time_from_start=Duration(sec=p.time_from_start.sec,
                                                      nanosec=p.time_from_start.nanosec))
        for p in ex.points])
    return V.Request(trajectory=traj, **kw)


def _call(verify_node: tuple[Any, Any, Any], req: Any) -> Any:
    client, ex, _ = verify_node
    future = client.call_async(req)
    ex.spin_until_future_complete(future, timeout_sec=60)
    assert future.done(), "no answer in time"
    return future.result()


def test_the_service_verifies_a_jaco_trajectory_in_any_joint_order(verify_node: Any,
                                                                    verifier: Verifier) -> None:
    V = verify_node[2]
    a = _call(verify_node, _ros_request(V, "transport_feasible.json"))
    b = _call(verify_node, _ros_request(V, "transport_feasible.json", [2, 0, 5, 1, 4, 3]))
    assert a.feasible and b.feasible and a.reason == "ok", a.message
    assert a.samples_checked == b.samples_checked > 200
    assert a.velocity_margin == pytest.approx(b.velocity_margin, abs=1e-9)
    assert list(a.wrist_trajectory.joint_names) == ["atool_joint1", "atool_joint2"]
    assert len(a.wrist_trajectory.points) == a.samples_checked
    assert list(a.max_required_velocity) and a.first_failure_time == -1.0
    local = verifier.answer(_req(_example("transport_feasible.json")))
    np.testing.assert_allclose([p.positions for p in a.wrist_trajectory.points],
                               local["wrist_trajectory"].positions, atol=1e-9)


def test_the_service_refuses_bad_requests(verify_node: Any) -> None:
    V = verify_node[2]
    empty = _call(verify_node, V.Request())
    assert (empty.feasible, empty.reason) == (False, "bad_request")
    assert "trajectory.points is empty" in empty.message
    flip = _call(verify_node, _ros_request(V, "transport_flip.json"))
    assert not flip.feasible and flip.reason == "discontinuity" and flip.first_failure_time > 0
    ladle = _call(verify_node, _ros_request(V, "transport_feasible.json", utensil="ladle"))
    assert ladle.reason == "bad_request" and "utensil" in ladle.message
