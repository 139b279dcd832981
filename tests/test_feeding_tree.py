"""The feeding tree against a fake arm and tool on an injected clock (deterministic)."""

from __future__ import annotations

import threading
from types import SimpleNamespace

import py_trees
import pytest
from py_trees.common import Status

from articutool.api_types import JobResult
from articutool.feeding.behaviours import Board, RunPrimitive, ToolModeScope
from articutool.feeding.system import Planner, System
from articutool.feeding.tree import (
    BiteRecorder,
    attempts_used,
    board_of,
    safe_stop_reason,
    tick_until_done,
    transport_tree,
)
from articutool.tool.api import Mode, PrimitiveStatus, ToolState

ARTICUTOOL, BASELINE = System.of("articutool"), System.of("baseline", tolerance_deg=20.0)


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class FakeJob:
    def __init__(self, clock: Clock, duration: float, result: JobResult) -> None:
        self.clock, self.end, self._result = clock, clock.t + duration, result
        self.cancelled = False

    def done(self) -> bool:
        return self.cancelled or self.clock.t >= self.end

    def result(self) -> JobResult:
        return JobResult(False, "cancelled") if self.cancelled else self._result

    def cancel(self) -> None:
        self.cancelled = True


class FakeArm:
    """Plans take ``plan_s``; ``plans`` and ``verdicts`` say how each attempt ends."""

    def __init__(self, clock: Clock, plans: list[bool], verdicts: list[bool],
                 plan_s: float = 0.2, motion_s: float = 1.0) -> None:
        self.clock, self.plans, self.verdicts = clock, list(plans), list(verdicts)
        self.plan_s, self.motion_s = plan_s, motion_s
        self.plan_wall_s = 0.05  # what each plan reports as the planner's own time
        self.started_plans, self.executed, self.stopped = 0, [], 0
        self.jobs: list[FakeJob] = []
        self.fail_paths: set[str] = set()

    def start_plan(self, goal: str, planner: Planner, budget_s: float) -> FakeJob:
        self.started_plans += 1
        ok = self.plans.pop(0) if self.plans else True
        job = FakeJob(self.clock, self.plan_s,
                      JobResult(ok, "" if ok else "no path in budget", f"traj{self.started_plans}",
                                wall_s=self.plan_wall_s))
        self.jobs.append(job)
        return job

    def start_plan_path(self, name: str, waypoints) -> FakeJob:
        fail = name in self.fail_paths
        job = FakeJob(self.clock, self.plan_s, JobResult(not fail, "no IK" if fail else "",
                                                         f"path {name}"))
        self.jobs.append(job)
        return job

    def start_plan_lift(self, height_m: float) -> FakeJob:
        return self.start_plan_path("lift", None)

    def verify(self, trajectory: str) -> JobResult:
        ok = self.verdicts.pop(0) if self.verdicts else True
        return JobResult(ok, "feasible" if ok else "wrist speed 4.3 rad/s > 4 at waypoint 12")

    def check_food(self, trajectory: str) -> JobResult:
        # nothing on the fork: the transport runs as planned
        return JobResult(True, "no load to check",
                         SimpleNamespace(trajectory=trajectory, record=None))

    def start_execute(self, trajectory: str) -> FakeJob:
        self.executed.append(trajectory)
        job = FakeJob(self.clock, self.motion_s, JobResult(True, "arrived"))
        self.jobs.append(job)
        return job

    def stop(self) -> None:
        self.stopped += 1
        for j in self.jobs:
            j.cancel()


