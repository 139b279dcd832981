"""The feeding tree's transport subtree driving the physics world (SimArm + the tool runtime)."""

from __future__ import annotations

import py_trees
import pytest
from py_trees.common import Status

pytest.importorskip("mujoco")

from articutool.feeding.sim_arm import SimArm
from articutool.feeding.tree import run_tree, transport_tree
from articutool.sim.world import FeedingWorld
from articutool.tool.api import Mode


def test_decoupled_transport_to_staging_in_physics_keeps_the_load_level() -> None:
    py_trees.blackboard.Blackboard.clear()
    w = FeedingWorld("pecans", seed=0, load_g=4.0)
    w.tool.set_mode(Mode.LEVELING)
    w.run(1.0)
    w.tare_ft(0.3)
    held = w.place_load(1.0)
    arm = SimArm(w)
    tilts = []
    w.on_tick.append(lambda world: tilts.append(world.tilt_deg()))
    try:
        root = transport_tree(arm, w.tool, "Staging", "decoupled", attempts=3, budget_s=10.0,
                              clock=w.clock)
        status, rec = run_tree(root, w.run, w.clock, timeout_s=60.0)
    finally:
        arm.close()
    g = w.masses_g()
    assert status == Status.SUCCESS, rec.failed_stage
    assert py_trees.blackboard.Blackboard.get("/bite/planning_attempts_Staging") == 1
    assert rec.motion_time_s > 1.0
    assert g["table"] == 0 and g["critical"] == 0  # nothing spilled on the way
    assert g["utensil"] + g["eaten"] == pytest.approx(held)  # delivered: on it or eaten
    assert max(tilts) < 10.0  # the wrist leveled it all the way (IMU in physics)
    assert w.tool.mode == Mode.DISABLED and w.tool.fault == ""  # scope restored


def test_baseline_strict_transport_from_a_rigid_level_start() -> None:
    py_trees.blackboard.Blackboard.clear()
    w = FeedingWorld("water", seed=0, load_g=8.0)  # the wrist stays locked (DISABLED)
    arm = SimArm(w, tolerance_deg=20.0)
    try:
        w.move_arm(arm.rigid_level_configuration("Resting"))
        w.run(0.5)
        assert w.tilt_deg() < 3.0
        w.tare_ft(0.3)
        w.place_load(1.0)
        tilts = []
        w.on_tick.append(lambda world: tilts.append(world.tilt_deg()))
        root = transport_tree(arm, w.tool, "Staging", "strict6", attempts=3, budget_s=10.0,
                              clock=w.clock)
        status, rec = run_tree(root, w.run, w.clock, timeout_s=90.0)
    finally:
        arm.close()
    assert status == Status.SUCCESS, rec.failed_stage
    # ±20° per axis (pitch and roll of the tip) is up to 28° from vertical in all.
    assert max(tilts) < 28.5
    assert w.tool.mode == Mode.DISABLED and w.wrist_q == pytest.approx([0.0, 0.0], abs=0.05)
