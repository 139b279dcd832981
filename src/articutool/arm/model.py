"""Kinova Jaco 2 (j2n6s200) + Articutool models in Pinocchio, loaded from the robot's one
description (:mod:`articutool.arm.description`: its MJCF, ``pinocchio.buildModelFromMJCF``).

The chain, the frames (``atool_base`` = F0, ``utensil`` = the utensil mount, the tip frames
``atool_tip_<name>``, whose y axis is the up vector of Eq. 4.1) and the collision capsules
are the description's (docs/hardware.md §1, §3). ``dof=8`` gives q = [j1..j6, pitch, roll];
``dof=6`` locks the wrist at zero (rigid tool). The planning model's roll range is
``spec.wrist.roll_limits`` (one turn), not the motor's turn budget the description gives the
joint; velocities are the spec's.

Collision: the description's capsules (the selected utensil's: the planner's proxy from the
mount to the tip) and base cylinder, checked by coal against each other (pairs at most one
body apart along the chain, and ``spec.collision.excluded_pairs``, are skipped) and against
every object of a :class:`~articutool.arm.scene.Scene`.

An ``ArmModel`` owns one ``pinocchio.Data``: use one instance per thread.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from articutool.arm.description import (
    TOOL_BASE_BODY,
    UTENSIL_BODY,
    exact_xml,
    robot_spec,
    tip_site_name,
)
from articutool.arm.scene import Scene
from articutool.spec import Spec

__all__ = ["DOFS", "TOOL_BASE_FRAME", "UTENSIL_MOUNT_FRAME", "ArmModel", "load_robot",
           "tip_frame_name"]

DOFS = (6, 8)
TOOL_BASE_FRAME = TOOL_BASE_BODY
UTENSIL_MOUNT_FRAME = UTENSIL_BODY  # the utensil body's origin is the utensil mount


def tip_frame_name(utensil: str) -> str:
    """Name of the tip frame of ``utensil`` in the Pinocchio model."""
    return tip_site_name(utensil)


def load_robot(spec: Spec, utensil: str) -> tuple[pin.Model, pin.GeometryModel, dict[str, int]]:
    """The 8-DOF Pinocchio model and collision geometry of the robot's description
    (:func:`articutool.arm.description.robot_spec`) with ``utensil``, and each collision
    geom's place along the chain. Pinocchio reads MJCF from a file: a temporary one."""
    mj, chain = robot_spec(spec, utensil)
    with tempfile.TemporaryDirectory(prefix="articutool-robot-") as d:
        path = Path(d) / "robot.xml"
        path.write_text(exact_xml(mj), encoding="utf-8")
        model = pin.buildModelFromMJCF(str(path))
        geoms = pin.buildGeomFromMJCF(model, str(path), pin.GeometryType.COLLISION)
    return model, geoms, chain


def _configure_requests(geometry_data: pin.GeometryData) -> None:
    """The collision and distance request settings every check of this model uses."""
    for req in geometry_data.collisionRequests:
        # coal 3.0.3 misses some penetrations (a capsule's core segment inside a cylinder)
        # on its GJK-only path (enable_contact=False); EPA gets them. A fixed initial guess
        # keeps results independent of the query history.
        req.enable_contact = True
        req.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess
    for dreq in geometry_data.distanceRequests:
        dreq.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess


