"""The PC's arm: what the feeding tree asks of the arm
(:class:`~articutool.feeding.behaviours.ArmInterface`), made on the PC over a small
:class:`ArmDriver` — planning, plan-then-verify, the food check, goal IK and the tip's paths
are here; the driver only reports the joints and follows, stops and runs trajectories.

The physics world's arm is one driver (:class:`articutool.sim.arm_driver.MujocoArm`); a real
Jaco is another, of the same four members (its joint states, a
``FollowJointTrajectory`` goal, a stop, whether the goal is active).

Plans run in a worker thread (the tree polls them) under the planner's own wall-time budget,
and report that wall time; motions run through the driver while the caller's clock runs.
Goals are the spec's named configurations (``Resting``, ``AbovePlate``, ``Home``), ``Staging``
(the spec's pose, solved by IK and backed off until the tool clears the user, as in
``articutool demo``) and any extra ``goals`` given (a scene's staging set). With ``rigid``
(the 6-DOF baseline, wrist locked), a goal where a food-carrying utensil waits (Resting,
Staging) is the arm configuration that holds the locked utensil level there
(:meth:`PCArm.rigid_level_configuration`).

Cartesian paths (insertion, extraction, lift) are solved by the Pinocchio IK for the arm
joints with the wrist where it is, timed by TOPP-RA (:mod:`articutool.planning.tip_paths`);
the first waypoint is reached by a rest-to-rest joint motion from where the arm is.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as _wait
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.api_types import JobResult
from articutool.arm.model import ArmModel
from articutool.arm.scene import Scene
from articutool.planning.api import plan
from articutool.planning.tip_paths import (
    PathError,
    cartesian_path,
    concatenate,
    first_ik,
    lift_trajectory,
    with_wrist,
    wrist_sweep,
)
from articutool.planning.types import PlanRequest, TransportTask
from articutool.spec import Spec
from articutool.trajectory import JointTrajectory, smooth_joint_motion
from articutool.verify.verifier import verify_trajectory

__all__ = ["ArmDriver", "FoodDecision", "PCArm"]

# Where a rigid utensil must wait level with food on it.
_CARRY_GOALS = ("Resting", "Staging")
# A path whose first waypoint is this close to the tip starts from the arm as it is.
_HERE_M = 0.02


class ArmDriver(Protocol):
    """The arm as the PC commands it (the physics world's, a real Jaco's)."""

    def joint_positions(self) -> NDArray[np.float64]:
        """The 8 joints now (rad): the six arm joints and the wrist's [pitch, roll], in the
        arm model's order (the spec's joint names)."""
        ...

    def follow(self, trajectory: JointTrajectory) -> None:
        """Start following ``trajectory``'s six arm joints (by name; wrist joints in it are
        the tool's, ignored) from now; returns at once. Raises ``ValueError`` for a point
        outside the arm's joint limits."""
        ...

    def stop(self) -> None:
        """Stop following: hold the arm where it is now, at rest."""
        ...

    @property
    def busy(self) -> bool:
        """True while a trajectory is being followed."""
        ...


class Planner(Protocol):
    """What the arm reads of the tree's planner (:class:`~articutool.feeding.system.Planner`)."""

    @property
    def name(self) -> str: ...

    @property
    def tolerance_deg(self) -> float | None: ...


class Waypoint(Protocol):
    """A tip waypoint (:class:`~articutool.feeding.insertion.TipWaypoint`)."""

    @property
    def position(self) -> tuple[float, float, float]: ...

    @property
    def pitch_down(self) -> float: ...

    @property
    def speed(self) -> float: ...

    @property
    def wrist(self) -> bool: ...


def _timed(work: Callable[[], JobResult]) -> Callable[[], JobResult]:
    """``work`` that reports its own wall time (``JobResult.wall_s``), measured in the worker
    thread: the planner's time, whatever the caller's clock did meanwhile."""

    def run() -> JobResult:
        t0 = time.perf_counter()
        r = work()
        return dataclasses.replace(r, wall_s=time.perf_counter() - t0)

    return run


class _FutureJob:
    def __init__(self, fut: Future[JobResult]) -> None:
        self.fut = fut

    def done(self) -> bool:
        return self.fut.done()

    def wait_off_clock(self, poll_s: float = 0.005) -> None:
        """Block until the worker thread finished (polled, so Ctrl-C still interrupts)."""
        while not self.fut.done():
            _wait([self.fut], timeout=poll_s)

    def result(self) -> JobResult:
        if self.fut.cancelled():
            return JobResult(False, "cancelled")
        return self.fut.result()

    def cancel(self) -> None:
        self.fut.cancel()  # a plan already running finishes in the worker and is dropped


