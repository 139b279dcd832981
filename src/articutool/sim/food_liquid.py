"""A liquid in the feeding world: spheres on a lattice inside the container (a fill), or a
load of finer spheres parked for the utensil (the SPH load's particles when the food's load
is SPH). Registered for ``kind = "liquid"`` in :data:`articutool.sim.world_spec.FOOD_BUILDERS`."""

from __future__ import annotations

import math

import mujoco
import numpy as np

from articutool.arm.scene import Cylinder
from articutool.sim.params import Liquid
from articutool.sim.world_parts import ALL, FOOD, WorldLayout, add_items, set_contact, sig

__all__ = ["build_liquid"]

_RGBA = [0.3, 0.5, 0.95, 0.8]


def build_liquid(food: Liquid, box: Cylinder, rng: np.random.Generator, layout: WorldLayout,
                 parent: mujoco.MjsBody, load_g: float | None = None) -> None:
    """Spheres of the food's particle radius (a placed load has its own, finer particles,
    ``physics.toml``; one sphere per particle of an SPH load, for when it leaves the dish), as
    many as the fill's (or ``load_g``'s) mass holds, on a lattice inside the container's inner
    radius, layer by layer, with a small seeded jitter. A load's radii may spread
    (``load_radius_spread``): they are drawn while the load stays within its mass."""
    inner = box.radius - box.container_wall
    floor_z = float(box.inner_floor()[2])
    sph = load_g is not None and food.sph_load
    radius = food.load_particle_radius if load_g is not None else food.particle_radius
    mass = food.particle_mass(radius)
    if sph:
        radius, mass = food.sph_particle_radius, food.sph_particle_mass()
    layout.piece_mass = mass
    count = max(1, round((food.fill_g if load_g is None else load_g) / 1000.0 / mass))
    spread = food.load_radius_spread if load_g is not None and not sph else 0.0
    radii = np.full(count, radius)
    if spread > 0:
        assert load_g is not None
        drawn: list[float] = []
        total = 0.0
        while True:
            r_k = radius * (1.0 + spread * rng.uniform(-1.0, 1.0))
            if total + food.particle_mass(r_k) > load_g / 1000.0 and drawn:
                break
            drawn.append(r_k)
            total += food.particle_mass(r_k)
        radii, count = np.array(drawn), len(drawn)
    cell = 2 * radius * (1.0 + spread) * 1.02
    pts: list[tuple[float, float, float]] = []
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
    bits = (0, 0) if load_g is not None else (FOOD, ALL)

    def geoms(body: mujoco.MjsBody, name: str, k: int) -> None:
        rk = float(radii[k])
        g = body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[sig(rk), 0.0, 0.0],
                          mass=sig(mass if sph else food.particle_mass(rk)),
                          contype=bits[0], conaffinity=bits[1], rgba=_RGBA)
        set_contact(g, food.contacts.food, 0)

    add_items(parent, layout.food_bodies, pts, (box.xyz[0], box.xyz[1]), cell, rng,
              load_g is not None, False, geoms)