class FakeTool:
    def __init__(self, clock: Clock) -> None:
        self.clock, self.mode, self.fault, self.modes = clock, Mode.DISABLED, "", []
        self.primitive: tuple[str, float] | None = None
        self.cancelled = 0
        self.stale = False
        self.primitives: list[str] = []

    def set_mode(self, mode, pitch_offset_deg=0.0, roll_offset_deg=0.0):
        self.mode = Mode(mode)
        self.modes.append(self.mode)
        return True, f"mode {self.mode.name}"

    def state(self) -> ToolState:
        stamp = self.clock.t - (10.0 if self.stale else 0.0)
        return ToolState(stamp=stamp, mode=self.mode, joint_names=("p", "r"),
                         position=(0.0, 0.0), velocity=(0.0, 0.0),
                         orientation_wxyz=(1.0, 0.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0),
                         linear_acceleration=(0.0, 0.0, 9.81), fault=self.fault)

    def start_primitive(self, name, parameters):
        if self.mode == Mode.LEVELING:  # as the runtime: no primitive while leveling
            return False, "refused: the tool is LEVELING"
        self.primitive = (name, self.clock.t + 1.0)
        self.primitives.append(name)
        return True, "started"

    def primitive_status(self):
        if self.primitive is None:
            return None
        done = self.clock.t >= self.primitive[1]
        return PrimitiveStatus(name=self.primitive[0], percent_complete=100.0 if done else 50.0,
                               feedback="", current_joint_values=(0.0, 0.0), done=done,
                               success=done, message="done" if done else "",
                               final_joint_values=())

    def cancel_primitive(self):
        self.cancelled += 1
        self.primitive = None
        return True


class FakeUser:
    """Takes 2 g each bite, noting the tool's mode then."""

    def __init__(self, tool: FakeTool | None = None) -> None:
        self.tool, self.bites = tool, []

    def take_bite(self) -> float:
        self.bites.append(self.tool.mode if self.tool is not None else None)
        return 2.0


def _run(root, clock: Clock, max_ticks: int = 500, every=None):
    tree = py_trees.trees.BehaviourTree(root)
    rec = BiteRecorder(clock)
    tree.visitors.append(rec)
    tree.setup()
    for k in range(max_ticks):
        if every is not None:
            every(k, tree)
        tree.tick()
        clock.t += 0.1
        if tree.root.status in (Status.SUCCESS, Status.FAILURE):
            break
    return tree, rec


def _staging_attempts(root: py_trees.behaviour.Behaviour) -> int:
    return attempts_used(root)["planning_attempts_Staging"]


def test_success_path_plans_verifies_executes_and_restores_the_tool() -> None:
    clock = Clock()
    arm, tool = FakeArm(clock, [True], [True]), FakeTool(clock)
    tree, rec = _run(transport_tree(arm, tool, "Staging", ARTICUTOOL, attempts=3,
                                    budget_s=1.0, clock=clock), clock)
    assert tree.root.status == Status.SUCCESS
    assert arm.executed == ["traj1"] and _staging_attempts(tree.root) == 1
    assert tool.modes == [Mode.LEVELING, Mode.DISABLED]  # scoped, then restored
    assert rec.record.planning_wall_s == pytest.approx(0.05)  # the planner's own time
    assert rec.record.planning_wait_sim_s == pytest.approx(0.2, abs=0.11)  # the tree's clock
    assert rec.record.motion_time_s == pytest.approx(1.0, abs=0.11)


def test_planner_failure_then_success_counts_attempts() -> None:
    clock = Clock()
    arm, tool = FakeArm(clock, [False, True], [True]), FakeTool(clock)
    tree, rec = _run(transport_tree(arm, tool, "Staging", BASELINE, attempts=3, budget_s=1.0,
                                    clock=clock), clock)
    assert tree.root.status == Status.SUCCESS
    assert _staging_attempts(tree.root) == 2 and arm.executed == ["traj2"]
    assert rec.record.failures[0][1] == "no plan to Staging: no path in budget"


def test_verifier_rejection_replans_and_exhausted_attempts_fail_in_words() -> None:
    clock = Clock()
    arm, tool = FakeArm(clock, [], [False, True]), FakeTool(clock)
    tree, _ = _run(transport_tree(arm, tool, "Staging", ARTICUTOOL, attempts=3, budget_s=1.0,
                                  clock=clock), clock)
    assert tree.root.status == Status.SUCCESS and arm.started_plans == 2
    clock = Clock()
    arm, tool = FakeArm(clock, [], [False] * 5), FakeTool(clock)
    tree, rec = _run(transport_tree(arm, tool, "Staging", ARTICUTOOL, attempts=3, budget_s=1.0,
                                    clock=clock), clock)
    assert tree.root.status == Status.FAILURE and arm.started_plans == 3
    assert arm.executed == []
    assert rec.record.failed_stage == "Verify: wrist speed 4.3 rad/s > 4 at waypoint 12"
    assert tool.modes[-1] == Mode.DISABLED


