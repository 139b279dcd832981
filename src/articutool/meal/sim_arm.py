"""The feeding tree's arm in the physics world: :class:`SimArm` implements
:class:`~articutool.feeding.behaviours.ArmInterface` on a
:class:`~articutool.sim.world.FeedingWorld`, with the project's planners and verifier.

Plans run in a worker thread (the tree polls them) under the planner's own wall-time budget,
and report that wall time; motions run through the world's arm
servos while the caller keeps stepping the world. Goals are the spec's named configurations
(``Resting``, ``AbovePlate``, ``Home``) and ``Staging`` (the spec's pose, solved by IK and
backed off until the tool clears the user, as in ``articutool demo``). With ``rigid`` (the
6-DOF baseline, wrist locked), a goal where a food-carrying utensil waits (Resting, Staging)
is the arm configuration that holds the locked utensil level there
(:meth:`SimArm.rigid_level_configuration`).

Cartesian paths (insertion, extraction, lift) are solved by the Pinocchio IK for the arm
joints with the wrist where it is, timed by TOPP-RA (:mod:`articutool.sim.scenes`); the first
waypoint is reached by a rest-to-rest joint motion from where the arm is.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as _wait
from typing import Any

import numpy as np

from articutool.arm.model import ArmModel
from articutool.arm.scene import SCOOP_HEADING
from articutool.feeding.behaviours import JobResult
from articutool.feeding.insertion import TipWaypoint
from articutool.feeding.system import Planner
from articutool.planning.api import plan
from articutool.planning.types import PlanRequest, TransportTask
from articutool.sim.scenes import (
    ScriptError,
    cartesian_path,
    first_ik,
    lift_trajectory,
    tip_target,
)
from articutool.sim.world import FeedingWorld, smooth_joint_motion
from articutool.trajectory import JointTrajectory
from articutool.verify.verifier import verify_trajectory

__all__ = ["FoodDecision", "SimArm", "world_load", "wrist_sweep"]

# Where a rigid utensil must wait level with food on it.
_CARRY_GOALS = ("Resting", "Staging")
# A path whose first waypoint is this close to the tip starts from the arm as it is.
_HERE_M = 0.02


def _concatenate(parts: list[JointTrajectory]) -> JointTrajectory:
    """Rest-to-rest trajectories one after the other (each starts where the last ended)."""
    times, pos, vel, t0 = [parts[0].times], [parts[0].positions], [parts[0].velocities], 0.0
    for a, b in itertools.pairwise(parts):
        t0 += a.duration
        times.append(t0 + b.times[1:])
        pos.append(b.positions[1:])
        vel.append(b.velocities[1:])
    return JointTrajectory(parts[0].joint_names, np.concatenate(times), np.concatenate(pos),
                           np.concatenate(vel))


_PITCH_MARGIN = math.radians(5.0)


def _pitch_down(model: ArmModel, q: np.ndarray) -> float:
    """How far the utensil points below the horizon at ``q`` (rad)."""
    return float(math.asin(-np.clip(model.tip_pose(q)[2, 2], -1.0, 1.0)))


def wrist_sweep(model: ArmModel, q: np.ndarray, p0: np.ndarray, a0: float, p1: np.ndarray,
                a1: float, speed: float, step_m: float = 0.002, dt: float = 0.02
                ) -> JointTrajectory:
    """8-joint trajectory of a tip segment p0 → p1 whose pitch change a0 → a1 the wrist's
    pitch makes while the arm translates (thesis §4.3.1, "a 2-DOF local motion with
    the Articutool"): the wrist pitch is interpolated from ``q``'s to the one that gives
    ``a1`` with the tool base as at ``q`` (within its range: beyond it the arm makes the rest
    of the turn), and the arm joints are solved by IK for every tip
    pose along the segment. Rest to rest, on a smoothstep in time no faster than ``speed`` on
    average and within the arm's and the wrist's velocity limits. Raises ``ScriptError``."""
    from articutool.arm.ik import IKSettings, solve_pose_ik

    spec = model.spec
    # The wrist pitch that turns the utensil by a1 − a0 with the arm still (sign from the
    # kinematics, refined by two secant steps).
    w0 = float(q[6])
    cands = [w0 + (a1 - a0), w0 - (a1 - a0)]

    def err(w: float) -> float:
        qq = q.copy()
        qq[6] = w
        return _pitch_down(model, qq) - a1

    w1 = min(cands, key=lambda w: abs(err(w)))
    for _ in range(2):
        e, h = err(w1), 1e-4
        d = (err(w1 + h) - e) / h
        if abs(d) > 1e-6:
            w1 -= e / d
    # Beyond the wrist's range the arm makes the rest of the turn (IK below solves the tip's
    # pitch whatever the wrist gives), 5° inside the limit the runtime enforces.
    lo, hi = spec.wrist.pitch_limits
    w1 = min(max(w1, lo + _PITCH_MARGIN), hi - _PITCH_MARGIN)
    n = max(2, math.ceil(max(np.linalg.norm(p1 - p0) / step_m,
                             abs(a1 - a0) / math.radians(1.0))))
    settings = IKSettings(random_seeds=0)
    qs = [q.copy()]
    for k in range(1, n + 1):
        s = k / n
        q_try = qs[-1].copy()
        q_try[6] = w0 + s * (w1 - w0)
        target = tip_target(p0 + s * (p1 - p0), SCOOP_HEADING, a0 + s * (a1 - a0))
        sol = solve_pose_ik(model, "tip", target, q_try, settings, free=6)
        if sol is None:
            raise ScriptError(f"no arm IK solution for the tip at {np.round(target[:3, 3], 3)}"
                              " m with the wrist levelling")
        qs.append(sol)
    Q = np.array(qs)
    vmax = np.concatenate([spec.arm.max_velocity, spec.wrist.max_velocity])
    dq_ds = np.max(np.abs(np.diff(Q, axis=0)) * n, axis=0)  # per unit of path parameter
    # Smoothstep s(τ) = 3τ² − 2τ³ peaks at 1.5/T.
    T = max(float(np.linalg.norm(p1 - p0)) / speed, 1.5 * float(np.max(dq_ds / vmax)), 4 * dt)
    T = math.ceil(T / dt) * dt
    tau = np.linspace(0.0, 1.0, round(T / dt) + 1)
    sv = 3 * tau**2 - 2 * tau**3
    grid = np.linspace(0.0, 1.0, n + 1)
    pos = np.column_stack([np.interp(sv, grid, Q[:, j]) for j in range(Q.shape[1])])
    vel = np.gradient(pos, tau * T, axis=0)
    vel[0] = vel[-1] = 0.0
    return JointTrajectory(tuple(model.joint_names), tau * T, pos, vel)


def _with_wrist(traj: JointTrajectory, model: ArmModel, wrist: np.ndarray) -> JointTrajectory:
    """An arm trajectory as an 8-joint one, the wrist held at ``wrist``."""
    n = len(traj.times)
    return JointTrajectory(tuple(model.joint_names), traj.times,
                           np.column_stack([traj.positions, np.tile(wrist, (n, 1))]),
                           np.column_stack([traj.velocities, np.zeros((n, 2))]))


def _timed(work: Callable[[], JobResult]) -> Callable[[], JobResult]:
    """``work`` that reports its own wall time (``JobResult.wall_s``), measured in the worker
    thread: the planner's time, whatever the simulated clock did meanwhile."""

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
    def __init__(self, world: FeedingWorld) -> None:
        self.world = world
        self.cancelled = False

    def done(self) -> bool:
        return self.cancelled or not self.world.arm_busy

    def result(self) -> JobResult:
        if self.cancelled:
            return JobResult(False, "motion cancelled; the arm holds where it is")
        return JobResult(True, f"arrived (tracking error ≤ "
                               f"{np.degrees(self.world.arm_tracking_error):.2f}°)")

    def cancel(self) -> None:
        if not self.done():
            self.world.stop_arm()
        self.cancelled = True


@dataclasses.dataclass(frozen=True)
class FoodDecision:
    """What :meth:`SimArm.check_food` decided: the trajectory to execute (None when no
    timing is predicted spill-free) and the record of what was done and predicted."""

    trajectory: JointTrajectory | None
    record: dict[str, Any]


def world_load(world: FeedingWorld) -> Any:
    """The load on the world's utensil as the food check models it: its food and the grams
    on the utensil (the physics world's count stands for the weighing the F/T sensor gives
    a real tool), or None for a food whose spill is not modelled (strands) or nothing."""
    from articutool.food.loads import LoadError, food_load

    if not world.food:
        return None
    grams = world.masses_g()["utensil"]
    try:
        return food_load(world.params.definition(world.food), round(grams, 3))
    except LoadError:
        return None


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


class SimArm:
    """The physics world's arm for the feeding tree (see module doc).

    ``load`` gives the load on the utensil when a transport is checked (None: nothing to
    check): a :class:`~articutool.food.loads.FoodLoad` or a callable returning one (the
    protocols and the meal weigh it). ``leveling`` is what the decoupled wrist levels
    against: ``"gravity"`` (its IMU loop) or ``"apparent"`` (slosh-free).
    """

    def __init__(self, world: FeedingWorld, seed: int = 0, rigid: bool = False, load: Any = None,
                 leveling: str = "gravity") -> None:
        if leveling not in ("gravity", "apparent"):
            raise ValueError(f"leveling must be 'gravity' or 'apparent'; got {leveling!r}")
        self.world = world
        self.seed = seed
        self.rigid = rigid
        self.load = load
        self.leveling = leveling
        self.model = ArmModel(world.spec, world.utensil, 8, world.scene)
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plan")
        self._goals: dict[str, np.ndarray] = {}

    def goal_configuration(self, goal: str) -> np.ndarray:
        """Arm joints of a named goal (configurations of the spec, or Staging)."""
        if goal not in self._goals:
            spec = self.world.spec
            if self.rigid and goal in _CARRY_GOALS:
                self._goals[goal] = self.rigid_level_configuration(goal, free=True)
            elif goal in spec.arm.configurations:
                self._goals[goal] = spec.arm.configuration(goal)
            elif goal == "Staging":
                from articutool.arm.ik import staging_configuration

                self._goals[goal] = staging_configuration(spec, self.model, self.seed)[0]
            else:
                raise ValueError(f"goal: unknown goal {goal!r}; known: "
                                 f"{sorted([*spec.arm.configurations, 'Staging'])}")
        return self._goals[goal]

    def rigid_level_configuration(self, goal: str, free: bool = False) -> np.ndarray:
        """For a locked wrist (the rigid baseline): an arm configuration that puts the utensil
        level at ``goal``'s tip position, pointing as close as possible to the way it points
        at ``goal`` (headings tried in 15° steps, IK from the goal and the named
        configurations, collision-free). Raises ``ValueError`` if there is none.

        At the spec's Resting with the Articutool's long tool, only headings near +x and −y
        give a level rigid utensil (measured by IK from 33 starts)."""
        from articutool.arm.ik import solve_level_ik

        spec, wq = self.world.spec, self.world.wrist_q
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
        start = tuple(float(x) for x in self.world.arm_q)
        target = tuple(float(x) for x in self.goal_configuration(goal))
        req = PlanRequest(planner=planner.name, task=TransportTask(0, start, target),
                          timeout_s=budget_s, seed=self.seed, utensil=self.world.utensil,
                          tolerance_deg=planner.tolerance_deg)
        spec = self.world.spec

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
        arm = JointTrajectory(trajectory.joint_names[:6], trajectory.times,
                              trajectory.positions[:, :6], trajectory.velocities[:, :6])
        rep = verify_trajectory(arm, self.model, self.world.spec)
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
        spec, utensil = self.world.spec, self.world.utensil
        try:
            spill_model(spec, utensil, load)
        except LoadError as err:
            return JobResult(False, f"the load cannot be modelled: {err}",
                             FoodDecision(None, {"food": load.food, "load_g": load.grams,
                                                 "error": str(err)}))
        arm = JointTrajectory(trajectory.joint_names[:6], trajectory.times,
                              trajectory.positions[:, :6], trajectory.velocities[:, :6])
        tried: list[dict[str, Any]] = []
        fallback = ""
        for scale in RETIME_SCALES:
            timed = arm if scale == 1.0 else retime(arm, spec.arm.max_velocity,
                                                    spec.arm.max_acceleration, scale)
            if timed is None:
                continue
            if self.rigid:
                wrist: Any = np.asarray(self.world.wrist_q, dtype=float)
                kind, executed = "locked", timed
            else:
                rep = verify_trajectory(timed, self.model, spec)
                if not rep.feasible or rep.wrist_trajectory is None:
                    tried.append({"scale": scale, "infeasible": rep.reason})
                    continue
                wrist, kind, executed = rep.wrist_trajectory, "leveling", timed
                if self.leveling == "apparent":
                    sf = slosh_free_wrist(timed, self.model, spec, utensil,
                                          q_wrist_start=self.world.wrist_q)
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

    def start_plan_path(self, name: str, waypoints: Sequence[TipWaypoint]) -> _FutureJob:
        """Plan the tip's Cartesian path through ``waypoints`` in a worker thread: a joint
        motion to the first, then straight segments (see module doc)."""
        q_now = np.concatenate([self.world.arm_q, self.world.wrist_q])
        q_now[7] = math.remainder(q_now[7], 2 * math.pi)  # a twirl turns the roll whole turns
        pts = [(np.array(w.position), w.pitch_down, w.speed) for w in waypoints]
        spec, joints = self.world.spec, tuple(self.world.layout.arm_joints)

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
                    parts = [_with_wrist(p, self.model, q0[6:]) for p in parts]
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
                            parts.append(_with_wrist(seg6, self.model, q[6:]))
                            q = np.concatenate([seg6.positions[-1], q[6:]])
                        k = j
            except ScriptError as err:
                return JobResult(False, str(err))
            traj = _concatenate(parts)
            return JobResult(True, f"{traj.duration:.1f} s", traj)

        return _FutureJob(self._pool.submit(_timed(work)))

    def start_plan_lift(self, height_m: float) -> _FutureJob:
        """Plan lifting the tool base straight up by ``height_m`` in a worker thread."""
        q_now = np.concatenate([self.world.arm_q, self.world.wrist_q])
        q_now[7] = math.remainder(q_now[7], 2 * math.pi)

        def work() -> JobResult:
            try:
                traj = lift_trajectory(self.model, q_now, height_m)
            except ScriptError as err:
                return JobResult(False, str(err))
            return JobResult(True, f"{traj.duration:.1f} s", traj)

        return _FutureJob(self._pool.submit(_timed(work)))

    def start_execute(self, trajectory: Any) -> _MotionJob:
        """Run the trajectory through the world's arm servos (the caller steps the world)."""
        self.world.follow_arm(trajectory, wait=False)
        return _MotionJob(self.world)

    def stop(self) -> None:
        """Hold the arm where it is."""
        self.world.stop_arm()

    def close(self) -> None:
        """Stop the planning thread."""
        self._pool.shutdown(wait=False, cancel_futures=True)
