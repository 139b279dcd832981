"""Planning's queries on the arm models and on paths, without OMPL (thesis §4.2, §4.3).

:class:`ArmQueries` (forward kinematics, the tip's
rotation and angular Jacobian, collisions, joint bounds on one model: what the planners'
validity checks and constraints evaluate tens of thousands of times per query),
:func:`level_configuration` (a level tip by Gauss–Newton) and the dense sampling of paths and
trajectories for the motion checks and the final re-check. :mod:`.ompl_planner` composes
them with OMPL.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from articutool.arm.model import ArmModel, tip_frame_name
from articutool.planning.constraints import StrictConstraint
from articutool.trajectory import JointTrajectory

__all__ = ["ArmQueries", "dense_times", "densify", "level_configuration",
           "path_length"]

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

class ArmQueries:
    """Per-request kinematics on one ``ArmModel``: validity, tilt, projection Jacobians."""

    def __init__(self, model: ArmModel, frame: str, broadphase: bool = True) -> None:
        self.arm = model
        self.m, self.d = model.model, model.data
        self.gm, self.gd = model.geometry_model, model.geometry_data
        if not model.model.existFrame(frame):
            raise ValueError(f"unknown frame {frame!r}")
        self.fid = model.model.getFrameId(frame)
        self.n = model.nq
        self.lo, self.hi = model.lower, model.upper
        self.bp = model.broadphase if broadphase else None
        self.pool = model.broadphase_pool if broadphase else None

    def rotation(self, q: NDArray[np.float64]) -> NDArray[np.float64]:
        pin.forwardKinematics(self.m, self.d, q)
        return pin.updateFramePlacement(self.m, self.d, self.fid).rotation

    def rotation_and_jacobian(
        self, q: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        pin.computeJointJacobians(self.m, self.d, q)
        R = pin.updateFramePlacement(self.m, self.d, self.fid).rotation
        J = pin.getFrameJacobian(self.m, self.d, self.fid, _LWA)
        return R, J[3:]

    def collides(self, q: NDArray[np.float64]) -> bool:
        if self.pool is not None:  # the broad phase, as a batch of one: the cheapest call
            return bool(pin.computeCollisionsInParallel(1, self.pool, q.reshape(-1, 1),
                                                        True, False)[0])
        return bool(pin.computeCollisions(self.m, self.d, self.gm, self.gd, q, True))

    def first_collision(self, q: NDArray[np.float64]) -> int | None:
        """Index of the first of the configurations ``q`` (N, n) in collision, or ``None``."""
        if self.pool is not None:
            return self.arm.first_collision(q)
        return next((k for k in range(q.shape[0]) if self.collides(q[k])), None)

    def in_bounds(self, q: NDArray[np.float64]) -> bool:
        return bool(np.all(q >= self.lo - 1e-9) and np.all(q <= self.hi + 1e-9))


def level_configuration(
    model: ArmModel, q0: NDArray[np.float64], *, iterations: int = 50, tol: float = 1e-10
) -> NDArray[np.float64] | None:
    """Project ``q0`` (nq,) to a configuration with the tip exactly level (Gauss–Newton).

    Drives ``w_x = w_z = 0`` (see :mod:`~articutool.planning.constraints`) with minimum-norm
    steps. Returns ``None`` if it does not converge, ends upside down or leaves the joint
    limits. Does not check collisions. Useful for making level test/benchmark tasks.
    """
    kin = ArmQueries(model, tip_frame_name(model.utensil))
    exact = StrictConstraint(1e-9)
    q = np.asarray(q0, dtype=np.float64).copy()
    for _ in range(iterations):
        R, Jw = kin.rotation_and_jacobian(q)
        w = R[2]
        e = np.array([w[2], w[0]])
        if e @ e < tol and w[1] > 0:
            return q if kin.in_bounds(q) else None
        J = exact.deadzone_jacobian(R, Jw) if np.abs(e).max() > 1e-9 else None
        if J is None:
            break
        q = q - np.linalg.lstsq(J, e, rcond=None)[0]
    return None


def densify(q: NDArray[np.float64], step: float) -> NDArray[np.float64]:
    """Insert linear samples so that consecutive rows differ by at most ``step`` (max-norm):
    segment ``a → b`` of ``k = max(⌈max|b − a| / step⌉, 1)`` steps gets the rows
    ``a + (j / k)(b − a)``, ``j = 1 … k``, all segments at once."""
    q = np.asarray(q, dtype=np.float64)
    d = np.diff(q, axis=0)
    if d.shape[0] == 0:
        return q[:1].copy()
    k = np.maximum(np.ceil(np.abs(d).max(axis=1) / step).astype(np.int64), 1)
    seg = np.repeat(np.arange(k.size), k)
    j = np.arange(1, seg.size + 1) - np.repeat(np.cumsum(k) - k, k)
    f = (j / k[seg])[:, None]
    return np.concatenate([q[:1], q[seg] + f * d[seg]])


def dense_times(traj: JointTrajectory, step: float) -> NDArray[np.float64]:
    """Sample times with joint steps ≲ ``step``: each interval split by its velocity bound."""
    t = traj.times
    dt = np.diff(t)
    vpeak = np.maximum(np.abs(traj.velocities[:-1]), np.abs(traj.velocities[1:])).max(axis=1)
    dpos = np.abs(np.diff(traj.positions, axis=0)).max(axis=1)
    k = np.maximum(np.ceil(np.maximum(dpos, 1.5 * vpeak * dt) / step), 1).astype(int)
    seg = np.repeat(np.arange(dt.size), k)  # interval i split into k[i] equal steps
    j = np.arange(seg.size) - np.repeat(np.cumsum(k) - k, k)
    return np.concatenate([t[seg] + dt[seg] * j / k[seg], t[-1:]])


def path_length(q: NDArray[np.float64]) -> float:
    """Summed joint-space length of the polyline ``q`` (rows: configurations)."""
    return float(np.linalg.norm(np.diff(q, axis=0), axis=1).sum())