def test_a_plan_slow_on_the_trees_clock_is_awaited_not_timed_out() -> None:
    """The budget is the planner's own: a plan that takes 10 s of the tree's clock (a slow
    machine while the world steps) with a 1 s budget is neither cancelled nor retried."""
    clock = Clock()
    arm, tool = FakeArm(clock, [], [], plan_s=10.0), FakeTool(clock)
    tree, rec = _run(transport_tree(arm, tool, "Staging", ARTICUTOOL, attempts=2, budget_s=1.0,
                                    clock=clock), clock)
    assert tree.root.status == Status.SUCCESS
    assert arm.started_plans == 1 and not any(j.cancelled for j in arm.jobs)
    assert arm.executed == ["traj1"] and _staging_attempts(tree.root) == 1
    assert rec.record.planning_wall_s == pytest.approx(0.05)
    assert rec.record.planning_wait_sim_s == pytest.approx(10.0, abs=0.11)


def test_tool_fault_mid_transport_stops_safely() -> None:
    clock = Clock()
    arm, tool = FakeArm(clock, [True], [True], motion_s=5.0), FakeTool(clock)

    def fault(k, tree):
        if k == 10:
            tool.fault = "motor hardware error: roll: OVERLOAD"

    tree, _ = _run(transport_tree(arm, tool, "Staging", ARTICUTOOL, attempts=3, budget_s=1.0,
                                  clock=clock), clock, every=fault)
    assert tree.root.status == Status.SUCCESS  # the guard's branch: stopped safely
    assert arm.stopped >= 1 and arm.jobs[-1].cancelled
    assert tool.mode == Mode.DISABLED


def test_the_guard_is_py_trees_eternal_guard_failing_while_safe_and_naming_the_stop() -> None:
    # The root guard is py_trees' EternalGuard ("Unsafe?" around "Safe stop"):
    # checked before the task every tick, FAILURE while safe, SUCCESS with the reason after.
    clock = Clock()
    arm, tool = FakeArm(clock, [True], [True], motion_s=5.0), FakeTool(clock)
    root = transport_tree(arm, tool, "Staging", ARTICUTOOL, attempts=3, budget_s=1.0,
                          clock=clock)
    guard = root.children[0]
    assert isinstance(guard, py_trees.decorators.EternalGuard)
    assert (guard.name, guard.decorated.name) == ("Unsafe?", "Safe stop")
    seen: list[tuple[Status, Status]] = []

    def fault(k, tree):
        if k:
            seen.append((guard.status, root.children[1].status))
        if k == 10:
            tool.fault = "motor hardware error: roll: OVERLOAD"

    tree, rec = _run(root, clock, every=fault)
    assert seen and all(g == Status.FAILURE and t == Status.RUNNING for g, t in seen)
    assert guard.status == Status.SUCCESS and "OVERLOAD" in guard.feedback_message
    assert safe_stop_reason(tree.root) == guard.feedback_message
    assert root.children[1].status == Status.INVALID  # the task was preempted
    assert not any(name == "Unsafe?" for name, _ in rec.record.failures)


@pytest.mark.parametrize("k", range(0, 16))
def test_preemption_at_any_tick_restores_the_tool_and_cancels_work(k: int) -> None:
    clock = Clock()
    arm, tool = FakeArm(clock, [True], [True]), FakeTool(clock)

    def stop(i, tree):
        if i == k:
            tool.stale = True  # the tool went silent: the guard preempts the task

    _run(transport_tree(arm, tool, "Staging", ARTICUTOOL, attempts=3, budget_s=1.0,
                        clock=clock), clock, every=stop)
    assert tool.mode == Mode.DISABLED
    assert all(j.done() for j in arm.jobs)  # nothing left running


