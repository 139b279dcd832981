"""Assembling and running the feeding tree: the transport subtree with plan → verify →
execute, bounded attempts, the tool's mode scoped, a safety guard at the root, a visitor that
records the bite's telemetry, and the one runner that ticks a tree (:func:`run_tree`).

Each attempt's budget is the planner's own (``budget_s`` of wall time inside ``plan()``, as
OMPL counts it), never the simulated clock. While a plan is computed in its worker
thread the world waits for it (:meth:`BiteRecorder.wait_for_plans`): a plan costs exactly one
tick period of simulated time, so a trial's outcome does not depend on the machine's speed
(a faster or a loaded machine gives the same record for the same seed).

Shape of :func:`transport_tree`::

    Selector "bite" (no memory: the guard is checked every tick)
      EternalGuard "Unsafe?"    -> Safe stop (py_trees' EternalGuard: checked every tick)
      ToolModeScope <carry mode> (then DISABLED)
        Sequence "transport"
          CountedRetry "up to N attempts" (planning_attempts_<goal>, counted on the node)
            Sequence "plan+verify"  Plan (the planner's own budget) -> Verify
                                    [-> Check the food: retime until predicted spill-free]
          Execute motion            (a slosh-free wrist trajectory goes to the tool; then
                                     LEVELING again)

The behaviours of a tree share that tree's :class:`~articutool.feeding.behaviours.Board`
(the plan passed from planning to execution, the tool's mode for the guard, a stop request),
created by the tree's builder; nothing is shared between trees, so trees run in threads of
one process side by side.

The carry mode is the system's (:class:`~articutool.feeding.system.System`): LEVELING for the
Articutool, DISABLED (wrist locked) for the rigid baseline.
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import py_trees
from py_trees.common import Status

from articutool.feeding.behaviours import (
    ArmInterface,
    Board,
    CheckFood,
    CountedRetry,
    Execute,
    Plan,
    PlanPath,
    Retreat,
    SafeStop,
    SafetyGuard,
    ToolModeScope,
    Verify,
)
from articutool.feeding.system import Planner, System
from articutool.tool.api import Mode, ToolAPI

__all__ = ["BiteRecorder", "ClockedTimeout", "TreeRun", "attempts_used", "board_of", "guarded",
           "motion", "motion_steps", "run_tree", "safe_stop_reason", "tick_until_done",
           "transport_tree"]


class ClockedTimeout(py_trees.decorators.Timeout):
    """py_trees' Timeout on an injected clock (the simulation's, or a test's)."""

    def __init__(self, child: py_trees.behaviour.Behaviour, duration: float,
                 clock: Callable[[], float]) -> None:
        super().__init__(name=f"timeout {duration:g} s", child=child, duration=duration)
        self.clock = clock

    def initialise(self) -> None:
        self.finish_time = self.clock() + self.duration
        self.feedback_message = ""

    def update(self) -> Status:
        if self.decorated.status == Status.RUNNING and self.clock() > self.finish_time:
            self.feedback_message = f"timed out after {self.duration:g} s"
            self.decorated.stop(Status.INVALID)
            return Status.FAILURE
        return self.decorated.status


def motion_steps(arm: ArmInterface, goal: str, planner: Planner, *, attempts: int,
                 budget_s: float, board: Board, food: bool = False,
                 tool: ToolAPI | None = None, clock: Callable[[], float] | None = None,
                 then: Mode | None = None) -> list[py_trees.behaviour.Behaviour]:
    """The steps of :func:`motion`, for a sequence of the caller's (a bite's stage)."""
    steps: list[py_trees.behaviour.Behaviour] = [Plan(arm, goal, planner, budget_s,
                                                      board=board)]
    if planner.verified:
        steps.append(Verify(arm, board=board))
    if food:
        steps.append(CheckFood(arm, board=board))
    plan_verify = py_trees.composites.Sequence("plan+verify", memory=True, children=steps)
    tries = CountedRetry(plan_verify, attempts, f"planning_attempts_{goal}")
    return [tries, Execute(arm, f"to {goal}", tool, clock, then, board=board)]