class _MotionJob:
    def __init__(self, driver: ArmDriver) -> None:
        self.driver = driver
        self.cancelled = False

    def done(self) -> bool:
        return self.cancelled or not self.driver.busy

    def result(self) -> JobResult:
        if self.cancelled:
            return JobResult(False, "motion cancelled; the arm holds where it is")
        return JobResult(True, "arrived")

    def cancel(self) -> None:
        if not self.done():
            self.driver.stop()
        self.cancelled = True


@dataclasses.dataclass(frozen=True)
class FoodDecision:
    """What :meth:`PCArm.check_food` decided: the trajectory to execute (None when no
    timing is predicted spill-free) and the record of what was done and predicted."""

    trajectory: JointTrajectory | None
    record: dict[str, Any]


def _food_record(pred: Any, load: Any, wrist: str, scale: float, planned: JointTrajectory,
                 executed: JointTrajectory | None) -> dict[str, Any]:
    return {"food": load.food, "load_g": round(load.grams, 4), "wrist": wrist,
            "scale": scale, "retimed": scale < 1.0,
            "planned_duration_s": round(planned.duration, 3),
            "duration_s": None if executed is None else round(executed.duration, 3),
            "predicted_spill_g": round(pred.spilled_g, 4),
            "peak_apparent_tilt_deg": round(pred.peak_apparent_tilt_deg, 3),
            "peak_surface_tilt_deg": round(pred.peak_surface_tilt_deg, 3),
            "min_margin_deg": round(pred.min_margin_deg, 3)}


def _arm_part(trajectory: JointTrajectory) -> JointTrajectory:
    """The six arm joints of a trajectory (of 6 or 8)."""
    return JointTrajectory(trajectory.joint_names[:6], trajectory.times,
                           trajectory.positions[:, :6], trajectory.velocities[:, :6])


