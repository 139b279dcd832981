"""The three Exp. 2a transport planners (imperative shell over OMPL).

* ``decoupled``: 6-DOF arm in a plain joint space; the loose F0 constraint
  (:class:`~articutool.planning.constraints.LooseConstraint`) and collisions are checked in
  the state validity checker, motions at ``resolution`` rad steps (the loose band is wide,
  so most samples are valid: rejection is cheap here). Collisions are checked *as executed*:
  the 8-DOF model at the arm configuration and the wrist angles that level the tool there
  (Eqs. 4.2–4.3 on the loose reference's branch, a closed form), since the leveling wrist
  swings the utensil by up to ~90° from where a locked wrist would hold it. The path is
  time-parameterised (wrist-aware by default) and verified (Alg. 2); the dense re-check then
  uses the verifier's synchronised wrist trajectory, i.e. exactly what the tool will do. A
  rejected plan is re-planned within the time budget.
* ``strict6`` / ``strict8``: OMPL constrained planning — a ``ProjectedStateSpace`` over the
  6-/8-DOF joint space with a *dead-zone* constraint on the tip tilt
  (:meth:`StrictConstraint.deadzone`: zero inside ±tol, Newton projection onto the band's
  edge outside). Samples are projected into the band and every motion is a chain of projected
  steps ``delta`` rad apart, so the whole path stays inside (``method="projection"``). The
  default, ``method="rejection"``, plans the strict planners like ``decoupled`` (validity
  checker with the tolerance band + fine motion checks): it measured faster and more
  reliable on the benchmark tasks (see :func:`plan_transport`).

Speed (per-phase times in ``PlanResult.phases``, ``benchmarks/plan_breakdown.py``):
RRT-Connect extends at most ``range`` rad in every mode; in rejection mode the straight
start→goal motion is tried first (it is the whole path of most decoupled tasks); paths are
simplified with shortcuts and a few B-spline steps; collisions go through coal's broad phase;
the arm models and toppra's joint-limit constraints are reused across plans; a plan's
linear algebra runs on one BLAS thread (its matrices are a few joints wide, and OpenBLAS's
worker threads, spinning between calls, cost more CPU than they save: docs/planning.md, *One
BLAS thread per plan*). None of this skips a check: every motion still passes the search's
motion check, the dense re-check and, for ``decoupled``, verification.

Every accepted trajectory is checked again after time parameterisation, sampled at most
``check_step`` rad apart (joint limits, collisions, the strict tolerance); a failure counts
as a rejection and triggers a re-plan. Planning uses a band 10 % tighter than the requested
tolerance so the time-parameterised spline stays inside the requested one.

Where it lives: this module is the OMPL part (settings, the model cache, the problem with its
validity checker and constraint, the attempt loop); the kinematic and path queries it
evaluates are ``planning/queries.py``. What remains is one unit on purpose: the OMPL objects
of an attempt are built together after the seed is set (see Determinism), and the problem's
checks, the attempt loop and the re-plan on a rejection share them.

Determinism: OMPL's global seed is reset (``ompl.util.RNG.setSeed``) before every attempt
and all OMPL objects are built afterwards, so a (request, seed) pair replays the same plan
(unless the wall-clock timeout cuts a search at a different point). That seed is one per
process, so the plans of a process run one at a time (:data:`_SEEDED`): two plans in two
threads (two trials in one Dask worker) would otherwise draw from each other's seed. A plan's
wall budget starts once it holds the lock.
"""

from __future__ import annotations

import functools
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou
from threadpoolctl import ThreadpoolController

from articutool.arm.model import TOOL_BASE_FRAME, ArmModel, tip_frame_name
from articutool.arm.scene import default_scene_path
from articutool.planning.constraints import (
    LooseConstraint,
    StrictConstraint,
    tip_axis_tilt_deg,
    tip_tilt_deg,
)
from articutool.planning.queries import (
    ArmQueries,
    dense_times,
    densify,
    path_length,
)
from articutool.planning.timing import time_parameterize, wrist_rate_profile
from articutool.planning.types import PHASES, PlanRequest, PlanResult
from articutool.spec import Spec
from articutool.tool.kinematics import rotation as wrist_rotation
from articutool.trajectory import JointTrajectory
from articutool.verify.verifier import verify_trajectory

__all__ = ["METHODS", "PlannerSettings", "plan_transport"]