def test_primitive_is_cancelled_when_preempted_and_none_succeeds_at_once() -> None:
    clock = Clock()
    tool = FakeTool(clock)
    board = Board()
    prim = RunPrimitive(tool, "TWIRL_CW", [1.0, 3.0], "post_move_into", board=board)
    scope = ToolModeScope(prim, tool, Mode.DISABLED, Mode.LEVELING, board=board)
    tree = py_trees.trees.BehaviourTree(scope)
    tree.tick()
    assert prim.status == Status.RUNNING
    tree.root.stop(Status.INVALID)  # preempted by a higher-priority branch
    assert tool.cancelled == 1 and tool.mode == Mode.LEVELING
    none = py_trees.trees.BehaviourTree(RunPrimitive(tool, "NONE", [], "pre_move_into",
                                                     board=board))
    none.tick()
    assert none.root.status == Status.SUCCESS


# ---- the whole bite (articutool.feeding.bite) -------------------------------------------

def _bite(arm, tool, clock, system: str = "articutool", stages=None, user=None):
    from articutool.feeding.bite import BITE_STAGES, bite_tree
    from articutool.feeding.insertion import acquisition_waypoints
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.spec import load_spec

    lib = StrategyLibrary.load(load_spec())
    strat = lib.strategies["noodles_twirl" if system == "articutool" else "noodles_baseline"]
    wps = acquisition_waypoints(strat, [0.45, -0.45, 0.004], [0.0, -1.0, 0.0])
    return bite_tree(arm, tool, strat, wps, clock, system=System.from_strategy(strat),
                     user=user or FakeUser(), stages=stages or BITE_STAGES)


def test_a_whole_bite_runs_its_stages_in_order_and_restores_the_tool() -> None:
    from articutool.feeding.behaviours import BiteStage, Retreat
    from articutool.feeding.bite import BITE_STAGES

    clock = Clock()
    arm, tool = FakeArm(clock, [], []), FakeTool(clock)
    user = FakeUser(tool)
    root = _bite(arm, tool, clock, user=user)
    assert [n.stage for n in root.iterate() if isinstance(n, BiteStage)] == list(BITE_STAGES)
    assert sum(isinstance(n, Retreat) for n in root.iterate()) == 1
    tree, rec = _run(root, clock, max_ticks=2000)
    assert tree.root.status == Status.SUCCESS, rec.record.failed_stage
    assert arm.executed == ["traj1", "path to above the food", "path into the food",
                            "path out of the food", "path lift", "traj2", "traj3", "traj4"]
    # Thesis §4.4: TWIRL_CW before insertion, TWIRL_CCW inside, NOODLE_SHED after leveling.
    assert tool.primitives == ["TWIRL_CW", "TWIRL_CCW", "NOODLE_SHED"]
    assert Mode.LEVELING in tool.modes and tool.mode == Mode.DISABLED
    # The user takes the bite once, at the end of ``present``: still presented (LEVELING),
    # whatever visitors watch the tree.
    assert user.bites == [Mode.LEVELING]


def test_the_user_takes_no_bite_from_a_bite_that_failed_before_it_was_presented() -> None:
    clock = Clock()
    arm, tool = FakeArm(clock, [False] * 10, []), FakeTool(clock)
    user = FakeUser(tool)
    tree, _ = _run(_bite(arm, tool, clock, stages=("staging", "present"), user=user), clock)
    assert tree.root.status == Status.FAILURE and user.bites == []


def test_the_baseline_never_levels_with_the_wrist_nor_runs_primitives() -> None:
    clock = Clock()
    arm, tool = FakeArm(clock, [], []), FakeTool(clock)
    user = FakeUser(tool)
    tree, rec = _run(_bite(arm, tool, clock, "baseline", user=user), clock, max_ticks=2000)
    assert tree.root.status == Status.SUCCESS, rec.record.failed_stage
    assert tool.primitives == [] and Mode.LEVELING not in tool.modes
    assert user.bites == [Mode.DISABLED]  # presented with the wrist locked


