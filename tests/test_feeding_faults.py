"""Faults during a meal (issue 22): the feeding tree in the physics world with the real tool
runtime, a fault injected at a chosen moment of a bite. For each: the tool ends in its safe
state, the tree ends in a named state the bite record reports, and nothing is counted as
delivered that was not.

The bite is the loaded part of one (a placed pecan load, then ``staging``, ``present`` and
``return``): the stages a fault can hurt most, at a fraction of a whole bite's cost.

Covered: the user's stop request, a motor overload, an IMU that freezes, planning failures
past the attempts (fast); a planning failure that is retried, and a stop request or an
overload during the shedding primitive after a real acquisition (slow).
Not covered yet: link loss and return, a stop from a second paired PC, an F/T spike (the
tree talks to the in-process runtime here, not over the link, and nothing in the tree reads
the F/T sensor).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import py_trees
import pytest
from py_trees.common import Status

pytest.importorskip("mujoco")

from articutool.feeding.behaviours import JobResult
from articutool.feeding.meal import BiteResult, MealSetup, make_bite_world, run_bite
from articutool.tool.api import Mode

STAGES = ("staging", "present", "return")
THRESHOLD_G = 0.5  # below one pecan piece: a delivered load would be a meaningful success


class FaultAt(py_trees.visitors.VisitorBase):
    """Calls ``inject()`` once, ``after_s`` of simulated time into the first run of the
    behaviour named ``name`` (a chosen moment of the bite)."""

    def __init__(self, name: str, after_s: float, clock: Callable[[], float],
                 inject: Callable[[], None]) -> None:
        super().__init__(full=False)
        self.name, self.after_s, self.clock, self.inject = name, after_s, clock, inject
        self.started: float | None = None
        self.fired_at: float | None = None

    def run(self, behaviour: py_trees.behaviour.Behaviour) -> None:
        if behaviour.name != self.name or behaviour.status != Status.RUNNING:
            return
        if self.started is None:
            self.started = self.clock()
        if self.fired_at is None and self.clock() - self.started >= self.after_s:
            self.fired_at = self.clock()
            self.inject()


def _loaded(seed: int = 0) -> tuple[MealSetup, float]:
    py_trees.blackboard.Blackboard.clear()
    setup = make_bite_world("pecans", "articutool", seed, load_g=4.0)
    held = setup.world.place_load(1.0)
    assert held > 0.5
    return setup, held


def _bite(setup: MealSetup, *faults: FaultAt) -> BiteResult:
    try:
        return run_bite(setup, stages=STAGES, threshold_g=THRESHOLD_G, visitors=faults)
    finally:
        setup.arm.close()


def _assert_stopped_safely(setup: MealSetup, r: BiteResult, reason: str) -> None:
    """The guard's safe stop: reported as stopped (not completed, the reason named), the
    tool DISABLED, the arm holding still, the load never counted as delivered."""
    w = setup.world
    assert r.end_state == "stopped" and not r.completed, r
    assert r.failed_stage.startswith("Safe stop: ") and reason in r.failed_stage, r.failed_stage
    assert r.outcome in ("failed", "table_spill", "user_spill")
    assert r.delivered_g == 0.0
    assert w.tool.mode == Mode.DISABLED
    q = w.arm_q.copy()
    w.run(1.0)
    assert np.allclose(w.arm_q, q, atol=2e-3)  # no motion after the stop
    assert w.tool.mode == Mode.DISABLED


def test_the_user_stopping_during_transport_stops_safely_and_delivers_nothing() -> None:
    setup, held = _loaded()

    def request_stop() -> None:
        py_trees.blackboard.Blackboard.set("/bite/stop_requested", True)

    fault = FaultAt("Execute to Staging", 1.0, setup.world.clock, request_stop)
    r = _bite(setup, fault)
    assert fault.fired_at is not None
    _assert_stopped_safely(setup, r, "stop requested")
    assert setup.world.tool.fault == ""  # a stop request is no fault
    assert r.outcome == "failed" and r.spilled_g == 0.0
    assert setup.world.masses_g()["utensil"] == pytest.approx(held)  # still held, level


def test_a_motor_overload_during_transport_faults_the_tool_and_stops_safely() -> None:
    setup, _ = _loaded()
    w = setup.world
    fault = FaultAt("Execute to Staging", 1.0, w.clock,
                    lambda: w.motors.inject_hardware_error(1))
    r = _bite(setup, fault)
    _assert_stopped_safely(setup, r, "tool fault: ")
    assert "OVERLOAD" in r.failed_stage
    assert "OVERLOAD" in w.tool.fault  # sticky until cleared


def test_an_imu_that_freezes_while_leveling_faults_the_tool_and_stops_safely() -> None:
    setup, _ = _loaded()
    w = setup.world

    def freeze() -> None:
        w.imu._sample = lambda *args: None  # the sensor stops delivering samples

    fault = FaultAt("Execute to Staging", 1.0, w.clock, freeze)
    r = _bite(setup, fault)
    _assert_stopped_safely(setup, r, "tool fault: ")
    assert "IMU" in w.tool.fault


class _FailingPlans:
    """The planner fails its next ``n`` plans to ``goal`` (then plans as usual)."""

    def __init__(self, setup: MealSetup, goal: str, n: int) -> None:
        self.start_plan, self.goal, self.left = setup.arm.start_plan, goal, n
        setup.arm.start_plan = self  # type: ignore[method-assign]

    def __call__(self, goal: str, planner: str, budget_s: float):
        if goal == self.goal and self.left > 0:
            self.left -= 1
            return _Failed()
        return self.start_plan(goal, planner, budget_s)


class _Failed:
    def done(self) -> bool:
        return True

    def result(self) -> JobResult:
        return JobResult(False, "injected planner failure")

    def cancel(self) -> None:
        pass


@pytest.mark.slow
def test_a_planning_failure_is_retried_and_the_bite_completes() -> None:
    setup, _ = _loaded()
    _FailingPlans(setup, "Staging", 1)
    r = _bite(setup)
    assert r.end_state == "completed" and r.completed and r.failed_stage == ""
    assert r.planning_attempts_by_goal["Staging"] == 2
    assert r.delivered_g > THRESHOLD_G and r.outcome == "meaningful_success"
    assert setup.world.tool.mode == Mode.DISABLED and setup.world.tool.fault == ""


def test_planning_failures_past_the_attempts_retreat_and_deliver_nothing() -> None:
    setup, _ = _loaded()
    _FailingPlans(setup, "Staging", 99)
    r = _bite(setup)
    assert r.end_state == "retreated" and not r.completed
    assert r.failed_stage.startswith("Plan to Staging: no plan to Staging: injected")
    assert r.planning_attempts_by_goal["Staging"] == setup.strategy.attempts.plan
    assert r.delivered_g == 0.0 and r.outcome in ("failed", "table_spill", "user_spill")
    assert setup.world.tool.mode == Mode.DISABLED and setup.world.tool.fault == ""


@pytest.mark.slow
@pytest.mark.parametrize("fault", ["stop request", "overload"])
def test_a_fault_during_the_shedding_primitive_answers_its_goal_and_stops_safely(
        fault: str) -> None:
    # The whole acquisition first (a full bowl), then the fault 0.3 s into VIBRATE_ROLL.
    py_trees.blackboard.Blackboard.clear()
    setup = make_bite_world("pecans", "articutool", 0)
    w = setup.world

    def inject() -> None:
        if fault == "overload":
            w.motors.inject_hardware_error(1)
        else:
            py_trees.blackboard.Blackboard.set("/bite/stop_requested", True)

    at = FaultAt("post-acquisition: VIBRATE_ROLL", 0.3, w.clock, inject)
    try:
        r = run_bite(setup, stages=("above", "acquire", "shed", "resting"),
                     threshold_g=THRESHOLD_G, visitors=[at])
    finally:
        setup.arm.close()
    assert at.fired_at is not None
    _assert_stopped_safely(setup, r, "tool fault: " if fault == "overload" else fault)
    st = w.tool.primitive_status()
    assert st is not None and st.name == "VIBRATE_ROLL"
    assert st.done and not st.success  # the goal was answered: aborted, not left running
    assert r.acquired_g > 0  # it did hold food, and none of it counts as delivered