METHODS = ("projection", "rejection")
# OMPL's names of the planners (``Planner.getName()``), recorded for a straight motion too.
_ALGORITHM_NAMES = {"rrtconnect": "RRTConnect", "rrtstar": "RRTstar"}
_TWO_PI = 2.0 * math.pi

ou.setLogLevel(ou.LOG_NONE)  # OMPL's console chatter (reseeding notices) is not ours to show


@dataclass(frozen=True)
class PlannerSettings:
    """Tuning knobs (not part of the request; defaults chosen by measurement)."""

    # rad, motion check step during the search. 0.04 halves the decoupled median against 0.02
    # (first 30 benchmark tasks: 50 vs 80 ms, both 30/30); the rare motion it misses is caught
    # by the dense re-check of the timed trajectory (check_step) and re-planned.
    resolution: float = 0.04
    delta: float = 0.03  # rad, projected-space step (ProjectedStateSpace.setDelta)
    check_step: float = 0.025  # rad, final dense check of the time-parameterised trajectory
    plan_margin: float = 0.9  # strict: plan inside tol * plan_margin
    # rad, RRT-Connect's extension range, in every mode. OMPL's automatic range (0.2 x the
    # space's extent, ~5.2 rad with +-2pi joints) makes 96-98 % of strict motions leave the
    # band; 1 rad measured strict6 0.17x / strict8 0.094x the time, decoupled 0.92x (paired
    # medians, first 20 tasks). range_everywhere=False: projected spaces only.
    range: float = 1.0
    range_everywhere: bool = True
    # Accept the straight start->goal motion when it passes the search's own motion check
    # (rejection mode; projected motions are not straight): most decoupled tasks are one
    # straight motion, which then needs no search or simplification (decoupled 0.54x).
    try_direct: bool = True
    # "shortcut": reduceVertices + partialShortcutPath + bspline_steps of B-spline smoothing;
    # "full": OMPL's simplifySolution (iterated, time-capped); "rope": reduceVertices +
    # ropeShortcutPath. Shortcuts + 5 smoothing steps measured 0.84-0.94x the plan time of
    # "full" with 10-13 % shorter strict trajectories; shortcuts alone 0.59-0.67x but 19 %
    # longer trajectories (sharp corners slow toppra down); "rope" has a heavy time tail.
    simplify: str = "shortcut"
    bspline_steps: int = 5
    wrist_velocity_margin: float = 0.95  # wrist-aware timing uses this fraction of the limit
    simplify_time: float = 0.2  # s, cap on path simplification per attempt
    broadphase: bool = True  # ArmModel.broadphase (coal's AABB tree) instead of the pair loop
    # rad of joint-space arc between toppra grid points. 0.02 measured 0.81-0.84x the plan
    # time of 0.01 with trajectory durations +0-1.3 % (median; max +2.7 %); 0.03: max +7.7 %.
    toppra_grid: float = 0.02
    cache_models: bool = True  # reuse this thread's arm models (and scene) across plans


def _fail(req: PlanRequest, t0: float, attempts: int, rejections: int, msg: str,
          phases: dict[str, float], verified: bool | None = None) -> PlanResult:
    return PlanResult(req.planner, req.task.task_id, False, time.perf_counter() - t0, attempts,
                      rejections, math.nan, math.nan, verified, msg, None, None,
                      phases=phases)


class _Phases(dict):
    """Wall time per phase (``PHASES``), summed over attempts."""

    def __init__(self) -> None:
        super().__init__(dict.fromkeys(PHASES, 0.0))
        self._t = time.perf_counter()

    def lap(self, phase: str) -> None:
        """Charge the time since the previous lap to ``phase``."""
        now = time.perf_counter()
        self[phase] += now - self._t
        self._t = now


class _DeadzoneConstraint(ob.Constraint):
    """OMPL constraint ``f(q) = deadzone(tip tilt)`` (2 rows) with the analytic Jacobian."""

    def __init__(self, kin: ArmQueries, strict: StrictConstraint) -> None:
        super().__init__(kin.n, 2)
        self.kin, self.strict = kin, strict
        self._b = strict.bound

    # Scalar forms of StrictConstraint.deadzone / deadzone_jacobian: OMPL calls these tens
    # of thousands of times per query, so NumPy call overhead dominates otherwise.
    def function(self, x, out) -> None:
        w0, _, w2 = self.kin.rotation(np.asarray(x, dtype=np.float64))[2].tolist()
        b = self._b
        out[0] = math.copysign(max(abs(w2) - b, 0.0), w2)
        out[1] = math.copysign(max(abs(w0) - b, 0.0), w0)

    def jacobian(self, x, out) -> None:
        R, Jw = self.kin.rotation_and_jacobian(np.asarray(x, dtype=np.float64))
        out[:, :] = self.strict.deadzone_jacobian(R, Jw)


