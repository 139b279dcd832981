"""Numerical inverse kinematics on the arm models (damped least squares CLIK, Pinocchio)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from articutool.arm.model import TOOL_BASE_FRAME, ArmModel, tip_frame_name
from articutool.spec import Spec

__all__ = ["IKSettings", "solve_level_ik", "solve_pose_ik", "staging_configuration"]


@dataclass(frozen=True)
class IKSettings:
    """CLIK parameters: success tolerances, iteration cap, damping, random seeds per target."""

    position_tol_m: float = 1e-4
    rotation_tol_rad: float = 1e-3
    max_iterations: int = 300
    damping: float = 1e-4
    max_step_rad: float = 0.5
    random_seeds: int = 6


def solve_pose_ik(
    model: ArmModel,
    frame: str,
    target: NDArray[np.float64],
    q0: NDArray[np.float64],
    settings: IKSettings,
    free: int | None = None,
) -> NDArray[np.float64] | None:
    """Closed-loop IK of ``frame`` onto the (4, 4) ``target`` pose from ``q0``.

    Damped least squares on the frame's SE(3) log error, ``dq = −Jᵀ(JJᵀ + λI)⁻¹ e`` with
    ``J = −Jlog6 · J_local`` (the standard Pinocchio CLIK), steps capped at ``max_step_rad``
    and clipped to the joint limits. ``free`` limits the update to the first ``free`` joints
    (the arm only). Returns the configuration, or ``None`` when it does not converge.
    """
    pm, data = model.model, model.data
    name = {"tip": tip_frame_name(model.utensil), "tool_base": TOOL_BASE_FRAME,
            "ee": model.spec.arm.ee_frame}.get(frame, frame)
    if not pm.existFrame(name):
        raise ValueError(f"unknown frame {frame!r}; use 'tip', 'tool_base', 'ee' or a model frame")
    fid = pm.getFrameId(name)
    oMdes = pin.SE3(target[:3, :3], target[:3, 3])
    lo, hi = model.lower, model.upper
    n = pm.nv if free is None else free
    q = np.clip(np.asarray(q0, dtype=float), lo, hi)
    eye = settings.damping * np.eye(6)
    for _ in range(settings.max_iterations):
        pin.forwardKinematics(pm, data, q)
        pin.updateFramePlacement(pm, data, fid)
        iMd = data.oMf[fid].actInv(oMdes)
        err = pin.log6(iMd).vector
        if (np.linalg.norm(err[:3]) < settings.position_tol_m
                and np.linalg.norm(err[3:]) < settings.rotation_tol_rad):
            return q
        J = pin.computeFrameJacobian(pm, data, q, fid, pin.ReferenceFrame.LOCAL)[:, :n]
        J = -pin.Jlog6(iMd.inverse()) @ J
        dq = -J.T @ np.linalg.solve(J @ J.T + eye, err)
        step = np.abs(dq).max()
        if step > settings.max_step_rad:
            dq *= settings.max_step_rad / step
        q = q.copy()
        q[:n] = np.clip(q[:n] + dq, lo[:n], hi[:n])
    return None


def solve_level_ik(
    model: ArmModel,
    tip_at: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    heading0: float,
    seeds: Sequence[NDArray[np.float64]],
    step_deg: float = 15.0,
) -> NDArray[np.float64] | None:
    """The first collision-free configuration whose utensil is level (its axis horizontal)
    with the tip at ``tip_at(z)`` for the utensil axis ``z``: headings from ``heading0``
    outwards in ``step_deg`` steps, each tried from every seed (deterministic). None if no
    heading and seed gives one."""
    y = np.array([0.0, 0.0, 1.0])
    for dh in sorted(np.radians(np.arange(-180.0, 180.0, step_deg)), key=abs):
        z = np.array([np.cos(heading0 + dh), np.sin(heading0 + dh), 0.0])
        target = np.eye(4)
        target[:3, :3] = np.column_stack([np.cross(y, z), y, z])
        target[:3, 3] = tip_at(z)
        for q0 in seeds:
            q = solve_pose_ik(model, "tip", target, q0, IKSettings(), free=6)
            if q is not None and not model.in_collision(q):
                return q
    return None


def staging_configuration(spec: Spec, model: ArmModel, seed: int = 0
                          ) -> tuple[NDArray[np.float64], float]:
    """Arm configuration for the spec's Staging pose (end-effector IK), collision-free.

    The reference system's Staging pose was taught for a shorter tool; with the Articutool's
    geometry it puts the utensil into the head of the default scene. The end effector is
    therefore backed off along its approach axis (1 cm steps, up to 20 cm) until the whole
    tool is clear. Returns the configuration and the back-off distance (m).
    """
    pose = spec.arm.poses["Staging"]
    R = pin.Quaternion(*pose.orientation_wxyz).normalized().toRotationMatrix()
    rng = np.random.default_rng(seed)
    seeds = [spec.arm.configuration(n) for n in ("Home", "Resting", "AbovePlate")]
    seeds += list(rng.uniform(spec.arm.lower, spec.arm.upper, size=(24, 6)))
    settings = IKSettings(max_iterations=500)
    for back in np.arange(0.0, 0.2001, 0.01):
        target = np.eye(4)
        target[:3, :3] = R
        target[:3, 3] = np.asarray(pose.position) - back * R[:, 2]
        best = None
        for q0 in seeds:
            q = solve_pose_ik(model, "ee", target, np.r_[q0, np.zeros(model.nq - 6)],
                              settings, free=6)
            if q is None or model.in_collision(q):
                continue
            # Prefer the solution closest to Resting: a short, natural transport.
            d = np.linalg.norm(q[:6] - spec.arm.configuration("Resting"))
            if best is None or d < best[0]:
                best = (d, q[:6])
        if best is not None:
            return np.asarray(best[1]), float(back)
    raise RuntimeError("no collision-free IK solution near the Staging pose")
