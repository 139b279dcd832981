"""The PC's arm over a driver without physics (:class:`conftest.PerfectArm`, which follows a
commanded trajectory exactly): plan → verify → follow, the tip's paths and a stop, the same
code the physics world's arm driver runs under, so a real arm is one driver."""

from __future__ import annotations

import math

import numpy as np
import py_trees
import pytest
from py_trees.common import Status

from articutool.arm.scene import SCOOP_HEADING, Cylinder, Scene
from articutool.feeding.insertion import TipWaypoint
from articutool.feeding.system import DECOUPLED, System
from articutool.feeding.tree import BiteRecorder, attempts_used, tick_until_done, transport_tree
from articutool.planning.pc_arm import PCArm
from articutool.planning.tip_paths import tip_target
from conftest import PerfectArm
from test_feeding_tree import Clock, FakeTool

UTENSIL = "spoon"


def _arm(spec, start: str = "Resting") -> tuple[PCArm, PerfectArm]:  # type: ignore[no-untyped-def]
    driver = PerfectArm(spec, spec.arm.configuration(start))
    return PCArm(driver, spec, UTENSIL, Scene.load(), seed=0), driver


def _planned(arm: PCArm, goal: str):  # type: ignore[no-untyped-def]
    """The trajectory the decoupled planner makes from where the arm is to ``goal``."""
    job = arm.start_plan(goal, DECOUPLED, budget_s=10.0)
    job.wait_off_clock()
    plan = job.result()
    assert plan.ok, plan.message
    return plan.value


def _run_motion(arm: PCArm, driver: PerfectArm, traj, dt: float = 0.02) -> None:  # type: ignore[no-untyped-def]
    job = arm.start_execute(traj)
    while not job.done():
        driver.advance(dt)
    assert job.result().ok


def test_plan_verify_follow_reaches_the_goal(spec) -> None:  # type: ignore[no-untyped-def]
    arm, driver = _arm(spec)
    try:
        plan = _planned(arm, "Staging")
        assert plan.positions[0] == pytest.approx(spec.arm.configuration("Resting"))
        checked = arm.verify(plan)
        assert checked.ok, checked.message
        _run_motion(arm, driver, plan)
    finally:
        arm.close()
    goal = arm.goal_configuration("Staging")
    assert driver.joint_positions()[:6] == pytest.approx(goal, abs=1e-6)
    assert not driver.busy and len(driver.followed) == 1


def test_the_feeding_trees_transport_drives_the_pc_arm(spec) -> None:  # type: ignore[no-untyped-def]
    clock = Clock()
    tool = FakeTool(clock)
    arm, driver = _arm(spec)

    def step(dt: float) -> None:
        clock.t += dt
        driver.advance(dt)

    root = transport_tree(arm, tool, "Staging", System.of("articutool"), attempts=3,
                          budget_s=10.0, clock=clock)
    tree = py_trees.trees.BehaviourTree(root)
    rec = BiteRecorder(clock)
    tree.visitors.append(rec)
    tree.setup()
    try:
        status = tick_until_done(tree, rec, step, clock, period_s=0.05, timeout_s=120.0)
    finally:
        arm.close()
    assert status == Status.SUCCESS, rec.record.failures
    assert attempts_used(root) == {"planning_attempts_Staging": 1}
    assert driver.joint_positions()[:6] == pytest.approx(arm.goal_configuration("Staging"),
                                                         abs=1e-6)
    assert rec.record.motion_time_s > 1.0


def _bowl_waypoints(pitch_deg: float = 60.0) -> list[TipWaypoint]:
    box = Scene.load().get("bowl")
    assert isinstance(box, Cylinder)
    c = box.inner_floor()
    a = math.radians(pitch_deg)
    return [TipWaypoint(tuple(c + [0.0, 0.0, z]), a, v)  # type: ignore[arg-type]
            for z, v in ((0.12, 0.1), (0.06, 0.05))]


def test_a_tip_path_ends_with_the_tip_at_its_last_waypoint(spec) -> None:  # type: ignore[no-untyped-def]
    arm, driver = _arm(spec, "AbovePlate")
    wps = _bowl_waypoints()
    try:
        job = arm.start_plan_path("into the bowl", wps)
        job.wait_off_clock()
        r = job.result()
        assert r.ok, r.message
        _run_motion(arm, driver, r.value)
    finally:
        arm.close()
    want = tip_target(wps[-1].position, SCOOP_HEADING, wps[-1].pitch_down)
    tip = arm.model.tip_pose(driver.joint_positions())
    assert np.linalg.norm(tip[:3, 3] - want[:3, 3]) < 0.002
    assert tip[:3, 2] @ want[:3, 2] > math.cos(math.radians(1.0))


def test_a_cancelled_motion_leaves_the_arm_stopped_where_it_is(spec) -> None:  # type: ignore[no-untyped-def]
    arm, driver = _arm(spec)
    try:
        plan = _planned(arm, "Home")
        motion = arm.start_execute(plan)
        driver.advance(plan.duration / 2)
        held = driver.joint_positions()
        motion.cancel()
        driver.advance(1.0)
    finally:
        arm.close()
    assert motion.done() and not motion.result().ok
    assert not driver.busy
    assert driver.joint_positions() == pytest.approx(held)
    assert not np.allclose(held[:6], spec.arm.configuration("Home"))


def test_an_unknown_goal_is_refused_naming_the_known_ones(spec) -> None:  # type: ignore[no-untyped-def]
    driver = PerfectArm(spec, spec.arm.configuration("Resting"))
    arm = PCArm(driver, spec, UTENSIL, Scene.load(), goals={"centre": np.zeros(6)})
    try:
        assert arm.goal_configuration("centre") == pytest.approx(np.zeros(6))
        with pytest.raises(ValueError, match="centre"):
            arm.goal_configuration("nowhere")
    finally:
        arm.close()
