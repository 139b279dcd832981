"""Exp. 2a benchmark tasks: level (start, goal) transports from the plate/bowl to the user.

Thesis §5.2.1: a candidate set of (start, goal) transport tasks with level tool orientation
at both ends is filtered down to the tasks that all three planners reach by IK (the "common
IK-filtered set"). Here a candidate is a pair of tool-tip targets in the feeding scene
(docs/hardware.md §2, ``data/scene.toml``):

* start: the tip above the plate or the bowl, level, heading roughly away from the arm base;
* goal: a staging pose in front of the user's mouth, level, the utensil pointing at the user.

Each target is a full tip pose (position + level orientation with a sampled heading). For
every planner the target is solved by closed-loop IK (CLIK, damped least squares on the SE(3)
log error, Pinocchio) from several seeds — the named configurations first, then random ones:

* ``strict6``: the 6-DOF arm with the rigid utensil (wrist locked at 0), tip frame;
* ``strict8``: the 8-DOF arm + wrist, tip frame;
* ``decoupled``: the 6-DOF arm for the tool base F0 (the pose F0 has when the wrist at zero
  puts the tip on target), then a leveling wrist solution inside the wrist limits
  (Eqs. 4.2–4.3) for the F0 orientation the arm reached.

A solution counts when it is within the joint limits, on target, and collision-free (arm,
wrist, utensil vs. themselves and the scene). The stored configuration is the one shared by
the three planners: the 6 arm joints, and for the 8-DOF start/goal the leveling wrist angles
at that arm configuration. Generation is deterministic given the seed; the file records the
seed, the generator version and hashes of the spec and scene it was made with.

The task file itself (its format, loading, checks and saving) is ``bench/taskfile.py``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from articutool.arm.ik import IKSettings, solve_pose_ik
from articutool.arm.model import ArmModel
from articutool.arm.scene import Scene
from articutool.bench.taskfile import (
    TaskSet,
    scene_hash,
    spec_hash,
)
from articutool.planning.types import PLANNERS, TransportTask
from articutool.spec import Spec
from articutool.tool.kinematics import nearest_leveling_solution, tilt_from_vertical

__all__ = ["generate_tasks", "tip_tilt_deg"]

# Candidates per generated set: IK-filtering one takes ~0.1-1 s, so this bounds a run to
# hours (the thesis' set came from 100); a typo such as 1000000000 is refused, not run.
MAX_CANDIDATES = 10_000
_WORLD_UP = np.array([0.0, 0.0, 1.0])


# ----------------------------------------------------------------------- IK --
def tip_tilt_deg(model: ArmModel, q: Sequence[float]) -> float:
    """Angle (deg) between the utensil's up axis (tip frame y, Eq. 4.1) and world up."""
    return float(np.degrees(tilt_from_vertical(model.tip_pose(np.asarray(q, dtype=float))[:3, 1])))


def _level_tip_rotation(heading: float) -> NDArray[np.float64]:
    """Tip orientation with y up and the utensil (tip z) pointing along ``heading`` (rad).

    At zero wrist angles the tip z axis is the roll axis (the utensil's direction), and its
    y axis is the up vector of Eq. 4.1.
    """
    z = np.array([math.cos(heading), math.sin(heading), 0.0])
    y = _WORLD_UP
    return np.column_stack([np.cross(y, z), y, z])


def _wrap_near(q: NDArray[np.float64], ref: NDArray[np.float64], continuous: NDArray[np.bool_],
               lo: NDArray[np.float64], hi: NDArray[np.float64]) -> NDArray[np.float64]:
    """Shift continuous joints by whole turns to lie nearest ``ref`` inside the limits."""
    out = q.copy()
    for i in np.flatnonzero(continuous):
        k = np.round((ref[i] - q[i]) / (2 * np.pi))
        cand = q[i] + 2 * np.pi * np.array([k - 1, k, k + 1])
        cand = cand[(cand >= lo[i]) & (cand <= hi[i])]
        if cand.size:
            out[i] = cand[np.argmin(np.abs(cand - ref[i]))]
    return out


# ----------------------------------------------------------------- regions --
@dataclass(frozen=True)
class _Target:
    position: NDArray[np.float64]
    heading: float

    def pose(self) -> NDArray[np.float64]:
        T = np.eye(4)
        T[:3, :3] = _level_tip_rotation(self.heading)
        T[:3, 3] = self.position
        return T


# Benchmark design (not hardware limits): where the tip starts and ends, relative to the
# scene objects. Start: 6–18 cm above the food's top surface, inside 65 % of its radius, the
# utensil heading along −y or +x within ±20° (pointing radially away from the arm base puts
# the hand over the base: unreachable). Goal: 10–18 cm in front of the face (the head
# sphere's front), ±6 cm sideways, 0–10 cm below the head centre, the utensil pointing
# towards the user: heading 50°–100° (+y is 90°).
_START_HEIGHT = (0.06, 0.18)
_START_RADIUS_FRACTION = 0.65
_START_HEADINGS = (math.radians(-90.0), 0.0)
_START_HEADING_SPREAD = math.radians(20.0)
_GOAL_STANDOFF = (0.10, 0.18)
_GOAL_LATERAL = 0.06
_GOAL_BELOW_HEAD = (0.0, 0.10)
_GOAL_HEADING = (math.radians(50.0), math.radians(100.0))
_FOOD = ("plate", "bowl")
_HEAD = "user_head"


