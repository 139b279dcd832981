"""What every part of the feeding world is built with: the collision bits, the contact laws
set on an ``MjsGeom``, the solver options a food sets, poses, and the loose items a container
is filled with (:mod:`articutool.sim.world_spec` and the food builders use them, and so do the
calibration experiments' small worlds).

The world's poses, masses and contact laws are its numbers to 9 significant digits
(:func:`sig`: nanometres at a metre, far below any measured dimension), so they do not hang
on the last bits of the arithmetic that places them.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray

from articutool.arm.description import exact_xml, mj_quat
from articutool.arm.scene import Cylinder
from articutool.sim.params import ContactParams, Granular, Liquid, Strands, WorldParams

__all__ = ["ALL", "FOOD", "ROBOT", "STATIC", "UTENSIL", "Food", "FoodBuilder", "GeomSetter",
           "WorldLayout", "add_items", "pair_law", "set_contact", "set_food_solver",
           "set_pose", "sig", "sigs", "solver_spec"]

# Collision filtering (contype/conaffinity bits): static surfaces, food, utensil, robot links.
STATIC, FOOD, UTENSIL, ROBOT = 1, 2, 4, 8
ALL = STATIC | FOOD | UTENSIL | ROBOT

Food = Granular | Liquid | Strands
GeomSetter = Callable[[mujoco.MjsGeom], None]


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
    # The container's fill is an SPH liquid beside MuJoCo (sim/bowl_liquid.py); the parked
    # items are the particles it hands to MuJoCo (what leaves it, what a dip takes).
    container_liquid: bool = False
    piece_size: float = 0.0  # lattice cell of one piece (m)
    food_contype: int = 0
    food_conaffinity: int = 0
    static_geoms: list[str] = field(default_factory=list)

    @property
    def xml(self) -> str:
        """The world as MJCF text that reads back as the same model (``python -m
        mujoco.viewer --mjcf FILE`` opens it)."""
        return exact_xml(self.spec)


# A food kind's builder: ``(food, container, rng, layout, parent, load_g)`` adds the food's
# bodies under ``parent`` (the world body) in ``container`` (an open bowl), or with
# ``load_g`` that many grams parked for the utensil, and records them in ``layout``. (The
# food is its kind's model: Granular, Liquid or Strands.)
FoodBuilder = Callable[[Any, Cylinder, np.random.Generator, WorldLayout, mujoco.MjsBody,
                        float | None], None]


def sig(x: float, digits: int = 9) -> float:
    """``x`` to ``digits`` significant digits."""
    return float(f"{x:.{digits}g}")


def sigs(v: float | Sequence[float] | NDArray[np.float64], digits: int = 9) -> list[float]:
    """Each value of ``v`` to ``digits`` significant digits."""
    return [sig(float(x), digits) for x in np.atleast_1d(np.asarray(v, dtype=float))]


def set_pose(e: mujoco.MjsBody | mujoco.MjsGeom, xyz: NDArray[np.float64] | Sequence[float],
             R: NDArray[np.float64]) -> None:
    """Place body or geom ``e`` at ``xyz`` turned by ``R`` (in its parent's frame)."""
    e.pos, e.quat = sigs(xyz), sigs(mj_quat(R))


def set_contact(g: mujoco.MjsGeom, law: ContactParams | None, priority: int) -> None:
    """Give geom ``g`` the contact law ``law`` at ``priority`` (nothing without a law: the
    geom then meets no food and MuJoCo's defaults never act)."""
    if law is None:
        return
    g.priority, g.condim = priority, law.condim
    g.friction, g.solref, g.solimp = sigs(law.friction), sigs(law.solref), sigs(law.solimp)


def pair_law(law: ContactParams) -> dict[str, object]:
    """An explicit pair's law as :meth:`mujoco.MjSpec.add_pair` takes it (its friction has five
    values: both sliding directions, torsional, both rolling directions)."""
    sl, tor, roll = law.friction
    return {"condim": law.condim, "friction": sigs((sl, sl, tor, roll, roll)),
            "solref": sigs(law.solref), "solimp": sigs(law.solimp)}


def set_food_solver(option: mujoco.MjOption, food: Food | None) -> None:
    """The solver option a food sets: its no-slip passes (strands, pieces; none for any other
    world)."""
    option.noslip_iterations = food.noslip_iterations if isinstance(food, Strands | Granular) else 0


def solver_spec(world: WorldParams, food: Food | None) -> mujoco.MjSpec:
    """An empty world (angles in radians) with the feeding world's solver (``[world]``:
    timestep, solver, iterations, tolerance, friction cone; the implicit-fast integrator) and
    ``food``'s solver options (:func:`set_food_solver`)."""
    s = mujoco.MjSpec()
    s.compiler.degree = False
    opt = s.option
    opt.timestep, opt.iterations, opt.tolerance = world.timestep, world.iterations, world.tolerance
    opt.solver = getattr(mujoco.mjtSolver, f"mjSOL_{world.solver.upper()}")
    opt.cone = getattr(mujoco.mjtCone, f"mjCONE_{world.cone.upper()}")
    opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    set_food_solver(opt, food)
    return s


def add_items(parent: mujoco.MjsBody, names: list[str], pts: list[tuple[float, float, float]],
              centre: tuple[float, float], cell: float, rng: np.random.Generator,
              parked: bool, flat: bool, add_geoms: Callable[[mujoco.MjsBody, str, int], None]
              ) -> None:
    """Loose items ``food0``, ``food1``, … with free joints at the points ``pts`` (container
    frame, offset by ``centre``), each turned at random; ``flat`` items lie flat (the same
    draw, as a turn about the vertical) and stand exactly on their points, others get a
    seeded jitter of a tenth of a ``cell``. ``parked`` items wait in a row far from everything,
    weightless (gravity compensated). ``add_geoms(body, name, k)`` gives item k its geoms;
    the items' names are appended to ``names``."""
    cx, cy = centre
    for k, (x, y, z) in enumerate(pts):
        jitter = np.zeros(3) if flat else rng.uniform(-0.1, 0.1, 3) * cell
        jitter[2] = abs(jitter[2])
        ox, oy = cx, cy
        if parked:
            x, y, z, ox, oy, jitter = 50.0 + k * cell, 50.0, 1.0, 0.0, 0.0, np.zeros(3)
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        if flat:
            yaw = math.atan2(q[1], q[0])
            q = np.array([math.cos(yaw), 0.0, 0.0, math.sin(yaw)])
        name = f"food{k}"
        names.append(name)
        body = parent.add_body(name=name, pos=sigs(np.array([ox + x, oy + y, z]) + jitter),
                               quat=sigs(q), gravcomp=1.0 if parked else 0.0)
        body.add_freejoint()
        add_geoms(body, name, k)

