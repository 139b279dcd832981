"""The feeding tree's transport subtree driving the physics world (the PC arm over the
world's arm driver, and the tool runtime)."""

from __future__ import annotations

from typing import Any

import numpy as np
import py_trees
import pytest
from py_trees.common import Status

pytest.importorskip("mujoco")

from articutool.feeding.behaviours import BiteStage
from articutool.feeding.system import System
from articutool.feeding.tree import attempts_used, run_tree, transport_tree
from articutool.meal.bites import BiteResult, MealSetup
from articutool.sim.arm_driver import sim_arm
from articutool.sim.world import FeedingWorld
from articutool.tool.api import Mode


def test_decoupled_transport_to_staging_in_physics_keeps_the_load_level() -> None:
    w = FeedingWorld.make("pecans", seed=0, load_g=4.0)
    w.tool.set_mode(Mode.LEVELING)
    w.run(1.0)
    w.weighing.tare(0.3)
    held = w.placement.place(1.0)
    g0 = w.ledger.masses_g()  # a piece the loader drops beside the spoon is not the transport's
    arm = sim_arm(w)
    tilts = []
    w.on_tick.append(lambda world: tilts.append(world.tilt_deg()))
    try:
        root = transport_tree(arm, w.tool, "Staging", System.of("articutool"), attempts=3,
                              budget_s=10.0, clock=lambda: w.time)
        run = run_tree(root, w.run, lambda: w.time, timeout_s=60.0)
        status, rec = run.status, run.record
    finally:
        arm.close()
    g = w.ledger.masses_g()
    assert status == Status.SUCCESS, rec.failed_stage
    assert attempts_used(root) == {"planning_attempts_Staging": 1}
    assert rec.motion_time_s > 1.0
    # Every gram of the load is on the utensil, eaten or spilled on the way, once. (Seed 0's
    # loader leaves a 1.66 g half perched on the heap, and it falls off the level spoon under
    # the transport's accelerations: a hand-placed load's risk the accounting must count.)
    lost = sum(g[p] - g0[p] for p in ("airborne", "container", "table", "critical"))
    assert g["utensil"] + g["eaten"] + lost == pytest.approx(held)
    assert max(tilts) < 10.0  # the wrist leveled it all the way (IMU in physics)
    assert w.tool.mode == Mode.DISABLED and w.tool.fault == ""  # scope restored


def test_baseline_strict_transport_from_a_rigid_level_start() -> None:
    # The strict baseline's tilt bound and its locked wrist, with a load of pecans (the same
    # transport with SPH water costs ~5x the CPU and asserts nothing more here).
    w = FeedingWorld.make("pecans", seed=0, load_g=4.0)  # the wrist stays locked (DISABLED)
    arm = sim_arm(w)
    try:
        w.move_arm(arm.rigid_level_configuration("Resting"))
        w.run(0.5)
        assert w.tilt_deg() < 3.0
        w.weighing.tare(0.3)
        w.placement.place(1.0)
        tilts = []
        w.on_tick.append(lambda world: tilts.append(world.tilt_deg()))
        root = transport_tree(arm, w.tool, "Staging", System.of("baseline", tolerance_deg=20.0),
                              attempts=3, budget_s=10.0, clock=lambda: w.time)
        run = run_tree(root, w.run, lambda: w.time, timeout_s=90.0)
        status, rec = run.status, run.record
    finally:
        arm.close()
    assert status == Status.SUCCESS, rec.failed_stage
    # ±20° per axis (pitch and roll of the tip) is up to 28° from vertical in all.
    assert max(tilts) < 28.5
    assert w.tool.mode == Mode.DISABLED and w.wrist_q == pytest.approx([0.0, 0.0], abs=0.05)


def _meal_json(capsys: pytest.CaptureFixture[str], *args: str) -> dict:
    import json

    from articutool.cli import main

    assert main(["meal", "--bites", "1", "--json", *args]) == 0
    return json.loads(capsys.readouterr().out)


