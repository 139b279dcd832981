"""A load placed on the utensil by hand (the thesis' Exp. 2b/2c protocol): how much, and how.

A world built with ``load_g`` holds a parked supply of its food; :class:`LoadPlacement` (the
world's ``placement``) puts the load on the utensil the way a scoop leaves it, with the pure
geometry of :mod:`articutool.sim.loading`. The capacity bound (:func:`utensil_capacity_bound_g`)
refuses a load no utensil holds; :func:`load_supply_g` sizes the supply.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from articutool.sim.ledger import FoodLedger
from articutool.sim.loading import (
    DEPOSIT_CLEARANCE_M,
    deposit_spot,
    dish_surface_height,
    max_load_g,
    pour_lattice,
)
from articutool.sim.params import Granular, Liquid, PhysicsParams, Strands
from articutool.sim.world_spec import WorldLayout
from articutool.spec import Spec, UtensilSpec

if TYPE_CHECKING:
    from articutool.sim.liquid_load import LiquidLoad

__all__ = ["SUPPLY_FACTOR", "LoadPlacement", "capacity_bound_reason", "load_supply_g",
           "utensil_capacity_bound_g"]

# Pieces in a placed load's supply per gram of the load (``place`` deposits until the utensil
# holds the load; the rest stays parked). A numerical choice: at the capacity load a third of
# the deposited pieces rolled off the heap in trials (seeds 0-4), so twice the load suffices.
SUPPLY_FACTOR = 2.0


def utensil_capacity_bound_g(spec: Spec, params: PhysicsParams, food: str,
                             utensil: str | None = None) -> float:
    """The most ``utensil`` (default: the food's) can hold of ``food`` (g): a liquid fills
    its dish level to the rim, pieces the dish and a heap at their angle of repose
    (:func:`articutool.sim.loading.max_load_g`)."""
    fp = params.food(food)
    u = spec.utensil(utensil or fp.utensil)
    return max_load_g(u, fp.kind, fp.density,
                      fp.angle_of_repose_deg if isinstance(fp, Granular) else None)


def load_supply_g(params: PhysicsParams, food: str | None,
                  load_g: float | None) -> float | None:
    """What the world places to leave ``load_g`` of ``food`` on the utensil. A hand takes
    pieces from a supply until the utensil holds the load: some roll off on the way
    (:meth:`LoadPlacement.place`), so a granular supply holds more than the load."""
    if load_g is not None and food is not None and isinstance(params.food(food), Granular):
        return SUPPLY_FACTOR * load_g
    return load_g


def capacity_bound_reason(fp: Granular | Liquid | Strands) -> str:
    """Why :func:`utensil_capacity_bound_g` is the bound, in words."""
    if isinstance(fp, Liquid):
        return "its dish filled level to the rim: a liquid without surface tension holds no more"
    return (f"its dish and a heap at the pieces' {fp.angle_of_repose_deg:g}° angle of repose, "
            "as solid kernel")


class LoadPlacement:
    """Puts a world's load (``load_g``) on its utensil.

    Args:
        model, data: the world's MuJoCo model and data.
        layout: the world's layout (the parked supply, the particles' size and mass).
        ledger: the world's food ledger (which items are placed, their masses and classes).
        spec: the hardware spec (the utensil's shape).
        utensil: the utensil the load goes on.
        food: the food's physics parameters.
        load_g: the load (g); ``None``: the world has no load to place.
        seed: the world's seed (the deposit spots are drawn from it).
        run: advances the world by so many seconds (pieces fall between deposits).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, layout: WorldLayout,
                 ledger: FoodLedger, spec: Spec, utensil: str,
                 food: Granular | Liquid | Strands | None, load_g: float | None, seed: int,
                 run: Callable[[float], None]) -> None:
        self.model, self.data, self.layout, self.ledger = model, data, layout, ledger
        self.utensil, self.food, self.load_g, self.seed = utensil, food, load_g, seed
        self._shape: UtensilSpec = spec.utensil(utensil)
        self._run = run
        # The SPH liquid of a placed liquid load (``load_model = "sph"``), once placed.
        self.liquid: LiquidLoad | None = None

    def place(self, settle_s: float = 0.5) -> float:
        """Put the load on the utensil the way a scoop leaves it
        (:mod:`articutool.sim.loading`), at the utensil's velocity, then run ``settle_s``;
        returns the mass on the utensil after that (g).

        Rigid pieces are deposited one at a time from the supply over the whole dish (a fork:
        its tines), each let go just above what is under its spot, 0.3 s apart, while each
        brings the mass on the utensil nearer the load (to within half a piece); what does
        not stay falls where physics takes it. Particles fill the dish from its floor up (a
        liquid poured in), so a load the spoon can hold stays. An SPH liquid
        (:class:`~articutool.sim.liquid_load.LiquidLoad`) is poured so, at rest in the dish.
        """
        if self.load_g is None or self.ledger.active.any():
            raise RuntimeError("placing a load needs a world built with load_g, not yet placed")
        body = self.model.body("utensil").id
        n = self.ledger.n_items
        if isinstance(self.food, Granular):
            self._deposit(body, float(self.load_g or 0.0))
        elif isinstance(self.food, Liquid) and self.food.sph_load:
            from articutool.sim.liquid_load import LiquidLoad

            self.liquid = LiquidLoad(self.model, self.data, self.ledger, self._shape,
                                     self.food)
        else:
            pts = pour_lattice(self._shape, self.layout.piece_size)
            if len(pts) < n:
                raise ValueError(f"load_g: {n} particles do not fit on the "
                                 f"{self.utensil} (at most {len(pts)}, "
                                 f"{self.max_load_g():.1f} g); place less")
            for k in range(n):
                self.ledger.unpark(k, body, pts[k])
            mujoco.mj_forward(self.model, self.data)
        self._run(settle_s)
        return self.ledger.masses_g()["utensil"]

    def _deposit(self, body: int, target_g: float) -> None:
        """Deposit supply pieces over the dish while each brings the load on the utensil
        nearer ``target_g`` (see :meth:`place`)."""
        m, d, u, ledger = self.model, self.data, self._shape, self.ledger
        rng = np.random.default_rng(self.seed + 7)
        # Rays down the dish's normal start 5 cm above its rim: above any heap it holds.
        depth_m = u.physics.bowl[2] if u.physics.bowl is not None else 0.0
        top = u.tip_x + depth_m + 0.05
        gid = np.zeros(1, dtype=np.int32)
        node = ledger.geom_node
        for k in range(ledger.n_items):
            # The next piece goes on only if the load comes nearer the target with it.
            if ledger.masses_g()["utensil"] + ledger.item_g[k] / 2 > target_g:
                break
            bid = int(ledger.item_body[k])
            g0, gn = m.body_geomadr[bid], m.body_geomnum[bid]
            thick = float(max(m.geom_size[g0:g0 + gn, 0]))  # a flat piece's half thickness
            reach = float(max(np.linalg.norm(m.geom_pos[g], ord=2) + m.geom_rbound[g]
                              for g in range(g0, g0 + gn)))
            y, z = deposit_spot(u, reach, rng)
            R, p = d.xmat[body].reshape(3, 3), d.xpos[body]
            start = p + R @ np.array([top, y, z])
            hit = mujoco.mj_ray(m, d, start, -R[:, 0], None, 1, -1, gid)
            # What is under the spot: a piece already there or the dish (else its surface).
            if hit >= 0 and node[gid[0]] >= -1:
                under = top - hit
            else:
                under = u.tip_x + min(dish_surface_height(u, y, z), depth_m)
            local = (under + thick + DEPOSIT_CLEARANCE_M, y, z)
            # Lying flat (the piece's own z along the dish's normal), turned at random about it.
            yaw = float(rng.uniform(0.0, 2.0 * math.pi))
            flat = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
            spin = np.array([[math.cos(yaw), -math.sin(yaw), 0.0],
                             [math.sin(yaw), math.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
            ledger.unpark(k, body, local, R @ flat @ spin)
            self._run(0.3)

    def max_load_g(self) -> float:
        """The most a liquid load :meth:`place` can pour onto the utensil (g); infinite
        for pieces (they are dropped one by one, what does not stay falls)."""
        if isinstance(self.food, Granular):
            return math.inf
        if isinstance(self.food, Liquid) and self.food.sph_load:  # it levels: the dish's own
            return max_load_g(self._shape, "liquid", self.food.density)
        return (len(pour_lattice(self._shape, self.layout.piece_size))
                * self.layout.piece_mass * 1000.0)