def motion(arm: ArmInterface, goal: str, planner: Planner, *, attempts: int, budget_s: float,
           board: Board, food: bool = False, tool: ToolAPI | None = None,
           clock: Callable[[], float] | None = None, then: Mode | None = None
           ) -> py_trees.behaviour.Behaviour:
    """Move the arm to a named goal: bounded attempts of (plan → verify → check the food),
    then execute. Each plan gets ``budget_s`` of the planner's own wall time (see the module
    doc). A ``planner`` that is ``verified`` adds plan-then-verify (Alg. 2, thesis §4.2); a
    strict plan's constraint is the planner's own. ``food`` adds the food-aware check
    (:class:`CheckFood`: retimed until predicted spill-free, or re-planned); with ``tool``
    and ``clock`` a trajectory carrying the wrist's joints (slosh-free leveling) sends them
    to the tool, whose mode is ``then`` afterwards. The steps share ``board`` (the tree's);
    attempts are counted on the :class:`~articutool.feeding.behaviours.CountedRetry` node, keyed
    ``planning_attempts_<goal>``."""
    return py_trees.composites.Sequence(
        f"move to {goal}", memory=True,
        children=motion_steps(arm, goal, planner, attempts=attempts, budget_s=budget_s,
                              board=board, food=food, tool=tool, clock=clock, then=then))


def guarded(child: py_trees.behaviour.Behaviour, arm: ArmInterface, tool: ToolAPI,
            clock: Callable[[], float], stale_s: float = 0.5, *,
            board: Board) -> py_trees.behaviour.Behaviour:
    """``child`` under the root safety guard: every tick, a tool fault, stale tool state or a
    stop request (on ``board``, the tree's) preempts it and stops the arm with the tool
    DISABLED."""
    guard = SafetyGuard(arm, tool, clock, stale_s, board=board)
    return py_trees.composites.Selector("bite", memory=False, children=[guard, child])


def board_of(root: py_trees.behaviour.Behaviour) -> Board:
    """The board of the tree under ``root`` (its safety guard's): where a caregiver or a UI
    requests a stop (``board_of(root).stop_requested = True``)."""
    for node in root.iterate():
        if isinstance(node, SafetyGuard):
            return node.board
    raise ValueError(f"{root.name!r} has no safety guard (build it with guarded())")


def attempts_used(root: py_trees.behaviour.Behaviour) -> dict[str, int]:
    """The attempts each :class:`~articutool.feeding.behaviours.CountedRetry` node of the tree
    under ``root`` used in its last run, by key (``planning_attempts_<goal>``,
    ``acquisition_attempts``); of two nodes with one key (a stage's move to Resting and the
    retreat's), the later in tree order that ran."""
    used: dict[str, int] = {}
    for node in root.iterate():
        if isinstance(node, CountedRetry) and node.count > 0:
            used[node.key] = node.count
    return used


def safe_stop_reason(root: py_trees.behaviour.Behaviour) -> str | None:
    """Why the guard of :func:`guarded` stopped the tree in its last tick (the reason its
    ``Unsafe?`` gave: a tool fault, stale state, a stop request), or None if it did not. The
    guard's branch *succeeds* — the tree reached its safe state — but the task did not: the
    callers report it as stopped, never as completed."""
    for node in root.iterate():
        if isinstance(node, SafeStop) and node.status == Status.SUCCESS:
            guard = node.parent
            return guard.feedback_message if isinstance(guard, SafetyGuard) else "safe stop"
    return None


def transport_tree(arm: ArmInterface, tool: ToolAPI, goal: str, system: System, *,
                   attempts: int, budget_s: float, clock: Callable[[], float],
                   stale_s: float = 0.5, food: bool = False) -> py_trees.behaviour.Behaviour:
    """The transport subtree of ``system`` (see the module doc): it runs alone as a tree.
    ``food`` checks the load before executing (:func:`motion`)."""
    board = Board()
    move = motion(arm, goal, system.transport, attempts=attempts, budget_s=budget_s,
                  board=board, food=food, tool=tool, clock=clock,
                  then=system.carry if system.wrist else None)
    return guarded(ToolModeScope(move, tool, system.carry, Mode.DISABLED, board=board), arm,
                   tool, clock, stale_s, board=board)


