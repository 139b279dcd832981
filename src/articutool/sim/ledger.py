"""The food ledger of the feeding world: where every food item is, its spills, eating.

:class:`FoodLedger` reads the MuJoCo world's contacts once per tool tick and keeps each
item's class (utensil, container, table, critical, airborne, eaten — the pure rules are in
:mod:`articutool.sim.accounting`), the spill events (thesis §5's outcome classes), and
removes what is eaten: food entering the scene's ``mouth`` region, or on the utensil when the
user takes the bite. It owns the accounting state; :class:`~articutool.sim.world.FeedingWorld`
steps the physics and calls :meth:`FoodLedger.classify` every loop period.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Protocol

import mujoco
import numpy as np
from numpy.typing import NDArray

from articutool.arm.description import mj_quat
from articutool.arm.scene import Box, Cylinder, Scene, Sphere
from articutool.sim import accounting as acc
from articutool.sim.world_spec import WorldLayout

__all__ = ["FoodLedger", "LiquidInDish"]

_UTENSIL_NODE, _OTHER_NODE, _SURFACE0 = -1, -2, -10


class LiquidInDish(Protocol):
    """What the ledger needs of a liquid load in the dish (its particles are items)."""

    def force_world(self) -> NDArray[np.float64]:
        """The liquid's force on the utensil now (N, world frame)."""
        ...

    def positions_world(self) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """(items, world positions (n, 3)) of the particles in the dish."""
        ...

    def remove(self, items: NDArray[np.int64]) -> None:
        """Take these items' particles out of the liquid (eaten)."""
        ...


