"""The robot's one description: the Kinova Jaco 2 (j2n6s200) + Articutool + utensil as a
MuJoCo ``MjSpec``, built from the hardware spec (``data/hardware.toml``).

Both models of the robot come from it: :class:`~articutool.arm.model.ArmModel` loads its
MJCF into Pinocchio (``pinocchio.buildModelFromMJCF``, collision geometry with
``buildGeomFromMJCF``), and the physics world (:mod:`articutool.sim.world_spec`) adds the robot to
its world spec with :func:`add_robot` and drives it. So a dimension, a joint axis or a limit
is written here once (docs/hardware.md §1, §3):

* Jaco chain: each joint of ``spec.arm.joints`` is a body placed at ``(xyz, rpy)`` in its
  parent (URDF fixed-axis roll-pitch-yaw) with a hinge about its local z, limited to the
  joint's range (continuous joints to the spec's ±2π); a capsule from the joint to the next
  one (the hand's: to the end effector) carries the link's mass. The end effector
  ``spec.arm.ee_frame`` sits at ``(ee_xyz, ee_rpy)`` on link 6.
* Articutool: the tool base F0 (``atool_base``, the IMU's site) is fixed to the end effector
  at ``mount_xyz/mount_rpy``. The pitch joint turns about F0's −y axis through
  ``(0, 0, pitch_z)``, the roll joint about +z, ``roll_dz`` further; its range is the roll's
  turn budget. The utensil body (the F/T sensor's site at its origin) is ``utensil_mount_dz``
  further. Each utensil's tip site ``atool_tip_<name>`` sits at ``(tip_x, 0, tip_z)`` in the
  utensil body, rotated by Rz(−π/2), so that its orientation in F0 is
  ``R_y(−θp) R_z(θr) R_z(−π/2)`` = ``articutool.tool.kinematics.rotation`` and its y axis is
  the up vector of Eq. 4.1.
* Collision: capsules (radii from ``spec.collision``) for the links, the wrist housing and the
  distal wrist link, a cylinder for the arm base. The utensil's geometry is the caller's: the
  planner's proxy (a capsule from the mount to the tip, :func:`robot_spec`) or the simulated
  utensil's shape (the physics world's).

What the simulation adds — servo armature and friction, gravity compensation, actuators,
sensors, contact filtering and colours — is the world's (:mod:`articutool.sim.world_spec`).
"""

from __future__ import annotations

import ctypes
import math
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import NDArray

from articutool.rotations import rpy_matrix
from articutool.spec import Spec

__all__ = [
    "FT_SITE",
    "IMU_SITE",
    "TOOL_BASE_BODY",
    "UTENSIL_BODY",
    "add_robot",
    "exact_xml",
    "mj_quat",
    "robot_spec",
    "tip_site_name",
]

TOOL_BASE_BODY = "atool_base"
UTENSIL_BODY = "utensil"
IMU_SITE = "imu"
FT_SITE = "ft"
_TIP_SITE = "atool_tip_{}"
_CAPSULE = mujoco.mjtGeom.mjGEOM_CAPSULE
_CYLINDER = mujoco.mjtGeom.mjGEOM_CYLINDER
_HINGE = mujoco.mjtJoint.mjJNT_HINGE


def tip_site_name(utensil: str) -> str:
    """The utensil tip's site (MuJoCo) and frame (Pinocchio)."""
    return _TIP_SITE.format(utensil)


def mj_quat(R: NDArray[np.float64]) -> NDArray[np.float64]:
    """MuJoCo's unit quaternion (w, x, y, z) of rotation matrix ``R`` (``mju_mat2Quat``, the
    same arithmetic MuJoCo uses, so a pose set from it compiles as MuJoCo would place it)."""
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).reshape(9))
    return q


def _rpy_quat(rpy: tuple[float, float, float] | list[float]) -> NDArray[np.float64]:
    return mj_quat(rpy_matrix(tuple(rpy)))


def _sphere_site(body: mujoco.MjsBody, name: str, radius: float) -> mujoco.MjsSite:
    site = body.add_site(name=name)
    site.size[0] = radius
    return site


UtensilGeoms = Callable[[mujoco.MjsBody], None]