@dataclass
class BiteRecord:
    """Telemetry of one bite, collected by :class:`BiteRecorder`."""

    # The planners' own wall time (inside the planning jobs): what a real robot's user waits.
    planning_wall_s: float = 0.0
    # Simulated time that passed while plans were computed (one tick period per plan).
    planning_wait_sim_s: float = 0.0
    motion_time_s: float = 0.0  # on the tree's clock
    # Every leaf failure in order (behaviour, reason).
    failures: list[tuple[str, str]] = field(default_factory=list)
    # The failure that ended the bite: the one that made it retreat (a retreat's own
    # failures come after it), or the guard's safe stop.
    cause: tuple[str, str] | None = None
    # Every food check before a transport (what was done — retimed, slosh-free — and the
    # prediction), in order.
    food_checks: list[dict] = field(default_factory=list)

    @property
    def failed_stage(self) -> str:
        """What failed and why, in words: the failure that ended the bite, else the last
        leaf that failed (empty if none failed)."""
        f = self.cause or (self.failures[-1] if self.failures else None)
        return f"{f[0]}: {f[1]}" if f else ""


class BiteRecorder(py_trees.visitors.VisitorBase):
    """Visits every ticked behaviour: accumulates the planning jobs' own wall time (as they
    report it), and the time on ``clock`` from the tick a planning or motion job started to the
    tick it ended; keeps every leaf failure with its reason — telemetry outside the
    behaviours."""

    def __init__(self, clock: Callable[[], float] = _time.monotonic) -> None:
        super().__init__(full=False)
        self.clock = clock
        self.record = BiteRecord()
        self._started: dict[int, float] = {}
        self._planning: dict[int, tuple[float, py_trees.behaviour.Behaviour]] = {}

    def initialise(self) -> None:
        self._now = self.clock()

    def planning_wait_s(self, now: float) -> float:
        """Time on ``clock`` spent waiting for plans so far, the plans still running
        included: what a timeout on ``clock`` must not count, since on a slower machine the
        world steps further while the same plan is computed."""
        running = [(t0, b) for t0, b in self._planning.values() if b.status == Status.RUNNING]
        return self.record.planning_wait_sim_s + sum(now - t0 for t0, _ in running)

    def wait_for_plans(self) -> None:
        """Block (wall time) until every plan the last tick left running in a worker thread
        (a job with ``wait_off_clock``, as :class:`~articutool.planning.pc_arm.PCArm`'s) has
        its result.
        The arm holds still while it plans, and the world waits with it: how much simulated
        time passes during a plan must not depend on how fast this machine plans, or a trial
        could not be reproduced from its seed. Bounded by each plan's own wall budget."""
        for _, b in list(self._planning.values()):
            wait = getattr(getattr(b, "job", None), "wait_off_clock", None)
            if b.status == Status.RUNNING and wait is not None:
                wait()

    def run(self, behaviour: py_trees.behaviour.Behaviour) -> None:
        if isinstance(behaviour, CheckFood) and behaviour.status in (Status.SUCCESS,
                                                                    Status.FAILURE):
            while behaviour.records:
                self.record.food_checks.append(behaviour.records.pop(0))
        if isinstance(behaviour, Plan | PlanPath | Execute):
            key = id(behaviour)
            if behaviour.status == Status.RUNNING:
                self._started.setdefault(key, self._now)
                if not isinstance(behaviour, Execute):
                    self._planning.setdefault(key, (self._started[key], behaviour))
            elif behaviour.status in (Status.SUCCESS, Status.FAILURE):
                self._planning.pop(key, None)
                dt = self._now - self._started.pop(key, self._now)
                if isinstance(behaviour, Execute):
                    self.record.motion_time_s += dt
                else:
                    self.record.planning_wait_sim_s += dt
                    self.record.planning_wall_s += behaviour.job_wall_s
        # The cause is the last failure before anything of the retreat ran: a decorator is
        # visited after its children, so a retreat step that fails in the retreat's first
        # tick (an instant IK failure) must not be mistaken for it.
        if self.record.cause is None and self.record.failures and _in_retreat(behaviour):
            self.record.cause = self.record.failures[-1]
        if behaviour.status == Status.FAILURE and not behaviour.children:
            self.record.failures.append((behaviour.name, behaviour.feedback_message))


