"""A transport's outcome does not depend on how fast the machine is: the
attempt budget and the recorded planning time are the planner's own, and the physics world
waits for a plan (one tick period of simulated time), so a slower planner, or one that has
finished before the tree looks at it again, gives the same record, state for state."""

from __future__ import annotations

import time

import pytest
from py_trees.common import Status

pytest.importorskip("mujoco")

from articutool.feeding.system import System
from articutool.feeding.tree import attempts_used, run_tree, transport_tree
from articutool.planning import pc_arm
from articutool.planning.pc_arm import PCArm
from articutool.sim.arm_driver import sim_arm
from articutool.sim.world import FeedingWorld
from articutool.tool.api import Mode

BUDGET_S = 2.0
# A machine this much slower at planning (wall seconds added to every plan): an attempt timed
# on the simulated clock, or a world that steps on while a plan is computed, would change the
# bite's state by this lag.
LAG_WALL_S = 1.5


def _transport(monkeypatch: pytest.MonkeyPatch, slow: bool, ahead: bool = False) -> dict:
    w = FeedingWorld.make("pecans", seed=0, load_g=4.0)
    w.tool.set_mode(Mode.LEVELING)
    w.run(1.0)
    w.placement.place(1.0)
    before = w.ledger.masses_g()  # the loader may drop a piece beside the spoon (seed 0: 0.46 g)
    if slow:
        real = pc_arm.plan

        def slow_plan(*args, **kwargs):
            r = real(*args, **kwargs)
            time.sleep(LAG_WALL_S)  # the real plan, on a slower machine
            return r

        monkeypatch.setattr(pc_arm, "plan", slow_plan)
    if ahead:
        real_start = PCArm.start_plan

        def start_plan_done(self, *args, **kwargs):
            job = real_start(self, *args, **kwargs)
            job.fut.result()  # the worker thread ran while the tree's thread was not scheduled
            return job

        monkeypatch.setattr(PCArm, "start_plan", start_plan_done)
    arm = sim_arm(w)
    try:
        root = transport_tree(arm, w.tool, "Staging", System.of("articutool"), attempts=3,
                              budget_s=BUDGET_S, clock=lambda: w.time)
        run = run_tree(root, w.run, lambda: w.time, timeout_s=120.0)
        status, rec = run.status, run.record
    finally:
        arm.close()
        monkeypatch.undo()
    return {"status": status, "rec": rec, "masses": w.ledger.masses_g(), "before": before,
            "t": w.time, "qpos": w.data.qpos.copy(),
            "attempts": attempts_used(root).get("planning_attempts_Staging")}


@pytest.fixture(scope="module")
def polled() -> dict:
    """The transport with the plan polled as it comes (shared: the tests compare to it)."""
    with pytest.MonkeyPatch.context() as mp:
        return _transport(mp, False)


def test_a_slower_planner_gives_the_same_attempts_and_outcome(
        polled: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    fast, slow = polled, _transport(monkeypatch, True)
    assert fast["status"] == slow["status"] == Status.SUCCESS, slow["rec"].failed_stage
    assert fast["attempts"] == slow["attempts"] == 1
    assert slow["rec"].failures == []
    # The world waited for the plan: the same simulated time, the same state, the same record.
    assert slow["rec"].planning_wait_sim_s == fast["rec"].planning_wait_sim_s
    assert slow["t"] == fast["t"]
    assert (slow["qpos"] == fast["qpos"]).all()
    assert slow["masses"] == fast["masses"]
    assert slow["rec"].planning_wall_s >= LAG_WALL_S  # the recorded time is the planner's own


def test_a_plan_finished_before_the_tree_looks_again_costs_the_same_tick(
        polled: dict, monkeypatch: pytest.MonkeyPatch) -> None:
    """Whether the planner's thread ends before the tree's thread polls the plan in the tick
    that started it is up to the operating system (a busy machine, a Dask worker's threads):
    the world waits one tick period for the plan either way."""
    ahead = _transport(monkeypatch, False, ahead=True)
    assert polled["status"] == ahead["status"] == Status.SUCCESS, ahead["rec"].failed_stage
    assert ahead["rec"].planning_wait_sim_s == polled["rec"].planning_wait_sim_s > 0.0
    assert ahead["t"] == polled["t"]
    assert (ahead["qpos"] == polled["qpos"]).all()
    assert ahead["masses"] == polled["masses"]
