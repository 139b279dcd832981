"""Calibration experiments: what a food model's parameters produce, measured in the physics.

These are measurements to compare with physical properties of the real food — never a loop
that adjusts parameters towards an outcome of the thesis.

- ``angle_of_repose_deg`` (granular): the "lifted cylinder" test — a column of pieces on the
  table is released and spreads into a heap; the angle is ``atan(height / radius)`` of the
  heap (radius: the distance from the heap's axis within which 90 % of the pieces lie).
- ``level_capacity_g`` (granular, liquid): what the level utensil holds when loaded far
  beyond its capacity by the world's own loading (pieces dropped one by one; particles
  poured into the dish), after 1 s at rest.
- ``bulk_density_g_per_ml`` (liquid): the mass of the settled fill over the volume it fills
  in its container (the particle model is meant to weigh what the same volume of water does).
- strands: each mechanism alone beside its law (capstan, bending, tack, mass and diameter;
  :mod:`articutool.sim.strand_laws`).
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from articutool.arm.scene import Cylinder, Scene
from articutool.sim.params import Granular, Liquid, PhysicsParams, Strands
from articutool.sim.pieces import draw_piece, piece_extent
from articutool.sim.world import FeedingWorld
from articutool.spec import Spec
from articutool.tool.api import Mode

__all__ = ["angle_of_repose_deg", "level_capacity_g", "run_calibration"]


def angle_of_repose_deg(food: Granular, params: PhysicsParams, n: int = 80,
                        seed: int = 0) -> float:
    """Lifted-cylinder angle of repose of ``n`` pieces on a flat surface (degrees)."""
    rng = np.random.default_rng(seed)
    cell = piece_extent(food) * 1.05
    per_layer = [(x, y) for x in (-1, 0, 1) for y in (-1, 0, 1)]
    bodies = []
    for k in range(n):
        x, y = per_layer[k % len(per_layer)]
        z = cell / 2 + (k // len(per_layer)) * cell
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        geoms = "".join(
            f'<geom type="capsule" size="{r}" fromto="{" ".join(map(str, (*a, *b)))}" '
            f'density="{food.density}" friction="{food.friction[0]} {food.friction[1]} '
            f'{food.friction[2]}" condim="6" solref="{food.solref[0]} {food.solref[1]}"/>'
            for a, b, r in draw_piece(food, rng))
        bodies.append(
            f'<body pos="{x * cell + rng.uniform(-1e-3, 1e-3)} {y * cell} {z}" '
            f'quat="{q[0]} {q[1]} {q[2]} {q[3]}"><freejoint/>{geoms}</body>')
    w = params.world
    xml = (f'<mujoco><option timestep="{w.timestep}" solver="{w.solver}" '
           f'iterations="{w.iterations}" tolerance="{w.tolerance}" cone="{w.cone}"/>'
           f'<worldbody><geom type="plane" size="1 1 0.1" friction="{w.surface_friction} '
           f'0.005 0.0001"/>{"".join(bodies)}</worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    for _ in range(round(4.0 / m.opt.timestep)):
        mujoco.mj_step(m, d)
    p = d.xpos[1:]
    centre = np.median(p[:, :2], axis=0)
    radius = float(np.quantile(np.linalg.norm(p[:, :2] - centre, axis=1), 0.9))
    height = float(p[:, 2].max())
    return math.degrees(math.atan2(height, radius))


def level_capacity_g(food_name: str, spec: Spec, params: PhysicsParams, utensil: str | None,
                     seed: int = 0, load_g: float = 20.0) -> tuple[float, float]:
    """(held, loaded) in g: what the leveled utensil still holds 1 s after being loaded with
    ``load_g``, or with as much as the loader can pour if that is less (a liquid heaped
    above the rim); if all of it stays, the capacity is at least that."""
    world = FeedingWorld(food_name, utensil, spec=spec, params=params, seed=seed,
                         load_g=load_g)
    if world.max_load_g() < load_g:
        world = FeedingWorld(food_name, utensil, spec=spec, params=params, seed=seed,
                             load_g=world.max_load_g() - 1e-6)
    world.tool.set_mode(Mode.LEVELING)
    world.run(1.0)
    world.place_load(settle_s=1.0)
    return world.masses_g()["utensil"], world.report().total_g


def run_calibration(food_name: str, utensil: str | None, *, spec: Spec,
                    params: PhysicsParams, seed: int = 0) -> dict[str, Any]:
    """Every calibration experiment that applies to the food; a dict of measured values."""
    food = params.food(food_name)
    out: dict[str, Any] = {"food": food_name, "kind": food.kind,
                                   "piece_mass_g": round(food.piece_mass * 1000.0, 4)}
    if isinstance(food, Granular):
        out["angle_of_repose_deg"] = round(angle_of_repose_deg(food, params, seed=seed), 1)
    if isinstance(food, Granular | Liquid):
        held, loaded = level_capacity_g(food_name, spec, params, utensil, seed)
        out["level_capacity_g"] = round(held, 2)
        out["loaded_g"] = round(loaded, 2)
        if held >= loaded - 1e-9:  # all of it stayed: the utensil holds at least this
            out["level_capacity_is_lower_bound"] = "yes"
    if isinstance(food, Liquid):
        box = Scene.load().get(food.container)
        world = FeedingWorld(food_name, utensil, spec=spec, params=params, seed=seed)
        assert isinstance(box, Cylinder) and box.container_wall is not None
        inner = box.radius - box.container_wall
        floor = box.xyz[2] - box.length / 2 + box.container_wall
        z = np.array([world.data.xpos[b][2] for b in world.ledger.item_body])
        top = float(np.quantile(z, 0.95)) + food.particle_radius
        vol_ml = math.pi * inner**2 * (top - floor) * 1e6
        out["bulk_density_g_per_ml"] = round(world.masses_g()["container"] / vol_ml, 3)
    if isinstance(food, Strands):
        from articutool.sim.strand_laws import run_strand_calibration

        out.update(run_strand_calibration(food, params, spec, utensil or food.utensil))
    return out
