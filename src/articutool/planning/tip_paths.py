"""Paths of the utensil tip for the PC's arm: Cartesian tip segments, the wrist's sweep and a
straight lift, solved by the Pinocchio IK and timed by TOPP-RA (functional core: no arm, no
world; the PC arm (:mod:`articutool.planning.pc_arm`) and the scripted scenes
(:mod:`articutool.sim.scenes`) run them).

A tip pose is a position, a heading (:data:`~articutool.arm.scene.SCOOP_HEADING`) and a pitch
below the horizon (:func:`tip_target`). The arm joints are solved for each pose with the
wrist where it is, except in :func:`wrist_sweep`, where the wrist's pitch turns the utensil
while the arm translates.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from articutool.arm.ik import IKSettings, solve_pose_ik
from articutool.arm.model import ArmModel
from articutool.arm.scene import SCOOP_HEADING
from articutool.planning.timing import time_parameterize
from articutool.trajectory import JointTrajectory

__all__ = ["PathError", "cartesian_path", "concatenate", "first_ik", "lift_trajectory",
           "tip_target", "with_wrist", "wrist_sweep"]

_Z = np.array([0.0, 0.0, 1.0])
# The wrist sweep's pitch stays this far inside the limit the tool's runtime enforces.
_PITCH_MARGIN = math.radians(5.0)


class PathError(RuntimeError):
    """A tip path could not be made (no IK solution, no timing)."""


def tip_target(position: Sequence[float], heading: NDArray[np.float64],
               pitch_down: float) -> NDArray[np.float64]:
    """(4, 4) tip pose: the utensil points along horizontal ``heading`` tipped ``pitch_down``
    rad below the horizon; its up vector (tip y, Eq. 4.1) stays in the vertical plane."""
    h = np.asarray(heading, dtype=float)
    h = h / np.linalg.norm(h)
    z = h * math.cos(pitch_down) - _Z * math.sin(pitch_down)
    y = h * math.sin(pitch_down) + _Z * math.cos(pitch_down)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([np.cross(y, z), y, z])
    T[:3, 3] = position
    return T


def _ik_segment(model: ArmModel, q: NDArray[np.float64],
                p0: NDArray[np.float64], a0: float, p1: NDArray[np.float64], a1: float,
                step_m: float) -> list[NDArray[np.float64]]:
    """8-DOF configurations along the straight tip segment p0 → p1 (pitch a0 → a1), IK every
    ``step_m`` from the previous solution (arm joints only)."""
    settings = IKSettings(random_seeds=0)
    n = max(1, math.ceil(np.linalg.norm(p1 - p0) / step_m))
    out = []
    for k in range(1, n + 1):
        s = k / n
        target = tip_target(p0 + s * (p1 - p0), SCOOP_HEADING, a0 + s * (a1 - a0))
        sol = solve_pose_ik(model, "tip", target, q, settings, free=6)
        if sol is None:
            raise PathError(f"no arm IK solution for the tip at "
                            f"{np.round(target[:3, 3], 3)} m")
        out.append(sol)
        q = sol
    return out


def first_ik(model: ArmModel, q_now: NDArray[np.float64], p: NDArray[np.float64],
             a: float) -> NDArray[np.float64]:
    """An 8-DOF configuration for the tip pose at ``p`` pitched ``a`` down along
    :data:`SCOOP_HEADING`, solved for the arm joints (the wrist at ``q_now[6:]``) from the
    present configuration ``q_now`` or a named one."""
    target = tip_target(p, SCOOP_HEADING, a)
    spec = model.spec
    for q0 in (q_now[:6], *(spec.arm.configuration(n) for n in ("AbovePlate", "Home"))):
        sol = solve_pose_ik(model, "tip", target, np.concatenate([q0, q_now[6:]]),
                            IKSettings(random_seeds=0), free=6)
        if sol is not None:
            return sol
    raise PathError(f"no arm IK solution for the tip at {np.round(p, 3)} m")


def cartesian_path(model: ArmModel, q: NDArray[np.float64],
                   waypoints: list[tuple[NDArray[np.float64], float, float]],
                   step_m: float = 0.004) -> JointTrajectory:
    """Arm trajectory through tip waypoints ``(position, pitch_down, speed m/s)``: each
    straight segment is solved by IK and timed by TOPP-RA under the arm's velocity and
    acceleration limits, slowed so the tip does not exceed the segment's speed (the speed of
    the segment ending at the waypoint); segments run rest to rest. ``q``: the 8-DOF
    configuration at the first waypoint (the wrist stays at ``q[6:]``)."""
    arm = model.spec.arm
    names = tuple(model.joint_names[:6])
    times, pos, vel = [np.zeros(1)], [q[None, :6]], [np.zeros((1, 6))]
    t_end = 0.0
    for (p0, a0, _), (p1, a1, speed) in itertools.pairwise(waypoints):
        qs = np.array([q] + _ik_segment(model, q, p0, a0, p1, a1, step_m))[:, :6]
        q = np.concatenate([qs[-1], q[6:]])
        want = float(np.linalg.norm(p1 - p0)) / speed
        scale, seg = 1.0, None
        for _ in range(2):
            seg = time_parameterize(qs, names, arm.max_velocity * scale,
                                    arm.max_acceleration * scale * scale)
            if seg is None:
                raise PathError("TOPP-RA found no timing for a tip segment")
            if seg.duration >= want * 0.95:
                break
            scale *= seg.duration / want
        assert seg is not None
        times.append(t_end + seg.times[1:])
        pos.append(seg.positions[1:])
        vel.append(seg.velocities[1:])
        t_end += seg.duration
    return JointTrajectory(names, np.concatenate(times), np.concatenate(pos),
                           np.concatenate(vel))


def lift_trajectory(model: ArmModel, q: NDArray[np.float64], height: float = 0.12,
                    speed_scale: float = 0.3) -> JointTrajectory:
    """Arm trajectory lifting the tool base straight up by ``height`` from ``q`` (8-DOF), its
    orientation kept, with the arm's limits scaled by ``speed_scale``."""
    T = model.tool_base_pose(q)
    qs = [q]
    n = max(2, round(height / 0.01))
    for k in range(1, n + 1):
        Tk = T.copy()
        Tk[2, 3] += height * k / n
        sol = solve_pose_ik(model, "tool_base", Tk, qs[-1], IKSettings(random_seeds=0), free=6)
        if sol is None:
            raise PathError("no arm IK solution for lifting the utensil")
        qs.append(sol)
    arm = model.spec.arm
    lift = time_parameterize(np.array(qs)[:, :6], tuple(model.joint_names[:6]),
                             arm.max_velocity * speed_scale,
                             arm.max_acceleration * speed_scale**2)
    if lift is None:
        raise PathError("TOPP-RA found no timing for the lift")
    return lift


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
    average and within the arm's and the wrist's velocity limits. Raises ``PathError``."""
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
            raise PathError(f"no arm IK solution for the tip at {np.round(target[:3, 3], 3)}"
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


def with_wrist(traj: JointTrajectory, model: ArmModel, wrist: np.ndarray) -> JointTrajectory:
    """An arm trajectory as an 8-joint one, the wrist held at ``wrist``."""
    n = len(traj.times)
    return JointTrajectory(tuple(model.joint_names), traj.times,
                           np.column_stack([traj.positions, np.tile(wrist, (n, 1))]),
                           np.column_stack([traj.velocities, np.zeros((n, 2))]))


def concatenate(parts: list[JointTrajectory]) -> JointTrajectory:
    """Rest-to-rest trajectories one after the other (each starts where the last ended)."""
    times, pos, vel, t0 = [parts[0].times], [parts[0].positions], [parts[0].velocities], 0.0
    for a, b in itertools.pairwise(parts):
        t0 += a.duration
        times.append(t0 + b.times[1:])
        pos.append(b.positions[1:])
        vel.append(b.velocities[1:])
    return JointTrajectory(parts[0].joint_names, np.concatenate(times), np.concatenate(pos),
                           np.concatenate(vel))
