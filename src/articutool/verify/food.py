"""Food-aware verification: what a transport does to the load on the utensil, and a wrist
trajectory that keeps the dish square to the apparent gravity.

The dish's pose along a motion comes from the arm's trajectory (F0 by the vectorised forward
kinematics of :meth:`articutool.arm.model.ArmModel.tool_base_poses`) and the wrist's (the
pitch/roll chain of ``spec.wrist``: pitch about F0's −y through ``pitch_z``, roll about z
``roll_dz`` further, the utensil ``utensil_mount_dz`` further; the dish of
:func:`~articutool.food.dish.spoon_dish` in the roll link). On a uniform grid the load's
centroid is differentiated twice for its acceleration, and the apparent gravity ``Rᵀ(g − a)``
drives the load's model (:func:`~articutool.food.loads.load_model`).

:func:`slosh_free_wrist` levels against the apparent gravity instead of gravity: the dish
normal follows ``−(g − a(t))`` of the planned motion, the acceleration smoothed by a
zero-phase Gaussian of ``σ`` (a TOPP-RA trajectory's acceleration jumps, which no wrist can
follow; the residual's spectrum at the slosh frequency ω is ``1 − exp(−ω²σ²/2)`` of the
unsmoothed one). The arm holds ``3σ`` before and after its motion while the wrist turns into
and out of the motion. The trajectory passes the tool's own validation
(:meth:`~articutool.tool.following.TrajectoryFollower.prevalidate`: limits, rates along the
spline) or is not used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.food.dish import spoon_dish
from articutool.food.loads import FoodLoad, load_model
from articutool.food.pile import PileModel
from articutool.food.slosh import (
    STANDARD_GRAVITY,
    SloshModel,
    SloshPrediction,
    _second_differences,
    apparent_gravity,
)
from articutool.spec import Spec
from articutool.trajectory import JointTrajectory, TrajectoryError

__all__ = ["FoodCheckReport", "PoseModel", "SloshFreeResult", "dish_poses", "food_check",
           "predict_transport", "slosh_free_wrist", "spill_model"]

SPILL_G = 0.001  # g: below the capacity table's resolution a prediction counts as no spill
# The food check's grid: 8 ms resolves the 2–4 Hz slosh modes (ω·dt ≤ 0.2, exact
# first-order-hold discretisation) and the arm's accelerations, at half the cost of 4 ms.
CHECK_DT_S = 0.008
_CONVERGED_RAD = math.radians(0.5)  # the slosh-free wrist's last two passes agree within this
# The slosh-free wrist's smoothing (Gaussian σ, s), tried in turn. It starts at 80 ms, not at
# what the tool's validation would accept: the check verifies the planned wrist, and the wrist
# follows a σ 30 ms plan (up to 43 rad/s² of turning) 20-40 ms late and up to 3.4° off it,
# 1.6° at 50 ms and 1.0° at 80 ms (docs/planning.md): errors in the band of the dish's slosh
# modes (3-4 Hz for 8 g) that the liquid answers and the plan does not contain.
SLOSH_FREE_SIGMAS_S = (0.08, 0.12)


class PoseModel(Protocol):
    """What the food check needs of an arm model (``ArmModel`` provides it)."""

    def tool_base_poses(self, q_arm: ArrayLike
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(..., 6) → rotations (..., 3, 3) and origins (..., 3) of F0 in the base frame."""
        ...


def spill_model(spec: Spec, utensil: str, load: FoodLoad, *, dt: float = CHECK_DT_S,
                tail_s: float = 1.0) -> SloshModel | PileModel:
    """The load's model on ``utensil`` (:class:`LoadError` if it cannot be modelled)."""
    u = spec.utensil(utensil)
    dish = spoon_dish(u) if u.physics.kind == "spoon" else None
    return load_model(dish, load, utensil, dt=dt, tail_s=tail_s)


def _centroid_height(model: SloshModel | PileModel) -> float:
    if isinstance(model, SloshModel):
        return 0.5 * model.fill_height
    return 0.5 * model.dish.depth


