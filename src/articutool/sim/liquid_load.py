"""A liquid load in the loop: SPlisHSPlasH in the utensil's frame, coupled to MuJoCo.

A liquid placed on the utensil (``load_model = "sph"`` in ``physics.toml``, the default) is
an SPH liquid (:class:`~articutool.sim.sph_scene.SphLiquid`) poured into the dish's closed
shell (:func:`~articutool.food.dish_mesh.dish_boundary_mesh`: the dish of
:mod:`articutool.food.dish`, the one MuJoCo collides with and the hydrostatics integrates).
It is simulated in the utensil body's frame, where the dish is static
(:mod:`articutool.sim.liquid_frame`). Every control period (:meth:`LiquidLoad.advance`, called
by the world on each tick):

1. MuJoCo gives the utensil body's pose and its velocity; the period's mean acceleration of
   the body's origin and angular acceleration are the velocity changes over the period;
2. the liquid is stepped to MuJoCo's time under the apparent gravity ``R⊤(g − a)`` and the
   rotation terms ``−α×x − 2ω×v − ω×(ω×x)`` (per particle);
3. its force and torque on the dish (momentum balance over the particles in the dish) are put
   on the utensil body (``xfrc_applied``, the torque moved to the body's centre of mass) for
   the next period — so the F/T sensor between the wrist and the utensil, the tool's weighing
   and its closed-loop shedding read the liquid one control period (20 ms) late;
4. a particle that has left the dish (:func:`~articutool.sim.liquid_frame.outside_dish`) is
   taken out of the liquid and handed to MuJoCo as a sphere of the world's parked pool (one
   per particle, the particle's mass and radius) at its world position and velocity; from then
   on the food ledger classifies it from its contacts like any item, so acquired, shed,
   spilled and delivered keep their meaning (docs/accounting.md). It never returns to the
   liquid (one-way; docs/limits.md).

Each SPH particle is a food item of the ledger (item ``k``, the sphere ``food{k}``): while it is
in the dish the ledger counts it on the utensil (``FoodLedger.in_liquid``) and reads the
liquid's force as the scale's.

SPlisHSPlasH keeps its scene in process-wide singletons: one liquid is open per process. A new
load closes the liquid its thread has open (a load's or a bowl's, whose world can then no
longer step it: :func:`~articutool.sim.sph_scene.close_this_threads_liquid`).
"""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import NDArray

from articutool.food.dish import spoon_dish
from articutool.food.dish_fill import dish_pour
from articutool.food.dish_mesh import dish_boundary_mesh
from articutool.sim.ledger import FoodLedger
from articutool.sim.liquid_frame import (
    apparent_gravity,
    outside_dish,
)
from articutool.sim.params import Liquid
from articutool.sim.sph_scene import (
    Boundary,
    FluidParticles,
    SphLiquid,
    SphSettings,
    close_this_threads_liquid,
    momentum_balance_force,
    momentum_balance_torque,
    rotating_frame_acceleration,
)
from articutool.spec import UtensilSpec

__all__ = ["LiquidLoad", "sph_settings"]

def sph_settings(food: Liquid) -> SphSettings:
    """The solver settings of a liquid food (``physics.toml``): its particle radius, density
    and viscosity (at the walls too); DFSPH, 0.1 % density error, CFL steps ≤ 2 ms."""
    return SphSettings(particle_radius=food.sph_particle_radius, density0=food.density,
                       viscosity=food.viscosity, boundary_viscosity=food.viscosity)