def _sample_start(scene: Scene, rng: np.random.Generator) -> tuple[str, _Target]:
    name = _FOOD[int(rng.integers(len(_FOOD)))]
    obj = scene.get(name)
    r = getattr(obj, "radius", 0.05) * _START_RADIUS_FRACTION * math.sqrt(rng.uniform())
    a = rng.uniform(0.0, 2 * math.pi)
    top = obj.xyz[2] + getattr(obj, "length", 0.0) / 2
    p = np.array([obj.xyz[0] + r * math.cos(a), obj.xyz[1] + r * math.sin(a),
                  top + rng.uniform(*_START_HEIGHT)])
    centre = _START_HEADINGS[int(rng.integers(len(_START_HEADINGS)))]
    heading = centre + rng.uniform(-_START_HEADING_SPREAD, _START_HEADING_SPREAD)
    return name, _Target(p, heading)


def _sample_goal(scene: Scene, rng: np.random.Generator) -> _Target:
    head = scene.get(_HEAD)
    c = np.asarray(head.xyz, dtype=float)
    front = c[1] - getattr(head, "radius", 0.1)
    p = np.array([c[0] + rng.uniform(-_GOAL_LATERAL, _GOAL_LATERAL),
                  front - rng.uniform(*_GOAL_STANDOFF),
                  c[2] - rng.uniform(*_GOAL_BELOW_HEAD)])
    heading = rng.uniform(*_GOAL_HEADING)
    return _Target(p, heading)