class PCArm:
    """The feeding tree's arm on the PC, over ``driver`` (see module doc).

    ``spec``, ``utensil`` and ``scene`` make the planning model. ``load`` gives the load on
    the utensil when a transport is checked (None: nothing to check): a
    :class:`~articutool.food.loads.FoodLoad` or a callable returning one. ``leveling`` is what
    the decoupled wrist levels against: ``"gravity"`` (its IMU loop) or ``"apparent"``
    (slosh-free). ``goals``: extra named arm configurations (6 joints), found before the
    spec's.
    """

    def __init__(self, driver: ArmDriver, spec: Spec, utensil: str, scene: Scene, *,
                 seed: int = 0, rigid: bool = False, load: Any = None,
                 leveling: str = "gravity", goals: Mapping[str, ArrayLike] | None = None
                 ) -> None:
        if leveling not in ("gravity", "apparent"):
            raise ValueError(f"leveling must be 'gravity' or 'apparent'; got {leveling!r}")
        self.driver = driver
        self.spec = spec
        self.utensil = utensil
        self.seed = seed
        self.rigid = rigid
        self.load = load
        self.leveling = leveling
        self.extra = {k: np.asarray(v, dtype=float) for k, v in (goals or {}).items()}
        self.model = ArmModel(spec, utensil, 8, scene)
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plan")
        self._goals: dict[str, np.ndarray] = {}

    def _q(self) -> NDArray[np.float64]:
        """The 8 joints now, the roll wrapped to (−π, π] (a twirl turns it whole turns)."""
        q = np.asarray(self.driver.joint_positions(), dtype=float).copy()
        q[7] = math.remainder(q[7], 2 * math.pi)
        return q

    def goal_configuration(self, goal: str) -> np.ndarray:
        """Arm joints of a named goal (an extra goal, a configuration of the spec, or
        Staging)."""
        if goal in self.extra:
            return self.extra[goal]
        if goal not in self._goals:
            spec = self.spec
            if self.rigid and goal in _CARRY_GOALS:
                self._goals[goal] = self.rigid_level_configuration(goal, free=True)
            elif goal in spec.arm.configurations:
                self._goals[goal] = spec.arm.configuration(goal)
            elif goal == "Staging":
                from articutool.arm.ik import staging_configuration

                self._goals[goal] = staging_configuration(spec, self.model, self.seed)[0]
            else:
                raise ValueError(f"goal: unknown goal {goal!r}; known: "
                                 f"{sorted([*self.extra, *spec.arm.configurations, 'Staging'])}")
        return self._goals[goal]

    def rigid_level_configuration(self, goal: str, free: bool = False) -> np.ndarray:
        """For a locked wrist (the rigid baseline): an arm configuration that puts the utensil
        level at ``goal``'s tip position, pointing as close as possible to the way it points
        at ``goal`` (headings tried in 15° steps, IK from the goal and the named
        configurations, collision-free). Raises ``ValueError`` if there is none.

        At the spec's Resting with the Articutool's long tool, only headings near +x and −y
        give a level rigid utensil (measured by IK from 33 starts)."""
        from articutool.arm.ik import solve_level_ik

        spec, wq = self.spec, self.driver.joint_positions()[6:]
        named = (spec.arm.configuration(goal) if goal in spec.arm.configurations else None)
        if named is None:
            rigid, self.rigid = self.rigid, False  # the Articutool's Staging, to start from
            try:
                named = self.goal_configuration(goal)
            finally:
                self.rigid = rigid
        q_goal = np.concatenate([named, wq])
        T = self.model.tip_pose(q_goal)
        h0 = float(np.arctan2(T[1, 2], T[0, 2]))
        seeds = [q_goal] + [np.concatenate([spec.arm.configuration(n), wq])
                            for n in spec.arm.configurations]
        q = solve_level_ik(self.model, lambda z: T[:3, 3], h0, seeds)
        if q is not None:
            return q[:6]
        raise ValueError(f"goal: no collision-free level configuration at {goal!r} for the "
                         "locked wrist")

    def start_plan(self, goal: str, planner: Planner, budget_s: float) -> _FutureJob:
        """Plan from where the arm is to ``goal`` with ``planner`` in a worker thread."""
        start = tuple(float(x) for x in self.driver.joint_positions()[:6])
        target = tuple(float(x) for x in self.goal_configuration(goal))
        req = PlanRequest(planner=planner.name, task=TransportTask(0, start, target),
                          timeout_s=budget_s, seed=self.seed, utensil=self.utensil,
                          tolerance_deg=planner.tolerance_deg)
        spec = self.spec

        def work() -> JobResult:
            r = plan(req, spec)
            if not r.success or r.trajectory is None:
                return JobResult(False, r.message or "no plan")
            return JobResult(True, f"{r.attempts} attempt(s), {r.planning_time_s:.2f} s",
                             r.trajectory)

        return _FutureJob(self._pool.submit(_timed(work)))

    def verify(self, trajectory: Any) -> JobResult:
        """Plan-then-verify: can the wrist level along this arm trajectory (Alg. 2)?"""
        if not isinstance(trajectory, JointTrajectory):
            return JobResult(False, "no trajectory to verify")
        rep = verify_trajectory(_arm_part(trajectory), self.model, self.spec)
        if rep.feasible:
            return JobResult(True, f"feasible, velocity margin {rep.velocity_margin:.0%}")
        return JobResult(False, f"the wrist cannot follow: {rep.reason}")

    def current_load(self) -> Any:
        """The load to check (``self.load`` called if it is a callable), or None."""
        return self.load() if callable(self.load) else self.load

    def check_food(self, trajectory: Any) -> JobResult:
        """Food-aware verification (see :class:`~articutool.feeding.behaviours.CheckFood`):
        predict the load's spill along ``trajectory`` with the wrist as this system moves it
        — locked (rigid), leveling, or slosh-free (``leveling = "apparent"``; plain leveling
        when the tool would refuse that trajectory) — and retime it with TOPP-RA at the
        speed scales of :data:`~articutool.planning.timing.RETIME_SCALES` until it is
        predicted spill-free. Both systems get the same retiming."""
        from articutool.food.loads import LoadError
        from articutool.planning.timing import RETIME_SCALES, retime
        from articutool.verify.food import food_check, slosh_free_wrist, spill_model

        load = self.current_load()
        if load is None or load.grams <= 0:
            return JobResult(True, "no load to check", FoodDecision(trajectory, None))
        if not isinstance(trajectory, JointTrajectory):
            return JobResult(False, "no trajectory to check")
        spec, utensil = self.spec, self.utensil
        try:
            spill_model(spec, utensil, load)
        except LoadError as err:
            return JobResult(False, f"the load cannot be modelled: {err}",
                             FoodDecision(None, {"food": load.food, "load_g": load.grams,
                                                 "error": str(err)}))
        arm = _arm_part(trajectory)
        wrist_now = np.asarray(self.driver.joint_positions()[6:], dtype=float)
        tried: list[dict[str, Any]] = []
        fallback = ""
        for scale in RETIME_SCALES:
            timed = arm if scale == 1.0 else retime(arm, spec.arm.max_velocity,
                                                    spec.arm.max_acceleration, scale)
            if timed is None:
                continue
            if self.rigid:
                wrist: Any = wrist_now
                kind, executed = "locked", timed
            else:
                rep = verify_trajectory(timed, self.model, spec)
                if not rep.feasible or rep.wrist_trajectory is None:
                    tried.append({"scale": scale, "infeasible": rep.reason})
                    continue
                wrist, kind, executed = rep.wrist_trajectory, "leveling", timed
                if self.leveling == "apparent":
                    sf = slosh_free_wrist(timed, self.model, spec, utensil,
                                          q_wrist_start=wrist_now)
                    if sf.ok:
                        assert sf.arm is not None
                        wrist, kind, executed = sf.wrist, "slosh_free", sf.combined()
                        timed = sf.arm
                    else:
                        fallback = sf.message
            rep_f = food_check(timed, wrist, self.model, spec, utensil, load, kind)
            pred = rep_f.prediction
            tried.append({"scale": scale, "wrist": kind,
                          "predicted_spill_g": round(pred.spilled_g, 4)})
            record = _food_record(pred, load, kind, scale, arm, executed)
            record["tried"] = tried
            if fallback:
                record["slosh_free_fallback"] = fallback
            if not rep_f.spills:
                what = ("as planned" if scale == 1.0 else
                        f"retimed to {scale:g}× speed ({arm.duration:.1f} → "
                        f"{executed.duration:.1f} s)")
                return JobResult(True, f"food check: {what}, wrist {kind.replace('_', '-')}, "
                                       f"predicted spill {pred.spilled_g:.3f} g, margin "
                                       f"{pred.min_margin_deg:.1f}°",
                                 FoodDecision(executed, record))
        worst = tried[-1].get("predicted_spill_g") if tried else None
        record = {"food": load.food, "load_g": load.grams, "tried": tried,
                  "predicted_spill_g": worst, "executed": False}
        return JobResult(False, f"predicted to spill {load.food} even at "
                                f"{RETIME_SCALES[-1]:g}× speed ({worst} g): re-plan",
                         FoodDecision(None, record))

    def start_plan_path(self, name: str, waypoints: Sequence[Waypoint]) -> _FutureJob:
        """Plan the tip's Cartesian path through ``waypoints`` in a worker thread: a joint
        motion to the first, then straight segments (see module doc)."""
        q_now = self._q()
        pts = [(np.array(w.position), w.pitch_down, w.speed) for w in waypoints]
        spec = self.spec
        joints = tuple(spec.arm.joint_names)

        def work() -> JobResult:
            try:
                # A path that starts where the tip is (into or out of the food) starts from
                # the arm as it is, the utensil maybe touching the container; otherwise a
                # free joint motion to the first waypoint, which must be clear.
                here = np.linalg.norm(self.model.tip_pose(q_now)[:3, 3] - pts[0][0]) < _HERE_M
                if here:
                    q0, parts = q_now, []
                else:
                    q0 = first_ik(self.model, q_now, pts[0][0], pts[0][1])
                    if self.model.in_collision(q0):
                        return JobResult(False, f"the pose {name} is in collision")
                    parts = [smooth_joint_motion(q_now[:6], q0[:6], spec.arm.max_velocity,
                                                 joints)]
                if self.rigid or not any(w.wrist for w in waypoints):
                    if len(pts) > 1:
                        parts.append(cartesian_path(self.model, q0, pts))
                else:  # the Articutool: the wrist makes the marked segments' pitch change
                    parts = [with_wrist(p, self.model, q0[6:]) for p in parts]
                    q, k = q0, 1
                    while k < len(pts):
                        j = k
                        while j < len(pts) and waypoints[j].wrist == waypoints[k].wrist:
                            j += 1
                        if waypoints[k].wrist:
                            for i in range(k, j):
                                seg = wrist_sweep(self.model, q, *pts[i - 1][:2], *pts[i])
                                parts.append(seg)
                                q = seg.positions[-1].copy()
                        else:
                            seg6 = cartesian_path(self.model, q, pts[k - 1:j])
                            parts.append(with_wrist(seg6, self.model, q[6:]))
                            q = np.concatenate([seg6.positions[-1], q[6:]])
                        k = j
            except PathError as err:
                return JobResult(False, str(err))
            traj = concatenate(parts)
            return JobResult(True, f"{traj.duration:.1f} s", traj)

        return _FutureJob(self._pool.submit(_timed(work)))

    def start_plan_lift(self, height_m: float) -> _FutureJob:
        """Plan lifting the tool base straight up by ``height_m`` in a worker thread."""
        q_now = self._q()

        def work() -> JobResult:
            try:
                traj = lift_trajectory(self.model, q_now, height_m)
            except PathError as err:
                return JobResult(False, str(err))
            return JobResult(True, f"{traj.duration:.1f} s", traj)

        return _FutureJob(self._pool.submit(_timed(work)))

    def start_execute(self, trajectory: Any) -> _MotionJob:
        """Run the trajectory through the driver (the caller's clock runs meanwhile)."""
        self.driver.follow(trajectory)
        return _MotionJob(self.driver)

    def stop(self) -> None:
        """Hold the arm where it is."""
        self.driver.stop()

    def close(self) -> None:
        """Stop the planning thread."""
        self._pool.shutdown(wait=False, cancel_futures=True)
