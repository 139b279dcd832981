"""What the viewer draws, taken from the MuJoCo model of the feeding world.

The robot (Jaco + Articutool + the current utensil) and the scene (table, plate, bowl, user,
wheelchair) are the geoms of :func:`articutool.sim.world_spec.build_world_spec`, built from the
one spec and the one scene file, so the viewer restates no dimension. Each geom becomes a
triangle mesh in its own frame once (:func:`geom_meshes`); a configuration only moves them
(:class:`Poser`). Food bodies (free joints) are not meshes here: the viewer draws food as
points. A ground plane is drawn as a square tile (MuJoCo's is infinite).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import trimesh
from numpy.typing import ArrayLike, NDArray

__all__ = ["GeomMesh", "Poser", "geom_meshes", "model_for_view"]

_GROUND_HALF = 1.2  # m: the drawn part of a ground plane around its origin
_GROUND_RGBA = (0.93, 0.93, 0.93, 1.0)  # light, under the grid


@dataclass(frozen=True)
class GeomMesh:
    """One geom as a mesh in the geom's own frame."""

    name: str
    geom_id: int
    vertices: NDArray[np.float32]  # (V, 3)
    faces: NDArray[np.int32]  # (F, 3)
    rgba: tuple[float, float, float, float]
    robot: bool  # moves with the arm (else a static scene object)
    plane: bool = False  # a ground plane, drawn as a square tile


def _primitive(gtype: int, size: NDArray[np.float64]) -> trimesh.Trimesh | None:
    g = mujoco.mjtGeom
    if gtype == g.mjGEOM_SPHERE:
        return trimesh.creation.icosphere(subdivisions=3, radius=size[0])
    if gtype == g.mjGEOM_CAPSULE:
        return trimesh.creation.capsule(height=2 * size[1], radius=size[0], count=[16, 16])
    if gtype == g.mjGEOM_CYLINDER:
        return trimesh.creation.cylinder(radius=size[0], height=2 * size[1], sections=32)
    if gtype == g.mjGEOM_BOX:
        return trimesh.creation.box(extents=2 * size)
    if gtype == g.mjGEOM_ELLIPSOID:
        m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
        m.apply_scale(size)
        return m
    if gtype == g.mjGEOM_PLANE:  # infinite in MuJoCo: a square floor tile, top at z = 0
        m = trimesh.creation.box(extents=(2 * _GROUND_HALF, 2 * _GROUND_HALF, 0.002))
        m.apply_translation((0.0, 0.0, -0.001))
        return m
    return None  # height fields, meshes: none in our worlds


def geom_meshes(model: mujoco.MjModel, robot_root: str) -> list[GeomMesh]:
    """Meshes of every geom except food (bodies with a free joint).

    ``robot_root`` names the body whose subtree is the robot (the arm base frame).
    """
    root = model.body(robot_root).id
    free = {int(model.jnt_bodyid[j]) for j in range(model.njnt)
            if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE}

    def in_robot(b: int) -> bool:
        while b > 0:
            if b == root:
                return True
            b = int(model.body_parentid[b])
        return False

    out = []
    for gid in range(model.ngeom):
        b = int(model.geom_bodyid[gid])
        if b in free:
            continue
        mesh = _primitive(int(model.geom_type[gid]), model.geom_size[gid])
        if mesh is None:
            continue
        out.append(GeomMesh(
            name=model.geom(gid).name or f"geom{gid}", geom_id=gid,
            vertices=np.asarray(mesh.vertices, dtype=np.float32),
            faces=np.asarray(mesh.faces, dtype=np.int32),
            rgba=(_GROUND_RGBA if model.geom_type[gid] == mujoco.mjtGeom.mjGEOM_PLANE
                  else tuple(float(c) for c in model.geom_rgba[gid])),
            robot=in_robot(b), plane=bool(model.geom_type[gid] == mujoco.mjtGeom.mjGEOM_PLANE)))
    return out


def model_for_view(spec: object, scene: object, utensil: str) -> tuple[mujoco.MjModel, str]:
    """The feeding world's model without food, for showing plans and configurations;
    returns the compiled model and the robot's root body name."""
    from articutool.sim.params import PhysicsParams
    from articutool.sim.world_spec import build_world_spec

    layout = build_world_spec(spec, scene, PhysicsParams.load(), utensil)  # type: ignore[arg-type]
    return layout.spec.compile(), spec.arm.base_frame  # type: ignore[attr-defined]


class Poser:
    """Poses geoms for a robot configuration (or a full recorded ``qpos``).

    Args:
        model: the compiled MuJoCo model.
        joint_names: names of the joints ``q`` gives, in order (the 8 robot joints).
    """

    def __init__(self, model: mujoco.MjModel, joint_names: list[str] | tuple[str, ...]) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self._adr = np.array([model.joint(n).qposadr[0] for n in joint_names], dtype=np.int64)

    def set_q(self, q: ArrayLike) -> None:
        """Put the robot at ``q`` (the food stays where the model put it)."""
        self.data.qpos[self._adr] = np.asarray(q, dtype=float)
        mujoco.mj_kinematics(self.model, self.data)

    def set_qpos(self, qpos: ArrayLike) -> None:
        """Put the whole world at a recorded ``qpos`` (robot and food)."""
        self.data.qpos[:] = np.asarray(qpos, dtype=float)
        mujoco.mj_kinematics(self.model, self.data)

    def poses(self, geom_ids: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Positions (K, 3) and unit quaternions (K, 4, w x y z) of the geoms now."""
        ids = np.asarray(geom_ids, dtype=np.int64)
        pos = self.data.geom_xpos[ids].copy()
        quat = np.empty((ids.size, 4))
        for k, g in enumerate(ids):
            mujoco.mju_mat2Quat(quat[k], self.data.geom_xmat[g])
        return pos, quat