# ---------------------------------------------------------------- planners --
@dataclass
class _Models:
    spec: Spec
    m6: ArmModel
    m8: ArmModel
    settings: IKSettings
    continuous: NDArray[np.bool_]
    tip_in_f0: NDArray[np.float64] = field(init=False)

    def __post_init__(self) -> None:
        zero = np.zeros(self.m8.nq)
        self.tip_in_f0 = np.linalg.inv(self.m8.frame_pose(zero, "tool_base")) @ self.m8.tip_pose(
            zero)

    def leveling(self, q_arm: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """Wrist angles that level the tip at ``q_arm`` (nearest to zero), or None."""
        R = self.m6.tool_base_rotations(q_arm)
        q, found = nearest_leveling_solution(R.T @ _WORLD_UP, self.spec.wrist.limits, [0.0, 0.0])
        return q if bool(found) else None

    def solve(self, planner: str, target: _Target, seeds: Sequence[NDArray[np.float64]],
              nearest_to: NDArray[np.float64] | None = None) -> NDArray[np.float64] | None:
        """IK of ``target`` for one planner; returns its configuration (6 or 8 joints).

        Without ``nearest_to`` the first seed that converges wins; with it every seed is
        tried and the arm solution nearest to ``nearest_to`` (whole turns of continuous
        joints ignored) is returned.
        """
        if nearest_to is None:
            return next(self._solutions(planner, target, seeds), None)
        best, dist = None, np.inf
        for q in self._solutions(planner, target, seeds):
            d = self.distance(q, nearest_to)
            if d < dist:
                best, dist = q, d
        return best

    def distance(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
        """Arm joint-space distance, whole turns of continuous joints ignored."""
        d = np.abs(a[:6] - b[:6])
        d = np.where(self.continuous, np.minimum(d % (2 * np.pi), -d % (2 * np.pi)), d)
        return float(np.linalg.norm(d))

    def solve_pair(self, planner: str, start: _Target, goal: _Target,
                   s_seeds: Sequence[NDArray[np.float64]],
                   g_seeds: Sequence[NDArray[np.float64]],
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """Start and goal solutions of one planner, the pair nearest in joint space.

        Start and goal on different IK branches (elbow or wrist flipped) may not connect
        under a level constraint, so every start solution is tried with the goal solution
        nearest to it (the goal seeded from that start first).
        """
        best, dist = None, np.inf
        for qs in _unique(self._solutions(planner, start, s_seeds), self.distance):
            qg = self.solve(planner, goal, [qs[:6], *g_seeds], nearest_to=qs)
            if qg is not None and self.distance(qs, qg) < dist:
                best, dist = (qs, qg), self.distance(qs, qg)
        return best

    def _solutions(self, planner: str, target: _Target,
                   seeds: Sequence[NDArray[np.float64]]) -> Iterator[NDArray[np.float64]]:
        T = target.pose()
        for seed in seeds:
            if planner == "strict6":
                q = solve_pose_ik(self.m6, "tip", T, seed, self.settings)
                if q is not None and not self.m6.in_collision(q):
                    yield q
            elif planner == "strict8":
                q = solve_pose_ik(self.m8, "tip", T, np.concatenate([seed, [0.0, 0.0]]),
                                  self.settings)
                if q is not None and not self.m8.in_collision(q):
                    yield q
            else:  # decoupled: arm IK for F0, then the wrist levels the tip
                T_f0 = T @ np.linalg.inv(self.tip_in_f0)
                q = solve_pose_ik(self.m6, "tool_base", T_f0, seed, self.settings)
                if q is None:
                    continue
                w = self.leveling(q)
                if w is not None and not self.m8.in_collision(np.concatenate([q, w])):
                    yield np.concatenate([q, w])


def _unique(qs: Iterator[NDArray[np.float64]],
            distance: Callable[[NDArray[np.float64], NDArray[np.float64]], float],
            tol: float = 1e-2) -> Iterator[NDArray[np.float64]]:
    seen: list[NDArray[np.float64]] = []
    for q in qs:
        if all(distance(q, p) > tol for p in seen):
            seen.append(q)
            yield q


# ------------------------------------------------------------- generation --
def _round(q: NDArray[np.float64]) -> tuple[float, ...]:
    return tuple(round(float(x), 10) for x in q)


def generate_tasks(
    spec: Spec,
    count: int,
    seed: int,
    scene: Scene | None = None,
    utensil: str = "spoon",
    settings: IKSettings | None = None,
    progress: Callable[[int], None] | None = None,
) -> TaskSet:
    """Sample ``count`` candidate tasks and keep those all three planners reach by IK.

    Deterministic given ``seed`` (NumPy PCG64 stream; Pinocchio IK is deterministic).
    ``progress(k)`` is called after each candidate. Task ids are the candidate indices.
    """
    if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= MAX_CANDIDATES:
        raise ValueError(f"count must be an integer in [1, {MAX_CANDIDATES}]; got {count!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0; got {seed!r}")
    scene = scene if scene is not None else Scene.load()
    settings = settings or IKSettings()
    models = _Models(spec, ArmModel(spec, utensil, 6, scene), ArmModel(spec, utensil, 8, scene),
                     settings, np.array([j.continuous for j in spec.arm.joints]))
    lo, hi = spec.arm.lower, spec.arm.upper
    named = {n: spec.arm.configuration(n) for n in spec.arm.configurations}
    # Seeds: the named configurations first (Home is a level transport pose), then random
    # ones from the task's own stream.
    start_order = [n for n in ("Home", "AbovePlate", "Resting") if n in named]
    goal_order = [n for n in ("Home", "Resting", "AbovePlate") if n in named]
    start_order += [n for n in named if n not in start_order]
    goal_order += [n for n in named if n not in goal_order]
    ref_start = named.get("AbovePlate", np.zeros(6))
    rng = np.random.default_rng(seed)
    rejections = dict.fromkeys(PLANNERS, 0)
    tasks: list[TransportTask] = []
    extras: list[dict[str, Any]] = []
    for k in range(count):
        source, start_t = _sample_start(scene, rng)
        goal_t = _sample_goal(scene, rng)
        rand = [rng.uniform(lo, hi) for _ in range(2 * settings.random_seeds)]
        s_seeds = [named[n] for n in start_order] + rand[: settings.random_seeds]
        g_seeds = [named[n] for n in goal_order] + rand[settings.random_seeds:]
        ok = True
        sol: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
        for planner in PLANNERS:
            pair = models.solve_pair(planner, start_t, goal_t, s_seeds, g_seeds)
            if pair is None:
                rejections[planner] += 1
                ok = False
            else:
                sol[planner] = pair
        if progress is not None:
            progress(k + 1)
        if not ok:
            continue
        # The shared configuration: the rigid tool's (level with the wrist at zero), which the
        # decoupled arm also reaches; the 8-DOF start adds the exact leveling wrist angles.
        qs, qg = sol["strict6"]
        qs = _wrap_near(qs, ref_start, models.continuous, lo, hi)
        qg = _wrap_near(qg, qs, models.continuous, lo, hi)
        ws, wg = models.leveling(qs), models.leveling(qg)
        if ws is None or wg is None:  # cannot happen for a level rigid tool; keep it honest
            rejections["decoupled"] += 1
            continue
        tasks.append(TransportTask(k, _round(qs), _round(qg), _round(ws), _round(wg)))
        extras.append({
            "start_tip": [*_round(start_t.position), round(start_t.heading, 10)],
            "goal_tip": [*_round(goal_t.position), round(goal_t.heading, 10)],
            "source": source,
        })
    return TaskSet(tasks=tuple(tasks), seed=seed, candidates=count,
                   spec_hash=spec_hash(spec), scene_hash=scene_hash(scene), utensil=utensil,
                   ik_rejections=rejections, extras=tuple(extras))
