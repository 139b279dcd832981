"""The feeding world as a MuJoCo ``MjSpec``, built in code from the hardware spec, the scene
and a food.

Nothing here restates a dimension: the robot is the one description
(:mod:`articutool.arm.description`, which the Pinocchio model loads too), to which this adds
what the simulation needs (servos, sensors, contact filtering); the obstacles come from the
:class:`~articutool.arm.scene.Scene`; the food from :mod:`articutool.sim.params`.

MuJoCo collides a mesh as its convex hull, so every concave thing is a compound of
primitives: a bowl is a floor disc plus a ring of wall boxes; a spoon is a floor plate plus a
ring of sloped wall boxes round an ellipse (a dish); a fork is a handle plus capsule tines.

Every body, geom, site, camera, light, option, pair, actuator and sensor is added through
MuJoCo's ``MjSpec`` API; :attr:`WorldLayout.xml` writes the result as MJCF text. Each food
kind has its builder (:data:`FOOD_BUILDERS`, one module each: its bodies and where a load
waits), so a new kind is a module plus its parameters.

Collision filtering (``contype``/``conaffinity`` bits, :mod:`articutool.sim.world_parts`):
static surfaces 1, food 2, utensil 4, robot links 8. Food collides with everything; the robot
links only with food; static never with static. The utensil touches the static surfaces (it
scrapes the bowl) through explicit pairs.

Contact parameters: every pair that holds a food item gets exactly the law ``physics.toml``
states for that food and that partner (``FoodContacts``: food, utensil, container, surface).
MuJoCo mixes two geoms' parameters (larger condim, larger friction, solmix-weighted solref)
unless their ``priority`` differs, when the higher-priority geom's values are used whole;
so the food's geoms carry the food–food law at priority 0, and every other geom (utensil,
containers, surfaces, the arm's links) carries the food–partner law at priority 1. Food–food
pairs are then one law on both sides, and each food–partner pair takes the partner's. The
utensil–surface pairs hold no food and are explicit pairs with ``[world]
utensil_contact``, so what the partners carry for the food never reaches them. (Explicit pairs
for every food pair would be one per item and geom — hundreds of thousands in a bowl.)
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from numpy.typing import NDArray

from articutool.arm.description import FT_SITE, IMU_SITE, add_robot, exact_xml, tip_site_name
from articutool.arm.scene import Box, Capsule, Cylinder, Halfspace, Scene, Sphere
from articutool.food.dish import spoon_dish
from articutool.rotations import rpy_matrix
from articutool.sim.food_granular import build_granular
from articutool.sim.food_liquid import build_liquid
from articutool.sim.food_strands import build_strands, set_fork_strand
from articutool.sim.loading import max_load_g
from articutool.sim.params import ContactParams, Liquid, PhysicsParams
from articutool.sim.world_parts import (
    ALL,
    FOOD,
    ROBOT,
    STATIC,
    UTENSIL,
    Food,
    FoodBuilder,
    WorldLayout,
    pair_law,
    set_contact,
    set_pose,
    sigs,
    solver_spec,
)
from articutool.spec import Spec, UtensilSpec

__all__ = ["FOOD_BUILDERS", "FT_SITE", "IMU_SITE", "WorldLayout", "build_world_spec", "dish_walls",
           "tip_site_name", "viewer_mjcf"]

_WALL_BOXES = 24
_DISH_WALLS = 32
_G = mujoco.mjtGeom

# The builder of each food kind (``kind`` in physics.toml).
FOOD_BUILDERS: dict[str, FoodBuilder] = {
    "granular": build_granular,
    "liquid": build_liquid,
    "strands": build_strands,
}

_PLACE_RGBA = {"container": [0.95, 0.95, 0.92, 1.0], "table": [0.55, 0.4, 0.3, 1.0],
               "critical": [0.6, 0.65, 0.8, 1.0]}


def _static_geoms(world: mujoco.MjSpec, scene: Scene, food: Food | None, wall_factor: float,
                  layout: WorldLayout) -> None:
    """The scene's objects as static geoms carrying the food's law for their place; an open
    container (a cylinder with ``container_wall``) is a body of a floor disc and a ring of
    wall boxes."""
    for o in scene.objects:
        law = None if food is None else (food.contacts.container if o.place == "container"
                                         else food.contacts.surface)
        rgba = _PLACE_RGBA.get(o.place or "", [0.7, 0.7, 0.7, 1.0])
        names = [f"scene/{o.name}"]

        def geom(parent: mujoco.MjsBody, name: str, kind: mujoco.mjtGeom, size: list[float],
                 rgba: list[float] = rgba, law: ContactParams | None = law
                 ) -> mujoco.MjsGeom:
            g = parent.add_geom(name=name, type=kind, size=size, contype=STATIC,
                                conaffinity=0, rgba=rgba)
            set_contact(g, law, 1)
            return g

        wb = world.worldbody
        if isinstance(o, Box):
            set_pose(geom(wb, names[0], _G.mjGEOM_BOX, sigs(np.array(o.size) / 2)),
                     o.xyz, o.rotation)
        elif isinstance(o, Sphere):
            set_pose(geom(wb, names[0], _G.mjGEOM_SPHERE, [o.radius, 0.0, 0.0]),
                     o.xyz, o.rotation)
        elif isinstance(o, Capsule):
            set_pose(geom(wb, names[0], _G.mjGEOM_CAPSULE, [o.radius, o.length / 2, 0.0]),
                     o.xyz, o.rotation)
        elif isinstance(o, Halfspace):
            set_pose(geom(wb, names[0], _G.mjGEOM_PLANE, [0.0, 0.0, 0.05],
                          rgba=[0.3, 0.3, 0.3, 1.0]), o.xyz, o.rotation)
        elif isinstance(o, Cylinder) and o.container_wall is None:
            set_pose(geom(wb, names[0], _G.mjGEOM_CYLINDER, [o.radius, o.length / 2, 0.0]),
                     o.xyz, o.rotation)
        elif isinstance(o, Cylinder):
            t = o.container_wall
            body = wb.add_body(name=f"scene/{o.name}")
            set_pose(body, np.asarray(o.xyz), o.rotation)
            names = [f"scene/{o.name}/floor"]
            geom(body, names[0], _G.mjGEOM_CYLINDER, [o.radius, t / 2, 0.0]).pos = [
                0.0, 0.0, -o.length / 2 + t / 2]
            n = _WALL_BOXES
            half_w = o.radius * math.tan(math.pi / n) * 1.1
            # Collision walls reach outward to wall_factor × the wall, the inner face kept
            # (physics.toml [world] collision_wall_factor says why).
            tc = t * wall_factor
            for k in range(n):
                a = 2 * math.pi * k / n
                c = (o.radius - t + tc / 2) * np.array([math.cos(a), math.sin(a), 0.0])
                nm = f"scene/{o.name}/wall{k}"
                names.append(nm)
                set_pose(geom(body, nm, _G.mjGEOM_BOX, [tc / 2, half_w, o.length / 2]),
                         c, rpy_matrix((0.0, 0.0, a)))
        else:  # pragma: no cover - the scene schema has no other shapes
            raise ValueError(f"scene object {o.name!r}: unsupported shape")
        if o.place:
            for nm in names:
                layout.places[nm] = o.place
        layout.static_geoms += names


def dish_walls(u: UtensilSpec, n: int = _DISH_WALLS
               ) -> list[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]]:
    """The spoon dish's sloped wall as ``n`` boxes (centre, rotation, half sizes; utensil
    frame) whose inner faces lie on the ideal dish of :func:`spoon_dish`.

    The ideal wall is ruled: the line from the floor ellipse's point at angle φ to the rim's.
    Box k is the plate through the ruling at φ_k = 2πk/n, in the plane tangent to the wall
    at the ruling's mid-height (the wall is not developable, so that plane meets the ideal
    surface only there: it departs from it by < 0.1 mm along the ruling, tested), thick
    outward only; its inner face spans exactly the floor's height to the rim's, with
    horizontal bottom and top edges, and is as wide as the farthest point where it meets a
    neighbour's plane at the rim plus 0.2 mm, so neighbouring plates overlap outside the
    dish and leave no gap. With n divisible by 4 a plate is centred on the tip, the back and
    both sides: the rim's lowest point when tilted is the ideal one.
    """
    zc, a, b, a0, b0, depth = spoon_dish(u)
    th = u.physics.thickness
    x0 = u.tip_x

    def to_utensil(p: NDArray[np.float64]) -> NDArray[np.float64]:
        # Dish coordinates (along, across, up from the floor) → utensil frame.
        return np.array([x0 + p[2], p[1], zc + p[0]])

    def plate(phi: float) -> tuple[NDArray[np.float64], ...]:
        c, s_ = math.cos(phi), math.sin(phi)
        bottom = np.array([a0 * c, b0 * s_, 0.0])
        top = np.array([a * c, b * s_, depth])
        mid = (bottom + top) / 2
        am, bm = (a0 + a) / 2, (b0 + b) / 2
        t = np.array([-am * s_, bm * c, 0.0])
        t /= np.linalg.norm(t)
        normal = np.cross(top - bottom, t)  # outward (the ruling rises outward)
        normal /= np.linalg.norm(normal)
        if normal @ np.array([c, s_, 0.0]) < 0:
            normal = -normal
        slope = np.cross(normal, t)  # in the plate, perpendicular to its horizontal edges
        if slope[2] < 0:
            slope = -slope
        return mid, t, normal, slope, top

    plates = [plate(2 * math.pi * k / n) for k in range(n)]
    out = []
    for k, (mid, t, normal, slope, _) in enumerate(plates):
        # Where this plate's top edge meets each neighbour's plane (both at the rim height).
        reach = 0.0
        for j in (k - 1, (k + 1) % n):
            _, _, nj, _, topj = plates[j]
            top_mid = mid + slope * ((depth - mid[2]) / slope[2])
            # Solve for s: (top_mid + s·t − topj) · nj = 0.
            denom = float(t @ nj)
            if abs(denom) > 1e-12:
                reach = max(reach, abs(float((topj - top_mid) @ nj) / denom))
        half_w = reach + 2e-4
        half_len = depth / slope[2] / 2
        centre = mid + normal * th / 2
        # The box's axes in the utensil frame (dish → utensil swaps along and up, a
        # reflection; the width axis is flipped to keep the rotation proper — a box is
        # symmetric).
        P = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
        R = np.column_stack([P @ normal, -(P @ t), P @ slope])
        out.append((to_utensil(centre), R, np.array([th / 2, half_w, half_len])))
    return out


def _utensil_geoms(spec: Spec, utensil: str, layout: WorldLayout, body: mujoco.MjsBody,
                   food: Food | None = None) -> None:
    """The utensil's geoms in its ``body`` (origin at the utensil mount, roll-link axes:
    x = up vector at zero angles, z = out along the roll axis), carrying the food–utensil
    contact law and, with strands, the fork-strand adhesion."""
    u = spec.utensil(utensil)
    ph = u.physics
    th = ph.thickness

    def geom(name: str, kind: mujoco.mjtGeom, size: list[float]) -> mujoco.MjsGeom:
        layout.utensil_geoms.append(name)
        g = body.add_geom(name=name, type=kind, size=size, contype=UTENSIL, conaffinity=0,
                          rgba=[0.75, 0.75, 0.78, 1.0])
        if food is not None and food.kind == "strands":
            set_fork_strand(g, food)  # type: ignore[arg-type]
        elif food is not None:
            set_contact(g, food.contacts.utensil, 1)
        return g

    if ph.kind == "spoon":
        zc, a, _, a0, b0, depth = spoon_dish(u)
        length = 2 * a
        x0 = u.tip_x  # the floor's inner surface
        geom("utensil/floor", _G.mjGEOM_BOX, [th / 2, b0, a0]).pos = [x0 - th / 2, 0.0, zc]
        for k, (c, R, half) in enumerate(dish_walls(u)):
            set_pose(geom(f"utensil/wall{k}", _G.mjGEOM_BOX, sigs(half)), c, R)
        z_end = u.tip_z - length
        geom("utensil/handle", _G.mjGEOM_BOX, [th / 2, 0.004, z_end / 2]).pos = [
            x0 + depth / 2, 0.0, z_end / 2]
    else:
        assert ph.tines and ph.tine_length and ph.tine_radius and ph.tine_pitch
        r, n = ph.tine_radius, ph.tines
        z0 = u.tip_z - ph.tine_length
        half_w = (n - 1) / 2 * ph.tine_pitch + r
        geom("utensil/handle", _G.mjGEOM_BOX, [th / 2, 0.004, z0 / 2]).pos = [
            u.tip_x, 0.0, z0 / 2]
        geom("utensil/bridge", _G.mjGEOM_BOX, [th / 2, half_w, 2 * r]).pos = [u.tip_x, 0.0, z0]
        for k in range(n):
            y = (k - (n - 1) / 2) * ph.tine_pitch
            geom(f"utensil/tine{k}", _G.mjGEOM_CAPSULE, [r, 0.0, 0.0]).fromto = [
                u.tip_x, y, z0, u.tip_x, y, u.tip_z - r]


def _food_bodies(food: Food, scene: Scene, rng: np.random.Generator, layout: WorldLayout,
                 parent: mujoco.MjsBody, load_g: float | None = None) -> None:
    """Food placed loosely above the container's floor by its kind's builder
    (:data:`FOOD_BUILDERS`); ``settle_s`` lets it fall in.

    With ``load_g`` the food is a load for the utensil instead: that many grams of pieces,
    parked out of the world (no collisions, weightless) until the world places them on the
    utensil (``world.placement.place``), as an experimenter loads a tared spoon.
    """
    try:
        box = scene.get(food.container)
    except KeyError as err:
        raise ValueError(f"food container: {err.args[0]}") from None
    if not isinstance(box, Cylinder) or box.container_wall is None:
        raise ValueError(f"food container: scene object {food.container!r} must be a cylinder "
                         "with container_wall (an open bowl)")
    layout.container = food.container
    layout.food_contype, layout.food_conaffinity = FOOD, ALL
    layout.parked = load_g is not None
    FOOD_BUILDERS[food.kind](food, box, rng, layout, parent, load_g)


# MuJoCo's arena holds a step's contacts, constraint rows and the solvers' scratch. It is
# reserved, not touched: only what the steps use becomes resident. A strand's contact rows
# couple through its whole chain (one kinematic tree), so a heap of strands needs far more per
# contact than loose pieces do: 63 strands (125 g) overflow 256 MB while they fall and used
# 778 MB (12 MB a strand; 11 000 contacts, 24 000 rows: studies/results/noodle_settle_125g.json),
# so the arena grows with the strands, with room for a fork pressed into the heap.
ARENA_MIN_BYTES = 256 << 20
ARENA_PER_STRAND_BYTES = 64 << 20


# Parked items of a world whose container holds an SPH liquid, per gram the utensil holds
# level: what a dip leaves in the dish (at most that) and what leaves the container (a
# numerical choice: headroom for splashes).
BOWL_POOL_FACTOR = 1.5


def arena_bytes(strands: int) -> int:
    """The arena MuJoCo reserves for a world with ``strands`` strands (see above)."""
    return max(ARENA_MIN_BYTES, ARENA_PER_STRAND_BYTES * strands)


def build_world_spec(spec: Spec, scene: Scene, params: PhysicsParams, utensil: str,
                     food: str | None = None, seed: int = 0,
                     load_g: float | None = None) -> WorldLayout:
    """The world's ``MjSpec``: the arm + Articutool with ``utensil``, the scene and
    (optionally) ``food``: a fill of its container, or with ``load_g`` a load parked for the
    utensil.

    Joint qpos order: the six arm joints, pitch, roll, then the food's free joints.
    """
    spec.utensil(utensil)  # unknown utensils fail here, naming the allowed ones
    arm, w, wp = spec.arm, spec.wrist, params.world
    food_p = params.food(food) if food is not None else None
    rng = np.random.default_rng(seed)
    # The no-slip solver removes soft contacts' creep: a loaded wrap of strands slides off the
    # tines, a heap of pieces flows below its angle of repose (physics.toml says why, per food;
    # it costs time, docs/notes/2026-11-22-simulation-prototypes.md).
    world = solver_spec(wp, food_p)
    layout = WorldLayout(spec=world, arm_joints=arm.joint_names,
                         wrist_joints=list(w.joint_names))
    layout.timestep = wp.timestep
    world.modelname = f"{arm.model}_articutool_feeding"
    world.option.sleep_tolerance = wp.sleep_tolerance
    if wp.sleep:
        world.option.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP
    world.visual.global_.offwidth, world.visual.global_.offheight = 1280, 720
    world.visual.quality.shadowsize = 2048
    wb = world.worldbody
    wb.add_light(pos=[0.3, -0.2, 2.0], dir=[0.0, 0.0, -1.0],
                 type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    cam = wb.add_camera(name="overview", pos=[1.6, -0.9, 1.1])
    cam.alt.type = mujoco.mjtOrientation.mjORIENTATION_XYAXES
    cam.alt.xyaxes = [0.5, 0.87, 0.0, -0.4, 0.23, 0.89]
    _static_geoms(world, scene, food_p, wp.collision_wall_factor, layout)
    # Cameras placed from the scene: a close view of each container, and one that follows
    # the utensil from beside the food's container (the first container if there is none).
    containers = [o for o in scene.objects
                  if isinstance(o, Cylinder) and o.container_wall is not None]
    view = np.array([0.22, -0.14, 0.16])  # viewpoint offset from the object (m)
    target = mujoco.mjtCamLight.mjCAMLIGHT_TARGETBODY
    for o in containers:
        wb.add_camera(name=o.name, mode=target, targetbody=f"scene/{o.name}",
                      pos=sigs(np.asarray(o.xyz) + view))
    if containers:
        home = next((o for o in containers if food_p is not None and o.name == food_p.container),
                    containers[0])
        wb.add_camera(name="utensil", mode=target, targetbody="utensil",
                      pos=sigs(np.asarray(home.xyz) + 1.5 * view))
        # A close-up of what the utensil holds once lifted out of the container.
        wb.add_camera(name="utensil_close", mode=target, targetbody="utensil",
                      pos=sigs(np.asarray(home.xyz) + 0.6 * view + [0.0, 0.0, 0.1]))
    for r in scene.regions:
        site = wb.add_site(name=f"region/{r.name}", pos=sigs(r.xyz), rgba=[1.0, 0.3, 0.3, 0.25])
        site.size = [r.radius, *site.size[1:]]
    # The robot's place in the world: its bodies come from the description (below), after the
    # scene's and before the food's.
    base = wb.add_body(name=arm.base_frame)
    if food_p is not None:
        if load_g is None and isinstance(food_p, Liquid) and food_p.sph_load:
            # The container's SPH liquid; parked items for the particles it hands over.
            layout.container_liquid = True
            load_g = BOWL_POOL_FACTOR * max_load_g(spec.utensil(utensil), "liquid",
                                                   food_p.density)
        _food_bodies(food_p, scene, rng, layout, wb, load_g)
    world.memory = arena_bytes(len(layout.food_strands))
    add_robot(base, spec, utensil,
              lambda body: _utensil_geoms(spec, utensil, layout, body, food_p))
    # The utensil against every static surface: explicit pairs with their own law.
    law = pair_law(wp.utensil_contact)
    for g in layout.utensil_geoms:
        for sg in layout.static_geoms:
            world.add_pair(geomname1=g, geomname2=sg, **law)  # type: ignore[arg-type]
    _drive_robot(world, spec, params, layout,
                 food_p.contacts.surface if food_p is not None else None)
    return layout


def viewer_mjcf(layout: WorldLayout, q_arm: NDArray[np.float64]) -> str:
    """The world as MJCF for MuJoCo's own viewer (``python -m mujoco.viewer --mjcf FILE``),
    with a keyframe ``start``: the arm at ``q_arm`` and its servos holding it there, the food
    as placed (it settles when the simulation runs). The world's model is left as it is."""
    s = layout.spec.copy()
    m = s.compile()
    qpos, ctrl = m.qpos0.copy(), np.zeros(m.nu)
    for name, q in zip(layout.arm_joints, q_arm, strict=True):
        qpos[m.joint(name).qposadr[0]] = q
        ctrl[m.actuator(f"{name}/pos").id] = q
    s.add_key(name="start", qpos=qpos, ctrl=ctrl)
    return exact_xml(s)