def test_the_system_is_decided_once_from_its_name_or_strategy() -> None:
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.feeding.system import DECOUPLED, LOOSE
    from articutool.spec import load_spec

    assert (ARTICUTOOL.wrist, ARTICUTOOL.carry) == (True, Mode.LEVELING)
    assert ARTICUTOOL.transport == ARTICUTOOL.home == DECOUPLED and DECOUPLED.verified
    assert not LOOSE.verified and LOOSE.name == DECOUPLED.name
    assert (BASELINE.wrist, BASELINE.carry) == (False, Mode.DISABLED)
    assert BASELINE.transport == BASELINE.home
    assert (BASELINE.transport.name, BASELINE.transport.verified,
            BASELINE.transport.tolerance_deg) == ("strict6", False, 20.0)
    # The decoupled planner keeps no tolerance (its band is the spec's).
    assert System.of("articutool", tolerance_deg=20.0) == ARTICUTOOL
    for s in StrategyLibrary.load(load_spec()).strategies.values():
        assert System.from_strategy(s) == (ARTICUTOOL if s.system == "articutool"
                                           else BASELINE), s
    with pytest.raises(ValueError, match="system: unknown system 'rigid'"):
        System.of("rigid")
    with pytest.raises(ValueError, match="planner: a baseline cannot use the decoupled"):
        System.of("baseline", "decoupled")


def test_a_failed_insertion_retreats_to_resting_and_names_the_stage() -> None:
    clock = Clock()
    arm, tool = FakeArm(clock, [], []), FakeTool(clock)
    arm.fail_paths.add("into the food")
    tree, rec = _run(_bite(arm, tool, clock), clock, max_ticks=2000)
    assert tree.root.status == Status.FAILURE
    assert rec.record.failures[0] == ("Plan into the food", "no path into the food: no IK")
    assert rec.record.failed_stage == "Plan into the food: no path into the food: no IK"
    # The retreat: up out of the container, then to Resting.
    assert arm.executed[-2:] == ["path lift", "traj2"]
    assert tool.mode == Mode.DISABLED


def test_a_subset_of_stages_runs_alone() -> None:
    clock = Clock()
    arm, tool = FakeArm(clock, [], []), FakeTool(clock)
    tree, _ = _run(_bite(arm, tool, clock, stages=("shed", "staging")), clock)
    assert tree.root.status == Status.SUCCESS
    assert tool.primitives == ["NOODLE_SHED"] and arm.executed == ["traj1"]


def test_stages_out_of_order_or_unknown_are_refused() -> None:
    clock = Clock()
    with pytest.raises(ValueError, match="order"):
        _bite(FakeArm(clock, [], []), FakeTool(clock), clock, stages=("staging", "acquire"))
    with pytest.raises(ValueError, match="unknown"):
        _bite(FakeArm(clock, [], []), FakeTool(clock), clock, stages=("eat",))


def test_preempting_the_whole_bite_at_any_tick_restores_the_tool_and_stops_everything() -> None:
    clock = Clock()
    arm, tool = FakeArm(clock, [], []), FakeTool(clock)
    _, _ = _run(_bite(arm, tool, clock), clock, max_ticks=2000)
    n_ticks = round(clock.t / 0.1)
    for k in range(0, n_ticks, 3):
        clock = Clock()
        arm, tool = FakeArm(clock, [], []), FakeTool(clock)
        root = _bite(arm, tool, clock)
        tree, _ = _run(root, clock, max_ticks=k + 1)
        tree.root.stop(Status.INVALID)
        assert tool.mode == Mode.DISABLED, k
        running = tool.primitive is not None and clock.t < tool.primitive[1]
        assert not running, k  # no primitive left running (cancel_primitive clears it)
        assert all(j.done() for j in arm.jobs), k  # no plan or motion left running


def test_a_failed_acquisition_is_retried_up_to_the_strategy_s_limit() -> None:
    from articutool.feeding.bite import bite_tree
    from articutool.feeding.insertion import acquisition_waypoints, dish_outline
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.spec import load_spec

    s = StrategyLibrary.load(load_spec()).strategies["pecans_tilted_scoop"]
    outline = dish_outline(load_spec(), s.utensil)
    s = s.model_copy(update={"attempts": s.attempts.model_copy(update={"acquire": 3})})
    clock = Clock()
    arm, tool = FakeArm(clock, [], []), FakeTool(clock)
    arm.fail_paths.add("out of the food")
    wps = acquisition_waypoints(s, [0.45, -0.45, 0.0], [0, -1, 0], outline)
    root = bite_tree(arm, tool, s, wps, clock, system=ARTICUTOOL, user=FakeUser(),
                     stages=("acquire", "resting"))
    tree, _ = _run(root, clock, max_ticks=2000)
    assert tree.root.status == Status.FAILURE
    assert arm.executed.count("path into the food") == 3  # three tries, then the retreat
    assert attempts_used(root)["acquisition_attempts"] == 3