def add_robot(parent: mujoco.MjsBody, spec: Spec, utensil: str,
              utensil_geoms: UtensilGeoms | None = None) -> dict[str, int]:
    """Add the robot's bodies, joints, geoms and sites under ``parent`` (the arm's base body,
    see the module doc) with ``utensil``'s body; ``utensil_geoms(body)`` adds the utensil's
    geometry to it (default: the planner's capsule proxy, named ``utensil_<name>``).

    Returns each robot collision geom's place along the chain (base 0, links 1–6, the wrist
    housing with link 6, the distal wrist link 7, the utensil 8): a pair at most one apart
    touches by construction and is not checked for collision.
    """
    u = spec.utensil(utensil)  # unknown utensils fail here, naming the allowed ones
    arm, w, col = spec.arm, spec.wrist, spec.collision
    chain: dict[str, int] = {}
    h0 = arm.joints[0].xyz[2]
    parent.name = arm.base_frame
    parent.add_geom(name=arm.base_frame, type=_CYLINDER, size=[col.base_radius, h0 / 2, 0.0],
                    pos=[0.0, 0.0, h0 / 2])
    chain[arm.base_frame] = 0
    ee = np.asarray(arm.ee_xyz, dtype=float)
    body = parent
    for i, j in enumerate(arm.joints):
        link = f"{arm.model}_link_{i + 1}"
        end = np.asarray(arm.joints[i + 1].xyz) if i + 1 < len(arm.joints) else ee
        body = body.add_body(name=link, pos=list(j.xyz), quat=_rpy_quat(j.rpy))
        body.add_joint(name=j.name, type=_HINGE, axis=[0.0, 0.0, 1.0],
                       range=[j.lower, j.upper], actfrcrange=[-j.effort, j.effort])
        body.add_geom(name=link, type=_CAPSULE, size=[col.link_radii[i], 0.0, 0.0],
                      fromto=[0.0, 0.0, 0.0, *end], mass=arm.link_masses[i])
        chain[link] = i + 1
    ee_body = body.add_body(name=arm.ee_frame, pos=list(arm.ee_xyz), quat=_rpy_quat(arm.ee_rpy))
    f0 = ee_body.add_body(name=TOOL_BASE_BODY, pos=list(w.mount_xyz),
                          quat=_rpy_quat(w.mount_rpy))
    _sphere_site(f0, IMU_SITE, 0.004).rgba = [0.0, 1.0, 0.0, 1.0]
    f0.add_geom(name="atool_body", type=_CAPSULE, size=[col.wrist_body_radius, 0.0, 0.0],
                fromto=[0.0, 0.0, 0.0, 0.0, 0.0, w.pitch_z], mass=w.mass_kg - w.distal_mass_kg)
    chain["atool_body"] = len(arm.joints)
    # Rotation about F0's −y axis by θp is R_y(−θp) (thesis Eq. 4.1). The pitch link carries
    # no geometry: a small mass keeps its joint's inertia finite.
    tq = spec.motors.stall_torque_nm
    pitch = f0.add_body(name="atool_pitch_link", pos=[0.0, 0.0, w.pitch_z], mass=0.005,
                        ipos=[0.0, 0.0, 0.0], inertia=[1e-6, 1e-6, 1e-6], explicitinertial=True)
    pitch.add_joint(name=w.joint_names[0], type=_HINGE, axis=[0.0, -1.0, 0.0],
                    range=list(w.pitch_limits), actfrcrange=[-tq, tq])
    turns = w.roll_turn_budget * 2 * math.pi
    roll = pitch.add_body(name="atool_roll_link", pos=[0.0, 0.0, w.roll_dz])
    roll.add_joint(name=w.joint_names[1], type=_HINGE, axis=[0.0, 0.0, 1.0],
                   range=[-turns, turns], actfrcrange=[-tq, tq])
    roll.add_geom(name="atool_distal", type=_CAPSULE, size=[col.wrist_distal_radius, 0.0, 0.0],
                  fromto=[0.0, 0.0, -w.roll_dz, 0.0, 0.0, w.utensil_mount_dz],
                  mass=w.distal_mass_kg)
    chain["atool_distal"] = len(arm.joints) + 1
    # The F/T sensor sits between the roll output and the utensil: the utensil is its own
    # (welded) body, so the sensor at its origin measures what it carries.
    m = u.physics.mass_kg
    ub = roll.add_body(name=UTENSIL_BODY, pos=[0.0, 0.0, w.utensil_mount_dz], mass=m,
                       ipos=[0.0, 0.0, u.tip_z / 2], explicitinertial=True,
                       inertia=np.array([1.0, 1.0, 0.02]) * m * u.tip_z**2 / 12)
    _sphere_site(ub, FT_SITE, 0.004).rgba = [1.0, 0.0, 0.0, 1.0]
    if utensil_geoms is None:
        name = f"utensil_{utensil}"
        ub.add_geom(name=name, type=_CAPSULE, size=[col.utensil_radius, 0.0, 0.0],
                    fromto=[0.0, 0.0, 0.0, u.tip_x, 0.0, u.tip_z], mass=0.0)
        chain[name] = len(arm.joints) + 2
    else:
        utensil_geoms(ub)
    tip_q = _rpy_quat((0.0, 0.0, -math.pi / 2))
    for name, us in spec.utensils.items():
        site = _sphere_site(ub, tip_site_name(name), 0.002)
        site.pos, site.quat = [us.tip_x, 0.0, us.tip_z], tip_q
    return chain


def robot_spec(spec: Spec, utensil: str) -> tuple[mujoco.MjSpec, dict[str, int]]:
    """The robot alone, with ``utensil``'s planning proxy (see :func:`add_robot`), and each
    collision geom's place along the chain."""
    s = mujoco.MjSpec()
    s.modelname = f"{spec.arm.model}_articutool"
    s.compiler.degree = False
    s.compiler.autolimits = True
    chain = add_robot(s.worldbody.add_body(), spec, utensil)
    return s, chain


_XML_LOCK = threading.Lock()


def _mujoco_library() -> ctypes.CDLL:
    pkg = Path(mujoco.__file__).parent
    found = sorted(pkg.glob("libmujoco.so*")) + sorted(pkg.glob("libmujoco*.dylib")) + \
        sorted(pkg.glob("mujoco.dll"))
    if not found:
        raise RuntimeError(f"MuJoCo's library is not in {pkg}")
    return ctypes.CDLL(str(found[0]))


@contextmanager
def _exact_floats() -> Iterator[None]:
    """MuJoCo's XML writer prints 6 significant digits; within this, every number as the
    shortest text that reads back as the same double (MuJoCo 4's precision 0, the setting
    its own round-trip tests use), so the written MJCF is the model, not an approximation."""
    lib = _mujoco_library()
    get, put = lib._mjPRIVATE__get_xml_precision, lib._mjPRIVATE__set_xml_precision
    get.restype, put.argtypes = ctypes.c_int, [ctypes.c_int]
    with _XML_LOCK:
        before = get()
        put(0)
        try:
            yield
        finally:
            put(before)


def exact_xml(s: mujoco.MjSpec) -> str:
    """``s`` as MJCF whose every number reads back exactly (see :func:`_exact_floats`)."""
    with _exact_floats():
        return s.to_xml()