def _drive_robot(world: mujoco.MjSpec, spec: Spec, params: PhysicsParams,
                 layout: WorldLayout, food_law: ContactParams | None) -> None:
    """What the simulation adds to the robot's description: the servos (the arm's position
    and velocity loops, their armature; the wrist motors' torque, armature and friction),
    the arm's gravity compensation (the Jaco's controller carries its own links), the IMU and
    F/T sensors, and the robot links' contact filter, colour and ``food_law`` (the food's law
    against a surface, at priority 1 as every partner of the food carries its law)."""
    arm, w = spec.arm, spec.wrist
    sp, wm = params.arm_servo, params.wrist_motor
    utensil = set(layout.utensil_geoms)
    for g in world.geoms:
        if g.name not in utensil and _in_robot(g.parent, arm.base_frame):
            g.contype, g.conaffinity = ROBOT, 0
            g.rgba = [0.25, 0.25, 0.28, 1.0]
            if food_law is not None:
                g.priority, g.condim = 1, food_law.condim
                g.friction, g.solref = list(food_law.friction), list(food_law.solref)
                g.solimp = list(food_law.solimp)
    for i, j in enumerate(arm.joints):
        world.body(f"{arm.model}_link_{i + 1}").gravcomp = 1.0
        world.joint(j.name).armature = sp.armature
    for jn in w.joint_names:
        jt = world.joint(jn)
        jt.armature, jt.frictionloss = wm.armature, wm.frictionloss
    tq = spec.motors.stall_torque_nm
    joint = mujoco.mjtTrn.mjTRN_JOINT
    for j in arm.joints:
        world.add_actuator(name=f"{j.name}/pos", target=j.name, trntype=joint).set_to_position(
            kp=sp.kp)
        world.add_actuator(name=f"{j.name}/vel", target=j.name, trntype=joint).set_to_velocity(
            kv=sp.kv)
    for jn in w.joint_names:  # torque from the world's velocity PI (the XC430's own loop)
        world.add_actuator(name=f"{jn}/motor", target=jn, trntype=joint,
                           ctrlrange=[-tq, tq]).set_to_motor()
    site = mujoco.mjtObj.mjOBJ_SITE
    for name, kind, where in (("imu_accel", "ACCELEROMETER", IMU_SITE),
                              ("imu_gyro", "GYRO", IMU_SITE), ("ft_force", "FORCE", FT_SITE),
                              ("ft_torque", "TORQUE", FT_SITE)):
        world.add_sensor(name=name, type=getattr(mujoco.mjtSensor, f"mjSENS_{kind}"),
                         objtype=site, objname=where)


def _in_robot(body: mujoco.MjsBody, root: str) -> bool:
    while body is not None and body.name != "world":
        if body.name == root:
            return True
        body = body.parent
    return False

