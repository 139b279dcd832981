"""The feeding tree acts on the food check: a transport predicted to spill is retimed (both
systems alike) or re-planned, and never executed; the slosh-free wrist goes to the tool and
the leveling loop takes over after."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import py_trees
import pytest
from py_trees.common import Status

from articutool.api_types import JobResult
from articutool.arm.scene import Scene
from articutool.feeding.system import Planner, System
from articutool.feeding.tree import BiteRecorder, tick_until_done, transport_tree
from articutool.food.definitions import load_food_definitions
from articutool.food.loads import food_load
from articutool.planning.pc_arm import FoodDecision, PCArm
from articutool.planning.timing import time_parameterize
from articutool.tool.api import Mode
from articutool.trajectory import JointTrajectory
from articutool.verify.food import food_check
from articutool.verify.verifier import verify_trajectory
from conftest import PerfectArm, packaged_spec
from test_feeding_tree import Clock, FakeArm, FakeJob, FakeTool

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SPEC = packaged_spec()
FOODS = load_food_definitions()
PATH = JointTrajectory.load(EXAMPLES / "transport_feasible.json")
FAST = time_parameterize(PATH.positions, PATH.joint_names, SPEC.arm.max_velocity,
                         SPEC.arm.max_acceleration)


def _water(g: float):
    return food_load(FOODS["water"], g)


def _pc_arm(load, rigid: bool = False, leveling: str = "gravity") -> PCArm:
    """The PC arm over a driver without physics (the food check reads only the wrist's
    joints of it)."""
    return PCArm(PerfectArm(SPEC, PATH.positions[0]), SPEC, "soup_spoon", Scene.load(),
                 rigid=rigid, load=load, leveling=leveling)


def _predicted(arm: PCArm, traj: JointTrajectory) -> float:
    """An independent prediction of what executing ``traj`` with ``arm``'s wrist spills."""
    load = arm.current_load()
    six = JointTrajectory(tuple(SPEC.arm.joint_names), traj.times, traj.positions[:, :6],
                          traj.velocities[:, :6])
    if arm.rigid:
        wrist = np.zeros(2)
    elif len(traj.joint_names) == 8:
        wrist = JointTrajectory(tuple(SPEC.wrist.joint_names), traj.times,
                                traj.positions[:, 6:], traj.velocities[:, 6:])
    else:
        wrist = verify_trajectory(six, arm.model, SPEC).wrist_trajectory
    return food_check(six, wrist, arm.model, SPEC, "soup_spoon", load).prediction.spilled_g


def test_a_transport_predicted_to_spill_is_retimed_until_it_is_not() -> None:
    arm = _pc_arm(_water(14.0))
    assert _predicted(arm, FAST) > 0.05  # as planned, 14 g spills
    r = arm.check_food(FAST)
    assert r.ok, r.message
    rec = r.value.record
    assert rec["retimed"] and rec["scale"] < 1.0 and rec["predicted_spill_g"] < 0.001
    assert r.value.trajectory.duration > FAST.duration
    assert _predicted(arm, r.value.trajectory) < 0.001
    assert rec["tried"][0]["scale"] == 1.0 and rec["tried"][0]["predicted_spill_g"] > 0.05


def test_the_locked_baseline_gets_the_same_retiming() -> None:
    # the example path turns the tool base far from level: no timing saves a locked dish
    arm = _pc_arm(_water(8.0), rigid=True)
    r = arm.check_food(FAST)
    assert not r.ok and "re-plan" in r.message
    assert [t["scale"] for t in r.value.record["tried"]] == [
        1.0, 0.8, 0.64, 0.51, 0.41, 0.33, 0.26]
    assert all(t["wrist"] == "locked" for t in r.value.record["tried"])


def test_slosh_free_leveling_runs_as_planned_where_leveling_needs_retiming() -> None:
    lev = _pc_arm(_water(14.0)).check_food(FAST)
    sf = _pc_arm(_water(14.0), leveling="apparent").check_food(FAST)
    assert lev.ok and sf.ok
    assert sf.value.record["wrist"] == "slosh_free" and not sf.value.record["retimed"]
    assert len(sf.value.trajectory.joint_names) == 8  # the wrist's joints go to the tool
    assert sf.value.trajectory.duration < lev.value.trajectory.duration


def test_no_load_nothing_to_check() -> None:
    r = _pc_arm(None).check_food(FAST)
    assert r.ok and r.value.trajectory is FAST