class FoodLedger:
    """Where each food item of a world is, its spills and what was eaten (see module doc).

    Args:
        model, data: the world's MuJoCo model and data (the ledger reads contacts and body
            positions, and moves eaten food out of the world).
        layout: the world's layout (food bodies, strands, places, utensil geoms).
        scene: the scene (places' shapes, the mouth region).
        spill_dwell_s: ``world.spill_dwell_s`` of ``physics.toml``.
        period: the accounting step (s): the tool's loop period.
        mouth: eat what enters the scene's ``mouth`` region (``False``: nothing is eaten
            there; the experimenter weighs the utensil, Exp. 2b/2c).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, layout: WorldLayout,
                 scene: Scene, spill_dwell_s: float, period: float, mouth: bool = True) -> None:
        self.model, self.data, self.layout, self.scene = model, data, layout, scene
        self.period = period
        m, lay = model, layout
        self.surface_names: list[str] = []
        codes = []
        node = np.full(m.ngeom, _OTHER_NODE, dtype=np.int64)
        for gname, place in lay.places.items():
            node[m.geom(gname).id] = _SURFACE0 - len(self.surface_names)
            self.surface_names.append(gname.split("/")[1])
            codes.append(acc.PLACE_CODES[place])
        self.surface_codes = np.array(codes, dtype=np.int64)
        for gname in lay.utensil_geoms:
            node[m.geom(gname).id] = _UTENSIL_NODE
        item_body = []
        for k, b in enumerate(lay.food_bodies):
            bid = m.body(b).id  # a piece may be a compound of several geoms
            node[m.body_geomadr[bid]:m.body_geomadr[bid] + m.body_geomnum[bid]] = k
            item_body.append(bid)
        n_bodies = len(lay.food_bodies)
        self.strand_bodies: list[NDArray[np.int64]] = []  # each strand's capsule bodies
        for k, sname in enumerate(lay.food_strands):  # a strand: one item, all its capsules
            for i in range(lay.strand_segments):
                node[m.geom(f"{sname}/{i}").id] = n_bodies + k
            self.strand_bodies.append(np.array(
                [m.body(f"{sname}/{i}").id for i in range(lay.strand_segments)], dtype=np.int64))
            item_body.append(m.body(f"{sname}/0").id)  # its root (free joint)
        self._geom_node = node
        # Per geom: the food item it belongs to (>= 0), the utensil (-1), other (< -1).
        self.geom_node = node
        self.item_body = np.array(item_body, dtype=np.int64)
        self.n_items = len(item_body)
        # Grams per item: a body's own mass (pieces vary in size), a strand's from the model.
        self.item_g = np.array([m.body_mass[b] * 1000.0 for b in item_body[:n_bodies]]
                               + [lay.piece_mass * 1000.0] * len(lay.food_strands))
        self.active = np.full(self.n_items, not lay.parked, dtype=bool)
        if lay.parked:
            # Parked items (a load's supply, a liquid's particles while the liquid holds them)
            # touch nothing and may sleep: an awake one costs MuJoCo's step as much as a
            # moving piece. Placing or releasing one writes its state, which wakes it.
            for b in item_body:
                m.tree_sleep_policy[m.body_treeid[b]] = int(
                    mujoco.mjtSleepPolicy.mjSLEEP_AUTO_ALLOWED)
        self.codes = np.full(self.n_items, acc.AIRBORNE, dtype=np.int64)
        self.where = np.full(self.n_items, -1, dtype=np.int64)
        self._spill = acc.SpillTracker(self.n_items, spill_dwell_s)
        self.spills: list[acc.SpillEvent] = []
        # The utensil's vertical contact force from the food at each of the last ticks: a
        # scale's reading is their mean (a 0.5 s window, like the F/T sensor's weighing).
        self._force_z: deque[float] = deque(maxlen=max(1, round(0.5 / period)))
        self._mouth = next(((np.asarray(r.xyz), r.radius) for r in scene.regions
                            if r.name == "mouth"), None) if mouth else None
        # A liquid load simulated beside MuJoCo (:mod:`articutool.sim.liquid_load`): its
        # particles are items whose spheres stay parked while they are in the dish
        # (``in_liquid``): on the utensil, until the liquid hands them to MuJoCo.
        self.in_liquid = np.zeros(self.n_items, dtype=bool)
        self.liquid: LiquidInDish | None = None
        # Grams of the container's liquid simulated beside MuJoCo (:mod:`articutool.sim.
        # bowl_liquid`): in the container, not items until they leave it.
        self.container_liquid_g = 0.0
        self.recycled_eaten_g = 0.0

    def contacts(self) -> tuple[NDArray, NDArray, NDArray]:
        """The food's contacts now: (item-item pairs, items on the utensil, [item, surface])."""
        d = self.data
        nc = d.ncon
        if nc == 0 or self.n_items == 0:
            e = np.zeros((0, 2), dtype=np.int64)
            return e, np.zeros(0, dtype=np.int64), e
        nodes = self._geom_node[d.contact.geom[:nc]]
        a, b = nodes[:, 0], nodes[:, 1]
        ii = (a >= 0) & (b >= 0) & (a != b)
        item_item = np.column_stack([a[ii], b[ii]])
        iu = np.concatenate([a[(a >= 0) & (b == _UTENSIL_NODE)],
                             b[(b >= 0) & (a == _UTENSIL_NODE)]])
        sa, sb = (a >= 0) & (b <= _SURFACE0), (b >= 0) & (a <= _SURFACE0)
        item_surface = np.concatenate([np.column_stack([a[sa], _SURFACE0 - b[sa]]),
                                       np.column_stack([b[sb], _SURFACE0 - a[sb]])])
        return item_item, iu, item_surface

    def carried_force_z(self) -> float:
        """Mean of :meth:`utensil_force_z` over the last 0.5 s of accounting steps (N)."""
        return float(np.mean(self._force_z)) if self._force_z else self.utensil_force_z()

    def utensil_force_z(self) -> float:
        """Vertical component (N, world z) of the total contact force the food's items put
        on the utensil now (negative when they press down on it)."""
        d, m = self.data, self.model
        nc = d.ncon
        fz = float(self.liquid.force_world()[2]) if self.liquid is not None else 0.0
        if nc == 0 or self.n_items == 0:
            return fz
        nodes = self._geom_node[d.contact.geom[:nc]]
        a, b = nodes[:, 0], nodes[:, 1]
        f6 = np.zeros(6)
        # MuJoCo's contact frame has its normal from geom1 to geom2; the force acts on geom2
        # along it (and on geom1 against it).
        for i in np.flatnonzero(((a >= 0) & (b == _UTENSIL_NODE))
                                | ((b >= 0) & (a == _UTENSIL_NODE))):
            mujoco.mj_contactForce(m, d, int(i), f6)
            world = d.contact.frame[i].reshape(3, 3).T @ f6[:3]
            fz += float(world[2]) if b[i] == _UTENSIL_NODE else -float(world[2])
        return fz

    def classify(self, t: float) -> None:
        """One accounting step at simulation time ``t``: eat what is in the mouth, classify
        every item from the contacts, record the spills that reached their dwell time."""
        if self.n_items == 0:
            return
        self._eat()
        self._force_z.append(self.utensil_force_z())
        ii, iu, isf = self.contacts()
        asleep = self.data.body_awake[self.item_body] == 0
        # A sleeping item has no contacts to classify it by, but it is at rest on something
        # static: the robot never sleeps and wakes what it touches. One that was last seen on
        # the utensil or in the air gets the place below it. (Parked items, and a liquid's
        # particles while the liquid holds them, are not where their bodies wait.)
        prev, prev_where = self.codes.copy(), self.where.copy()
        for k in np.flatnonzero(asleep & self.active & ~self.in_liquid
                                & ((prev == acc.UTENSIL) | (prev == acc.AIRBORNE))):
            prev[k], prev_where[k] = self._place_below(self.data.xpos[self.item_body[k]])
        codes, where = acc.classify_items(self.n_items, ii, iu, isf, self.surface_codes,
                                          prev, prev_where, asleep)
        codes[self.in_liquid], where[self.in_liquid] = acc.UTENSIL, -1  # in the dish
        self._sleep_policy(codes)
        # An event each time an item has stayed on a spill place worse than any it reached
        # before for the dwell time (a drop that lands on the table and rolls onto the floor
        # is two events; the spilled mass counts it once, at the floor: acc.spilled_by_place).
        for k, code, w, t0 in self._spill.update(t, self.period, codes, where, self.active):
            self.spills.append(acc.SpillEvent(
                t=round(t0, 4), mass_g=float(self.item_g[k]), place=acc.CLASS_NAMES[code],
                where=self.surface_names[w] if w >= 0 else "", item=k))
        self.codes, self.where = codes, where

    def _sleep_policy(self, codes: NDArray[np.int64]) -> None:
        """Food on the utensil may not sleep; food at rest on a place may again.

        A piece resting in a still dish can lose its contact for a few steps and fall
        asleep; a sleeping tree wakes only when an awake one touches it, so when the utensil
        moves away the piece would hang in the air where the dish was. What the utensil
        carries therefore stays awake until it lands in a container, on the table or the
        floor (an item in the air keeps its policy: it is on its way from one to the other).
        """
        if not self.active.any():
            return
        m = self.model
        trees = m.body_treeid[self.item_body]
        carried = self.active & (codes == acc.UTENSIL)
        landed = self.active & ((codes == acc.CONTAINER) | (codes == acc.TABLE)
                                | (codes == acc.CRITICAL))
        m.tree_sleep_policy[trees[carried]] = int(mujoco.mjtSleepPolicy.mjSLEEP_NEVER)
        m.tree_sleep_policy[trees[landed]] = int(mujoco.mjtSleepPolicy.mjSLEEP_AUTO_ALLOWED)

    def _place_below(self, p: NDArray[np.float64]) -> tuple[int, int]:
        """(class, surface index) of the least severe place whose object holds point ``p``
        (its footprint, up to 5 cm above it); the floor (critical) if none."""
        best = (acc.CRITICAL, -1)
        for i, name in enumerate(self.surface_names):
            o = self.scene.get(name)
            local = o.rotation.T @ (p - np.asarray(o.xyz))
            if isinstance(o, Cylinder):
                inside = (math.hypot(local[0], local[1]) <= o.radius
                          and -o.length / 2 <= local[2] <= o.length / 2 + 0.05)
            elif isinstance(o, Box):
                h = np.asarray(o.size) / 2
                inside = bool(np.all(np.abs(local[:2]) <= h[:2])
                              and -h[2] <= local[2] <= h[2] + 0.05)
            elif isinstance(o, Sphere):
                inside = float(np.linalg.norm(local)) <= o.radius + 0.05
            else:
                inside = local[2] <= 0.05
            code = int(self.surface_codes[i])
            if inside and code < best[0]:
                best = (code, i)
        return best

    def _eat(self) -> None:
        """Food that enters the mouth region is eaten: moved out of the world, frozen. A
        strand is eaten when any of its vertices enters it."""
        if self._mouth is None or self.n_items == 0:
            return
        c, r = self._mouth
        d = self.data
        n = len(self.layout.food_bodies)
        inside = np.zeros(self.n_items, dtype=bool)
        inside[:n] = np.linalg.norm(d.xpos[self.item_body[:n]] - c, axis=1) < r
        if self.liquid is not None:  # a liquid's particles are where the liquid has them
            items, pos = self.liquid.positions_world()
            inside[items] = np.linalg.norm(pos - c, axis=1) < r
        for k, verts in enumerate(self.strand_bodies):
            inside[n + k] = bool(np.any(np.linalg.norm(d.xpos[verts] - c, axis=1) < r))
        self._remove_eaten(np.flatnonzero(inside & self.active & (self.codes != acc.EATEN)))

    def eat_from_utensil(self) -> float:
        """The user takes the bite: what is on the utensil now — pieces, particles and noodle
        strands alike — is eaten (moved out of the world, never counted again). Returns the
        grams eaten. (The simulated user does not bite or chew; the feeding tree presents the
        bite and this stands for the user taking it.)"""
        on = np.flatnonzero(self.active & (self.codes == acc.UTENSIL))
        self._remove_eaten(on)
        return float(self.item_g[on].sum())

    def _remove_eaten(self, items: NDArray[np.int64]) -> None:
        m, d = self.model, self.data
        gone = items[self.in_liquid[items]]
        if gone.size and self.liquid is not None:
            self.liquid.remove(gone)
            self.in_liquid[gone] = False
        n_bodies = len(self.layout.food_bodies)
        for k in items:
            # A piece is one body; a strand all its capsules, carried by its root's free joint.
            bodies = self.strand_bodies[k - n_bodies] if k >= n_bodies else [self.item_body[k]]
            for b in bodies:
                g = slice(m.body_geomadr[b], m.body_geomadr[b] + m.body_geomnum[b])
                m.geom_contype[g] = m.geom_conaffinity[g] = 0
                m.body_contype[b] = m.body_conaffinity[b] = 0
                m.body_gravcomp[b] = 1.0
            j = m.body_jntadr[self.item_body[k]]
            qa, va = m.jnt_qposadr[j], m.jnt_dofadr[j]
            d.qpos[qa:qa + 3] = (100.0 + k, 0.0, 10.0)
            d.qvel[va:va + 6] = 0.0
            # Parked out of reach with no contacts, it cannot wake anything: it may sleep,
            # whatever policy it had while carried.
            m.tree_sleep_policy[m.body_treeid[self.item_body[k]]] = int(
                mujoco.mjtSleepPolicy.mjSLEEP_AUTO_ALLOWED)
            self.codes[k] = acc.EATEN

    def unpark(self, k: int, body: int, local: tuple[float, float, float],
               rotation: NDArray[np.float64] | None = None) -> None:
        """Give parked piece ``k`` its collisions and weight, at ``local`` in ``body``'s frame
        with ``body``'s velocity, and ``body``'s orientation or ``rotation`` (a world
        rotation matrix) (placing a load, thesis Exp. 2b/2c)."""
        m, d = self.model, self.data
        R, p = d.xmat[body].reshape(3, 3), d.xpos[body]
        v = np.zeros(6)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, body, v, 0)
        # without a rotation, lying along the utensil
        q = d.xquat[body].copy() if rotation is None else mj_quat(rotation)
        self.release(k, p + R @ np.asarray(local), v[3:], q)

    def release(self, k: int, position: NDArray[np.float64], velocity: NDArray[np.float64],
                quat: NDArray[np.float64] | None = None) -> None:
        """Give parked item ``k`` its collisions and weight at the world ``position`` with the
        world ``velocity`` (m/s; no spin), ``quat`` its orientation (default: unturned). A
        particle of a liquid load that leaves the dish is handed to MuJoCo so."""
        m, d = self.model, self.data
        bid = int(self.item_body[k])
        g = slice(m.body_geomadr[bid], m.body_geomadr[bid] + m.body_geomnum[bid])
        # The broad phase filters on the body's OR of its geoms' bits, kept in the model.
        m.geom_contype[g] = m.body_contype[bid] = self.layout.food_contype
        m.geom_conaffinity[g] = m.body_conaffinity[bid] = self.layout.food_conaffinity
        m.body_gravcomp[bid] = 0.0
        m.tree_sleep_policy[m.body_treeid[bid]] = int(mujoco.mjtSleepPolicy.mjSLEEP_AUTO_ALLOWED)
        j = m.body_jntadr[bid]
        qa, va = m.jnt_qposadr[j], m.jnt_dofadr[j]
        d.qpos[qa:qa + 3] = position
        d.qpos[qa + 3:qa + 7] = (1.0, 0.0, 0.0, 0.0) if quat is None else quat
        d.qvel[va:va + 3] = velocity
        d.qvel[va + 3:va + 6] = 0.0
        self.active[k] = True
        self.in_liquid[k] = False

    def item_classes(self) -> NDArray[np.int64]:
        """Where each food item is now: its code in ``accounting.CLASS_NAMES`` (utensil,
        container, table, …), or −1 for a piece of a load not yet placed."""
        return np.where(self.active, self.codes, -1)

    def masses_g(self) -> dict[str, float]:
        """Mass (g) per class: utensil, container, table, critical, airborne, eaten."""
        g = np.bincount(self.codes[self.active], weights=self.item_g[self.active],
                        minlength=len(acc.CLASS_NAMES))
        out = {name: float(g[i]) for i, name in enumerate(acc.CLASS_NAMES)}
        out["container"] += self.container_liquid_g
        out["eaten"] += self.recycled_eaten_g
        return out

    def total_g(self) -> float:
        """Grams of food in the world: its items, the container's liquid and what was eaten
        by items since recycled."""
        return (float(self.item_g[self.active].sum()) + self.container_liquid_g
                + self.recycled_eaten_g)

    def recycle_eaten(self, n: int) -> NDArray[np.int64]:
        """Up to ``n`` eaten items made parked again for reuse (a container's liquid hands
        out more particles over a meal than the world parked): their grams stay counted as
        eaten (``recycled_eaten_g``), their spill history is cleared."""
        k = np.flatnonzero(self.active & (self.codes == acc.EATEN))[:n]
        self.recycled_eaten_g += float(self.item_g[k].sum())
        self.active[k] = False
        self.codes[k], self.where[k] = acc.AIRBORNE, -1
        self._spill.forget(k)
        return k
