"""The feeding world as a MuJoCo ``MjSpec``, built in code from the hardware spec, the scene
and a food.

Nothing here restates a dimension: the robot is the one description
(:mod:`articutool.arm.description`, which the Pinocchio model loads too), to which this adds
what the simulation needs (servos, sensors, contact filtering); the obstacles come from the
:class:`~articutool.arm.scene.Scene`; the food from :mod:`articutool.sim.params`.

MuJoCo collides a mesh as its convex hull, so every concave thing is a compound of
primitives: a bowl is a floor disc plus a ring of wall boxes; a spoon is a floor plate plus a
ring of sloped wall boxes round an ellipse (a dish); a fork is a handle plus capsule tines.

Collision filtering (``contype``/``conaffinity`` bits): static surfaces 1, food 2,
utensil 4, robot links 8. Food collides with everything; the robot links only with food;
static never with static. The utensil touches the static surfaces (it scrapes the bowl)
through explicit ``<pair>``s.

Contact parameters: every pair that holds a food item gets exactly the law ``physics.toml``
states for that food and that partner (``FoodContacts``: food, utensil, container, surface).
MuJoCo mixes two geoms' parameters (larger condim, larger friction, solmix-weighted solref)
unless their ``priority`` differs, when the higher-priority geom's values are used whole;
so the food's geoms carry the food–food law at priority 0, and every other geom (utensil,
containers, surfaces, the arm's links) carries the food–partner law at priority 1. Food–food
pairs are then one law on both sides, and each food–partner pair takes the partner's. The
utensil–surface pairs hold no food and are explicit ``<pair>``s with ``[world]
utensil_contact``, so what the partners carry for the food never reaches them. (Explicit pairs
for every food pair would be one per item and geom — hundreds of thousands in a bowl.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np
from numpy.typing import NDArray

from articutool.arm.description import FT_SITE, IMU_SITE, add_robot, exact_xml, tip_site_name
from articutool.arm.scene import Box, Capsule, Cylinder, Halfspace, Scene, Sphere
from articutool.food.dish import spoon_dish
from articutool.rotations import rpy_matrix
from articutool.sim.params import ContactParams, Granular, Liquid, PhysicsParams, Strands
from articutool.sim.pieces import Capsule as PieceCapsules
from articutool.sim.pieces import capsule_mass, draw_piece, footprint, pack_layer
from articutool.spec import Spec, UtensilSpec

__all__ = ["FT_SITE", "IMU_SITE", "WorldLayout", "build_mjcf", "contact_attrs", "dish_walls",
           "food_solver_attrs",
           "fork_strand_attrs", "strand_chain", "strand_geom_attrs", "strand_tack_attrs",
           "tip_site_name", "viewer_mjcf"]

_STATIC, _FOOD, _UTENSIL, _ROBOT = 1, 2, 4, 8
_ALL = _STATIC | _FOOD | _UTENSIL | _ROBOT
_WALL_BOXES = 24
_DISH_WALLS = 32
_FRAGMENT = "fragment:"


@dataclass
class WorldLayout:
    """What the builder put where: the world's ``MjSpec`` and the names the world looks up
    after compiling."""

    spec: mujoco.MjSpec
    arm_joints: list[str]
    wrist_joints: list[str]
    food_bodies: list[str] = field(default_factory=list)
    food_strands: list[str] = field(default_factory=list)  # strand k: bodies/geoms "strandk/i"
    strand_segments: int = 0
    timestep: float = 0.0
    piece_mass: float = 0.0
    places: dict[str, str] = field(default_factory=dict)  # geom name → place
    utensil_geoms: list[str] = field(default_factory=list)
    container: str = ""
    parked: bool = False  # the food is a load waiting to be placed on the utensil
    piece_size: float = 0.0  # lattice cell of one piece (m)
    food_contype: int = 0
    food_conaffinity: int = 0
    static_geoms: list[str] = field(default_factory=list)

    @property
    def xml(self) -> str:
        """The world as MJCF text that reads back as the same model (``python -m
        mujoco.viewer --mjcf FILE`` opens it)."""
        return exact_xml(self.spec)


def _f(v: float | NDArray[np.float64] | list[float] | tuple[float, ...]) -> str:
    a = np.atleast_1d(np.asarray(v, dtype=float))
    return " ".join(f"{x:.9g}" for x in a)


def _quat(R: NDArray[np.float64]) -> NDArray[np.float64]:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, dtype=float).reshape(9))
    return q


def _pose_attr(xyz: NDArray[np.float64] | tuple[float, ...], R: NDArray[np.float64]) -> str:
    return f'pos="{_f(xyz)}" quat="{_f(_quat(R))}"'


def _frame(z_dir: NDArray[np.float64], hint: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation whose z axis is ``z_dir`` and whose x axis is as close to ``hint`` as can be."""
    z = z_dir / np.linalg.norm(z_dir)
    x = hint - z * float(hint @ z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def contact_attrs(law: ContactParams | None, priority: int) -> str:
    """A geom's contact attributes carrying ``law`` at ``priority`` (none without a law: the
    geom then meets no food and MuJoCo's defaults never act)."""
    if law is None:
        return ""
    return (f'priority="{priority}" condim="{law.condim}" friction="{_f(law.friction)}" '
            f'solref="{_f(law.solref)}" solimp="{_f(law.solimp)}"')


def food_solver_attrs(food: Granular | Liquid | Strands | None) -> str:
    """The ``<option>`` attributes a food sets: its no-slip passes (strands, pieces; none for
    any other world)."""
    noslip = food.noslip_iterations if isinstance(food, Strands | Granular) else 0
    return f'noslip_iterations="{noslip}"'


def _pair_attrs(law: ContactParams) -> str:
    """An explicit pair's attributes (its friction has five values: both sliding directions,
    torsional, both rolling directions)."""
    sl, tor, roll = law.friction
    return (f'condim="{law.condim}" friction="{_f((sl, sl, tor, roll, roll))}" '
            f'solref="{_f(law.solref)}" solimp="{_f(law.solimp)}"')


def _static_geoms(scene: Scene, food: Granular | Liquid | Strands | None, wall_factor: float,
                  layout: WorldLayout) -> list[str]:
    out = []
    for o in scene.objects:
        law = None if food is None else (food.contacts.container if o.place == "container"
                                         else food.contacts.surface)
        cls = f'contype="{_STATIC}" conaffinity="0" {contact_attrs(law, 1)}'
        rgba = {"container": "0.95 0.95 0.92 1", "table": "0.55 0.4 0.3 1",
                "critical": "0.6 0.65 0.8 1"}.get(o.place or "", "0.7 0.7 0.7 1")
        pose = _pose_attr(o.xyz, o.rotation)
        names = [f"scene/{o.name}"]
        if isinstance(o, Box):
            out.append(f'<geom name="{names[0]}" type="box" size="{_f(np.array(o.size) / 2)}" '
                       f'{pose} {cls} rgba="{rgba}"/>')
        elif isinstance(o, Sphere):
            out.append(f'<geom name="{names[0]}" type="sphere" size="{o.radius}" {pose} {cls} '
                       f'rgba="{rgba}"/>')
        elif isinstance(o, Capsule):
            out.append(f'<geom name="{names[0]}" type="capsule" size="{o.radius} '
                       f'{o.length / 2}" {pose} {cls} rgba="{rgba}"/>')
        elif isinstance(o, Halfspace):
            out.append(f'<geom name="{names[0]}" type="plane" size="0 0 0.05" {pose} {cls} '
                       f'rgba="0.3 0.3 0.3 1"/>')
        elif isinstance(o, Cylinder) and o.container_wall is None:
            out.append(f'<geom name="{names[0]}" type="cylinder" size="{o.radius} '
                       f'{o.length / 2}" {pose} {cls} rgba="{rgba}"/>')
        elif isinstance(o, Cylinder):
            t = o.container_wall
            R, p = o.rotation, np.asarray(o.xyz)
            body = [f'<body name="scene/{o.name}" {_pose_attr(p, R)}>',
                    f'<geom name="scene/{o.name}/floor" type="cylinder" '
                    f'size="{o.radius} {t / 2}" pos="0 0 {-o.length / 2 + t / 2}" {cls} '
                    f'rgba="{rgba}"/>']
            names = [f"scene/{o.name}/floor"]
            n = _WALL_BOXES
            half_w = o.radius * math.tan(math.pi / n) * 1.1
            # Collision walls reach outward to wall_factor × the wall, the inner face kept
            # (physics.toml [world] collision_wall_factor says why).
            tc = t * wall_factor
            for k in range(n):
                a = 2 * math.pi * k / n
                c = (o.radius - t + tc / 2) * np.array([math.cos(a), math.sin(a), 0.0])
                Rk = rpy_matrix((0.0, 0.0, a))
                nm = f"scene/{o.name}/wall{k}"
                names.append(nm)
                body.append(f'<geom name="{nm}" type="box" size="{tc / 2} {half_w} '
                            f'{o.length / 2}" {_pose_attr(c, Rk)} {cls} rgba="{rgba}"/>')
            body.append("</body>")
            out.extend(body)
        else:  # pragma: no cover - the scene schema has no other shapes
            raise ValueError(f"scene object {o.name!r}: unsupported shape")
        if o.place:
            for nm in names:
                layout.places[nm] = o.place
        layout.static_geoms += names
    return out


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


def _utensil_geoms(spec: Spec, utensil: str, layout: WorldLayout,
                   food: Granular | Liquid | Strands | None = None) -> list[str]:
    """Geoms of the utensil in the utensil body (origin at the utensil mount, roll-link axes:
    x = up vector at zero angles, z = out along the roll axis), carrying the food–utensil
    contact law and, with strands, the fork-strand adhesion."""
    u = spec.utensil(utensil)
    ph = u.physics
    th = ph.thickness
    if isinstance(food, Strands):
        law = fork_strand_attrs(food)
    else:
        law = contact_attrs(food.contacts.utensil, 1) if food is not None else ""
    cls = f'contype="{_UTENSIL}" conaffinity="0" {law} rgba="0.75 0.75 0.78 1"'
    out: list[str] = []

    def geom(name: str, body: str) -> None:
        layout.utensil_geoms.append(name)
        out.append(f'<geom name="{name}" {body} {cls}/>')

    if ph.kind == "spoon":
        zc, a, _, a0, b0, depth = spoon_dish(u)
        length = 2 * a
        x0 = u.tip_x  # the floor's inner surface
        geom("utensil/floor", f'type="box" size="{th / 2} {b0} {a0}" '
             f'pos="{x0 - th / 2} 0 {zc}"')
        for k, (c, R, half) in enumerate(dish_walls(u)):
            geom(f"utensil/wall{k}", f'type="box" size="{_f(half)}" {_pose_attr(c, R)}')
        z_end = u.tip_z - length
        geom("utensil/handle", f'type="box" size="{th / 2} 0.004 {z_end / 2}" '
             f'pos="{x0 + depth / 2} 0 {z_end / 2}"')
    else:
        assert ph.tines and ph.tine_length and ph.tine_radius and ph.tine_pitch
        r, n = ph.tine_radius, ph.tines
        z0 = u.tip_z - ph.tine_length
        half_w = (n - 1) / 2 * ph.tine_pitch + r
        geom("utensil/handle", f'type="box" size="{th / 2} 0.004 {z0 / 2}" '
             f'pos="{u.tip_x} 0 {z0 / 2}"')
        geom("utensil/bridge", f'type="box" size="{th / 2} {half_w} {2 * r}" '
             f'pos="{u.tip_x} 0 {z0}"')
        for k in range(n):
            y = (k - (n - 1) / 2) * ph.tine_pitch
            geom(f"utensil/tine{k}", f'type="capsule" size="{r}" '
                 f'fromto="{u.tip_x} {y} {z0} {u.tip_x} {y} {u.tip_z - r}"')
    return out


def _food_bodies(food: Granular | Liquid | Strands, scene: Scene, params: PhysicsParams,
                 rng: np.random.Generator, layout: WorldLayout,
                 load_g: float | None = None) -> list[str]:
    """Food placed loosely above the container's floor; ``settle_s`` lets it fall in.

    With ``load_g`` the food is a load for the utensil instead: that many grams of pieces,
    parked out of the world (no collisions, weightless) until the world places them on the
    utensil (``FeedingWorld.place_load``), as an experimenter loads a tared spoon.
    """
    try:
        box = scene.get(food.container)
    except KeyError as err:
        raise ValueError(f"food container: {err.args[0]}") from None
    if not isinstance(box, Cylinder) or box.container_wall is None:
        raise ValueError(f"food container: scene object {food.container!r} must be a cylinder "
                         "with container_wall (an open bowl)")
    layout.container = food.container
    inner = box.radius - box.container_wall
    floor_z = float(box.inner_floor()[2])
    cx, cy = box.xyz[0], box.xyz[1]
    out: list[str] = []
    radius, mass = 0.0, food.piece_mass
    sph = isinstance(food, Liquid) and load_g is not None and food.sph_load
    if isinstance(food, Liquid):  # a placed load has its own, finer particles (physics.toml)
        radius = food.load_particle_radius if load_g is not None else food.particle_radius
        mass = food.particle_mass(radius)
    if sph:  # one sphere per particle of the SPH load, for when it leaves the dish
        radius, mass = food.sph_particle_radius, food.sph_particle_mass()
    layout.piece_mass = mass
    count = max(1, round((food.fill_g if load_g is None else load_g) / 1000.0 / mass))
    fcls = f'contype="{_FOOD}" conaffinity="{_ALL}" {contact_attrs(food.contacts.food, 0)}'
    layout.food_contype, layout.food_conaffinity = _FOOD, _ALL
    if load_g is not None:
        if isinstance(food, Strands):
            raise ValueError("load_g: strands cannot be placed as a load; use a container fill")
        fcls = f'contype="0" conaffinity="0" {contact_attrs(food.contacts.food, 0)}'
        layout.parked = True
    if isinstance(food, Strands):
        return _strands(food, count, inner, floor_z, cx, cy, rng, layout)
    pieces: list[list[PieceCapsules]] = []
    if isinstance(food, Granular):
        # Pieces drawn until their mass reaches the fill (sizes vary: the count follows).
        target, total = (food.fill_g if load_g is None else load_g) / 1000.0, 0.0
        while total < target - 1e-12 and len(pieces) < 5000:
            pieces.append(draw_piece(food, rng))
            total += capsule_mass(pieces[-1], food.density)
        count = len(pieces)
        # Pieces are flat (capsules in one plane) and start lying flat, turned about the
        # vertical only, packed layer by layer without overlapping (a bowl filled a piece at
        # a time); a layer is 1.5 thicknesses high. A lattice cell that holds the largest
        # piece held 5 a layer: a 0.45 m column whose fall threw pieces out of the bowl.
        cell_z = 1.5 * max(food.half_width_m[1], food.piece_screen_m[1]) / 2.0
        radii = [footprint(c) for c in pieces]
        cell = 2.0 * max(radii)
        pts = []
        z = floor_z + cell_z / 2
        while len(pts) < count:
            layer = pack_layer(radii[len(pts):], inner, rng)
            if not layer:
                raise ValueError(f"food {food.container}: a piece does not fit in the bowl")
            pts += [(x, y, z) for x, y in layer]
            z += cell_z
        size = 'type="capsule"'
        rgba = "0.55 0.33 0.15 1"
    else:
        spread = food.load_radius_spread if load_g is not None and not sph else 0.0
        radii_p = np.full(count, radius)
        if spread > 0:  # radii drawn while the load stays within its mass (the count follows)
            drawn: list[float] = []
            total = 0.0
            while True:
                r_k = radius * (1.0 + spread * rng.uniform(-1.0, 1.0))
                if total + food.particle_mass(r_k) > load_g / 1000.0 and drawn:
                    break
                drawn.append(r_k)
                total += food.particle_mass(r_k)
            radii_p, count = np.array(drawn), len(drawn)
        cell = 2 * radius * (1.0 + spread) * 1.02
        size = 'type="sphere"'
        rgba = "0.3 0.5 0.95 0.8"
        # Lattice inside the inner radius, layer by layer, with a small seeded jitter.
        pts = []
        n_side = int(2 * inner / cell)
        z = floor_z + cell / 2
        while len(pts) < count:
            for i in range(n_side):
                for j in range(n_side):
                    x = -inner + cell / 2 + i * cell
                    y = -inner + cell / 2 + j * cell
                    if math.hypot(x, y) < inner - cell / 2:
                        pts.append((x, y, z))
            z += cell
        pts = pts[:count]
    layout.piece_size = cell
    for k, (x, y, z) in enumerate(pts):
        jitter = np.zeros(3) if pieces else rng.uniform(-0.1, 0.1, 3) * cell
        jitter[2] = abs(jitter[2])
        if load_g is not None:  # parked: a row far from everything
            x, y, z, cx, cy, jitter = 50.0 + k * cell, 50.0, 1.0, 0.0, 0.0, np.zeros(3)
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        if pieces:  # lying flat: the same draw, as a turn about the vertical
            yaw = math.atan2(q[1], q[0])
            q = np.array([math.cos(yaw), 0.0, 0.0, math.sin(yaw)])
        name = f"food{k}"
        layout.food_bodies.append(name)
        grav = ' gravcomp="1"' if load_g is not None else ""
        if pieces:  # capsules weighed by density; the first geom carries the body's name
            geoms = "".join(
                f'<geom name="{name}{"" if i == 0 else f"_{i}"}" {size} size="{r:.9g}" '
                f'fromto="{_f(np.r_[a, b])}" density="{food.density:.9g}" '
                f'{fcls} rgba="{rgba}"/>'
                for i, (a, b, r) in enumerate(pieces[k]))
        else:
            rk = float(radii_p[k])
            mk = mass if sph else food.particle_mass(rk)
            geoms = (f'<geom name="{name}" {size} size="{rk:.9g}" '
                     f'mass="{mk:.9g}" {fcls} rgba="{rgba}"/>')
        out.append(f'<body name="{name}" pos="{_f(np.array([cx + x, cy + y, z]) + jitter)}" '
                   f'quat="{_f(q)}"{grav}><freejoint/>{geoms}</body>')
    return out


def strand_tack_attrs(food: Strands, share: float) -> str:
    """A geom's starch tack toward strands: ``share`` × the tack of one contact
    (:attr:`Strands.tack_per_contact`) acting across the food's ``adhesion_gap``."""
    if food.stickiness_pa <= 0:
        return ""
    return f' adhesion="{share * food.tack_per_contact:.6g}" gap="{food.adhesion_gap:.6g}"'


def fork_strand_attrs(food: Strands, tack: bool = True) -> str:
    """The utensil geoms' contact attributes in a strand world: the strands' law for the
    utensil at priority 1 and the whole tack of one contact. MuJoCo takes a contact's
    adhesion from the higher-priority geom alone, so the fork's tack is all a fork-strand
    contact pulls with."""
    return (contact_attrs(food.contacts.utensil, 1)
            + (strand_tack_attrs(food, 1.0) if tack else ""))


def strand_geom_attrs(food: Strands, tack: bool = True) -> str:
    """A strand geom's contact attributes: the strand-strand law at priority 0 and half the
    tack. MuJoCo sums the adhesion of two geoms of equal priority, so two strands pull with
    the whole tack."""
    return (contact_attrs(food.contacts.food, 0)
            + (strand_tack_attrs(food, 0.5) if tack else ""))


def strand_chain(food: Strands, name: str, pos: NDArray[np.float64] | tuple[float, ...],
                 rotations: list[NDArray[np.float64]], geom_attrs: str,
                 free: bool = True) -> list[str]:
    """One strand: ``food.segments`` capsule bodies ``name/i`` of length ds = L/segments, body
    0 at ``pos`` turned by ``rotations[0]`` (with a free joint, or fixed to its parent when
    ``free`` is false), body i > 0 at the end of body i-1 turned by ``rotations[i]`` relative
    to it, joined by a ball joint whose spring gives the rod's bending stiffness
    (k = E·I/ds, :attr:`Strands.bend_stiffness`; its rest shape is the shape built) and whose
    damping is k × ``bend_damping_s``. Each geom carries ``geom_attrs`` (collision bits and
    contact law). The builder of the bowl's strands and of the calibration experiments."""
    n = food.segments
    ds = food.strand_length / n
    k = food.bend_stiffness
    out = []
    for i in range(n):
        if i == 0:
            joint = "<freejoint/>" if free else ""
            pose = _pose_attr(pos, rotations[0])
        else:
            joint = (f'<joint type="ball" stiffness="{k:.6g}" '
                     f'damping="{k * food.bend_damping_s:.6g}"/>')
            pose = _pose_attr((ds, 0.0, 0.0), rotations[i])
        out.append(f'<body name="{name}/{i}" {pose}>{joint}'
                   f'<geom name="{name}/{i}" type="capsule" size="{food.strand_radius}" '
                   f'fromto="0 0 0 {ds} 0 0" mass="{food.piece_mass / n:.9g}" {geom_attrs} '
                   f'rgba="0.95 0.85 0.45 1"/>')
    out.append("</body>" * n)
    return out


def _strands(food: Strands, count: int, inner: float, floor_z: float, cx: float, cy: float,
             rng: np.random.Generator, layout: WorldLayout) -> list[str]:
    """Strands (:func:`strand_chain`) heaped in layers as spirals of ``food.pile_radius``
    round the container's centre. The rest shape is the laid shape (cooked pasta relaxes to
    how it lies). Adjacent capsules do not collide (parent-child); every other pair does, so
    a strand can lie on its own wrap."""
    out = []
    r, n = food.strand_radius, food.segments
    ds = food.strand_length / n
    layout.strand_segments = n
    attrs = f'contype="{_FOOD}" conaffinity="{_ALL}" {strand_geom_attrs(food)}'
    for k in range(count):
        rad0 = food.pile_radius * rng.uniform(0.5, 1.0)
        off = rng.uniform(-0.3, 0.3, 2) * food.pile_radius
        a0 = rng.uniform(0, 2 * math.pi)
        z = floor_z + r + k * 2.2 * r + 0.002
        # A spiral laid segment by segment: its radius of curvature shrinks to half.
        p = np.array([cx + off[0] + rad0 * math.cos(a0), cy + off[1] + rad0 * math.sin(a0), z])
        turns = [a0 + math.pi / 2] + [ds / (rad0 * (1.0 - 0.5 * i / max(n - 1, 1)))
                                      for i in range(1, n)]
        name = f"strand{k}"
        layout.food_strands.append(name)
        out += strand_chain(food, name, p, [rpy_matrix((0.0, 0.0, t)) for t in turns], attrs)
    return out


# MuJoCo's arena holds a step's contacts, constraint rows and the solvers' scratch. It is
# reserved, not touched: only what the steps use becomes resident. A strand's contact rows
# couple through its whole chain (one kinematic tree), so a heap of strands needs far more per
# contact than loose pieces do: 63 strands (125 g) overflow 256 MB while they fall and used
# 778 MB (12 MB a strand; 11 000 contacts, 24 000 rows: studies/results/noodle_settle_125g.json),
# so the arena grows with the strands, with room for a fork pressed into the heap.
ARENA_MIN_BYTES = 256 << 20
ARENA_PER_STRAND_BYTES = 64 << 20


def arena_bytes(strands: int) -> int:
    """The arena MuJoCo reserves for a world with ``strands`` strands (see above)."""
    return max(ARENA_MIN_BYTES, ARENA_PER_STRAND_BYTES * strands)


def build_mjcf(spec: Spec, scene: Scene, params: PhysicsParams, utensil: str,
               food: str | None = None, seed: int = 0,
               load_g: float | None = None) -> WorldLayout:
    """MJCF of the arm + Articutool with ``utensil``, the scene and (optionally) ``food``:
    a fill of its container, or with ``load_g`` a load parked for the utensil.

    Joint qpos order: the six arm joints, pitch, roll, then the food's free joints.
    """
    spec.utensil(utensil)  # unknown utensils fail here, naming the allowed ones
    arm, w, wp = spec.arm, spec.wrist, params.world
    food_p = params.food(food) if food is not None else None
    rng = np.random.default_rng(seed)
    layout = WorldLayout(spec=mujoco.MjSpec(), arm_joints=arm.joint_names,
                         wrist_joints=list(w.joint_names))
    layout.timestep = wp.timestep
    # The no-slip solver removes soft contacts' creep: a loaded wrap of strands slides off the
    # tines, a heap of pieces flows below its angle of repose (physics.toml says why, per food;
    # it costs time, docs/notes/2026-11-22-simulation-prototypes.md).
    x: list[str] = [
        f'<mujoco model="{arm.model}_articutool_feeding">',
        '<compiler angle="radian" autolimits="true"/>',
        f'<option timestep="{wp.timestep}" solver="{wp.solver}" iterations="{wp.iterations}" '
        f'tolerance="{wp.tolerance}" cone="{wp.cone}" integrator="implicitfast" '
        f'{food_solver_attrs(food_p)} '
        f'sleep_tolerance="{wp.sleep_tolerance}">'
        f'<flag sleep="{"enable" if wp.sleep else "disable"}"/></option>',
        '<visual><global offwidth="1280" offheight="720"/><quality shadowsize="2048"/></visual>',
        '<worldbody>',
        '<light pos="0.3 -0.2 2.0" dir="0 0 -1" directional="true"/>',

        '<camera name="overview" pos="1.6 -0.9 1.1" xyaxes="0.5 0.87 0 -0.4 0.23 0.89"/>',
    ]
    x += _static_geoms(scene, food_p, wp.collision_wall_factor, layout)
    # Cameras placed from the scene: a close view of each container, and one that follows
    # the utensil from beside the food's container (the first container if there is none).
    containers = [o for o in scene.objects
                  if isinstance(o, Cylinder) and o.container_wall is not None]
    view = np.array([0.22, -0.14, 0.16])  # viewpoint offset from the object (m)
    for o in containers:
        x.append(f'<camera name="{o.name}" mode="targetbody" target="scene/{o.name}" '
                 f'pos="{_f(np.asarray(o.xyz) + view)}"/>')
    if containers:
        home = next((o for o in containers if food_p is not None and o.name == food_p.container),
                    containers[0])
        x.append(f'<camera name="utensil" mode="targetbody" target="utensil" '
                 f'pos="{_f(np.asarray(home.xyz) + 1.5 * view)}"/>')
        # A close-up of what the utensil holds once lifted out of the container.
        x.append(f'<camera name="utensil_close" mode="targetbody" target="utensil" '
                 f'pos="{_f(np.asarray(home.xyz) + 0.6 * view + [0.0, 0.0, 0.1])}"/>')
    for r in scene.regions:
        x.append(f'<site name="region/{r.name}" pos="{_f(r.xyz)}" size="{r.radius}" '
                 'rgba="1 0.3 0.3 0.25"/>')

    # The robot's place in the world: its bodies come from the description (below), after the
    # scene's and before the food's.
    x.append(f'<body name="{arm.base_frame}"/>')
    if food_p is not None:
        x += _food_bodies(food_p, scene, params, rng, layout, load_g)
    x.append("</worldbody>")
    # The utensil against every static surface: explicit pairs with their own law.
    geoms = _utensil_geoms(spec, utensil, layout, food_p)
    x.append("<contact>")
    law = _pair_attrs(wp.utensil_contact)
    x += [f'<pair geom1="{g}" geom2="{sg}" {law}/>'
          for g in layout.utensil_geoms for sg in layout.static_geoms]
    x.append("</contact>")
    x.append("</mujoco>")
    world = mujoco.MjSpec.from_string("\n".join(x))
    world.memory = arena_bytes(len(layout.food_strands))
    add_robot(world.body(arm.base_frame), spec, utensil,
              lambda body: _attach_fragment(world, body, geoms))
    _drive_robot(world, spec, params, layout,
                 food_p.contacts.surface if food_p is not None else None)
    layout.spec = world
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


def _attach_fragment(world: mujoco.MjSpec, body: mujoco.MjsBody, geoms: list[str]) -> None:
    """Add MJCF ``<geom>`` elements to ``body`` of ``world`` (the utensil's shape, written
    as MJCF text), keeping their names."""
    frag = mujoco.MjSpec.from_string(
        '<mujoco><compiler angle="radian"/><worldbody>' + "".join(geoms)
        + "</worldbody></mujoco>")
    world.attach(frag, frame=body.add_frame(), prefix=_FRAGMENT)
    for g in body.geoms:
        g.name = g.name.removeprefix(_FRAGMENT)


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
            g.contype, g.conaffinity = _ROBOT, 0
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

