"""What a plan looks like: the robot's motion, the tip's path and where verification failed.

:func:`plan_view` turns a timed trajectory into samples the viewer draws (no I/O):

* an **arm** trajectory (the six Jaco joints, as ``articutool verify`` and the decoupled
  planner give) is checked by plan-then-verify (:func:`articutool.verify.verify_trajectory`,
  thesis Alg. 2); the wrist follows the verifier's synchronised leveling trajectory, and
  each sample carries the **velocity margin** ``1 − max_j |q̇_j| / q̇max_j`` of the wrist rates
  that keep the utensil level there (Eq. 4.7; the verifier's ``velocity_margin`` is its
  minimum). Past the first failure the wrist holds its last angles and the margin is NaN;
* with ``wrist="locked"`` (the rigid ``strict6`` baseline) the wrist stays at zero;
* an **8-joint** trajectory (``strict8``) moves the wrist as planned.

Every sample also carries the utensil's **tilt from vertical**
(:func:`articutool.tool.kinematics.tilt_from_vertical`) and the robot's colliding pairs
(:meth:`articutool.arm.model.ArmModel.colliding_pairs`, scene objects named ``scene/…``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from articutool.arm.model import ArmModel
from articutool.spec import Spec
from articutool.tool.kinematics import tilt_from_vertical
from articutool.trajectory import JointTrajectory, TrajectoryError

__all__ = ["PlanView", "plan_view"]

WRIST_MODES = ("leveling", "locked")


@dataclass(frozen=True)
class PlanView:
    """Samples of a plan for the viewer (see the module doc)."""

    title: str
    t: NDArray[np.float64]  # (S,) s
    q: NDArray[np.float64]  # (S, 8) arm joints 1..6, pitch, roll
    tip: NDArray[np.float64]  # (S, 3) utensil tip in the arm base frame (m)
    tilt_deg: NDArray[np.float64]  # (S,)
    margin: NDArray[np.float64] | None  # (S,) velocity margin (leveling wrist only)
    collisions: list[list[tuple[str, str]]]  # per sample
    verified: bool | None  # plan-then-verify outcome (None: not applicable)
    reason: str = ""
    message: str = ""
    failure_time: float | None = None
    failure_index: int | None = None  # waypoint at or before the failure
    failure_xyz: NDArray[np.float64] | None = None
    summary: list[str] = field(default_factory=list)

    def sample_at(self, t: float) -> int:
        """Index of the last sample at or before ``t``."""
        return int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, self.t.size - 1))

    @property
    def colliding_samples(self) -> NDArray[np.int64]:
        """Indices of the samples where some pair collides."""
        return np.array([k for k, c in enumerate(self.collisions) if c], dtype=np.int64)


def _tips(model: ArmModel, q: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    poses = np.stack([model.tip_pose(qk) for qk in q])
    return poses[:, :3, 3], np.degrees(tilt_from_vertical(poses[:, :3, 1]))


def plan_view(traj: JointTrajectory, model: ArmModel, spec: Spec, *, wrist: str = "leveling",
              title: str = "plan", max_step_deg: float = 1.0,
              max_samples: int = 2000) -> PlanView:
    """Samples of ``traj`` on ``model`` (8 DOF) for drawing; see the module doc.

    Raises :class:`TrajectoryError` when the joints are neither the six arm joints nor the
    eight of the model, or ``wrist`` is not one of ``WRIST_MODES``.
    """
    if model.dof != 8:
        raise ValueError("plan_view needs the 8-DOF model (ArmModel(spec, dof=8))")
    if wrist not in WRIST_MODES:
        raise TrajectoryError(f"wrist must be one of {WRIST_MODES}; got {wrist!r}")
    arm_names = tuple(spec.arm.joint_names)
    all_names = (*arm_names, *spec.wrist.joint_names)
    names = set(traj.joint_names)
    verified: bool | None = None
    reason = message = ""
    fail_t: float | None = None
    fail_i: int | None = None
    margin: NDArray[np.float64] | None = None
    summary: list[str] = []
    if names == set(all_names):
        full = traj.reordered(all_names)
        t = _times(full.times, max_samples)
        q = full.sample(t)[0]
        summary.append("8-joint trajectory: the wrist moves as planned (not verified)")
    elif names == set(arm_names):
        arm = traj.reordered(arm_names)
        if wrist == "locked":
            t = _times(arm.times, max_samples)
            q = np.concatenate([arm.sample(t)[0], np.zeros((t.size, 2))], axis=1)
            summary.append("rigid tool: wrist locked at zero (not verified)")
        else:
            from articutool.verify.verifier import verify_trajectory

            rep = verify_trajectory(arm, model, spec, max_step_deg=max_step_deg)
            verified, reason, message = rep.feasible, rep.reason, rep.message
            fail_t, fail_i = rep.first_failure_time, rep.first_failure_index
            w = rep.wrist_trajectory
            vmax = np.asarray(spec.wrist.velocity_limits, dtype=float)
            if w is not None and len(w) > 0:
                keep = _thin(w.times.size, max_samples)
                tw, qw, vw = w.times[keep], w.positions[keep], w.velocities[keep]
                mw = 1.0 - (np.abs(vw) / vmax).max(axis=1)
            else:
                tw, qw, mw = np.zeros(0), np.zeros((0, 2)), np.zeros(0)
            rest = arm.times[arm.times > (tw[-1] if tw.size else -1.0)]
            t = np.concatenate([tw, rest])
            held = qw[-1] if qw.size else np.zeros(2)
            q = np.concatenate([arm.sample(t)[0],
                                np.concatenate([qw, np.tile(held, (rest.size, 1))])], axis=1)
            margin = np.concatenate([mw, np.full(rest.size, np.nan)])
            summary.append(f"plan-then-verify: {'FEASIBLE' if rep.feasible else 'INFEASIBLE'}"
                           f" ({rep.reason}); velocity margin {rep.velocity_margin:.1%}")
            summary.append(rep.message)
    else:
        raise TrajectoryError(
            f"joint_names must be the six arm joints {list(arm_names)} or those plus the "
            f"wrist {list(spec.wrist.joint_names)}; got {list(traj.joint_names)}")
    tip, tilt = _tips(model, q)
    collisions = [model.colliding_pairs(qk) for qk in q]
    n_col = sum(1 for c in collisions if c)
    summary.append(f"duration {t[-1]:.2f} s, {t.size} samples; max tilt {np.nanmax(tilt):.1f}°; "
                   f"{n_col} sample(s) in collision")
    fail_xyz = None
    if fail_t is not None:
        fail_xyz = tip[int(np.clip(np.searchsorted(t, fail_t, side="right") - 1, 0,
                                   t.size - 1))]
    return PlanView(title=title, t=t, q=q, tip=tip, tilt_deg=tilt, margin=margin,
                    collisions=collisions, verified=verified, reason=reason, message=message,
                    failure_time=fail_t, failure_index=fail_i, failure_xyz=fail_xyz,
                    summary=summary)


def _thin(n: int, max_samples: int) -> NDArray[np.int64]:
    """At most ``max_samples`` indices of ``n``, evenly spread, first and last kept."""
    if n <= max_samples:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, max_samples)).astype(np.int64))


def _times(waypoints: NDArray[np.float64], max_samples: int) -> NDArray[np.float64]:
    """Waypoint times plus evenly spaced ones (≈ 100 per second, at most ``max_samples``)."""
    n = min(max_samples, max(2, math.ceil(100 * float(waypoints[-1] - waypoints[0])) + 1))
    t = np.union1d(waypoints, np.linspace(waypoints[0], waypoints[-1], n))
    return t[_thin(t.size, max_samples)]
