"""Plan-then-verify: can the wrist level the utensil along an arm trajectory? (thesis Alg. 2)

For every sample of the arm trajectory — the waypoints, densified so that the tool base
rotates at most ``max_step_deg`` between samples *and* no arm joint moves more than
``max_step_deg`` along the cubic Hermite spline the trajectory describes — the verifier

0. checks the arm itself: every sample within the arm's joint position and velocity limits
   (``spec.arm``); the spline between two waypoints can leave them although both waypoints
   are inside (e.g. identical positions with a large velocity at one end);

1. computes the anti-gravity direction in the tool base frame F0, ``u = R_world←F0ᵀ z``
   (Alg. 2 line 6);
2. *kinematic check*: finds the leveling solutions inside the wrist limits (Eqs. 4.2–4.3, both
   branches) and follows the one nearest to the previous sample (Alg. 2 line 12);
3. *continuity check*: every step of the followed solution must be one the motors can make
   within the sample's time step — along one solution curve too (passing close to
   the wrist singularity, ``|cos θr| ≈ 0``, the leveling pitch swings by nearly π between two
   samples whose Eq. 4.7 rates are both small), and when the followed solution leaves the
   limits and the wrist must jump to another one (a branch switch or a whole roll turn);
4. *dynamic check*: the arm's angular velocity ``ω = J_jaco q̇`` gives the correction
   ``ω_corr = −Rᵀ ω`` (Eq. 4.5), the up vector's velocity ``ω_corr × u`` (Eq. 4.6, the cross
   product the reference implementation omitted) and the joint rates ``J⁺(q)(ω_corr × u)``
   (Eq. 4.7), which must stay within the spec's maximum joint velocity.

Everything is vectorised over samples; only branch switches (rare) are handled in a loop.
The report carries the synchronised leveling trajectory (positions and velocities) that the
tool's TRAJECTORY mode can execute.

With a ``load`` (food-aware verification) a feasible trajectory is also checked against the
food it carries (:mod:`articutool.verify.food`): the load's model predicts, along the arm and
the synchronised leveling wrist, the apparent tilt of the dish, the liquid's surface tilt, the
margin to the first spill and the grams spilled; a predicted spill makes the trajectory
infeasible (reason ``"spill"``). ``slosh_free`` checks the slosh-free wrist trajectory instead
(:func:`~articutool.verify.food.slosh_free_wrist`), plain leveling when none passes the tool's
validation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from articutool.api_types import OrientationModel
from articutool.food.loads import FoodLoad
from articutool.spec import Spec
from articutool.tool.kinematics import joint_rates_for_rotation
from articutool.trajectory import JointTrajectory, TrajectoryError
from articutool.verify.leveling import candidate_curves, follow

__all__ = ["VerificationReport", "densify", "verify_trajectory"]

_WORLD_UP = np.array([0.0, 0.0, 1.0])
_MAX_SAMPLES = 2_000_000
# toppra meets the velocity limits at its waypoints; the cubic Hermite spline between them
# exceeds them slightly (measured: at most 0.13 % on 12 packaged decoupled plans).
_ARM_VELOCITY_TOL = 0.01


@dataclass(frozen=True)
class VerificationReport:
    """Outcome of :func:`verify_trajectory`.

    ``reason`` is one of ``"ok"``, ``"arm_joint_limit"``, ``"arm_velocity_limit"``,
    ``"no_leveling_solution"``,
    ``"discontinuity"`` (a branch switch or jump the motors cannot make in the time step),
    ``"velocity"`` (Eq. 4.7 rate above the limit) and ``"spill"`` (feasible for the wrist, but
    the load is predicted to spill). ``velocity_margin`` is
    ``1 − max_j(max|q̇_j| / q̇max_j)`` over the checked samples: the fraction of motor speed
    left (negative when infeasible; NaN, like ``max_required_velocity``, when no sample's
    rates were evaluated — an arm limit or no leveling solution at the start).
    ``wrist_trajectory`` levels the tool up to the first failure (the whole trajectory when
    feasible). ``food`` is the food check (:class:`~articutool.verify.food.FoodCheckReport`) of a
    kinematically feasible trajectory when a load was given; ``slosh_free`` the slosh-free
    wrist (:class:`~articutool.verify.food.SloshFreeResult`) when asked for.
    """

    feasible: bool
    reason: str
    message: str
    first_failure_time: float | None
    first_failure_index: int | None  # index of the original waypoint at or before the failure
    max_required_velocity: tuple[float, float]
    velocity_limits: tuple[float, float]
    velocity_margin: float
    min_singularity_measure: float
    branch_switches: int
    samples_checked: int
    waypoints: int
    max_step_deg: float
    wrist_trajectory: JointTrajectory | None = field(repr=False, default=None)
    food: Any = field(repr=False, default=None)
    slosh_free: Any = field(repr=False, default=None)

    def to_dict(self, include_trajectory: bool = False) -> dict[str, Any]:
        """JSON-ready summary (the wrist trajectory only when asked)."""
        d = {k: getattr(self, k) for k in (
            "feasible", "reason", "message", "first_failure_time", "first_failure_index",
            "max_required_velocity", "velocity_limits", "velocity_margin",
            "min_singularity_measure", "branch_switches", "samples_checked", "waypoints",
            "max_step_deg")}
        d["max_required_velocity"] = [_num(v) for v in self.max_required_velocity]
        d["velocity_limits"] = list(self.velocity_limits)
        d["velocity_margin"] = _num(self.velocity_margin)
        d["min_singularity_measure"] = _num(self.min_singularity_measure)
        if include_trajectory and self.wrist_trajectory is not None:
            d["wrist_trajectory"] = self.wrist_trajectory.to_dict()
        if self.food is not None:
            d["food"] = self.food.to_dict()
        if self.slosh_free is not None:
            d["slosh_free"] = {"ok": self.slosh_free.ok, "message": self.slosh_free.message,
                               "sigma_s": _num(self.slosh_free.sigma_s)}
        return d


def _num(x: float) -> float | None:
    """JSON has no NaN: an unknown number is null."""
    return float(x) if np.isfinite(x) else None


def _step_angles(R: NDArray[np.float64]) -> NDArray[np.float64]:
    # Rotation angle between consecutive rotations: cos θ = (tr(R_kᵀ R_k+1) − 1) / 2.
    tr = np.einsum("kij,kij->k", R[:-1], R[1:])
    return np.arccos(np.clip((tr - 1.0) * 0.5, -1.0, 1.0))


def densify(
    traj: JointTrajectory, model: OrientationModel, max_step_rad: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Sample times at which consecutive tool-base orientations differ by ≤ ``max_step_rad``
    and no arm joint moves more than ``max_step_rad`` (rad) along the spline.

    Starts from the waypoints and subdivides offending intervals (uniformly in time) until
    every step is small enough. A joint's travel over an interval is bounded by
    ``max(|Δq|, max(|q̇₀|, |q̇₁|) Δt)``, which sees a spline that leaves and comes back
    between equal waypoints. Returns ``(t, q, qd, R)`` at the samples.
    """
    t = traj.times.copy()
    q, qd = traj.positions.copy(), traj.velocities.copy()
    R = model.tool_base_rotations(q)
    for _ in range(8):
        if t.size < 2:
            break
        travel = np.maximum(np.abs(np.diff(q, axis=0)),
                            np.maximum(np.abs(qd[:-1]), np.abs(qd[1:])) * np.diff(t)[:, None])
        step = np.maximum(_step_angles(R), travel.max(axis=1))
        # Counted in floats: a tiny max_step_rad makes them overflow an integer (and wrap to
        # "no subdivision needed"), which would pass a density never checked.
        n_float = np.ceil(step / max_step_rad * (1.0 + 1e-9))
        if (n_float <= 1).all():
            break
        total_float = float(np.maximum(n_float, 1).sum()) + 1
        if not total_float <= _MAX_SAMPLES:
            raise TrajectoryError(
                f"max_step_deg: densifying to {np.degrees(max_step_rad):g}° steps needs "
                f"{total_float:.3g} samples (limit {_MAX_SAMPLES}); use a larger max_step_deg"
            )
        n_sub = np.maximum(n_float, 1).astype(np.int64)
        seg = np.repeat(np.arange(t.size - 1), n_sub)
        frac = (np.arange(seg.size) - np.repeat(np.cumsum(n_sub) - n_sub, n_sub)) / n_sub[seg]
        t_new = np.append(t[seg] + frac * (t[seg + 1] - t[seg]), t[-1])
        # Keep exact waypoint samples; only new interior points are interpolated.
        q, qd = traj.sample(t_new)
        # The waypoints' own times among the samples (times increase strictly).
        at = np.minimum(np.searchsorted(traj.times, t_new), traj.times.size - 1)
        is_wp = traj.times[at] == t_new
        wp_idx = at[is_wp]
        q[is_wp], qd[is_wp] = traj.positions[wp_idx], traj.velocities[wp_idx]
        t = t_new
        R = model.tool_base_rotations(q)
    return t, q, qd, R


