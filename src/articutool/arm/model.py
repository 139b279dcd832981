"""Kinova Jaco 2 (j2n6s200) + Articutool models built with Pinocchio from the hardware spec.

Kinematics (docs/hardware.md §1, §3):

* Jaco chain: for each joint of ``spec.arm.joints`` the placement ``SE3(rpy, xyz)`` in the
  parent frame (URDF fixed-axis roll-pitch-yaw) followed by a revolute joint about local z;
  the fixed end-effector frame ``spec.arm.ee_frame`` is ``SE3(ee_rpy, ee_xyz)`` on joint 6.
  Continuous joints are plain revolute joints limited to the spec's ±2π.
* Articutool: the tool base frame F0 (``atool_base``) is fixed to the end effector by
  ``mount_xyz/mount_rpy``. The pitch joint turns about F0's −y axis through (0, 0, pitch_z),
  the roll joint about +z, roll_dz further along z; the utensil mount is utensil_mount_dz
  further. Each utensil's tip frame ``atool_tip_<name>`` sits at (tip_x, 0, mount + tip_z) in
  the roll link, rotated by Rz(−π/2), so that its orientation in F0 is
  ``R_y(−θp) R_z(θr) R_z(−π/2)`` = ``articutool.tool.kinematics.rotation`` and its y axis is
  the up vector of Eq. 4.1.

``dof=8`` gives q = [j1..j6, pitch, roll]; ``dof=6`` locks the wrist at zero (rigid tool).

Collision: capsules (radii from ``spec.collision``) for the Jaco links, the wrist housing,
the distal wrist link and the utensil, a cylinder for the arm base, checked by coal against
each other (pairs at most one body apart along the chain, and ``spec.collision.excluded_pairs``,
are skipped) and against every object of a :class:`~articutool.arm.scene.Scene`.

An ``ArmModel`` owns one ``pinocchio.Data``: use one instance per thread.
"""

from __future__ import annotations

from collections.abc import Sequence

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike, NDArray

from articutool.arm.scene import Scene
from articutool.rotations import rpy_matrix
from articutool.spec import Spec

__all__ = ["DOFS", "TOOL_BASE_FRAME", "UTENSIL_MOUNT_FRAME", "ArmModel", "tip_frame_name"]

DOFS = (6, 8)
TOOL_BASE_FRAME = "atool_base"
UTENSIL_MOUNT_FRAME = "atool_utensil_mount"
_TIP_FRAME = "atool_tip_{}"
_Z = np.array([0.0, 0.0, 1.0])


def tip_frame_name(utensil: str) -> str:
    """Name of the tip frame of ``utensil`` in the Pinocchio model."""
    return _TIP_FRAME.format(utensil)


def _se3(xyz: Sequence[float], rpy: Sequence[float] = (0.0, 0.0, 0.0)) -> pin.SE3:
    return pin.SE3(rpy_matrix(tuple(rpy)), np.asarray(xyz, dtype=float))