def dish_poses(spec: Spec, utensil: str, R0: NDArray[np.float64], p0: NDArray[np.float64],
               q_wrist: NDArray[np.float64], height: float = 0.0
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rotations world ← dish (N, 3, 3) and positions (N, 3) of the point ``height`` above the
    dish floor's centre, from F0's poses ``R0, p0`` and the wrist's ``q_wrist`` (N, 2)."""
    w, u = spec.wrist, spec.utensil(utensil)
    zc = spoon_dish(u).zc if u.physics.kind == "spoon" else u.tip_z
    cp, sp = np.cos(q_wrist[:, 0]), np.sin(q_wrist[:, 0])
    cr, sr = np.cos(q_wrist[:, 1]), np.sin(q_wrist[:, 1])
    n = q_wrist.shape[0]
    R_roll = np.empty((n, 3, 3))  # F0 ← roll link: R_y(−θp) R_z(θr)
    R_roll[:, 0, 0], R_roll[:, 0, 1], R_roll[:, 0, 2] = cp * cr, -cp * sr, -sp
    R_roll[:, 1, 0], R_roll[:, 1, 1], R_roll[:, 1, 2] = sr, cr, 0.0
    R_roll[:, 2, 0], R_roll[:, 2, 1], R_roll[:, 2, 2] = sp * cr, -sp * sr, cp
    x, z = u.tip_x + height, w.utensil_mount_dz + zc  # the point in the roll link (y = 0)
    in_f0 = np.empty((n, 3))  # pitch axis + R_y(−θp)·(0, 0, roll_dz) + R_roll·point
    in_f0[:, 0] = -sp * w.roll_dz + R_roll[:, 0, 0] * x + R_roll[:, 0, 2] * z
    in_f0[:, 1] = R_roll[:, 1, 0] * x
    in_f0[:, 2] = w.pitch_z + cp * w.roll_dz + R_roll[:, 2, 0] * x + R_roll[:, 2, 2] * z
    R = np.einsum("kij,kjl->kil", R0, R_roll)
    return R, p0 + np.einsum("kij,kj->ki", R0, in_f0)


def _wrist_samples(wrist: JointTrajectory | ArrayLike, t: NDArray[np.float64],
                   spec: Spec) -> NDArray[np.float64]:
    if isinstance(wrist, JointTrajectory):
        return wrist.reordered(list(spec.wrist.joint_names)).sample(t)[0]
    q = np.asarray(wrist, dtype=float)
    if q.shape != (2,) or not np.all(np.isfinite(q)):
        raise TrajectoryError("the wrist is a trajectory or two finite angles [pitch, roll]")
    return np.tile(q, (t.size, 1))


def _arm_part(traj: JointTrajectory, spec: Spec) -> JointTrajectory:
    """The arm's six joints of ``traj`` (which may carry the wrist's too), in spec order."""
    names = list(spec.arm.joint_names)
    missing = [n for n in names if n not in traj.joint_names]
    if missing:
        raise TrajectoryError(f"the trajectory lacks the arm joints {missing}")
    idx = [traj.joint_names.index(n) for n in names]
    return JointTrajectory(tuple(names), traj.times, traj.positions[:, idx],
                           traj.velocities[:, idx])


def predict_transport(arm: JointTrajectory, wrist: JointTrajectory | ArrayLike,
                      model: PoseModel, spec: Spec, utensil: str,
                      load_model_: SloshModel | PileModel) -> SloshPrediction:
    """What the load does along the arm trajectory ``arm`` (its six joints) with the wrist
    following ``wrist`` (a trajectory on the same clock, or held at two angles)."""
    arm6 = _arm_part(arm, spec)
    dt = load_model_.dt
    n = max(math.ceil((arm6.times[-1] - arm6.times[0]) / dt - 1e-9), 1) + 1
    t = arm6.times[0] + dt * np.arange(n)
    q = arm6.sample(t)[0]
    R0, p0 = model.tool_base_poses(q)
    R, p = dish_poses(spec, utensil, R0, p0, _wrist_samples(wrist, t, spec),
                      _centroid_height(load_model_))
    return load_model_.predict(t, apparent_gravity(t, p, R))


@dataclass(frozen=True)
class FoodCheckReport:
    """The food check of one transport: the load, its model's parameters, the wrist motion
    assumed (``"leveling"``, ``"locked"``, ``"slosh_free"``) and the prediction."""

    load: FoodLoad
    wrist: str
    model: dict[str, Any]
    prediction: SloshPrediction = field(repr=False)

    @property
    def spills(self) -> bool:
        """Whether the load is predicted to lose anything (≥ :data:`SPILL_G`)."""
        return self.prediction.spilled_g >= SPILL_G

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: every figure of the prediction."""
        return {"load": self.load.to_dict(), "wrist": self.wrist, "model": self.model,
                **self.prediction.summary(), "spill_free": not self.spills}


def food_check(arm: JointTrajectory, wrist: JointTrajectory | ArrayLike, model: PoseModel,
               spec: Spec, utensil: str, load: FoodLoad, wrist_kind: str = "leveling"
               ) -> FoodCheckReport:
    """:func:`predict_transport` with the load's model, as a report."""
    m = spill_model(spec, utensil, load)
    return FoodCheckReport(load, wrist_kind, m.summary(),
                      predict_transport(arm, wrist, model, spec, utensil, m))


# --------------------------------------------------------------- slosh-free leveling --
@dataclass(frozen=True)
class SloshFreeResult:
    """A slosh-free wrist trajectory and the arm trajectory padded to go with it (both on
    one clock), or ``None`` with the reason. ``sigma_s``: the acceleration smoothing used."""

    arm: JointTrajectory | None
    wrist: JointTrajectory | None
    sigma_s: float
    message: str

    @property
    def ok(self) -> bool:
        """Whether a trajectory passed the tool's validation."""
        return self.wrist is not None

    def combined(self) -> JointTrajectory:
        """The arm's and the wrist's joints as one trajectory (for execution)."""
        assert self.arm is not None and self.wrist is not None
        return JointTrajectory((*self.arm.joint_names, *self.wrist.joint_names),
                               self.arm.times,
                               np.column_stack([self.arm.positions, self.wrist.positions]),
                               np.column_stack([self.arm.velocities, self.wrist.velocities]))


def _gaussian_smooth(x: NDArray[np.float64], sigma_n: float) -> NDArray[np.float64]:
    """Zero-phase Gaussian smoothing of samples (N, 3) of a motion at rest before and after
    (zeros beyond the ends), σ in samples."""
    if sigma_n <= 0:
        return x
    half = math.ceil(4 * sigma_n)
    k = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma_n) ** 2)
    k /= k.sum()
    return np.column_stack([np.convolve(x[:, j], k, mode="same") for j in range(3)])