def test_the_trees_timeout_does_not_count_the_wait_for_a_plan() -> None:
    """A plan that takes 50 s of the tree's clock (a slow machine) inside a 20 s tree
    timeout: the transport still completes, because the timeout counts the rest of the time
    (the plan itself ends within the planner's own budget)."""
    from articutool.feeding.tree import run_tree

    clock = Clock()
    arm, tool = FakeArm(clock, [], [], plan_s=50.0, motion_s=5.0), FakeTool(clock)

    def step(dt: float) -> None:
        clock.t += dt

    run = run_tree(transport_tree(arm, tool, "Staging", ARTICUTOOL, attempts=2,
                                  budget_s=1.0, clock=clock), step, clock, timeout_s=20.0)
    assert run.status == Status.SUCCESS and arm.executed == ["traj1"], run.record.failures
    assert run.end == "completed"
    assert run.record.planning_wait_sim_s == pytest.approx(50.0, abs=0.11)
    # Work that is not planning still times out: a motion longer than the timeout.
    clock = Clock()
    arm, tool = FakeArm(clock, [], [], plan_s=0.2, motion_s=30.0), FakeTool(clock)
    run = run_tree(transport_tree(arm, tool, "Staging", ARTICUTOOL, attempts=2,
                                  budget_s=1.0, clock=clock), step, clock, timeout_s=20.0)
    assert run.status == Status.FAILURE and run.end == "timed_out"
    assert "did not finish within 20 s" in run.record.failed_stage
    assert all(j.done() for j in arm.jobs)


def test_run_tree_reports_a_safe_stop_as_a_failure_naming_its_reason() -> None:
    # The guard's branch succeeds (the safe state was reached), but the task did not: the
    # experiments' transports must not count it as completed.
    from articutool.feeding.tree import run_tree

    clock = Clock()
    arm, tool = FakeArm(clock, [True], [True], motion_s=5.0), FakeTool(clock)

    def step(dt: float) -> None:
        clock.t += dt
        if clock.t >= 1.0:
            tool.fault = "motor hardware error: roll: OVERLOAD"

    run = run_tree(transport_tree(arm, tool, "Staging", ARTICUTOOL, attempts=3,
                                  budget_s=1.0, clock=clock), step, clock)
    assert run.status == Status.FAILURE and run.end == "stopped"
    assert run.record.failed_stage == ("Safe stop: tool fault: motor hardware error: roll: "
                                       "OVERLOAD")
    assert tool.mode == Mode.DISABLED and arm.stopped >= 1


def test_a_retreat_step_failing_in_its_first_tick_is_not_taken_for_the_cause() -> None:
    # A lift whose IK fails at once: the bite's cause is the exhausted planning attempts,
    # not the failed IK.
    clock = Clock()
    arm, tool = FakeArm(clock, [False] * 10, [], plan_s=0.0), FakeTool(clock)
    arm.fail_paths.add("lift")
    tree, rec = _run(_bite(arm, tool, clock, stages=("staging",)), clock)
    assert tree.root.status == Status.FAILURE
    assert rec.record.failed_stage == "Plan to Staging: no plan to Staging: no path in budget"
    assert ("Plan lift 10 cm", "no path lift 10 cm: no IK") in rec.record.failures


@pytest.mark.parametrize("ticks", [1, 2, 7])
@pytest.mark.parametrize("end", [Status.SUCCESS, Status.FAILURE])
def test_the_tick_driver_steps_the_world_only_between_ticks_of_a_running_tree(
        ticks: int, end: Status) -> None:
    # TickCounter runs for ``ticks`` ticks then ends: the world moves between ticks only
    t = [0.0]
    steps: list[float] = []

    def step(dt: float) -> None:
        steps.append(dt)
        t[0] += dt

    clock = lambda: t[0]  # noqa: E731
    tree = py_trees.trees.BehaviourTree(py_trees.behaviours.TickCounter("c", ticks, end))
    rec = BiteRecorder(clock)
    tree.visitors.append(rec)
    assert tick_until_done(tree, rec, step, clock, period_s=0.1, timeout_s=60.0) == end
    assert steps == [0.1] * ticks