class _AtShed(py_trees.visitors.VisitorBase):
    """Where the utensil's tip is when the bite's shedding stage starts."""

    def __init__(self, world: FeedingWorld) -> None:
        super().__init__(full=False)
        self.world, self.seen = world, []

    def run(self, b: py_trees.behaviour.Behaviour) -> None:
        shedding = (isinstance(b, BiteStage) and b.stage == "shed"
                    and b.status == Status.RUNNING)
        if shedding and not self.seen:
            self.seen.append(self.world.tip_pose()[:3, 3].copy())


def _assert_shed_over_the_bowl(world: FeedingWorld, at_shed: _AtShed, r: BiteResult) -> None:
    """Every Articutool strategy's post-acquisition primitive runs after the lift out of the
    bowl: the tip is then over the bowl (thesis §4.4: shed "harmlessly back into the bowl"),
    and what the primitive moved off the utensil is what the shed stage counts."""
    from articutool.arm.scene import container_floor

    bowl = world.scene.get("bowl")
    floor = container_floor(world.scene, "bowl")
    (tip,) = at_shed.seen
    assert np.hypot(*(tip[:2] - floor[:2])) < bowl.radius
    assert tip[2] > floor[2] + 0.05  # lifted out, above the food
    assert r.shed_g == pytest.approx(r.acquired_g - r.masses_after["shed"]["utensil"])