def _hold(arm: JointTrajectory, lead: float, tail: float) -> JointTrajectory:
    """``arm`` with ``lead`` s of holding its first point before and ``tail`` s of holding its
    last after (it starts and ends at rest)."""
    t = arm.times - arm.times[0]
    times = np.concatenate([[0.0], lead + t, [lead + t[-1] + tail]])
    pos = np.vstack([arm.positions[:1], arm.positions, arm.positions[-1:]])
    vel = np.vstack([np.zeros((1, pos.shape[1])), arm.velocities,
                     np.zeros((1, pos.shape[1]))])
    return JointTrajectory(arm.joint_names, times, pos, vel)


def slosh_free_wrist(arm: JointTrajectory, model: PoseModel, spec: Spec, utensil: str, *,
                     height: float = 0.005, q_wrist_start: ArrayLike = (0.0, 0.0),
                     sigmas: tuple[float, ...] = SLOSH_FREE_SIGMAS_S,
                     dt: float = 0.01, iterations: int = 3) -> SloshFreeResult:
    """A wrist trajectory that turns the dish normal along ``−(g − a)`` of the planned arm
    motion ``arm`` (at rest at both ends), smoothed by the first ``σ`` of ``sigmas`` whose
    trajectory the tool's validation accepts; ``height``: the load's centroid above the dish
    floor (its acceleration is the one that counts). The centroid's acceleration depends on
    the wrist too, so after the plain leveling, wrist and acceleration are solved
    ``iterations`` more times in turn; a σ whose last two passes differ by more than 0.5° is
    not used (the wrist's own turning feeding back on its target)."""
    from articutool.tool.following import TrajectoryFollower
    from articutool.verify.leveling import candidate_curves, follow

    arm6 = _arm_part(arm, spec)
    w = spec.wrist
    lim, vmax = w.limits, w.velocity_limits
    follower = TrajectoryFollower(spec)
    up = np.array([0.0, 0.0, STANDARD_GRAVITY])
    reasons = []
    for sigma in sigmas:
        pad = math.ceil(3 * sigma / dt) * dt
        padded = _hold(arm6, pad, pad)
        n = round(padded.duration / dt) + 1
        t = np.linspace(0.0, padded.duration, n)
        q = padded.sample(t)[0]
        R0, p0 = model.tool_base_poses(q)
        target = np.tile([0.0, 0.0, 1.0], (n, 1))
        qw, prev, fail, why = None, None, None, ""
        for _ in range(iterations + 1):
            u = np.einsum("kji,kj->ki", R0, target)
            curves = candidate_curves(u, lim)
            inside = (curves >= lim[:, 0] - 1e-12) & (curves <= lim[:, 1] + 1e-12)
            prev = qw
            qw, _, fail, why = follow(curves, inside.all(axis=-1),
                                      np.asarray(q_wrist_start, dtype=float), t, vmax)
            if fail is not None:
                break
            _, pc = dish_poses(spec, utensil, R0, p0, qw, height)
            a = _gaussian_smooth(_second_differences(t, pc), sigma / dt)
            a[0] = a[-1] = 0.0
            target = a + up
            target /= np.linalg.norm(target, axis=1, keepdims=True)
        if fail is not None or qw is None:
            reasons.append(f"σ {sigma:g} s: no wrist solution followable at t = "
                           f"{t[fail if fail is not None else 0]:.3f} s ({why})")
            continue
        # The wrist's own turning accelerates the load; too short a σ lets that feed back
        # on the target without settling: such a σ is not used.
        change = float(np.abs(qw - prev).max()) if prev is not None else 0.0
        if change > _CONVERGED_RAD:
            reasons.append(f"σ {sigma:g} s: the wrist and the load's acceleration did not "
                           f"settle ({math.degrees(change):.2f}° between the last two passes)")
            continue
        qdw = np.gradient(qw, t, axis=0)
        qdw[0] = qdw[-1] = 0.0
        traj = JointTrajectory(tuple(w.joint_names), t, qw, qdw)
        try:
            follower.prevalidate(traj)
        except TrajectoryError as err:
            reasons.append(f"σ {sigma:g} s: {err}")
            continue
        return SloshFreeResult(JointTrajectory(tuple(spec.arm.joint_names), t, q,
                                               padded.sample(t)[1]), traj, sigma,
                               f"slosh-free wrist, σ {sigma:g} s, {pad:.2f} s lead-in and out")
    return SloshFreeResult(None, None, math.nan,
                           "no slosh-free wrist trajectory the tool accepts: "
                           + "; ".join(reasons))