class LiquidLoad:
    """The liquid load of one world (module doc). Built by the world's placement; the world
    calls :meth:`advance` every control period.

    Args:
        model, data: the world's MuJoCo model and data.
        ledger: the world's food ledger (its items are the liquid's particles, parked).
        utensil: the utensil's spec (its dish and thickness).
        food: the liquid's parameters.
        particles: where the liquid starts, (positions, velocities) in the utensil body's
            frame (m, m/s), e.g. what a dip into the container's liquid left in the dish;
            ``None``: the ledger's items poured into the dish at rest.
        items: the ledger's items the particles are, in order (default: every item).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, ledger: FoodLedger,
                 utensil: UtensilSpec, food: Liquid,
                 particles: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
                 items: NDArray[np.int64] | None = None) -> None:
        close_this_threads_liquid()  # one liquid a thread; another thread's is waited for
        self.model, self.data, self.ledger = model, data, ledger
        self.body = model.body("utensil").id
        self.dish = spoon_dish(utensil)
        self.x0 = utensil.tip_x
        self.thickness = utensil.physics.thickness
        self.settings = sph_settings(food)
        r = self.settings.particle_radius
        items = np.arange(ledger.n_items) if items is None else np.asarray(items, dtype=np.int64)
        verts, faces = dish_boundary_mesh(self.dish, self.x0, self.thickness)
        R = data.xmat[self.body].reshape(3, 3)
        g = np.asarray(model.opt.gravity, dtype=float)
        if particles is None:
            try:
                pour = dish_pour(self.dish, self.x0, r, len(items))
            except ValueError as err:
                raise ValueError(f"load_g: {err}; place less") from None
        else:
            pour = np.asarray(particles[0], dtype=float)
            if pour.shape != (len(items), 3):
                raise ValueError(f"particles: {len(items)} positions wanted, got {pour.shape}")
        self.liquid = SphLiquid([Boundary("dish", verts, faces)], [FluidParticles(pour)],
                                self.settings, gravity=R.T @ g)
        ids = np.sort(self.liquid.particle_ids())  # in the order of the positions given
        self._item_of_id = {int(i): int(k) for k, i in zip(items, ids, strict=True)}
        if particles is not None:
            self.liquid.set_velocities(particles[1])
        self.mass = float(self.liquid.particle_mass)
        self._force_body = np.zeros(3)
        self._force_world = np.zeros(3)
        self._torque_body = np.zeros(3)
        self._t0 = float(data.time) - self.liquid.time  # world time = liquid time + t0
        self._v_prev, self._w_prev = self._body_velocity()
        self.handed_off = 0
        ledger.active[items] = True
        ledger.in_liquid[items] = True
        ledger.liquid = self

    # ------------------------------------------------------------------------ state --
    def close(self) -> None:
        """Free the solver (its world's liquid then no longer steps) and take the liquid's
        wrench off the utensil (idempotent)."""
        self.liquid.close()
        self.data.xfrc_applied[self.body] = 0.0

    @property
    def closed(self) -> bool:
        """The solver was freed (by close(), or by another world's liquid opened in this
        thread)."""
        return self.liquid.closed

    def _body_velocity(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(linear velocity of the body's origin, angular velocity), world frame."""
        v = np.zeros(6)
        mujoco.mj_objectVelocity(self.model, self.data, mujoco.mjtObj.mjOBJ_BODY, self.body,
                                 v, 0)
        return v[3:].copy(), v[:3].copy()

    def _items(self) -> NDArray[np.int64]:
        return np.array([self._item_of_id[int(i)] for i in self.liquid.particle_ids()],
                        dtype=np.int64)

    def force_world(self) -> NDArray[np.float64]:
        """The liquid's force on the utensil over the last period (N, world frame)."""
        return self._force_world.copy()

    def force_body(self) -> NDArray[np.float64]:
        """… in the utensil body's frame (N)."""
        return self._force_body.copy()

    def torque_body(self) -> NDArray[np.float64]:
        """Its torque about the utensil body's origin (N·m, body frame)."""
        return self._torque_body.copy()

    def positions_world(self) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """(items, world positions) of the particles in the dish."""
        R, p = self.data.xmat[self.body].reshape(3, 3), self.data.xpos[self.body]
        return self._items(), self.liquid.positions() @ R.T + p

    def in_dish_g(self) -> float:
        """Grams of liquid in the dish."""
        return self.liquid.n_particles * self.mass * 1000.0

    def remove(self, items: NDArray[np.int64]) -> None:
        """Take these items' particles out of the liquid (eaten)."""
        gone = set(int(k) for k in items)
        self.liquid.remove_particles(np.array([int(k) in gone for k in self._items()],
                                              dtype=bool))

    def release_all(self) -> None:
        """Hand every particle still in the dish to MuJoCo (at its world position and
        velocity), as if it had left the dish."""
        if self.closed or self.liquid.n_particles == 0:
            return
        v_o, w = self._body_velocity()
        self._hand_off(np.ones(self.liquid.n_particles, dtype=bool), self.liquid.positions(),
                       self.liquid.velocities(), v_o, w)

    def _hand_off(self, out: NDArray[np.bool_], x: NDArray[np.float64],
                  v: NDArray[np.float64], v_o: NDArray[np.float64],
                  w: NDArray[np.float64]) -> None:
        """Take the particles ``out`` (at ``x``, ``v`` in the body's frame) out of the liquid
        and give their items to MuJoCo at their world positions and velocities (the body's
        ``v_o``, ``w``)."""
        R, p = self.data.xmat[self.body].reshape(3, 3), self.data.xpos[self.body]
        items = np.array([self._item_of_id[int(i)] for i in self.liquid.particle_ids()[out]],
                         dtype=np.int64)
        xw = x[out] @ R.T + p
        vw = v_o + np.cross(w, xw - p) + v[out] @ R.T
        self.liquid.remove_particles(out)
        for k, xk, vk in zip(items, xw, vw, strict=True):
            self.ledger.release(int(k), xk, vk)
        self.handed_off += len(items)

    # --------------------------------------------------------------------- stepping --
    def advance(self) -> None:
        """One control period (module doc): the liquid stepped to MuJoCo's time in the
        utensil's frame, its wrench put on the utensil, leavers handed to MuJoCo."""
        if self.closed:
            raise RuntimeError("this world's liquid was closed: another world's liquid was "
                               "opened in this thread (SPlisHSPlasH holds one scene at a time)")
        m, d, liq = self.model, self.data, self.liquid
        R = d.xmat[self.body].reshape(3, 3).copy()
        v_o, w = self._body_velocity()
        t_world = float(d.time)
        t_liq0 = liq.time
        span = t_world - self._t0 - t_liq0
        if span <= 0 or liq.n_particles == 0:
            self._v_prev, self._w_prev = v_o, w
            return
        a_o, alpha = (v_o - self._v_prev) / span, (w - self._w_prev) / span
        self._v_prev, self._w_prev = v_o, w
        g_app = apparent_gravity(R, m.opt.gravity, a_o)
        w_b, alpha_b = R.T @ w, R.T @ alpha
        liq.set_gravity(g_app)
        rotation = rotating_frame_acceleration(w_b, alpha_b)
        liq.extra_acceleration = rotation
        ids0, v0 = liq.particle_ids(), liq.velocities()
        liq.step_to(t_world - self._t0)
        dt = liq.time - t_liq0
        ids1, x1, v1 = liq.particle_ids(), liq.positions(), liq.velocities()
        if not np.array_equal(ids0, ids1):  # nothing removes particles while stepping
            raise RuntimeError("the liquid's particles changed while it stepped")
        out = outside_dish(x1, self.dish, self.x0, margin=self.settings.particle_radius,
                           floor_below=self.thickness * 3.0)
        inn = ~out
        acc = (v1 - v0) / dt
        g_i = (g_app + rotation(x1, v1))[inn]
        f = momentum_balance_force(self.mass, acc[inn], g_i)
        tau = momentum_balance_torque(self.mass, x1[inn], acc[inn], g_i, np.zeros(3))
        self._force_body, self._torque_body = f, tau
        self._force_world = R @ f
        c = m.body_ipos[self.body]  # xfrc_applied's torque is about the centre of mass
        d.xfrc_applied[self.body, :3] = R @ f
        d.xfrc_applied[self.body, 3:] = R @ (tau - np.cross(c, f))
        if out.any():
            self._hand_off(out, x1, v1, v_o, w)