def test_the_tick_driver_stops_a_tree_that_outlives_its_timeout() -> None:
    t = [0.0]
    clock = lambda: t[0]  # noqa: E731

    def step(dt: float) -> None:
        t[0] += dt

    root = py_trees.behaviours.Running("forever")
    tree = py_trees.trees.BehaviourTree(root)
    rec = BiteRecorder(clock)
    assert tick_until_done(tree, rec, step, clock, period_s=0.5, timeout_s=3.0) is None
    assert t[0] == pytest.approx(3.0) and root.status == Status.INVALID


def test_the_food_check_before_a_transport_is_a_bite_setting_the_thesis_systems_turn_off(
        ) -> None:
    from articutool.experiments.config import ExperimentsConfig
    from articutool.experiments.protocols import thesis_bite
    from articutool.feeding.behaviours import CheckFood
    from articutool.feeding.bite import BITE_STAGES, BiteSettings, bite_tree
    from articutool.feeding.insertion import acquisition_waypoints
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.spec import load_spec

    clock = Clock()
    arm, tool = FakeArm(clock, [], []), FakeTool(clock)
    strat = StrategyLibrary.load(load_spec()).strategies["noodles_twirl"]
    wps = acquisition_waypoints(strat, [0.45, -0.45, 0.004], [0.0, -1.0, 0.0])

    def checks(settings: BiteSettings) -> int:
        root = bite_tree(arm, tool, strat, wps, clock, system=ARTICUTOOL, user=FakeUser(),
                         stages=BITE_STAGES, settings=settings)
        return sum(isinstance(b, CheckFood) for b in root.iterate())

    assert checks(BiteSettings()) == 2  # to Resting and to Staging
    thesis = thesis_bite(ExperimentsConfig.load())
    assert not thesis.food_check and checks(thesis) == 0


def _lockstep_transport(plans: list[bool], stop_at: int | None,
                        barrier: threading.Barrier | None, ticks: int = 60) -> tuple:
    """A transport to Staging whose plans end as ``plans``, its stop requested at tick
    ``stop_at``; with ``barrier``, each tick waits for the other thread's tree to tick too.
    Returns what it ended as: status, attempts, executed plans, safe-stop reason."""
    clock = Clock()
    arm, tool = FakeArm(clock, plans, []), FakeTool(clock)
    root = transport_tree(arm, tool, "Staging", BASELINE, attempts=3, budget_s=1.0,
                          clock=clock)
    tree = py_trees.trees.BehaviourTree(root)
    tree.setup()
    for k in range(ticks):
        if barrier is not None:
            barrier.wait()  # the other thread's tree ticks between two ticks of this one
        if root.status in (Status.SUCCESS, Status.FAILURE):
            continue
        if k == stop_at:
            board_of(root).stop_requested = True
        tree.tick()
        clock.t += 0.1
    return root.status, attempts_used(root), arm.executed, safe_stop_reason(root)


def test_two_trees_ticked_in_two_threads_share_no_state() -> None:
    """Two trials in two threads of one process (a Dask worker's threads): their trees,
    ticked alternately, keep their own attempt counts, plans and stop requests, and end as
    the same trees run one after the other."""
    cases = {"a": ([False, False, True], None), "b": ([True], 4)}
    alone = {k: _lockstep_transport(plans, stop, None) for k, (plans, stop) in cases.items()}
    assert alone["a"] == (Status.SUCCESS, {"planning_attempts_Staging": 3}, ["traj3"], None)
    assert alone["b"][1:] == ({"planning_attempts_Staging": 1}, ["traj1"], "stop requested")
    barrier = threading.Barrier(2, timeout=30.0)
    threaded: dict[str, tuple] = {}

    def run(k: str) -> None:
        plans, stop = cases[k]
        threaded[k] = _lockstep_transport(plans, stop, barrier)

    threads = [threading.Thread(target=run, args=(k,)) for k in cases]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60.0)
    assert threaded == alone