@pytest.mark.slow  # the demo's bite: the spoon in an awake pile of 190 pieces, minutes of CPU
def test_a_whole_pecan_bite_by_the_articutool_in_physics(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    # The meal CLI's bite, watched where its primitive sheds (one whole bite for both).
    from articutool.meal import bites

    real, seen = bites.run_bite, []

    def watched(setup: MealSetup, **kw: Any) -> BiteResult:
        at_shed = _AtShed(setup.world)
        r = real(setup, **{**kw, "visitors": [*kw.get("visitors", ()), at_shed]})
        seen.append((setup.world, at_shed, r))
        return r

    monkeypatch.setattr(bites, "run_bite", watched)
    out = _meal_json(capsys, "--food", "pecans")
    (b,) = out["bites"]
    assert b["completed"] and b["failed_stage"] == ""
    assert b["strategy"] == "pecans_tilted_scoop"
    # Mass is conserved by the accounting: what was acquired was shed, spilled or delivered
    # (one piece is 0.92 g; a piece may still be rolling in the bowl at a stage's end).
    assert b["acquired_g"] > 0
    assert b["delivered_g"] + b["shed_g"] + b["spilled_g"] == pytest.approx(b["acquired_g"],
                                                                            abs=0.93)
    assert b["planning_attempts"] >= 1 and b["planning_attempts_by_goal"]["Staging"] >= 1
    assert b["transport_max_tilt_deg"] < 10.0  # the wrist kept it level to Staging
    assert b["spilled_g"] == 0.0  # nothing fell on the table or the user
    # Its class follows from what it delivered at the threshold the meal used.
    thr = out["threshold_g"]
    assert b["outcome"] == ("meaningful_success" if b["delivered_g"] > thr
                            else "trivial_success")
    (run,) = seen
    _assert_shed_over_the_bowl(*run)


@pytest.mark.slow
@pytest.mark.parametrize(("food", "system"), [("noodles", "articutool"), ("water", "articutool"),
                                              ("pecans", "baseline"), ("noodles", "baseline")])
def test_a_whole_bite_runs_to_its_end_in_physics(capsys: pytest.CaptureFixture[str],
                                                 food: str, system: str) -> None:
    out = _meal_json(capsys, "--food", food, "--system", system)
    (b,) = out["bites"]
    # Every stage ran to its end: acquired, (shed), carried, presented, back at Resting.
    assert b["completed"] and b["failed_stage"] == "", b
    assert b["planning_attempts_by_goal"]["Staging"] >= 1
    assert b["planning_attempts_by_goal"]["Resting"] >= 1
    # Every acquired gram was delivered, shed or spilled (one item, at most a 1.05 g strand,
    # may still be rolling in the bowl when a stage ends).
    assert b["delivered_g"] + b["shed_g"] + b["spilled_g"] == pytest.approx(
        b["acquired_g"], abs=1.06)
    # The class is the hierarchy's, from the bite's own masses at the meal's threshold.
    spilled, thr = b["spilled_by_place"], out["threshold_g"]
    assert b["outcome"] == ("user_spill" if spilled["critical"] > 0 else
                            "table_spill" if spilled["table"] > 0 else
                            "meaningful_success" if b["delivered_g"] > thr else
                            "trivial_success")
    if system == "baseline":
        assert b["shed_g"] == 0.0  # its wrist is locked: no shedding primitive


class _LockedCarry(py_trees.behaviour.Behaviour):
    """Turns the hand until the locked utensil tilts 40°, then waits ``hold_s``; with
    ``drop``, then moves a particle that spilled on the table off its edge to the floor and
    waits 0.5 s more (water deposits where it lands: the table-then-floor spill is staged)."""

    def __init__(self, world: FeedingWorld, hold_s: float, drop: bool = False) -> None:
        super().__init__("locked carry")
        self.world, self.hold_s, self.t_end, self.drop = world, hold_s, None, drop

    def update(self) -> Status:
        from articutool.sim.scenes import base_tilt_motion
        from articutool.trajectory import smooth_joint_motion
        from conftest import drop_off_the_table

        w = self.world
        if self.t_end is None:
            traj = smooth_joint_motion(w.arm_q, base_tilt_motion(w, 40.0),
                                       w.spec.arm.max_velocity, w.layout.arm_joints)
            w.follow_arm(traj, wait=False)
            self.t_end = w.time + traj.duration + self.hold_s
        if w.time >= self.t_end and self.drop:
            drop_off_the_table(w)
            self.drop, self.t_end = False, w.time + 0.5
        return Status.SUCCESS if w.time >= self.t_end else Status.RUNNING


def test_a_bites_spill_counts_a_particle_that_goes_from_table_to_floor_once() -> None:
    # A particle that lands on the table and then reaches the floor is one spill, not two
    # summed spill events. Here a bite whose tree is a locked 40° carry of 8 g of water
    # (seed 0), one of whose table spills is then moved off the table's edge.
    import mujoco

    from articutool.meal.bites import make_bite_world, run_bite

    setup = make_bite_world("water", "articutool", seed=0, load_g=8.0)
    w = setup.world
    w.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)  # moved by hand
    try:
        w.placement.place(settle_s=1.0)
        n0 = len(w.ledger.spills)
        r = run_bite(setup, stages=("resting",), root=_LockedCarry(w, 3.0, drop=True),
                     threshold_g=0.0)
    finally:
        setup.arm.close()
    events = w.ledger.spills[n0:]
    items = {e.item for e in events}
    assert len(events) > len(items)  # a particle spilled twice: table, then floor
    g = w.ledger.item_g
    assert r.spilled_g == pytest.approx(sum(g[k] for k in items))
    floor = {e.item for e in events if e.place == "critical"}
    assert r.spilled_by_place["critical"] == pytest.approx(sum(g[k] for k in floor))
    assert r.spilled_by_place["table"] == pytest.approx(sum(g[k] for k in items - floor))
    assert r.outcome == "user_spill"  # the floor is a critical place


@pytest.mark.slow  # the pecans' is checked in the whole bite above
@pytest.mark.parametrize("food", ["water", "noodles"])
def test_the_bite_tree_sheds_over_the_bowl(food: str) -> None:
    from articutool.meal.bites import make_bite_world, run_bite

    setup = make_bite_world(food, "articutool", seed=0)
    at_shed = _AtShed(setup.world)
    try:
        r = run_bite(setup, stages=("above", "acquire", "shed"), visitors=[at_shed])
    finally:
        setup.arm.close()
    assert r.completed, r.failed_stage
    assert r.spilled_g == 0.0  # what the primitive moved off the utensil went into the bowl
    _assert_shed_over_the_bowl(setup.world, at_shed, r)