def verify_trajectory(
    traj: JointTrajectory,
    model: OrientationModel,
    spec: Spec,
    *,
    max_step_deg: float = 1.0,
    q_wrist_start: tuple[float, float] | NDArray[np.float64] = (0.0, 0.0),
    load: FoodLoad | None = None,
    utensil: str | None = None,
    slosh_free: bool = False,
) -> VerificationReport:
    """Check that the wrist can keep the utensil level along an arm trajectory (Alg. 2).

    ``traj`` holds the arm's joints (any order; names must match ``spec.arm``).
    ``q_wrist_start`` is the wrist configuration the first sample's solution is chosen
    nearest to. With a ``load`` on ``utensil`` (default: the model's), the food check too
    (see the module doc; ``model`` then needs ``tool_base_poses``). Raises
    :class:`TrajectoryError` for malformed input and
    :class:`~articutool.food.loads.LoadError` for a load that cannot be modelled.
    """
    rep = _verify_leveling(traj, model, spec, max_step_deg, q_wrist_start)
    if load is None:
        return rep
    from dataclasses import replace

    from articutool.verify.food import food_check, slosh_free_wrist, spill_model

    name = utensil if utensil is not None else getattr(model, "utensil", None)
    if name is None:
        raise TrajectoryError("utensil: name the utensil that carries the load")
    spill_model(spec, name, load)  # refuses a load it cannot model, before any answer
    if not rep.feasible or rep.wrist_trajectory is None:
        return rep
    sf = None
    food = None
    if slosh_free:
        sf = slosh_free_wrist(traj, model, spec, name,  # type: ignore[arg-type]
                              q_wrist_start=rep.wrist_trajectory.positions[0])
        if sf.ok:
            assert sf.arm is not None and sf.wrist is not None
            food = food_check(sf.arm, sf.wrist, model, spec, name,  # type: ignore[arg-type]
                              load, "slosh_free")
    if food is None:
        food = food_check(traj, rep.wrist_trajectory, model, spec, name,  # type: ignore[arg-type]
                          load, "leveling")
    if not food.spills:
        return replace(rep, food=food, slosh_free=sf)
    p = food.prediction
    msg = (f"predicted to spill {p.spilled_g:.2f} g of {load.grams:g} g {load.food} "
           f"(first at t = {p.first_spill_time:.2f} s; peak apparent tilt "
           f"{p.peak_apparent_tilt_deg:.1f}°, liquid surface {p.peak_surface_tilt_deg:.1f}°, "
           f"margin {p.min_margin_deg:.1f}°) with the wrist {food.wrist.replace('_', '-')}")
    t_spill = p.first_spill_time
    wp = None if t_spill is None else max(
        int(np.searchsorted(traj.times, t_spill, side="right")) - 1, 0)
    return replace(rep, feasible=False, reason="spill", message=msg, first_failure_time=t_spill,
                   first_failure_index=wp, food=food, slosh_free=sf)