_SEEDED = threading.Lock()  # OMPL's seed is process-global: one seeded plan at a time
_models = threading.local()  # per thread: a model's data buffers are written by every query


def _arm_model(spec: Spec, utensil: str, dof: int, cached: bool) -> ArmModel:
    """The arm model (with the default scene) for ``(spec, utensil, dof)``.

    Cached per thread and rebuilt when the scene file changes (its mtime), since building the
    models and scene costs ~6 ms of a ~20 ms decoupled plan.
    """
    if not cached:
        return ArmModel(spec, utensil=utensil, dof=dof)
    try:
        stamp = default_scene_path().stat().st_mtime_ns
    except OSError:
        stamp = None
    cache: dict = _models.__dict__.setdefault("cache", {})
    key = (id(spec), utensil, dof, stamp)
    hit = cache.get(key)
    if hit is not None and hit[0] is spec:
        return hit[1]
    if len(cache) >= 8:
        cache.clear()
    model = ArmModel(spec, utensil=utensil, dof=dof)
    cache[key] = (spec, model)  # holding the spec keeps its id from being reused
    return model


@dataclass
class _Problem:
    """Everything one request needs: model, checkers, start/goal, final checks."""

    req: PlanRequest
    spec: Spec
    settings: PlannerSettings
    method: str

    def __post_init__(self) -> None:
        req, spec = self.req, self.spec
        self.strict8 = req.planner == "strict8"
        self.algorithm_name = _ALGORITHM_NAMES[req.algorithm]
        dof = 8 if self.strict8 else 6
        cached = self.settings.cache_models
        self.model = _arm_model(spec, req.utensil, dof, cached)
        task = req.task
        wrist_s = list(task.start_wrist) if self.strict8 else []
        wrist_g = list(task.goal_wrist) if self.strict8 else []
        self.start = np.array(list(task.start) + wrist_s, dtype=np.float64)
        self.goal = np.array(list(task.goal) + wrist_g, dtype=np.float64)
        pl = spec.planning
        bp = self.settings.broadphase
        self.executed: ArmQueries | None = None  # decoupled: the 8-DOF model the tool executes
        if req.planner == "decoupled":
            self.kin = ArmQueries(self.model, TOOL_BASE_FRAME, bp)
            self.executed = ArmQueries(_arm_model(spec, req.utensil, 8, cached),
                                       TOOL_BASE_FRAME, bp)
            self.loose = LooseConstraint.from_start(
                self.kin.rotation(self.start), task.start_wrist,
                math.radians(pl.loose_pitch_deg), math.radians(pl.loose_roll_deg),
                spec.wrist.pitch_limits)
            self.strict = None
            self.band = None
            self._q_executed = np.zeros(8)
        else:
            self.kin = ArmQueries(self.model, tip_frame_name(req.utensil), bp)
            tol = math.radians(req.tolerance_deg if req.tolerance_deg is not None
                               else pl.strict_tolerance_deg)
            self.strict = StrictConstraint(tol)
            # Plan in a tighter band, widened if an endpoint already sits outside it.
            ends = max(float(tip_axis_tilt_deg(self.kin.rotation(q)))
                       for q in (self.start, self.goal))
            self.band = StrictConstraint(min(max(tol * self.settings.plan_margin,
                                                 math.radians(ends) + 1e-6), tol))
            self.loose = None
            self._band_bound = self.band.bound + 1e-6

    # -------------------------------------------------------------- state checks --
    def leveling_wrist(self, q: NDArray[np.float64]) -> tuple[float, float] | None:
        """Decoupled: the wrist angles that level the tool at arm configuration ``q``
        (Eqs. 4.2–4.3 on the loose reference's branch, continuous about the reference), or
        ``None`` outside the loose constraint (its band, or past the wrist's pitch stop).

        Scalar fast path of ``LooseConstraint.satisfied``: called for every checked state,
        plain ``math`` on three numbers is ~10× cheaper than the vectorised NumPy form (which
        the final trajectory check uses).
        """
        assert self.loose is not None
        u0, u1, u2 = self.kin.rotation(q)[2].tolist()  # Rᵀ ẑ
        c = self.loose
        p, r = math.atan2(u2, u0), math.asin(min(1.0, max(-1.0, u1)))
        if c.branch:
            p, r = p + math.pi, math.pi - r
        dp = (p - c.reference[0] + math.pi) % _TWO_PI - math.pi
        dr = (r - c.reference[1] + math.pi) % _TWO_PI - math.pi
        p = c.reference[0] + dp
        if abs(dp) <= c.pitch_tol and abs(dr) <= c.roll_tol and (
                c.pitch_limits[0] <= p <= c.pitch_limits[1]):
            return p, c.reference[1] + dr
        return None

    def constraint_ok(self, q: NDArray[np.float64]) -> bool:
        """Scalar fast path of ``LooseConstraint.satisfied`` / ``StrictConstraint.satisfied``."""
        if self.loose is not None:
            return self.leveling_wrist(q) is not None
        u0, u1, u2 = self.kin.rotation(q)[2].tolist()  # Rᵀ ẑ
        b = self._band_bound
        return u1 > 0.0 and abs(u0) <= b and abs(u2) <= b

    def valid(self, q: NDArray[np.float64]) -> bool:
        if self.executed is not None:  # decoupled: collide the arm with the leveling wrist
            w = self.leveling_wrist(q)
            if w is None:
                return False
            x = self._q_executed  # reused: np.append cost as much as the leveling itself
            x[:6] = q
            x[6], x[7] = w
            return not self.executed.collides(x)
        return self.constraint_ok(q) and not self.kin.collides(q)

    def state_space(self) -> ob.RealVectorStateSpace:
        """OMPL's joint space of this problem, bounded by the arm's joint limits."""
        n = self.kin.n
        space = ob.RealVectorStateSpace(n)
        bounds = ob.RealVectorBounds(n)
        for i in range(n):
            bounds.setLow(i, float(self.kin.lo[i]))
            bounds.setHigh(i, float(self.kin.hi[i]))
        space.setBounds(bounds)
        return space

    def straight_motion_valid(self) -> bool:
        """Whether the straight start→goal motion passes the search's motion check: the
        states OMPL's ``DiscreteMotionValidator`` checks on it (the goal, and the start→goal
        segment cut into ``ceil(|goal − start| / resolution)`` equal steps), each by
        :meth:`valid`, with the constraint evaluated for all of them at once."""
        a, b = self.start, self.goal
        lo, hi = self.kin.lo, self.kin.hi
        # OMPL's arithmetic: the space's extent, its longest valid segment, the distance.
        extent = math.sqrt(sum((h - l_) * (h - l_) for l_, h in zip(lo.tolist(), hi.tolist(),
                                                                   strict=True)))
        segment = extent * (self.settings.resolution / extent)
        dist = math.sqrt(sum((x - y) * (x - y) for x, y in zip(a.tolist(), b.tolist(),
                                                               strict=True)))
        nd = max(math.ceil(dist / segment), 1)  # start = goal: OMPL checks the goal alone
        f = np.arange(1, nd + 1, dtype=np.float64) / nd
        q = a + (b - a) * f[:, None]
        q[-1] = b
        if self.loose is not None:
            R = self.model.tool_base_rotations(q)
            if not self.loose.satisfied(R).all():
                return False
            w = np.asarray(self.loose.reference) + self.loose.deviation(R)
            assert self.executed is not None
            return self.executed.first_collision(np.hstack([q, w])) is None
        u = self.tip_rotations(q)[:, 2, :]  # Rᵀ ẑ per state
        b_ = self._band_bound
        if not ((u[:, 1] > 0.0) & (np.abs(u[:, 0]) <= b_) & (np.abs(u[:, 2]) <= b_)).all():
            return False
        return self.kin.first_collision(q) is None

    def valid_bounded(self, q: NDArray[np.float64]) -> bool:
        # Projection can push a state past the joint limits; plain samplers cannot.
        return self.kin.in_bounds(q) and self.valid(q)

    def endpoint_problem(self) -> str | None:
        """Why the start or the goal cannot be planned from/to (``None`` when both are fine)."""
        for name, q in (("start", self.start), ("goal", self.goal)):
            if not self.kin.in_bounds(q):
                return (f"{name} is outside the joint limits "
                        f"[{np.array2string(self.kin.lo, precision=3)}, "
                        f"{np.array2string(self.kin.hi, precision=3)}] rad")
            model, qc = self.model, q
            w = self.leveling_wrist(q) if self.loose is not None else None
            if w is not None:  # decoupled: as executed, with the leveling wrist
                model, qc = self.executed.arm, np.append(q, w)
            if model.in_collision(qc):
                pairs = model.colliding_pairs(qc)[:3]
                return f"{name} is in collision ({', '.join('/'.join(p) for p in pairs)})"
            if not self.constraint_ok(q):
                R = self.kin.rotation(q)
                if self.loose is not None:
                    dev = np.degrees(self.loose.deviation(R))
                    lo, hi = np.degrees(self.loose.pitch_limits)
                    pitch = math.degrees(self.loose.reference[0]) + dev[0]
                    return (f"{name} violates the loose tool-base constraint: pitch/roll "
                            f"deviation {dev[0]:.1f}°/{dev[1]:.1f}° from the start's level "
                            f"reference (allowed ±{self.spec.planning.loose_pitch_deg:g}°/"
                            f"±{self.spec.planning.loose_roll_deg:g}°), leveling pitch "
                            f"{pitch:.1f}° (the wrist reaches [{lo:g}°, {hi:g}°])")
                assert self.strict is not None
                return (f"{name} tip pitch/roll {float(tip_axis_tilt_deg(R)):.1f}° exceeds "
                        f"±{math.degrees(self.strict.tol):g}°")
        return None

    # ------------------------------------------------------------------- OMPL --
    def solve(self, seed: int, budget: float,
              phases: _Phases) -> tuple[NDArray[np.float64] | None, str]:
        """One OMPL query; dense waypoints (N, n) of the simplified path, or a reason."""
        n, st = self.kin.n, self.settings
        projected = self.strict is not None and self.method == "projection"
        if st.try_direct and not projected and self.straight_motion_valid():
            # The straight motion is valid: nothing to set up, search or simplify.
            phases.lap("search")
            return densify(np.stack([self.start, self.goal]), st.resolution), ""
        ou.RNG.setSeed(seed)  # before any OMPL object is built: their RNGs draw from it
        space = self.state_space()
        valid = self.valid_bounded if projected else self.valid

        buf = np.empty(n)  # valid() reads the state and keeps none of it

        def checker(s) -> bool:
            for i in range(n):
                buf[i] = s[i]
            return valid(buf)

        keep: list[object] = [checker]
        if projected:
            assert self.band is not None
            con = _DeadzoneConstraint(self.kin, self.band)
            css = ob.ProjectedStateSpace(space, con)
            css.setDelta(st.delta)
            si = ob.ConstrainedSpaceInformation(css)
            ss = og.SimpleSetup(si)
            keep += [con, css]
            state_space = css
        else:
            ss = og.SimpleSetup(space)
            si = ss.getSpaceInformation()
            state_space = space
        ss.setStateValidityChecker(checker)
        if not projected:
            si.setStateValidityCheckingResolution(st.resolution / space.getMaximumExtent())
        a, b = state_space.allocState(), state_space.allocState()
        if projected:
            a.copy(self.start.tolist())
            b.copy(self.goal.tolist())
        else:
            for i in range(n):
                a[i], b[i] = float(self.start[i]), float(self.goal[i])
        ss.setStartAndGoalStates(a, b)
        algorithm = og.RRTstar(si) if self.req.algorithm == "rrtstar" else og.RRTConnect(si)
        self.algorithm_name = algorithm.getName()
        if projected or (st.range_everywhere and self.req.algorithm == "rrtconnect"):
            algorithm.setRange(st.range)
        ss.setPlanner(algorithm)
        ss.setup()
        phases.lap("setup")
        t_start = time.perf_counter()
        if self.req.algorithm == "rrtstar":
            # RRT* refines until the budget ends or it has refined for as long as it took to
            # find the first solution (bounded anytime behaviour, so benchmarks finish).
            pdef = ss.getProblemDefinition()
            first: list[float] = []

            def stop() -> bool:
                now = time.perf_counter()
                if not first and pdef.hasExactSolution():
                    first.append(now - t_start)
                return now - t_start >= budget or (bool(first) and now - t_start >= 2 * first[0])

            status = ss.solve(ob.PlannerTerminationCondition(stop))
        else:
            status = ss.solve(budget)
        phases.lap("search")
        if not ss.haveExactSolutionPath():
            return None, f"no path found within {budget:.3g} s ({status.asString()})"
        remaining = budget - (time.perf_counter() - t_start)
        if remaining > 0 and st.simplify == "full":
            ss.simplifySolution(min(remaining, st.simplify_time))
        path = ss.getSolutionPath()
        if remaining > 0 and st.simplify in ("shortcut", "rope"):
            simplifier = og.PathSimplifier(si)
            simplifier.reduceVertices(path)
            if st.simplify == "rope":
                simplifier.ropeShortcutPath(path)
            else:
                simplifier.partialShortcutPath(path)
                if st.bspline_steps:
                    simplifier.smoothBSpline(path, st.bspline_steps)
        path.interpolate()
        states = path.getStates()
        q = np.array([[s[i] for i in range(n)] for s in states])
        del keep
        out = densify(q, st.resolution)
        phases.lap("simplify")
        return out, ""

    # ------------------------------------------------------------ final checks --
    def tip_rotations(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        """Tip rotations along (N, nq) samples, vectorised (F0 chain × wrist, hw-facts §3)."""
        R0 = self.model.tool_base_rotations(q[:, :6])
        qw = q[:, 6:8] if self.strict8 else np.zeros((q.shape[0], 2))
        return R0 @ wrist_rotation(qw)

    def check_trajectory(
        self, traj: JointTrajectory, wrist: JointTrajectory | None = None
    ) -> str | None:
        """Dense check of the executed trajectory: limits, tolerance, collisions.

        ``wrist`` (decoupled): the verifier's synchronised leveling trajectory; collisions
        are then checked on the 8-DOF model with the wrist where it will be.
        """
        t = dense_times(traj, self.settings.check_step)
        q, _ = traj.sample(t)
        lo, hi = self.kin.lo, self.kin.hi
        out = np.flatnonzero(((q < lo - 1e-9) | (q > hi + 1e-9)).any(axis=1))
        if out.size:
            return f"t = {t[out[0]]:.3f} s: joint limit exceeded"
        if self.strict is not None:
            ok = self.strict.satisfied(self.tip_rotations(q))
            if not ok.all():
                k = int(np.flatnonzero(~ok)[0])
                return f"t = {t[k]:.3f} s: tip tilt exceeds the tolerance"
        elif self.loose is not None:
            ok = self.loose.satisfied(self.model.tool_base_rotations(q))
            if not ok.all():
                k = int(np.flatnonzero(~ok)[0])
                return f"t = {t[k]:.3f} s: tool base leaves the loose constraint"
        kin = self.kin
        if wrist is not None:
            assert self.executed is not None
            kin = self.executed
            q = np.hstack([q, wrist.sample(t)[0]])
        k = kin.first_collision(q)
        if k is not None:
            pairs = kin.arm.colliding_pairs(q[k])[:3]
            return f"t = {t[k]:.3f} s: collision ({', '.join('/'.join(p) for p in pairs)})"
        return None

    def sdot_limit(self) -> Callable[[NDArray[np.float64], NDArray[np.float64]],
                                     NDArray[np.float64]]:
        """Largest path speed the wrist can follow at each grid point (wrist-aware timing)."""
        spec = self.spec
        vmax = spec.wrist.velocity_limits * self.settings.wrist_velocity_margin
        kinematics = self.model.tool_base_kinematics

        def sdot_max(q: NDArray[np.float64], dq: NDArray[np.float64]) -> NDArray[np.float64]:
            A = wrist_rate_profile(q, dq, kinematics, spec.controller.pinv_rcond)
            ratio = (np.abs(A) / vmax).max(axis=1)
            return np.divide(1.0, ratio, out=np.full(ratio.shape, np.inf), where=ratio > 1e-12)

        return sdot_max


def _seed(seed: int, attempt: int) -> int:
    # OMPL seeds must be positive 32-bit; distinct per (seed, attempt).
    return (seed * 1009 + attempt) % 2_147_483_646 + 1


def plan_transport(
    request: PlanRequest, spec: Spec, *, method: str = "rejection",
    settings: PlannerSettings | None = None,
) -> PlanResult:
    """Plan one (validated) request; see :func:`articutool.planning.api.plan`.

    ``method`` selects the strict planners' constraint handling: ``"rejection"`` (validity
    checker + motion checks every ``resolution`` rad; the default because it measured best:
    first 10 tasks of transport_tasks_v1, 20 s: strict6 100 % / median 0.36 s, strict8 100 % /
    1.65 s) or ``"projection"`` (OMPL ProjectedStateSpace with the dead-zone constraint:
    strict6 40 % / 6.0 s, strict8 70 % / 1.5 s on the same tasks).
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}; got {method!r}")
    with _SEEDED, _blas().limit(limits=1, user_api="blas"):
        return _plan_seeded(request, spec, method, settings)


@functools.cache
def _blas() -> ThreadpoolController:
    """The process's BLAS thread pools (NumPy's and SciPy's OpenBLAS, loaded by now)."""
    return ThreadpoolController()


def _plan_seeded(request: PlanRequest, spec: Spec, method: str,
                 settings: PlannerSettings | None) -> PlanResult:
    t0 = time.perf_counter()
    phases = _Phases()
    req = request
    deadline = t0 + req.timeout_s
    prob = _Problem(req, spec, settings or PlannerSettings(), method)
    bad = prob.endpoint_problem()
    phases.lap("setup")
    if bad is not None:
        return _fail(req, t0, 0, 0, f"invalid task: {bad}", phases)
    arm = spec.arm
    vmax, amax = prob.model.velocity_limits, arm.max_acceleration
    if prob.strict8:
        # The wrist's acceleration is not in the spec; bound it like the arm's fastest joint.
        amax = np.concatenate([amax, np.full(2, amax.max())])
    names = tuple(prob.model.joint_names)
    attempts = rejections = 0
    last = "timeout before the first attempt"
    while True:
        remaining = deadline - time.perf_counter()
        if remaining <= 0:
            break
        attempts += 1
        phases.lap("setup")
        waypoints, why = prob.solve(_seed(req.seed, attempts), remaining, phases)
        if waypoints is None:
            last = why
            break
        sdot = (prob.sdot_limit() if req.planner == "decoupled" and req.wrist_aware_timing
                else None)
        traj = time_parameterize(waypoints, names, vmax, amax, sdot_max=sdot,
                                 grid_step=prob.settings.toppra_grid)
        phases.lap("timing")
        # A failed time parameterisation or dense re-check (the search checks motions at
        # ``resolution``; the final check is finer) is a replan, not a verifier rejection.
        if traj is None:
            last = "time parameterisation failed"
            continue
        length = path_length(waypoints)
        if req.planner != "decoupled":
            problem = prob.check_trajectory(traj)
            phases.lap("recheck")
            if problem is not None:
                last = f"trajectory check failed: {problem}"
                continue
            q, _ = traj.sample(dense_times(traj, prob.settings.check_step))
            tilt = float(tip_tilt_deg(prob.tip_rotations(q)).max())
            phases.lap("recheck")
            return PlanResult(req.planner, req.task.task_id, True, time.perf_counter() - t0,
                              attempts, rejections, length, tilt, None,
                              f"planned in {attempts} attempt(s)", traj, None,
                              prob.algorithm_name, phases)
        rep = verify_trajectory(traj, prob.model, spec, q_wrist_start=req.task.start_wrist)
        phases.lap("verify")
        if not rep.feasible:
            rejections += 1
            last = f"verification rejected the plan: {rep.reason}: {rep.message}"
            continue
        wt = rep.wrist_trajectory
        assert wt is not None
        problem = prob.check_trajectory(traj, wrist=wt)
        phases.lap("recheck")
        if problem is not None:
            last = f"trajectory check failed: {problem}"
            continue
        q_arm, _ = traj.sample(wt.times)
        tilt_R = prob.model.tool_base_rotations(q_arm) @ wrist_rotation(wt.positions)
        tilt = float(tip_tilt_deg(tilt_R).max())
        phases.lap("verify")
        return PlanResult(req.planner, req.task.task_id, True, time.perf_counter() - t0,
                          attempts, rejections, length, tilt, True,
                          f"planned and verified in {attempts} attempt(s); "
                          f"velocity margin {rep.velocity_margin:.3f}", traj, wt,
                          prob.algorithm_name, phases)
    verified = False if req.planner == "decoupled" and rejections else None
    return _fail(req, t0, attempts, rejections, f"failed after {attempts} attempt(s): {last}",
                 phases, verified)
