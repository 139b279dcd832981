"""py_trees behaviours of the feeding tree (thesis §3.2.1, §4.3), and the interfaces
they talk to.

The tree reaches the arm only through :class:`ArmInterface`, the tool only through
:class:`~articutool.tool.api.ToolAPI` and the user only through :class:`User`, so the same
tree drives the physics world, a real arm driver or a ROS 2 bridge, the in-process tool
runtime or a client over Zenoh, and the simulated user or a real one. Long actions
(planning, arm motions, primitives) are *jobs*: started in ``initialise``, polled in ``update``
(never waited for), cancelled in ``terminate`` when preempted.

What the behaviours of one tree share is that tree's own :class:`Board`, passed to each
behaviour when the tree is built (never py_trees' process-global blackboard): two trees in two
threads of one process, e.g. two trials in one Dask worker, share nothing. Attempt counts live
on the :class:`CountedRetry` nodes themselves.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import py_trees
from py_trees.common import Status

from articutool.api_types import JobResult
from articutool.feeding.system import Planner
from articutool.tool.api import ABORTED_BY_MODE_CHANGE, Mode, ToolAPI

__all__ = [
    "ArmInterface",
    "BiteStage",
    "Board",
    "CheckFood",
    "CountedRetry",
    "Execute",
    "Job",
    "Plan",
    "PlanLift",
    "PlanPath",
    "Retreat",
    "RunPrimitive",
    "SafeStop",
    "SafetyGuard",
    "Settle",
    "TakeBite",
    "ToolModeScope",
    "User",
    "Verify",
]


@dataclass
class Board:
    """What the behaviours of one tree share: ``trajectory`` (the last plan, passed from
    planning to verification and execution), ``tool_mode`` (the mode the tree last put the
    tool in, for the guard), ``stop_requested`` (set by a caregiver or a UI: the guard stops
    the bite in the next tick)."""

    trajectory: Any = None
    tool_mode: Mode | None = None
    stop_requested: bool = False


class Job(Protocol):
    """A long action in progress (a plan being computed, a motion being executed)."""

    def done(self) -> bool:
        """True once it ended (``result`` is then available)."""

    def result(self) -> JobResult:
        """How it ended."""

    def cancel(self) -> None:
        """Stop it (idempotent); a cancelled motion leaves the arm stopped."""

    # Optional: ``wait_off_clock() -> None`` on a job computed off the tree's clock (a plan in
    # a worker thread beside a simulated world): the tick driver blocks on it instead of
    # advancing the world, so the simulated time a plan costs does not depend on the machine
    # (:meth:`articutool.feeding.tree.BiteRecorder.wait_for_plans`); its result is read in the
    # tick after the one that started it, so it costs one tick period. A job without it (a real
    # robot's, on wall time) is polled while the clock runs.


class ArmInterface(Protocol):
    """What the tree needs of the arm (the physics world's arm now; a driver later)."""

    def start_plan(self, goal: str, planner: Planner, budget_s: float) -> Job:
        """Plan from the present configuration to the named goal with ``planner`` (its name
        and, for a strict planner, its tolerance band); value: the trajectory. The job ends
        on its own: ``budget_s`` is the planner's wall time, however fast the caller's clock
        runs meanwhile."""

    def verify(self, trajectory: Any) -> JobResult:
        """Plan-then-verify (Alg. 2) for the tool that will follow it."""

    def check_food(self, trajectory: Any) -> JobResult:
        """What the trajectory does to the load on the utensil: ok with a trajectory that is
        predicted not to spill (the plan itself, retimed slower, or with the wrist's joints
        for slosh-free leveling) as ``value.trajectory``; not ok with the reason when no
        timing within the arm's budget is. ``value.record`` says what was done and
        predicted."""

    def start_plan_path(self, name: str, waypoints: Any) -> Job:
        """Plan a Cartesian path of the utensil tip through ``waypoints`` (a list of
        :class:`~articutool.feeding.insertion.TipWaypoint`), from the first waypoint (reached
        first by a free motion if the arm is elsewhere); value: the trajectory."""

    def start_plan_lift(self, height_m: float) -> Job:
        """Plan lifting the tool base straight up by ``height_m``, its orientation kept."""

    def start_execute(self, trajectory: Any) -> Job:
        """Execute a trajectory."""

    def stop(self) -> None:
        """Stop the arm now."""


class User(Protocol):
    """What the tree needs of the person it feeds (the simulated user in the physics world)."""

    def take_bite(self) -> float:
        """The user takes the bite presented to them off the utensil; returns its grams."""


class _JobBehaviour(py_trees.behaviour.Behaviour):
    """Start a job in ``initialise``, poll it, cancel it when preempted."""

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.job: Job | None = None
        self.job_wall_s = 0.0  # the finished job's own wall time (``JobResult.wall_s``)
        self._started_this_tick = False

    def start(self) -> Job:
        raise NotImplementedError

    def finished(self, r: JobResult) -> Status:
        return Status.SUCCESS if r.ok else Status.FAILURE

    def initialise(self) -> None:
        self.job_wall_s = 0.0
        self.job = self.start()
        self._started_this_tick = True
        self.feedback_message = "started"

    def update(self) -> Status:
        assert self.job is not None
        started, self._started_this_tick = self._started_this_tick, False
        # A job computed off the tree's clock ends at the earliest in the tick after the one
        # that started it: whether its worker thread is done before this poll is up to the
        # operating system's scheduling, so without this the world would wait one tick for
        # the same plan on one run and none on another, and the physics would differ.
        if not self.job.done() or (started and hasattr(self.job, "wait_off_clock")):
            return Status.RUNNING
        r = self.job.result()
        self.feedback_message, self.job_wall_s = r.message, r.wall_s
        return self.finished(r)

    def terminate(self, new_status: Status) -> None:
        if new_status == Status.INVALID and self.job is not None and not self.job.done():
            self.job.cancel()
            self.feedback_message = "cancelled"


class _PlanJob(_JobBehaviour):
    """A planning job whose trajectory goes on the tree's board; a failure says what had no
    plan (``self.what``)."""

    what = ""

    def __init__(self, name: str, board: Board) -> None:
        super().__init__(name)
        self.board = board

    def finished(self, r: JobResult) -> Status:
        if r.ok:
            self.board.trajectory = r.value
            return Status.SUCCESS
        self.feedback_message = f"no {self.what}: {r.message}"
        return Status.FAILURE


class Plan(_PlanJob):
    """Plan to ``goal`` with ``planner``; the trajectory goes on the tree's board."""

    def __init__(self, arm: ArmInterface, goal: str, planner: Planner,
                 budget_s: float, *, board: Board) -> None:
        super().__init__(f"Plan to {goal}", board)
        self.arm, self.goal, self.planner, self.budget_s = arm, goal, planner, budget_s
        self.what = f"plan to {goal}"

    def start(self) -> Job:
        return self.arm.start_plan(self.goal, self.planner, self.budget_s)


class PlanPath(_PlanJob):
    """Plan the tip's Cartesian path through ``waypoints``; the trajectory goes on the
    tree's board (insertion and extraction, §4.3.1)."""

    def __init__(self, arm: ArmInterface, what: str, waypoints: Any, *, board: Board) -> None:
        super().__init__(f"Plan {what}", board)
        self.arm, self.waypoints = arm, waypoints
        self.path, self.what = what, f"path {what}"

    def start(self) -> Job:
        return self.arm.start_plan_path(self.path, self.waypoints)


class PlanLift(PlanPath):
    """Plan lifting the tool base straight up (the utensil keeps its orientation)."""

    def __init__(self, arm: ArmInterface, height_m: float, *, board: Board) -> None:
        super().__init__(arm, f"lift {height_m * 100:g} cm", None, board=board)
        self.height_m = height_m

    def start(self) -> Job:
        return self.arm.start_plan_lift(self.height_m)


class Settle(py_trees.behaviour.Behaviour):
    """Put the tool in ``mode`` and let ``seconds`` pass on ``clock`` (the tool-only leveling
    of §4.3.1: the wrist levels the utensil while the arm holds still)."""

    def __init__(self, tool: ToolAPI, mode: Mode, seconds: float,
                 clock: Callable[[], float], name: str | None = None, *,
                 board: Board) -> None:
        super().__init__(name or f"{mode.name} {seconds:g} s")
        self.tool, self.mode, self.seconds, self.clock = tool, mode, seconds, clock
        self._until = 0.0
        self._ok = False
        self.board = board

    def initialise(self) -> None:
        self._ok, msg = self.tool.set_mode(self.mode)
        self.feedback_message = msg
        self._until = self.clock() + self.seconds
        if self._ok:
            self.board.tool_mode = self.mode

    def update(self) -> Status:
        if not self._ok:
            return Status.FAILURE  # refused: the message says why
        return Status.RUNNING if self.clock() < self._until else Status.SUCCESS


class TakeBite(py_trees.behaviour.Behaviour):
    """The user takes the presented bite (:meth:`User.take_bite`), in the tick the
    presentation ends; it succeeds with the grams taken as feedback."""

    def __init__(self, user: User) -> None:
        super().__init__("the user takes the bite")
        self.user = user

    def update(self) -> Status:
        self.feedback_message = f"{self.user.take_bite():.2f} g taken"
        return Status.SUCCESS


class BiteStage(py_trees.composites.Sequence):
    """One stage of a bite (``stage``: a name of :data:`articutool.feeding.bite.BITE_STAGES`),
    the sequence of its steps; what watches the bite (telemetry, the food at each stage's
    end, the progress display) finds the stages by this class."""

    def __init__(self, stage: str, children: list[py_trees.behaviour.Behaviour],
                 name: str | None = None) -> None:
        super().__init__(name or stage, memory=True, children=children)
        self.stage = stage


class Retreat(py_trees.decorators.SuccessIsFailure):
    """A failed bite's retreat: ``child`` takes the arm away, and the bite still fails
    (py_trees' SuccessIsFailure); the telemetry keeps the failure that caused it."""

    def __init__(self, child: py_trees.behaviour.Behaviour,
                 name: str = "retreat (the bite failed)") -> None:
        super().__init__(name=name, child=child)


class Verify(py_trees.behaviour.Behaviour):
    """Plan-then-verify the trajectory on the tree's board (a rejection fails, so the
    enclosing attempts re-plan)."""

    def __init__(self, arm: ArmInterface, *, board: Board) -> None:
        super().__init__("Verify")
        self.arm, self.board = arm, board

    def update(self) -> Status:
        r = self.arm.verify(self.board.trajectory)
        self.feedback_message = r.message or ("feasible" if r.ok else "rejected")
        return Status.SUCCESS if r.ok else Status.FAILURE


class CheckFood(py_trees.behaviour.Behaviour):
    """Food-aware verification of the trajectory on the tree's board: the arm predicts what it
    does to the load and replaces it by one predicted not to spill (retimed, or slosh-free);
    a trajectory that cannot be made spill-free fails, so the enclosing attempts re-plan and
    the transport never executes a predicted spill. ``records`` keeps each check's record
    (what was done, the prediction) for the bite's telemetry."""

    def __init__(self, arm: ArmInterface, *, board: Board) -> None:
        super().__init__("Check the food")
        self.arm, self.board = arm, board
        self.records: list[dict[str, Any]] = []

    def update(self) -> Status:
        r = self.arm.check_food(self.board.trajectory)
        self.feedback_message = r.message
        if r.value is not None and getattr(r.value, "record", None) is not None:
            self.records.append(r.value.record)
        if not r.ok:
            return Status.FAILURE
        self.board.trajectory = r.value.trajectory
        return Status.SUCCESS


class Execute(_JobBehaviour):
    """Execute the trajectory on the tree's board. With ``tool`` and ``clock``, a trajectory
    that also moves the wrist's joints (a wrist-made sweep) sends them to the tool
    (TRAJECTORY mode) as the arm starts, and keeps the wrist's largest tracking error
    (``wrist_tracking_error``, rad, from the tool's measured joints). ``then``: the tool's
    mode once such a motion ended (the leveling loop takes over after a slosh-free
    transport)."""

    def __init__(self, arm: ArmInterface, what: str = "motion", tool: ToolAPI | None = None,
                 clock: Callable[[], float] | None = None, then: Mode | None = None, *,
                 board: Board) -> None:
        super().__init__(f"Execute {what}")
        self.arm, self.tool, self.clock, self.then = arm, tool, clock, then
        self.board = board
        self.wrist_tracking_error = 0.0
        self._wrist: Any = None

    def start(self) -> Job:
        traj = self.board.trajectory
        self._wrist, self.wrist_tracking_error = None, 0.0
        if self.tool is not None and self.clock is not None:
            self._wrist = _wrist_part(traj, self.tool.state().joint_names)
        if self._wrist is not None:
            ok, msg = self.tool.follow_trajectory(self._wrist)  # type: ignore[union-attr]
            if not ok:  # nothing moves: the arm does not start without the wrist
                self._wrist = None
                return _Ended(JobResult(False, f"the tool refused the wrist's part: {msg}"))
            self._t0 = self.clock()  # type: ignore[misc]
        return self.arm.start_execute(traj)

    def update(self) -> Status:
        if self._wrist is not None and not self.job.done():  # type: ignore[union-attr]
            q_ref, _ = self._wrist.sample(self.clock() - self._t0)  # type: ignore[misc]
            q = self.tool.state().position  # type: ignore[union-attr]
            err = max(abs(q[0] - q_ref[0]), abs(q[1] - q_ref[1]))
            self.wrist_tracking_error = max(self.wrist_tracking_error, float(err))
        status = super().update()
        if status != Status.RUNNING and self._wrist is not None:
            self.feedback_message += (f"; wrist tracking error ≤ "
                                      f"{math.degrees(self.wrist_tracking_error):.2f}°")
            if self.then is not None:
                ok, msg = self.tool.set_mode(self.then)  # type: ignore[union-attr]
                if ok:
                    self.board.tool_mode = self.then
                else:
                    self.feedback_message += f"; {self.then.name} refused: {msg}"
                    return Status.FAILURE
        return status


class _Ended:
    """A job that ended before it started (refused)."""

    def __init__(self, result: JobResult) -> None:
        self._result = result

    def done(self) -> bool:
        return True

    def result(self) -> JobResult:
        return self._result

    def cancel(self) -> None:
        pass


def _wrist_part(traj: Any, names: tuple[str, str]) -> Any:
    """The wrist's joints of ``traj`` as a trajectory, if it has them and they move."""
    from articutool.trajectory import JointTrajectory

    if not isinstance(traj, JointTrajectory) or not all(n in traj.joint_names for n in names):
        return None
    idx = [traj.joint_names.index(n) for n in names]
    pos = traj.positions[:, idx]
    if float(np.ptp(pos[:, 0])) < 1e-6 and float(np.ptp(pos[:, 1])) < 1e-6:
        return None
    return JointTrajectory(tuple(names), traj.times, pos, traj.velocities[:, idx])


class RunPrimitive(py_trees.behaviour.Behaviour):
    """Run a tool primitive (``NONE`` succeeds at once); cancelled when preempted. A
    primitive aborted by a mode change the tree did not make (a DISABLED from another
    client) is a stop, not a failure to retry or retreat from: it stays RUNNING for the
    guard (:class:`SafetyGuard`) to stop the bite in the next tick."""

    def __init__(self, tool: ToolAPI, primitive: str, params: list[float], stage: str, *,
                 board: Board) -> None:
        super().__init__(f"{stage}: {primitive}")
        self.tool, self.primitive, self.params = tool, primitive, list(params)
        self._running = False
        self.board = board

    def initialise(self) -> None:
        self._running = False
        if self.primitive == "NONE":
            return
        ok, msg = self.tool.start_primitive(self.primitive, self.params)
        self.feedback_message = msg
        self._running = ok
        if ok:
            self.board.tool_mode = Mode.PRIMITIVE

    def update(self) -> Status:
        if self.primitive == "NONE":
            return Status.SUCCESS
        if not self._running:
            return Status.FAILURE  # refused: the message says why
        st = self.tool.primitive_status()
        if st is None or not st.done:
            return Status.RUNNING
        self.feedback_message = st.message
        if st.message.startswith(ABORTED_BY_MODE_CHANGE):
            return Status.RUNNING  # stopped from elsewhere: the guard stops the bite
        self._running = False
        self.board.tool_mode = Mode.DISABLED  # where a primitive leaves the tool
        return Status.SUCCESS if st.success else Status.FAILURE

    def terminate(self, new_status: Status) -> None:
        if new_status == Status.INVALID and self._running:
            self.tool.cancel_primitive()
            self._running = False
            self.board.tool_mode = Mode.DISABLED


class ToolModeScope(py_trees.decorators.Decorator):
    """Run ``child`` with the tool in ``mode``; restore ``restore`` afterwards, whatever
    happened — success, failure or preemption (``terminate`` always runs)."""

    def __init__(self, child: py_trees.behaviour.Behaviour, tool: ToolAPI, mode: Mode,
                 restore: Mode, *, board: Board) -> None:
        super().__init__(name=f"tool {mode.name} (then {restore.name})", child=child)
        self.tool, self.mode, self.restore = tool, mode, restore
        self._ok = False
        self.board = board

    def initialise(self) -> None:
        ok, msg = self.tool.set_mode(self.mode)
        self._ok = ok
        self.feedback_message = msg
        if ok:
            self.board.tool_mode = self.mode

    def update(self) -> Status:
        if not self._ok:
            return Status.FAILURE
        return self.decorated.status

    def terminate(self, new_status: Status) -> None:
        self.tool.set_mode(self.restore)
        self.board.tool_mode = self.restore

    def stop(self, new_status: Status = Status.INVALID) -> None:
        """Stop the child first, then restore: py_trees' Decorator.stop runs ``terminate``
        before stopping the child, so a scope nested inside (a primitive's DISABLED, then
        LEVELING) would restore its mode after this one and leave the tool LEVELING."""
        if new_status == Status.INVALID and self.decorated.status != Status.INVALID:
            self.decorated.stop(Status.INVALID)
        super().stop(new_status)


class CountedRetry(py_trees.decorators.Retry):
    """py_trees' Retry, counting its attempts on itself (``count``: the attempt in progress,
    or the attempts used once it ended; 0 before it first ran) under ``key`` (the name a
    bite's record reports it by), and not mistaking a child left INVALID (e.g. by a
    timeout) for success (py_trees issue #434)."""

    def __init__(self, child: py_trees.behaviour.Behaviour, num_attempts: int, key: str,
                 name: str | None = None) -> None:
        super().__init__(name=name or f"up to {num_attempts} attempts", child=child,
                         num_failures=num_attempts)
        self.key = key
        self.count = 0

    def initialise(self) -> None:
        super().initialise()
        self.count = 1

    def update(self) -> Status:
        if self.decorated.status == Status.INVALID:
            self.failures += 1  # a timed-out attempt is a failed one
            if self.failures >= self.num_failures:
                self.feedback_message = f"final failure after {self.failures} attempts"
                return Status.FAILURE
            self.count = self.failures + 1
            return Status.RUNNING
        status = super().update()
        if self.decorated.status == Status.FAILURE and status == Status.RUNNING:
            self.count = self.failures + 1
        return status


class SafetyGuard(py_trees.decorators.EternalGuard):
    """The root safety guard: py_trees' EternalGuard, named ``Unsafe?``, around :class:`SafeStop`.
    Every tick, before the bite's steps, its condition asks whether the bite must stop: a tool
    fault, tool state older than ``stale_s``, a stop request on the tree's board
    (:attr:`Board.stop_requested`), or a stop from elsewhere (another paired PC, the tool's own
    console): the tool DISABLED while the tree has it LEVELING — seen in two ticks running,
    since over a link a snapshot taken just before the tree's own LEVELING was carried out can
    arrive after it — or the tree's primitive aborted by a mode change. Then Safe stop runs and
    the guard SUCCEEDS with the reason as its feedback; otherwise it FAILS ("safe"), no failure
    of the bite, and the root selector goes on to the bite."""

    def __init__(self, arm: ArmInterface, tool: ToolAPI, clock: Callable[[], float],
                 stale_s: float, *, board: Board) -> None:
        super().__init__("Unsafe?", SafeStop(arm, tool, board=board), condition=self._unsafe)
        self.tool, self.clock, self.stale_s = tool, clock, stale_s
        self.board = board
        self._disabled_ticks = 0  # consecutive ticks the tool was DISABLED while LEVELING
        self._reason = ""

    def _unsafe(self) -> bool:
        st = self.tool.state()
        stop = self.board.stop_requested
        expected = self.board.tool_mode
        self._disabled_ticks = self._disabled_ticks + 1 if (
            expected == Mode.LEVELING and st.mode == Mode.DISABLED) else 0
        ps = self.tool.primitive_status() if expected == Mode.PRIMITIVE else None
        if st.fault:
            self._reason = f"tool fault: {st.fault}"
        elif self.clock() - st.stamp > self.stale_s:
            self._reason = (f"tool state is {self.clock() - st.stamp:.2f} s old "
                            f"(limit {self.stale_s:g} s)")
        elif stop:
            self._reason = "stop requested"
        elif self._disabled_ticks >= 2:
            self._reason = "the tool was DISABLED by another client while leveling"
        elif ps is not None and ps.done and ps.message.startswith(ABORTED_BY_MODE_CHANGE):
            self._reason = f"{ps.name} {ps.message} by another client"
        else:
            return False
        return True

    def update(self) -> Status:
        """The safe stop's status, with the reason the bite was stopped as feedback."""
        self.feedback_message = self._reason
        return super().update()


class SafeStop(py_trees.behaviour.Behaviour):
    """Stop the arm and put the tool in DISABLED (motors hold, nothing moves)."""

    def __init__(self, arm: ArmInterface, tool: ToolAPI, *, board: Board) -> None:
        super().__init__("Safe stop")
        self.arm, self.tool, self.board = arm, tool, board

    def update(self) -> Status:
        self.arm.stop()
        self.tool.set_mode(Mode.DISABLED)
        self.board.tool_mode = Mode.DISABLED
        self.feedback_message = "arm stopped, tool DISABLED"
        return Status.SUCCESS
