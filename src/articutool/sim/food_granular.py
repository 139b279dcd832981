"""A granular food in the feeding world: pieces (flat clusters of capsules, drawn by
:func:`articutool.sim.pieces.draw_piece`) packed layer by layer in the container, or a load
of them parked for the utensil. Registered for ``kind = "granular"`` in
:data:`articutool.sim.world_spec.FOOD_BUILDERS`."""

from __future__ import annotations

import mujoco
import numpy as np

from articutool.arm.scene import Cylinder
from articutool.sim.params import Granular
from articutool.sim.pieces import capsule_mass, draw_piece, footprint, pack_layer
from articutool.sim.world_parts import ALL, FOOD, WorldLayout, add_items, set_contact, sig, sigs

__all__ = ["build_granular"]

_RGBA = [0.55, 0.33, 0.15, 1.0]


def build_granular(food: Granular, box: Cylinder, rng: np.random.Generator,
                   layout: WorldLayout, parent: mujoco.MjsBody,
                   load_g: float | None = None) -> None:
    """Pieces drawn until their mass reaches the fill (or ``load_g``; sizes vary: the count
    follows), lying flat, turned about the vertical only, packed layer by layer without
    overlapping (a bowl filled a piece at a time); a layer is 1.5 thicknesses high. (A
    lattice cell that holds the largest piece held 5 a layer: a 0.45 m column whose fall
    threw pieces out of the bowl.) Each piece is its capsules weighed by the food's density;
    the first capsule carries the body's name."""
    layout.piece_mass = food.piece_mass
    inner = box.radius - box.container_wall
    floor_z = float(box.inner_floor()[2])
    pieces = []
    target, total = (food.fill_g if load_g is None else load_g) / 1000.0, 0.0
    while total < target - 1e-12 and len(pieces) < 5000:
        pieces.append(draw_piece(food, rng))
        total += capsule_mass(pieces[-1], food.density)
    cell_z = 1.5 * max(food.half_width_m[1], food.piece_screen_m[1]) / 2.0
    radii = [footprint(c) for c in pieces]
    cell = 2.0 * max(radii)
    pts: list[tuple[float, float, float]] = []
    z = floor_z + cell_z / 2
    while len(pts) < len(pieces):
        layer = pack_layer(radii[len(pts):], inner, rng)
        if not layer:
            raise ValueError(f"food {food.container}: a piece does not fit in the bowl")
        pts += [(x, y, z) for x, y in layer]
        z += cell_z
    layout.piece_size = cell
    bits = (0, 0) if load_g is not None else (FOOD, ALL)

    def geoms(body: mujoco.MjsBody, name: str, k: int) -> None:
        for i, (a, b, r) in enumerate(pieces[k]):
            g = body.add_geom(name=name if i == 0 else f"{name}_{i}",
                              type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[sig(r), 0.0, 0.0],
                              fromto=sigs(np.r_[a, b]), density=sig(food.density),
                              contype=bits[0], conaffinity=bits[1], rgba=_RGBA)
            set_contact(g, food.contacts.food, 0)

    add_items(parent, layout.food_bodies, pts, (box.xyz[0], box.xyz[1]), cell, rng,
              load_g is not None, True, geoms)