class CheckingArm(FakeArm):
    """The fake arm of the tree tests, planning real trajectories and checking the food with
    the real :meth:`PCArm.check_food`."""

    def __init__(self, clock: Clock, sim: PCArm, plans: list[JointTrajectory]) -> None:
        super().__init__(clock, [True] * len(plans), [])
        self.sim, self.trajs = sim, list(plans)

    def start_plan(self, goal: str, planner: Planner, budget_s: float) -> FakeJob:
        self.started_plans += 1
        return FakeJob(self.clock, self.plan_s, JobResult(True, "", self.trajs.pop(0)))

    def check_food(self, trajectory):
        return self.sim.check_food(trajectory)


def _run(arm: FakeArm, tool: FakeTool, clock: Clock, system: str = "articutool"):
    root = transport_tree(arm, tool, "Staging", System.of(system, tolerance_deg=20.0),
                          attempts=len(arm.trajs) or 1,
                          budget_s=1.0, clock=clock, food=True)
    tree = py_trees.trees.BehaviourTree(root)
    rec = BiteRecorder(clock)
    tree.visitors.append(rec)
    tree.setup()

    def step(dt: float) -> None:
        clock.t += dt

    status = tick_until_done(tree, rec, step, clock, period_s=0.1, timeout_s=600.0)
    return status, rec.record


def test_the_tree_never_executes_a_transport_predicted_to_spill() -> None:
    # Three plans: 16.7 g of the dish's 16.79 mL leave at 0.1° of tilt, so the first two
    # (a real transport) spill at every timing; the third holds still: the tree must
    # re-plan past the first two and execute only the third.
    clock, tool = Clock(), FakeTool(Clock())
    tool.clock = clock
    sim = _pc_arm(_water(16.7))
    still = JointTrajectory(PATH.joint_names, np.array([0.0, 1.0]),
                            np.tile(PATH.positions[0], (2, 1)), np.zeros((2, 6)))
    arm = CheckingArm(clock, sim, [FAST, FAST, still])
    status, record = _run(arm, tool, clock)
    assert status == Status.SUCCESS
    assert len(arm.executed) == 1
    for traj in arm.executed:  # every executed transport is predicted spill-free
        assert _predicted(sim, traj) < 0.001
    assert len(record.food_checks) == 3
    assert [c.get("executed", True) for c in record.food_checks] == [False, False, True]


def test_a_transport_that_cannot_be_made_spill_free_fails_the_attempt_with_the_reason() -> None:
    clock, tool = Clock(), FakeTool(Clock())
    tool.clock = clock
    arm = CheckingArm(clock, _pc_arm(_water(8.0), rigid=True), [FAST, FAST])
    status, record = _run(arm, tool, clock, system="baseline")
    assert status == Status.FAILURE and arm.executed == []
    assert any("predicted to spill" in why for _, why in record.failures)


class WristTool(FakeTool):
    """The fake tool with the spec's wrist joints, following trajectories."""

    def __init__(self, clock: Clock) -> None:
        super().__init__(clock)
        self.followed: list[JointTrajectory] = []

    def state(self):
        return dataclasses.replace(super().state(), joint_names=tuple(SPEC.wrist.joint_names))

    def follow_trajectory(self, traj, start_delay=0.0):
        self.followed.append(traj)
        self.mode = Mode.TRAJECTORY
        self.modes.append(self.mode)
        return True, "following"


def test_the_slosh_free_wrist_goes_to_the_tool_and_leveling_resumes() -> None:
    clock = Clock()
    tool = WristTool(clock)
    followed = tool.followed
    arm = CheckingArm(clock, _pc_arm(_water(8.0), leveling="apparent"), [FAST])
    status, record = _run(arm, tool, clock)
    assert status == Status.SUCCESS
    assert len(followed) == 1 and followed[0].joint_names == tuple(SPEC.wrist.joint_names)
    assert record.food_checks[0]["wrist"] == "slosh_free"
    # LEVELING for the transport, the wrist's trajectory, then LEVELING again, then DISABLED
    assert tool.modes[-4:] == [Mode.LEVELING, Mode.TRAJECTORY, Mode.LEVELING, Mode.DISABLED]


@pytest.mark.parametrize("leveling", ["gravity", "apparent"])
def test_checked_transports_of_both_wrists_are_predicted_spill_free(leveling: str) -> None:
    arm = _pc_arm(_water(12.0), leveling=leveling)
    r = arm.check_food(FAST)
    assert r.ok
    assert _predicted(arm, r.value.trajectory) < 0.001
    assert isinstance(r.value, FoodDecision)