def _in_retreat(behaviour: py_trees.behaviour.Behaviour) -> bool:
    node: py_trees.behaviour.Behaviour | None = behaviour
    while node is not None:
        if isinstance(node, Retreat):
            return True
        node = node.parent
    return False


@dataclass(frozen=True)
class TreeRun:
    """How a run of a tree ended (:func:`run_tree`)."""

    status: Status  # SUCCESS only when the tree completed
    # "completed"; "failed" (the tree failed); "stopped" (the guard's safe stop: a tool
    # fault, stale tool state or a stop request); "timed_out" (the run's time limit)
    end: str
    record: BiteRecord


def run_tree(root: py_trees.behaviour.Behaviour, step: Callable[[float], None],
             clock: Callable[[], float], *, period_s: float = 0.1,
             timeout_s: float = 120.0,
             visitors: Sequence[py_trees.visitors.VisitorBase] = ()) -> TreeRun:
    """The one runner of the feeding trees: tick ``root`` every ``period_s`` of ``clock``
    until it ends or ``timeout_s`` passes (not counting the waits for plans,
    :meth:`BiteRecorder.planning_wait_s`), calling ``step(period_s)`` between ticks (the
    physics world's ``run``; :func:`tick_until_done`); returns how it ended and the
    telemetry. A timeout stops the tree (its clean-up runs); a safe stop by the guard is a
    FAILURE whose recorded cause is the guard's reason. ``visitors`` join the tree's own
    (e.g. a bite's food ledger, or a recording's
    :attr:`~articutool.sim.mcap_record.WorldMcapRecorder.tree_visitor`)."""
    tree = py_trees.trees.BehaviourTree(root)
    rec = BiteRecorder(clock)
    tree.visitors += [rec, *visitors]
    tree.setup()
    status = tick_until_done(tree, rec, step, clock, period_s=period_s, timeout_s=timeout_s)
    if status is None:
        rec.record.failures.append((root.name, f"did not finish within {timeout_s:g} s"))
        return TreeRun(Status.FAILURE, "timed_out", rec.record)
    stopped = safe_stop_reason(tree.root)
    if stopped is not None:
        rec.record.failures.append(("Safe stop", stopped))
        rec.record.cause = ("Safe stop", stopped)
        return TreeRun(Status.FAILURE, "stopped", rec.record)
    return TreeRun(status, "completed" if status == Status.SUCCESS else "failed", rec.record)


def tick_until_done(tree: py_trees.trees.BehaviourTree, rec: BiteRecorder,
                    step: Callable[[float], None], clock: Callable[[], float], *,
                    period_s: float, timeout_s: float) -> Status | None:
    """The one tick driver of the feeding trees (thesis §5.3): tick ``tree`` every
    ``period_s`` of ``clock``, a post-tick handler advancing the world (``step(period_s)``)
    while the root runs, until the root ends (its status is returned) or ``timeout_s`` passes,
    not counting the waits for plans (:meth:`BiteRecorder.planning_wait_s`): then the tree is
    stopped (its clean-up runs) and None returned. Not ``BehaviourTree.tick_tock``: that
    sleeps wall time between ticks and swallows Ctrl-C; here time is the world's."""
    def advance(t: py_trees.trees.BehaviourTree) -> None:
        if t.root.status not in (Status.SUCCESS, Status.FAILURE):
            rec.wait_for_plans()  # a plan costs one tick period of simulated time
            step(period_s)

    t_end = clock() + timeout_s
    while clock() - rec.planning_wait_s(clock()) < t_end:
        tree.tick(post_tick_handler=advance)
        if tree.root.status in (Status.SUCCESS, Status.FAILURE):
            return tree.root.status
    tree.root.stop(Status.INVALID)
    return None
