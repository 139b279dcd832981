"""Strands in the feeding world (noodles): chains of capsules joined by ball joints whose
springs give the rod's bending stiffness, heaped in the container; their contact laws and
starch tack toward each other and the fork. Registered for ``kind = "strands"`` in
:data:`articutool.sim.world_spec.FOOD_BUILDERS`; the calibration experiments
(:mod:`articutool.sim.strand_laws`) build their strands with :func:`strand_chain` too."""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np
from numpy.typing import NDArray

from articutool.arm.scene import Cylinder
from articutool.rotations import rpy_matrix
from articutool.sim.params import Strands
from articutool.sim.world_parts import (
    ALL,
    FOOD,
    GeomSetter,
    WorldLayout,
    set_contact,
    set_pose,
    sig,
)

__all__ = ["build_strands", "set_fork_strand", "set_strand_geom", "set_strand_tack",
           "strand_chain"]

_RGBA = [0.95, 0.85, 0.45, 1.0]


def set_strand_tack(g: mujoco.MjsGeom, food: Strands, adhesion: float) -> None:
    """Give geom ``g`` ``adhesion`` N of starch tack per contact point, acting across the
    food's ``adhesion_gap``; none when the food is not sticky. MuJoCo sums the gaps of a
    pair's two geoms (whatever their priorities), so each sticky geom carries half."""
    if food.stickiness_pa > 0:
        g.adhesion = sig(adhesion, 6)
        g.gap = sig(food.adhesion_gap / 2.0, 6)


def set_fork_strand(g: mujoco.MjsGeom, food: Strands, tack: bool = True) -> None:
    """A utensil geom's contact in a strand world: the strands' law for the utensil at
    priority 1 and the tack of one contact of a strand lying on it
    (:attr:`Strands.tack_per_contact`). MuJoCo takes a contact's adhesion from the
    higher-priority geom alone, so the fork's tack is all a fork-strand contact pulls with."""
    set_contact(g, food.contacts.utensil, 1)
    if tack:
        set_strand_tack(g, food, food.tack_per_contact)


def set_strand_geom(g: mujoco.MjsGeom, food: Strands, tack: bool = True) -> None:
    """A strand geom's contact: the strand-strand law at priority 0 and half the tack of a
    strand–strand contact point (:attr:`Strands.tack_per_strand_contact`, the film's law
    averaged over a settled nest's contact angles). MuJoCo sums the adhesion of two geoms of
    equal priority, so every strand–strand contact pulls with that mean: more than a
    right-angle crossing's law, less than two strands lying along each other (docs/food.md)."""
    set_contact(g, food.contacts.food, 0)
    if tack:
        set_strand_tack(g, food, food.tack_per_strand_contact / 2.0)


def strand_chain(food: Strands, parent: mujoco.MjsBody, name: str,
                 pos: NDArray[np.float64] | Sequence[float], rotations: list[NDArray[np.float64]],
                 set_geom: GeomSetter, free: bool = True) -> None:
    """One strand under ``parent``: ``food.segments`` capsule bodies ``name/i`` of length
    ds = L/segments, body 0 at ``pos`` turned by ``rotations[0]`` (with a free joint, or fixed
    to its parent when ``free`` is false), body i > 0 at the end of body i-1 turned by
    ``rotations[i]`` relative to it, joined by a ball joint whose spring gives the rod's
    bending stiffness (k = E·I/ds, :attr:`Strands.bend_stiffness`; its rest shape is the shape
    built) and whose damping is k × ``bend_damping_s``. ``set_geom`` gives each geom its
    collision bits and contact law. The builder of the bowl's strands and of the calibration
    experiments."""
    n = food.segments
    ds = food.strand_length / n
    k = food.bend_stiffness
    body = parent
    for i in range(n):
        body = body.add_body(name=f"{name}/{i}")
        if i == 0:
            set_pose(body, pos, rotations[0])
            if free:
                body.add_freejoint()
        else:
            set_pose(body, (ds, 0.0, 0.0), rotations[i])
            body.add_joint(type=mujoco.mjtJoint.mjJNT_BALL, stiffness=[sig(k, 6), 0.0, 0.0],
                           damping=[sig(k * food.bend_damping_s, 6), 0.0, 0.0])
        g = body.add_geom(name=f"{name}/{i}", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                          size=[food.strand_radius, 0.0, 0.0], fromto=[0.0, 0.0, 0.0, ds, 0.0, 0.0],
                          mass=sig(food.piece_mass / n), rgba=_RGBA)
        set_geom(g)


def build_strands(food: Strands, box: Cylinder, rng: np.random.Generator, layout: WorldLayout,
                  parent: mujoco.MjsBody, load_g: float | None = None) -> None:
    """Strands (:func:`strand_chain`), as many as the fill's mass holds, heaped in layers as
    spirals of ``food.pile_radius`` round the container's centre. The rest shape is the laid
    shape (cooked pasta relaxes to how it lies). Adjacent capsules do not collide
    (parent-child); every other pair does, so a strand can lie on its own wrap. Strands are
    never a load (``load_g``)."""
    if load_g is not None:
        raise ValueError("load_g: strands cannot be placed as a load; use a container fill")
    layout.piece_mass = food.piece_mass
    count = max(1, round(food.fill_g / 1000.0 / food.piece_mass))
    floor_z = float(box.inner_floor()[2])
    cx, cy = box.xyz[0], box.xyz[1]
    r, n = food.strand_radius, food.segments
    ds = food.strand_length / n
    layout.strand_segments = n

    def strand_geom(g: mujoco.MjsGeom) -> None:
        g.contype, g.conaffinity = FOOD, ALL
        set_strand_geom(g, food)

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
        strand_chain(food, parent, name, p, [rpy_matrix((0.0, 0.0, t)) for t in turns],
                     strand_geom)
