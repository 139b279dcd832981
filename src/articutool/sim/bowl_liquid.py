"""The container's liquid in the loop: SPlisHSPlasH in the world frame, the dish moving
through it, what a dip leaves in the dish handed to the load.

A liquid food whose model is the SPH liquid (``load_model = "sph"``) fills its container
(the scene's bowl) as SPH particles of ``sph_bowl_particle_radius`` inside the bowl's closed
mesh (:func:`~articutool.food.container_liquid.container_boundary_mesh`: the cylinder and
``container_wall`` MuJoCo collides with), with the utensil's dish
(:func:`~articutool.food.dish_mesh.dish_boundary_mesh`, the placed load's boundary) an animated
boundary. Every control period (:meth:`BowlLiquid.advance`, called by the world on each tick):

1. while the dish is far from the liquid (its lowest point more than ``sph_bowl_wake_m`` above
   the surface, or off the bowl's footprint) the liquid is at rest and is not stepped (its
   clock follows the world's). The first time the dish comes near, the fill is poured on a
   lattice and settled ``sph_bowl_settle_s`` with the dish held where it is (one settled
   fill per process serves every world: the fill is the same for every seed);
2. while the dish is near, MuJoCo gives the utensil body's pose; the liquid is stepped to
   MuJoCo's time with the dish moving from its last pose to this one (posed at least every
   5 ms along the way: position linear, rotation spherical, with that motion's velocities).
   The liquid's force on the dish does not act back on the arm (open loop: the arm is stiff
   and its path is the tree's, and at the bowl's particle the liquid's gap off the shell
   swells its buoyancy up to 3.7×, docs/limits.md); the F/T sensor reads the load from the
   hand-over on;
3. a particle that leaves the bowl (past its wall or below its floor) is taken out and handed
   to MuJoCo as the 2 × 2 × 2 load spheres of its cube (the world's parked items), so the
   ledger classifies it from its contacts;
4. once the dish has been below the surface and is ``sph_bowl_handover_m`` above it, the
   particles in the dish (inside its rim's ellipse grown by a particle, at most two particles
   above the rim plane) become a :class:`~articutool.sim.liquid_load.LiquidLoad`: each the
   2 × 2 × 2 particles of its cube at the load's radius (the same mass), with its velocity
   relative to the dish. What is elsewhere in the air goes to MuJoCo as in 3; what is in the
   bowl stays there, still. The bowl's solver is closed (SPlisHSPlasH holds one scene per
   process); its particles are kept, and when the dish comes near again with nothing left in
   it (a meal's next bite), the bowl's liquid is simulated again from where it was (what the
   load still holds then is handed to MuJoCo first).

The grams in the bowl count in the container (``FoodLedger.container_liquid_g``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import mujoco
import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from articutool.arm.scene import Cylinder
from articutool.food.container_liquid import container_boundary_mesh, container_fill
from articutool.food.dish import spoon_dish
from articutool.food.dish_mesh import dish_boundary_mesh
from articutool.sim.ledger import FoodLedger
from articutool.sim.liquid_frame import outside_dish
from articutool.sim.liquid_load import LiquidLoad, sph_settings
from articutool.sim.params import Liquid
from articutool.sim.sph_scene import (
    Boundary,
    FluidParticles,
    SphLiquid,
    SphSettings,
    close_this_threads_liquid,
)
from articutool.spec import UtensilSpec

if TYPE_CHECKING:
    from articutool.sim.placement import LoadPlacement

__all__ = ["BowlLiquid", "refine"]

# The settled fill per process, by its settings (the fill does not depend on the seed).
_SETTLED: dict[tuple[float, ...], tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
_SUB_DT = 0.005  # s: the dish is posed at least this often while the liquid steps


def refine(x: NDArray[np.float64], v: NDArray[np.float64], r: float
           ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Each particle of radius ``2r`` at ``x`` (n, 3) as the 8 particles of radius ``r`` that
    tile its cube (axes of the frame ``x`` is in), each with its parent's velocity."""
    corners = r * np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)],
                           dtype=float)
    return ((x[:, None, :] + corners[None]).reshape(-1, 3),
            np.repeat(np.asarray(v, dtype=float), 8, axis=0))