class ArmModel:
    """The Jaco 2, with the Articutool and a utensil, as one Pinocchio model plus collision.

    Args:
        spec: the hardware spec (``articutool.spec.load_spec()``).
        utensil: which utensil's tip frame and collision capsule to use (``spec.utensils``).
        dof: 8 = arm + active pitch/roll wrist, 6 = wrist locked at zero (rigid tool).
        scene: obstacles; ``None`` loads the packaged default scene (``Scene.load()``).
            Pass ``Scene()`` for none.
    """

    def __init__(
        self, spec: Spec, utensil: str = "spoon", dof: int = 8, scene: Scene | None = None
    ) -> None:
        if utensil not in spec.utensils:
            raise ValueError(f"unknown utensil {utensil!r}; allowed: {sorted(spec.utensils)}")
        if dof not in DOFS:
            raise ValueError(f"dof must be one of {DOFS}; got {dof!r}")
        self.spec = spec
        self.utensil = utensil
        self.dof = dof
        self.scene = scene if scene is not None else Scene.load()

        arm, w = spec.arm, spec.wrist
        lo8 = np.concatenate([arm.lower, [w.pitch_limits[0], w.roll_limits[0]]])
        hi8 = np.concatenate([arm.upper, [w.pitch_limits[1], w.roll_limits[1]]])
        vel8 = np.concatenate([arm.max_velocity, w.velocity_limits])
        full, geoms, segment = load_robot(spec, utensil)
        full.lowerPositionLimit, full.upperPositionLimit = lo8, hi8
        # Pinocchio keeps speed limits as magnitudes, the lower one too.
        full.velocityLimit = full.lowerVelocityLimit = full.upperVelocityLimit = vel8
        for o in self.scene.objects:
            geoms.addGeometryObject(pin.GeometryObject(f"scene/{o.name}", 0, 0, pin.SE3(o.pose),
                                                       o.geometry()))
            segment[f"scene/{o.name}"] = -1
        wrist_ids = [full.getJointId(n) for n in w.joint_names]
        if dof == 6:
            model, gmodel = pin.buildReducedModel(full, geoms, wrist_ids, pin.neutral(full))
        else:
            model, gmodel = full, geoms
        self.model: pin.Model = model
        self.data: pin.Data = model.createData()
        self.geometry_model: pin.GeometryModel = gmodel
        self._add_collision_pairs(segment)
        self.geometry_data: pin.GeometryData = pin.GeometryData(gmodel)
        _configure_requests(self.geometry_data)
        # A broad phase (coal's dynamic AABB tree) skips the pairs whose bounding boxes are
        # apart: same answer as the pair loop, ~1.6x faster per check (tests/test_arm_model).
        self.broadphase = pin.BroadPhaseManager_DynamicAABBTreeCollisionManager(
            model, gmodel, self.geometry_data)
        # The same broad phase on its own model/data copies, for batches of configurations
        # checked in one call (``collisions``): ~11 µs a configuration where a Python call per
        # configuration costs ~20 µs, most of it Boost.Python choosing among the overloads.
        self.broadphase_pool = pin.BroadPhaseManagerPool_DynamicAABBTreeCollisionManager(
            model, gmodel, 1)
        _configure_requests(self.broadphase_pool.getGeometryData(0))

        self.nq: int = model.nq
        self.joint_names: list[str] = list(model.names)[1:]
        self.lower: NDArray[np.float64] = lo8[:dof]
        self.upper: NDArray[np.float64] = hi8[:dof]
        self.velocity_limits: NDArray[np.float64] = vel8[:dof]

        self._frames = {
            "ee": model.getFrameId(arm.ee_frame),
            "tool_base": model.getFrameId(TOOL_BASE_FRAME),
            "tip": model.getFrameId(tip_frame_name(utensil)),
        }
        # Fixed placements of the vectorised F0 chain: the joints' in their parents and F0's
        # in link 6, as loaded.
        placements = [full.jointPlacements[full.getJointId(j.name)] for j in arm.joints]
        self._joint_rot = np.stack([p.rotation for p in placements])
        self._joint_xyz = np.array([p.translation for p in placements])
        f0 = full.frames[full.getFrameId(TOOL_BASE_FRAME)].placement
        self._f0_in_link6 = f0.rotation.copy()
        self._f0_xyz_in_link6 = f0.translation.copy()

    def _add_collision_pairs(self, segment: dict[str, int]) -> None:
        g = self.geometry_model
        names = [o.name for o in g.geometryObjects]
        excluded = set()
        for a, b in self.spec.collision.excluded_pairs:
            for n in (a, b):
                if n not in segment or segment[n] < 0:
                    robot = sorted(k for k, s in segment.items() if s >= 0)
                    raise ValueError(
                        f"collision.excluded_pairs: unknown body {n!r}; bodies: {robot}"
                    )
            excluded.add(frozenset((a, b)))
        contact_ok = {f"scene/{o.name}" for o in self.scene.objects if o.utensil_contact}
        utensil = f"utensil_{self.utensil}"
        self.collision_pairs: list[tuple[str, str]] = []
        for i, a in enumerate(names):
            for j in range(i + 1, len(names)):
                b = names[j]
                sa, sb = segment[a], segment[b]
                if sa < 0 and sb < 0:
                    continue  # scene vs scene: static
                if sa < 0 or sb < 0:
                    robot, obstacle = (b, a) if sa < 0 else (a, b)
                    if segment[robot] == 0:
                        continue  # the fixed base vs static obstacles
                    if robot == utensil and obstacle in contact_ok:
                        continue
                elif abs(sa - sb) <= 1 or frozenset((a, b)) in excluded:
                    continue
                g.addCollisionPair(pin.CollisionPair(i, j))
                self.collision_pairs.append((a, b))

    # --------------------------------------------------------------- validation --
    def _q(self, q: ArrayLike, allowed: Sequence[int], name: str = "q") -> NDArray[np.float64]:
        a = np.asarray(q, dtype=np.float64)
        if a.ndim != 1 or a.shape[0] not in allowed:
            raise ValueError(f"{name} must have shape ({' or '.join(map(str, allowed))},); "
                             f"got {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"{name} must be finite (got NaN or inf)")
        if a.shape[0] < self.nq:
            a = np.concatenate([a, np.zeros(self.nq - a.shape[0])])
        return a

    def _arm_q(self, q: ArrayLike) -> NDArray[np.float64]:
        return self._q(q, sorted({6, self.nq}), "q_arm")

    def _frame_id(self, frame: str) -> int:
        if frame in self._frames:
            return self._frames[frame]
        if self.model.existFrame(frame):
            return self.model.getFrameId(frame)
        raise ValueError(f"unknown frame {frame!r}; use one of {sorted(self._frames)} "
                         "or a model frame name")

    # ------------------------------------------------------------------ kinematics --
    def frame_pose(self, q: ArrayLike, frame: str) -> NDArray[np.float64]:
        """(4, 4) pose of ``frame`` ("ee", "tool_base", "tip" or any model frame) in the base."""
        q = self._q(q, (self.nq,))
        fid = self._frame_id(frame)
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, fid).homogeneous.copy()

    def ee_pose(self, q_arm: ArrayLike) -> NDArray[np.float64]:
        """(4, 4) pose of the Jaco end-effector frame in the arm base frame (6 or nq angles)."""
        return self.frame_pose(self._arm_q(q_arm), "ee")

    def tool_base_pose(self, q_arm: ArrayLike) -> NDArray[np.float64]:
        """(4, 4) pose of the tool base frame F0 in the arm base frame (6 or nq angles)."""
        return self.frame_pose(self._arm_q(q_arm), "tool_base")

    def tip_pose(self, q: ArrayLike) -> NDArray[np.float64]:
        """(4, 4) pose of the selected utensil's tip frame (y axis = up, Eq. 4.1); q: (nq,)."""
        return self.frame_pose(q, "tip")

    def frame_jacobian(self, q: ArrayLike, frame: str = "tip") -> NDArray[np.float64]:
        """(6, nq) Jacobian [linear; angular] of ``frame`` in LOCAL_WORLD_ALIGNED."""
        q = self._q(q, (self.nq,))
        fid = self._frame_id(frame)
        return pin.computeFrameJacobian(
            self.model, self.data, q, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        ).copy()

    def _tool_base_chain(
        self, q_arm: ArrayLike, qd_arm: ArrayLike | None, positions: bool = False
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.float64] | None]:
        q = np.asarray(q_arm, dtype=np.float64)
        if q.ndim == 0 or q.shape[-1] != 6:
            raise ValueError(f"q_arm must have shape (..., 6); got {q.shape}")
        if not np.isfinite(q).all():
            raise ValueError("q_arm must be finite (got NaN or inf)")
        qd = None
        if qd_arm is not None:
            qd = np.asarray(qd_arm, dtype=np.float64)
            if qd.shape != q.shape:
                raise ValueError(f"qd_arm must have the shape of q_arm {q.shape}; got {qd.shape}")
            if not np.isfinite(qd).all():
                raise ValueError("qd_arm must be finite (got NaN or inf)")
        lead = q.shape[:-1]
        c, s = np.cos(q), np.sin(q)
        R = np.empty((*lead, 3, 3))
        R[...] = self._joint_rot[0]
        p = np.zeros((*lead, 3)) + self._joint_xyz[0] if positions else None
        omega = np.zeros((*lead, 3)) if qd is not None else None
        for i in range(6):
            if i:
                if p is not None:  # the joint's origin, placed in its parent's frame
                    x, y, z = self._joint_xyz[i]
                    p = p + R[..., :, 0] * x + R[..., :, 1] * y + R[..., :, 2] * z
                # One GEMM for the whole batch: the fixed joint placement rotation.
                R = (R.reshape(-1, 3) @ self._joint_rot[i]).reshape(*lead, 3, 3)
            if omega is not None:
                omega += R[..., :, 2] * qd[..., i, None]  # joint axis z_i in the base frame
            # R @ Rz(q_i) only mixes the first two columns.
            x, y = R[..., :, 0].copy(), R[..., :, 1]
            ci, si = c[..., i, None], s[..., i, None]
            R[..., :, 0] = ci * x + si * y
            R[..., :, 1] = ci * y - si * x
        if p is not None:
            x, y, z = self._f0_xyz_in_link6
            p = p + R[..., :, 0] * x + R[..., :, 1] * y + R[..., :, 2] * z
        return (R.reshape(-1, 3) @ self._f0_in_link6).reshape(*lead, 3, 3), omega, p

    def tool_base_poses(
        self, q_arm: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Rotations (..., 3, 3) and origins (..., 3) of F0 in the base frame, vectorised."""
        R, _, p = self._tool_base_chain(q_arm, None, positions=True)
        assert p is not None
        return R, p

    def tool_base_rotations(self, q_arm: ArrayLike) -> NDArray[np.float64]:
        """Rotations of F0 in the arm base frame, vectorised: (..., 6) → (..., 3, 3)."""
        return self._tool_base_chain(q_arm, None)[0]

    def tool_base_angular_velocity(
        self, q_arm: ArrayLike, qd_arm: ArrayLike
    ) -> NDArray[np.float64]:
        """Angular velocity of F0 in the base frame, ``Σ z_i q̇_i``: (..., 6) × 2 → (..., 3)."""
        omega = self._tool_base_chain(q_arm, qd_arm)[1]
        assert omega is not None
        return omega

    def tool_base_kinematics(
        self, q_arm: ArrayLike, qd_arm: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Both F0 rotations (..., 3, 3) and angular velocities (..., 3) in one pass."""
        R, omega, _ = self._tool_base_chain(q_arm, qd_arm)
        assert omega is not None
        return R, omega

    # ------------------------------------------------------------------- collision --
    def _collide(self, q: ArrayLike, stop_at_first: bool) -> bool:
        q = self._q(q, (self.nq,))
        return bool(pin.computeCollisions(self.model, self.data, self.geometry_model,
                                          self.geometry_data, q, stop_at_first))

    def in_collision(self, q: ArrayLike) -> bool:
        """True if any checked pair (self or scene) collides at ``q`` (nq,); broad phase."""
        q = self._q(q, (self.nq,))
        return bool(pin.computeCollisions(self.model, self.data, self.broadphase, q, True))

    def collisions(self, q: ArrayLike, stop_at_first: bool = False) -> NDArray[np.bool_]:
        """``in_collision`` of every row of ``q`` (N, nq), in one call (the same broad phase,
        one thread, rows in order). ``stop_at_first``: rows after the first colliding one
        are not checked and read False."""
        a = np.asarray(q, dtype=np.float64)
        if a.ndim != 2 or a.shape[1] != self.nq:
            raise ValueError(f"q must have shape (N, {self.nq}); got {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError("q must be finite (got NaN or inf)")
        if a.shape[0] == 0:
            return np.zeros(0, dtype=bool)
        # One thread: the rows are checked in order, so the first True is the first contact.
        # (Pinocchio sets the thread count of its own OpenMP runtime, which nothing else here
        # uses: pysplishsplash ships its own.)
        return np.asarray(pin.computeCollisionsInParallel(
            1, self.broadphase_pool, np.asfortranarray(a.T), True, stop_at_first), dtype=bool)

    def first_collision(self, q: ArrayLike) -> int | None:
        """Index of the first row of ``q`` (N, nq) in collision, ``None`` if none is."""
        hit = np.flatnonzero(self.collisions(q, stop_at_first=True))
        return int(hit[0]) if hit.size else None

    def colliding_pairs(self, q: ArrayLike) -> list[tuple[str, str]]:
        """Names of every colliding pair at ``q``; scene objects are named ``scene/<name>``."""
        self._collide(q, False)
        res = self.geometry_data.collisionResults
        return [p for p, r in zip(self.collision_pairs, res, strict=True) if r.isCollision()]

    def pair_distances(self, q: ArrayLike) -> NDArray[np.float64]:
        """Signed distance (m, < 0 = penetration) of every pair in ``collision_pairs`` at q."""
        q = self._q(q, (self.nq,))
        pin.computeDistances(self.model, self.data, self.geometry_model, self.geometry_data, q)
        return np.array([r.min_distance for r in self.geometry_data.distanceResults])

    def min_distance(self, q: ArrayLike) -> float:
        """Smallest signed distance (m) over the checked pairs at ``q``; < 0 means collision."""
        d = self.pair_distances(q)
        return float(d.min()) if d.size else float("inf")