def _segment(p0: ArrayLike, p1: ArrayLike) -> tuple[float, pin.SE3]:
    """Length and placement of a z-axis primitive spanning p0 → p1 (its centre, z along it)."""
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    d = p1 - p0
    length = float(np.linalg.norm(d))
    R = pin.Quaternion.FromTwoVectors(_Z, d / length).matrix()
    return length, pin.SE3(R, 0.5 * (p0 + p1))


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

        full, geoms, segment = self._build_full()
        wrist_ids = [full.getJointId(n) for n in spec.wrist.joint_names]
        if dof == 6:
            model, gmodel = pin.buildReducedModel(full, geoms, wrist_ids, pin.neutral(full))
        else:
            model, gmodel = full, geoms
        self.model: pin.Model = model
        self.data: pin.Data = model.createData()
        self.geometry_model: pin.GeometryModel = gmodel
        self._add_collision_pairs(segment)
        self.geometry_data: pin.GeometryData = pin.GeometryData(gmodel)
        for req in self.geometry_data.collisionRequests:
            # coal 3.0.3 misses some penetrations (a capsule's core segment inside a cylinder)
            # on its GJK-only path (enable_contact=False); EPA gets them. A fixed initial guess
            # keeps results independent of the query history.
            req.enable_contact = True
            req.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess
        for dreq in self.geometry_data.distanceRequests:
            dreq.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess
        # A broad phase (coal's dynamic AABB tree) skips the pairs whose bounding boxes are
        # apart: same answer as the pair loop, ~1.6x faster per check (tests/test_arm_model).
        self.broadphase = pin.BroadPhaseManager_DynamicAABBTreeCollisionManager(
            model, gmodel, self.geometry_data)

        self.nq: int = model.nq
        self.joint_names: list[str] = list(model.names)[1:]
        arm, w = spec.arm, spec.wrist
        lo, hi, vel = arm.lower, arm.upper, arm.max_velocity
        if dof == 8:
            lo = np.concatenate([lo, [w.pitch_limits[0], w.roll_limits[0]]])
            hi = np.concatenate([hi, [w.pitch_limits[1], w.roll_limits[1]]])
            vel = np.concatenate([vel, w.velocity_limits])
        self.lower: NDArray[np.float64] = lo
        self.upper: NDArray[np.float64] = hi
        self.velocity_limits: NDArray[np.float64] = vel

        self._frames = {
            "ee": model.getFrameId(arm.ee_frame),
            "tool_base": model.getFrameId(TOOL_BASE_FRAME),
            "tip": model.getFrameId(tip_frame_name(utensil)),
        }
        # Fixed rotations of the vectorised F0 chain (docs/hardware.md §1, §3).
        self._joint_rot = np.stack([rpy_matrix(j.rpy) for j in arm.joints])
        self._joint_xyz = np.array([j.xyz for j in arm.joints])
        self._f0_in_link6 = rpy_matrix(arm.ee_rpy) @ rpy_matrix(w.mount_rpy)
        self._f0_xyz_in_link6 = (np.asarray(arm.ee_xyz)
                                 + rpy_matrix(arm.ee_rpy) @ np.asarray(w.mount_xyz))

    # ------------------------------------------------------------------ building --
    def _build_full(self) -> tuple[pin.Model, pin.GeometryModel, dict[str, int]]:
        """The 8-DOF model, its collision geometry and each body's index along the chain."""
        spec, arm, w, col = self.spec, self.spec.arm, self.spec.wrist, self.spec.collision
        m = pin.Model()
        m.name = f"{arm.model}_articutool"
        g = pin.GeometryModel()
        segment: dict[str, int] = {}
        body_frame = {0: 0}  # joint id → frame id of the body it moves

        def add_joint(parent: int, jm: object, place: pin.SE3, name: str, body: str,
                      effort: float, vmax: float, lo: float, hi: float) -> int:
            jid = m.addJoint(parent, jm, place, name, np.array([effort]), np.array([vmax]),
                             np.array([lo]), np.array([hi]))
            m.appendBodyToJoint(jid, pin.Inertia.Zero(), pin.SE3.Identity())
            jf = m.addJointFrame(jid, body_frame[parent])
            body_frame[jid] = m.addBodyFrame(body, jid, pin.SE3.Identity(), jf)
            return jid

        def add_frame(name: str, joint: int, place: pin.SE3) -> None:
            m.addFrame(pin.Frame(name, joint, body_frame[joint], place, pin.FrameType.OP_FRAME))

        def add_geom(name: str, joint: int, place: pin.SE3, shape: object, seg: int) -> None:
            # The parent frame must be given for buildReducedModel to re-parent the object.
            g.addGeometryObject(pin.GeometryObject(name, joint, body_frame[joint], place, shape))
            segment[name] = seg

        m.addFrame(pin.Frame(arm.base_frame, 0, 0, pin.SE3.Identity(), pin.FrameType.FIXED_JOINT))
        h0 = arm.joints[0].xyz[2]
        add_geom(arm.base_frame, 0, pin.SE3(np.eye(3), np.array([0.0, 0.0, h0 / 2])),
                 coal.Cylinder(col.base_radius, h0), 0)

        ee = _se3(arm.ee_xyz, arm.ee_rpy)
        jid = 0
        for i, j in enumerate(arm.joints):
            link = f"{arm.model}_link_{i + 1}"
            jid = add_joint(jid, pin.JointModelRZ(), _se3(j.xyz, j.rpy), j.name, link,
                            j.effort, j.max_velocity, j.lower, j.upper)
            # Capsule from this joint to the next one (the hand: to the end effector).
            end = arm.joints[i + 1].xyz if i + 1 < len(arm.joints) else ee.translation
            length, place = _segment(np.zeros(3), end)
            add_geom(link, jid, place, coal.Capsule(col.link_radii[i], length), i + 1)
        j6 = jid
        add_frame(arm.ee_frame, j6, ee)

        f0 = ee * _se3(w.mount_xyz, w.mount_rpy)
        add_frame(TOOL_BASE_FRAME, j6, f0)
        length, place = _segment(np.zeros(3), [0.0, 0.0, w.pitch_z])
        add_geom("atool_body", j6, f0 * place, coal.Capsule(col.wrist_body_radius, length), 6)

        # Rotation about F0's −y axis by θp is R_y(−θp) (thesis Eq. 4.1). The wrist motors'
        # effort is not modelled (kinematic model): 1.0 is a placeholder.
        pitch = add_joint(j6, pin.JointModelRevoluteUnaligned(0.0, -1.0, 0.0),
                          f0 * _se3([0.0, 0.0, w.pitch_z]), w.joint_names[0], "atool_pitch_link",
                          1.0, w.max_velocity[0], *w.pitch_limits)
        roll = add_joint(pitch, pin.JointModelRZ(), _se3([0.0, 0.0, w.roll_dz]),
                         w.joint_names[1], "atool_roll_link",
                         1.0, w.max_velocity[1], *w.roll_limits)
        mount = np.array([0.0, 0.0, w.utensil_mount_dz])
        add_frame(UTENSIL_MOUNT_FRAME, roll, pin.SE3(np.eye(3), mount))
        length, place = _segment([0.0, 0.0, -w.roll_dz], mount)
        add_geom("atool_distal", roll, place, coal.Capsule(col.wrist_distal_radius, length), 7)

        tip_rot = rpy_matrix((0.0, 0.0, -np.pi / 2))
        for name, u in spec.utensils.items():
            tip = mount + np.array([u.tip_x, 0.0, u.tip_z])
            add_frame(tip_frame_name(name), roll, pin.SE3(tip_rot, tip))
            if name == self.utensil:
                length, place = _segment(mount, tip)
                add_geom(f"utensil_{name}", roll, place,
                         coal.Capsule(col.utensil_radius, length), 8)

        for o in self.scene.objects:
            add_geom(f"scene/{o.name}", 0, pin.SE3(o.pose), o.geometry(), -1)
        return m, g, segment

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