def _verify_leveling(
    traj: JointTrajectory,
    model: OrientationModel,
    spec: Spec,
    max_step_deg: float,
    q_wrist_start: tuple[float, float] | NDArray[np.float64],
) -> VerificationReport:
    """Alg. 2 proper: the wrist can level along the arm trajectory (no food)."""
    if not (np.isfinite(max_step_deg) and 0.0 < max_step_deg <= 45.0):
        raise TrajectoryError(f"max_step_deg must be in (0, 45] degrees; got {max_step_deg}")
    q_start = np.asarray(q_wrist_start, dtype=np.float64)
    if q_start.shape != (2,) or not np.isfinite(q_start).all():
        raise TrajectoryError("q_wrist_start must be two finite angles [pitch, roll]")
    arm = traj.reordered(spec.arm.joint_names)
    wrist = spec.wrist
    lim = wrist.limits
    vmax = wrist.velocity_limits
    max_step = np.radians(max_step_deg)

    def report(feasible: bool, reason: str, message: str, fail: int | None,
               t: NDArray, qw: NDArray, qdw: NDArray, n_level: int, n_eval: int,
               switches: int, fail_wp: int | None = None) -> VerificationReport:
        # n_level: samples the wrist trajectory covers (before the first failure);
        # n_eval: samples whose required rates were evaluated (peak and margin use them).
        peak = np.abs(qdw[:n_eval]).max(axis=0) if n_eval else np.full(2, np.nan)
        sing = np.abs(np.cos(qw[:n_eval, 1]))
        wp = fail_wp
        if fail is not None and wp is None:
            wp = int(np.searchsorted(arm.times, t[fail], side="right") - 1)
        wtraj = None
        if n_level >= 1:
            wtraj = JointTrajectory(wrist.joint_names, t[:n_level], qw[:n_level], qdw[:n_level])
        return VerificationReport(
            feasible=feasible, reason=reason, message=message,
            first_failure_time=None if fail is None else float(t[fail]),
            first_failure_index=wp,
            max_required_velocity=(float(peak[0]), float(peak[1])),
            velocity_limits=(float(vmax[0]), float(vmax[1])),
            velocity_margin=float(1.0 - (peak / vmax).max()),
            min_singularity_measure=float(sing.min()) if sing.size else float("nan"),
            branch_switches=switches, samples_checked=n_eval, waypoints=len(arm),
            max_step_deg=float(max_step_deg), wrist_trajectory=wtraj,
        )

    # Arm limits first: outside them the arm itself cannot execute the plan.
    lo, hi = spec.arm.lower, spec.arm.upper
    out = (arm.positions < lo - 1e-9) | (arm.positions > hi + 1e-9)
    if out.any():
        i, j = (int(x) for x in np.argwhere(out)[0])
        empty = np.zeros((len(arm), 2))
        return report(False, "arm_joint_limit",
                      f"waypoint {i}: {arm.joint_names[j]} = {arm.positions[i, j]:.4f} rad is "
                      f"outside [{lo[j]:.4f}, {hi[j]:.4f}]",
                      i, arm.times, empty, empty, 0, 0, 0, fail_wp=i)

    t, q, qd, R = densify(arm, model, max_step)
    # The arm along the spline (between waypoints too): positions, then velocities.
    vmax_arm = spec.arm.max_velocity
    for reason, bad, what in (
        ("arm_joint_limit", (q < lo - 1e-9) | (q > hi + 1e-9), "outside"),
        ("arm_velocity_limit", np.abs(qd) > vmax_arm * (1.0 + _ARM_VELOCITY_TOL), "above"),
    ):
        if bad.any():
            k, j = (int(x) for x in np.argwhere(bad)[0])
            name = arm.joint_names[j]
            detail = (f"{name} = {q[k, j]:.4f} rad is {what} [{lo[j]:.4f}, {hi[j]:.4f}]"
                      if reason == "arm_joint_limit" else
                      f"{name} moves at {abs(qd[k, j]):.4f} rad/s, {what} its limit "
                      f"{vmax_arm[j]:.4f} rad/s")
            empty = np.zeros((t.size, 2))
            return report(False, reason, f"t = {t[k]:.3f} s (between waypoints): {detail}",
                          k, t, empty, empty, 0, 0, 0)
    u = np.einsum("kji,j->ki", R, _WORLD_UP)  # Rᵀ z, Alg. 2 line 6
    curves = candidate_curves(u, lim)
    inside = (curves >= lim[:, 0] - 1e-12) & (curves <= lim[:, 1] + 1e-12)
    valid = inside.all(axis=-1)
    qw, switches, fail, fail_reason = follow(curves, valid, q_start, t, vmax)

    omega = model.tool_base_angular_velocity(q, qd)
    omega_local = -np.einsum("kji,kj->ki", R, omega)  # Eq. 4.5
    qdw = np.zeros_like(qw)
    n_ok = t.size if fail is None else fail
    if n_ok:
        qdw[:n_ok] = joint_rates_for_rotation(qw[:n_ok], omega_local[:n_ok],
                                              spec.controller.pinv_rcond)  # Eqs. 4.6-4.7
    over = np.flatnonzero((np.abs(qdw[:n_ok]) > vmax).any(axis=-1))
    if over.size:
        k = int(over[0])
        j = int(np.argmax(np.abs(qdw[k]) / vmax))
        msg = (f"t = {t[k]:.3f} s: {wrist.joint_names[j]} must turn at "
               f"{abs(qdw[k, j]):.3f} rad/s to stay level; limit {vmax[j]:g} rad/s")
        return report(False, "velocity", msg, k, t, qw, qdw, k, n_ok, switches)
    if fail is not None:
        if fail_reason == "no_leveling_solution":
            msg = (f"t = {t[fail]:.3f} s: no wrist configuration inside the limits "
                   f"pitch [{lim[0, 0]:.3f}, {lim[0, 1]:.3f}], roll [{lim[1, 0]:.3f}, "
                   f"{lim[1, 1]:.3f}] rad levels the tool (up in F0 = "
                   f"{np.array2string(u[fail], precision=3)})")
        else:
            dt = t[fail] - t[fail - 1]
            what = ("along one solution (near the wrist singularity, min |cos roll| "
                    f"{np.abs(np.cos(qw[fail - 1:fail + 1, 1])).min():.4f})"
                    if fail_reason == "discontinuity_along" else "a branch switch")
            msg = (f"t = {t[fail]:.3f} s: the leveling solution jumps from "
                   f"{np.array2string(qw[fail - 1], precision=3)} to "
                   f"{np.array2string(qw[fail], precision=3)} rad in {dt:.4f} s, {what} "
                   f"the motors cannot make at {vmax.tolist()} rad/s")
            fail_reason = "discontinuity"
        return report(False, fail_reason, msg, fail, t, qw, qdw, fail, fail, switches)
    peak = np.abs(qdw).max(axis=0)
    msg = (f"feasible: {t.size} samples, peak wrist rates {peak[0]:.3f} / {peak[1]:.3f} "
           f"rad/s (limits {vmax[0]:g} / {vmax[1]:g})")
    return report(True, "ok", msg, None, t, qw, qdw, t.size, t.size, switches)