class BowlLiquid:
    """The liquid filling the world's container (module doc). Built by the world; the world
    calls :meth:`advance` every control period.

    Args:
        model, data: the world's MuJoCo model and data.
        ledger: the world's food ledger (its parked items are the particles handed over).
        container: the scene's open cylinder holding the liquid (upright).
        utensil: the utensil's spec (its dish).
        food: the liquid's parameters.
        placement: the world's load placement (the hand-over's load becomes its liquid).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, ledger: FoodLedger,
                 container: Cylinder, utensil: UtensilSpec, food: Liquid,
                 placement: LoadPlacement) -> None:
        if container.container_wall is None or not np.allclose(container.rotation, np.eye(3)):
            raise ValueError(f"{container.name}: the liquid's container must be an upright open "
                             "cylinder")
        self.model, self.data, self.ledger, self.food = model, data, ledger, food
        self.utensil, self.placement, self.box = utensil, placement, container
        self.body = model.body("utensil").id
        self.dish = spoon_dish(utensil)
        self.x0, self.thickness = utensil.tip_x, utensil.physics.thickness
        self.settings: SphSettings = sph_settings(food)
        self.r = food.sph_bowl_particle_radius
        self.bowl_settings = SphSettings(
            particle_radius=self.r, density0=food.density, viscosity=food.viscosity,
            boundary_viscosity=food.viscosity)
        self.mass = self.bowl_settings.particle_mass
        self.centre = np.asarray(container.xyz, dtype=float)
        self.inner_radius = container.radius - container.container_wall
        self.floor_z = float(container.inner_floor()[2])
        count = max(1, round(food.fill_g / 1000.0 / self.mass))
        # The liquid's level surface (its ideal height, the fill's volume over the floor).
        self.surface_z = self.floor_z + count * (2 * self.r) ** 3 / (math.pi
                                                                    * self.inner_radius ** 2)
        self.dish_verts, self.dish_faces = dish_boundary_mesh(self.dish, self.x0,
                                                              self.thickness)
        self._state: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._count = count
        self._liquid: SphLiquid | None = None
        self._last = (np.zeros(3), np.eye(3))  # the dish's pose the liquid was last stepped to
        self._t0 = 0.0  # world time = liquid time + t0, while the liquid is simulated
        self._dipped = False
        self._armed = True
        self._next_item = 0
        self.dips = 0
        self.handed_over_g: list[float] = []
        self.left_g = 0.0  # grams that left the bowl as particles handed to MuJoCo
        ledger.container_liquid_g = count * self.mass * 1000.0

    # ------------------------------------------------------------------------ state --
    @property
    def grams(self) -> float:
        """Grams of liquid in the bowl (simulated or at rest)."""
        return self.ledger.container_liquid_g

    @property
    def simulated(self) -> bool:
        """The bowl's liquid is being stepped now."""
        return self._liquid is not None and not self._liquid.closed

    def close(self) -> None:
        """Free the solver, keeping the liquid's state (idempotent; a solver another world
        of this thread closed is dropped with the state it was closed in)."""
        if self._liquid is not None:
            self._liquid.close()  # a closed liquid keeps the state it was closed in
            self._state = (self._liquid.positions(), self._liquid.velocities())
            self._liquid = None

    def positions_world(self) -> NDArray[np.float64]:
        """Where the bowl's particles are now (world frame, m): simulated, kept from the last
        dip, or, before the first, the fill settled in this process or else as poured."""
        if self._liquid is not None:
            return self._liquid.positions()
        if self._state is not None:
            return self._state[0].copy()
        settled = _SETTLED.get(self._key())
        if settled is not None:
            return settled[0].copy()
        fill = container_fill(self.inner_radius, self.floor_z, self._count, self.r)
        fill[:, :2] += self.centre[:2]
        return fill

    def _key(self) -> tuple[float, ...]:
        """The settled fill's key (its settings and the bowl's)."""
        s, b, f = self.bowl_settings, self.box, self.food
        return (s.particle_radius, s.density0, s.viscosity, float(self._count),
                *self.centre, b.radius, b.length, b.container_wall or 0.0, f.sph_bowl_settle_s)

    def settled_positions(self) -> NDArray[np.float64]:
        """The fill's particle centres once settled (world frame, m; settles it if no world
        of this process has)."""
        if self._state is None:
            close_this_threads_liquid()
            self._state = self._settled()
        return self._state[0].copy()

    def _bounds(self) -> list[Boundary]:
        """The bowl's mesh (world frame) and the dish's (animated)."""
        bv, bf = container_boundary_mesh(self.box.radius, self.box.length,
                                         self.box.container_wall or 0.0)
        return [Boundary("bowl", bv + self.centre, bf),
                Boundary("dish", self.dish_verts, self.dish_faces, animated=True)]

    def _pose(self) -> tuple[NDArray[np.float64], ...]:
        """The utensil body's (position, rotation, linear velocity, angular velocity)."""
        d = self.data
        v = np.zeros(6)
        mujoco.mj_objectVelocity(self.model, d, mujoco.mjtObj.mjOBJ_BODY, self.body, v, 0)
        return (d.xpos[self.body].copy(), d.xmat[self.body].reshape(3, 3).copy(),
                v[3:].copy(), v[:3].copy())

    def _dish_low(self, p: NDArray[np.float64], R: NDArray[np.float64]) -> tuple[float, bool]:
        """(the dish's lowest point's height above the surface, the dish over the bowl)."""
        w = self.dish_verts @ R.T + p
        over = bool(np.min(np.hypot(w[:, 0] - self.centre[0], w[:, 1] - self.centre[1]))
                    < self.box.radius)
        return float(w[:, 2].min()) - self.surface_z, over

    # --------------------------------------------------------------------- stepping --
    def advance(self) -> None:
        """One control period (module doc)."""
        p, R, v, w = self._pose()
        above, over = self._dish_low(p, R)
        near = over and above < self.food.sph_bowl_wake_m
        if self._liquid is None:
            if not near:
                self._armed = True  # the dish has left since the last hand-over
                return
            if not self._armed:
                return
            self._wake(p, R)
        liq = self._liquid
        assert liq is not None
        if liq.closed:
            raise RuntimeError("this world's bowl liquid was closed: another world's liquid "
                               "was opened in this thread (SPlisHSPlasH holds one scene at a "
                               "time)")
        t0, t_end = liq.time, float(self.data.time) - self._t0
        p0, R0 = self._last
        if t_end > t0 + 1e-9:
            # The dish moves from its last pose to this one over the period: posed along the
            # way (position linear, rotation spherical) with that motion's velocities.
            turn = Rotation.from_matrix(R @ R0.T)
            lin, ang = (p - p0) / (t_end - t0), turn.as_rotvec() / (t_end - t0)
            while liq.time < t_end - 1e-9:
                t = min(liq.time + _SUB_DT, t_end)
                u = (t - t0) / (t_end - t0)
                Ru = (Rotation.from_rotvec(u * turn.as_rotvec()).as_matrix() @ R0)
                liq.set_boundary_pose("dish", p0 + u * (p - p0), Ru, lin, ang)
                liq.step_to(t)
        self._last = (p, R)
        self._drop_leavers()
        self._dipped = self._dipped or above < 0.0
        if self._dipped and above >= self.food.sph_bowl_handover_m:
            self._hand_over(p, R, v, w)
        elif not near and not self._dipped:
            self.close()  # at rest again, the dish gone without a dip

    def _wake(self, p: NDArray[np.float64], R: NDArray[np.float64]) -> None:
        """Simulate the bowl's liquid from its state (first: the fill, settled)."""
        load = self.placement.liquid
        if load is not None:  # what the last dip's load still holds goes to MuJoCo
            load.release_all()
            load.close()
            self.placement.liquid = None
        bounds = self._bounds()
        close_this_threads_liquid()  # another world's, in this thread (one scene a process)
        if self._state is None:
            self._state = self._settled()
        x, v = self._state
        self._liquid = liq = SphLiquid(bounds, [FluidParticles(x)], self.bowl_settings)
        liq.set_velocities(v)
        liq.set_boundary_pose("dish", p, R)
        self._last = (p, R)
        self._t0 = float(self.data.time) - liq.time
        self._dipped = False
        self.dips += 1

    def _settled(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The fill poured on a lattice and settled in the bowl alone (cached per process).
        The dish is left out: a boundary anywhere moves the library's neighbour grid, which
        changes the sums' order and so the settled particles' places, so a fill settled with
        the dish where one trial had it would carry that trial into every later one."""
        s, f, key = self.bowl_settings, self.food, self._key()
        if key not in _SETTLED:
            fill = container_fill(self.inner_radius, self.floor_z, self._count, self.r)
            fill[:, :2] += self.centre[:2]
            with SphLiquid(self._bounds()[:1], [FluidParticles(fill)], s) as liq:
                liq.step_to(liq.time + f.sph_bowl_settle_s)
                keep = ~self._left(liq.positions())
                _SETTLED[key] = (liq.positions()[keep], liq.velocities()[keep])
        return _SETTLED[key]

    def _left(self, x: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Which world points have left the bowl: past its wall or below its floor."""
        rel = x - self.centre
        return ((np.hypot(rel[:, 0], rel[:, 1]) > self.box.radius + self.r)
                | (rel[:, 2] < -self.box.length / 2 - self.r))

    def _drop_leavers(self) -> None:
        liq = self._liquid
        assert liq is not None
        x = liq.positions()
        out = self._left(x)
        if out.any():
            self._to_mujoco(x[out], liq.velocities()[out])
            liq.remove_particles(out)
            self.ledger.container_liquid_g = liq.n_particles * self.mass * 1000.0

    def _items(self, n: int) -> NDArray[np.int64]:
        """``n`` parked items: the next never used (the world parks
        ``world_spec.BOWL_POOL_FACTOR`` × the utensil's level load), then eaten ones
        recycled (a meal's later dips)."""
        k = self._next_item
        fresh = np.arange(k, min(k + n, self.ledger.n_items), dtype=np.int64)
        self._next_item = k + len(fresh)
        if len(fresh) == n:
            return fresh
        more = self.ledger.recycle_eaten(n - len(fresh))
        if len(fresh) + len(more) < n:
            raise RuntimeError(f"the container's liquid hands {n} particles to MuJoCo; of the "
                               f"world's {self.ledger.n_items} parked items only "
                               f"{len(fresh) + len(more)} are free (neither in use nor "
                               "uneaten)")
        return np.concatenate([fresh, more])

    def _to_mujoco(self, x: NDArray[np.float64], v: NDArray[np.float64]) -> None:
        """These bowl particles (world frame) as MuJoCo's load spheres, 8 to a particle."""
        xs, vs = refine(x, v, self.settings.particle_radius)
        for k, xk, vk in zip(self._items(len(xs)), xs, vs, strict=True):
            self.ledger.release(int(k), xk, vk)
        self.left_g += len(x) * self.mass * 1000.0

    def _hand_over(self, p: NDArray[np.float64], R: NDArray[np.float64],
                   v: NDArray[np.float64], w: NDArray[np.float64]) -> None:
        """What the dish holds becomes the load; the rest of the air goes to MuJoCo; the
        bowl's solver closes (module doc, 4)."""
        liq = self._liquid
        assert liq is not None
        x, vel = liq.positions(), liq.velocities()
        xu = (x - p) @ R
        in_dish = ~outside_dish(xu, self.dish, self.x0, margin=self.r,
                                floor_below=self.thickness * 3.0)
        in_dish &= xu[:, 0] <= self.x0 + self.dish.depth + 2.0 * self.r
        rel = x - self.centre
        in_bowl = ~in_dish & (np.hypot(rel[:, 0], rel[:, 1]) < self.inner_radius) & (
            rel[:, 2] < self.box.length / 2)
        air = ~in_dish & ~in_bowl
        if air.any():
            self._to_mujoco(x[air], vel[air])
        n_in = int(in_dish.sum())
        self._state = (x[in_bowl], vel[in_bowl])
        self.ledger.container_liquid_g = int(in_bowl.sum()) * self.mass * 1000.0
        liq.close()
        self._liquid = None
        self._armed = False
        self.handed_over_g.append(n_in * self.mass * 1000.0)
        if n_in == 0:
            return
        # Relative to the dish, in the utensil body's frame.
        v_rel = (vel[in_dish] - v - np.cross(w, x[in_dish] - p)) @ R
        xs, vs = refine(xu[in_dish], v_rel, self.settings.particle_radius)
        self.placement.liquid = LiquidLoad(self.model, self.data, self.ledger, self.utensil,
                                           self.food, particles=(xs, vs),
                                           items=self._items(len(xs)))
