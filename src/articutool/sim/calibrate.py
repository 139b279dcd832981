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
- ``static_tilt`` (liquid): a load placed on the leveled utensil, the wrist turned slowly
  (``TILT_RATE``) to each tilt of ``TILT_STEPS_DEG`` and held ``TILT_HOLD_S``, over the tip
  (pitch) and sideways (roll), by the tool's own leveling loop with offsets; at every hold the
  grams that left the utensil beside what the dish's hydrostatics
  (:mod:`articutool.food.hydrostatics`, an ideal liquid of the load's volume) spills at the
  tilt the utensil really has. The spill onset is the first hold at which at least
  ``ONSET_G`` has left, beside the tilt at which the ideal liquid has lost as much.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from articutool.arm.scene import Cylinder, Scene
from articutool.food.dish import spoon_dish
from articutool.food.hydrostatics import SIDE, TIP, Hydrostatics, up_vector
from articutool.sim.mjcf import contact_attrs
from articutool.sim.params import Granular, Liquid, PhysicsParams, Strands
from articutool.sim.pieces import draw_piece, piece_extent
from articutool.sim.world import FeedingWorld
from articutool.spec import Spec, UtensilSpec
from articutool.tool.api import Mode

__all__ = ["ONSET_G", "TILT_HOLD_S", "TILT_RATE", "TILT_STEPS_DEG", "angle_of_repose_deg",
           "level_capacity_g", "max_liquid_load_g", "run_calibration", "static_tilt"]

# The static-tilt protocol (numerical choices of the test, not of the model): 1° steps where
# the onsets lie, coarser beyond; the wrist turns at ≤ 0.15 rad/s (quasi-static: the liquid's
# first slosh mode, ~2.4 Hz, is far faster) and holds each tilt 3 s.
TILT_STEPS_DEG = (4.0, 6.0, 8.0, *range(9, 22), 23.0, 25.0)
TILT_RATE = 0.15  # rad/s
TILT_HOLD_S = 3.0
ONSET_G = 0.05  # g: the first grams counted as the spill's onset (a few particles)


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
            f'density="{food.density}" {contact_attrs(food.contacts.food, 0)}/>'
            for a, b, r in draw_piece(food, rng))
        bodies.append(
            f'<body pos="{x * cell + rng.uniform(-1e-3, 1e-3)} {y * cell} {z}" '
            f'quat="{q[0]} {q[1]} {q[2]} {q[3]}"><freejoint/>{geoms}</body>')
    w = params.world
    xml = (f'<mujoco><option timestep="{w.timestep}" solver="{w.solver}" '
           f'iterations="{w.iterations}" tolerance="{w.tolerance}" cone="{w.cone}"/>'
           f'<worldbody><geom type="plane" size="1 1 0.1" '
           f'{contact_attrs(food.contacts.surface, 1)}/>{"".join(bodies)}</worldbody></mujoco>')
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
                    params: PhysicsParams, seed: int = 0,
                    load_g: float | None = None) -> dict:
    """Every calibration experiment that applies to the food; a dict of measured values (a
    liquid's static-tilt test with ``load_g``, default 8 g, under ``static_tilt``)."""
    food = params.food(food_name)
    out: dict[str, float | str] = {"food": food_name, "kind": food.kind,
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
        out["load_piece_mass_g"] = round(food.particle_mass(food.load_particle_radius) * 1e3, 5)
        box = Scene.load().get(food.container)
        world = FeedingWorld(food_name, utensil, spec=spec, params=params, seed=seed)
        assert isinstance(box, Cylinder) and box.container_wall is not None
        inner = box.radius - box.container_wall
        floor = box.xyz[2] - box.length / 2 + box.container_wall
        z = np.array([world.data.xpos[b][2] for b in world.ledger.item_body])
        top = float(np.quantile(z, 0.95)) + food.particle_radius
        vol_ml = math.pi * inner**2 * (top - floor) * 1e6
        out["bulk_density_g_per_ml"] = round(world.masses_g()["container"] / vol_ml, 3)
        out["static_tilt"] = static_tilt(food_name, spec, params, utensil,
                                         8.0 if load_g is None else load_g, seed)
    if isinstance(food, Strands):
        out["note"] = "no calibration experiment for strands yet"
    return out


def max_liquid_load_g(food: Liquid, u: UtensilSpec) -> float:
    """The most a liquid load may weigh on utensil ``u`` (g): what its level dish holds
    (hydrostatics) — more cannot be placed on it as a load."""
    if u.physics.kind != "spoon":
        return 0.0
    return float(Hydrostatics(spoon_dish(u)).level_capacity * food.density * 1000.0)


def _tilt_for_spill(h: Hydrostatics, volume: float, direction: float, grams: float,
                    density: float) -> float:
    """The tilt (deg) at which the ideal liquid of ``volume`` has lost ``grams``."""
    lo, hi = 0.0, math.radians(89.0)
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lost = float(h.spilled(volume, up_vector(mid, direction))) * density * 1000.0
        lo, hi = (mid, hi) if lost < grams else (lo, mid)
    return math.degrees(0.5 * (lo + hi))


def static_tilt(food_name: str, spec: Spec, params: PhysicsParams, utensil: str | None,
                load_g: float = 8.0, seed: int = 0,
                steps_deg: tuple[float, ...] = TILT_STEPS_DEG,
                directions: tuple[str, ...] = ("tip", "side")) -> dict:
    """The static-tilt test of a liquid (module doc): per direction, one row per hold —
    commanded and achieved tilt, grams spilled in the world and by hydrostatics — and the
    onsets; plus the load that stayed when placed and the CPU time."""
    food = params.food(food_name)
    if not isinstance(food, Liquid):
        raise ValueError(f"food: the static-tilt test needs a liquid; {food_name!r} is "
                         f"{food.kind}")
    uname = utensil or food.utensil
    u = spec.utensil(uname)
    hi = max_liquid_load_g(food, u)
    if not (math.isfinite(load_g) and 0 < load_g <= hi):
        raise ValueError(f"load_g must be in (0, {hi:.1f}] g (what the level {uname} holds); "
                         f"got {load_g}")
    h = Hydrostatics(spoon_dish(u))
    out: dict = {"load_g": load_g, "utensil": uname, "steps_deg": list(steps_deg),
                 "hold_s": TILT_HOLD_S, "rate_rad_s": TILT_RATE, "onset_g": ONSET_G}
    cpu, sim = 0.0, 0.0
    for direction in directions:
        world = FeedingWorld(food_name, uname, spec=spec, params=params, seed=seed,
                             load_g=load_g)
        world.tool.set_mode(Mode.LEVELING)
        world.run(1.0)
        world.place_load(settle_s=1.0)
        kept = world.masses_g()["utensil"]
        volume = kept / (food.density * 1000.0)
        dirn = TIP if direction == "tip" else SIDE
        body = world.model.body("utensil").id
        rows = []
        offset, dt = 0.0, world.spec.wrist.period
        for target in steps_deg:
            while offset < target - 1e-9:  # a slow ramp of the held tilt, one loop tick each
                offset = min(target, offset + math.degrees(TILT_RATE) * dt)
                world.tool.set_mode(Mode.LEVELING, *((offset, 0.0) if direction == "tip"
                                                     else (0.0, offset)))
                world.run(dt)
            world.run(TILT_HOLD_S)
            R = world.data.xmat[body].reshape(3, 3)
            up = R.T @ np.array([0.0, 0.0, 1.0])  # world up in the dish (utensil) frame
            tilt = math.degrees(math.acos(min(1.0, float(up[0]))))
            ideal = float(h.spilled(volume, up)) * food.density * 1000.0
            rows.append({"tilt_cmd_deg": target, "tilt_deg": round(tilt, 2),
                         "spilled_g": round(kept - world.masses_g()["utensil"], 3),
                         "hydrostatic_g": round(ideal, 3)})
        onset = next((r["tilt_deg"] for r in rows if r["spilled_g"] >= ONSET_G), None)
        out[direction] = {
            "kept_g": round(kept, 3), "rows": rows, "onset_deg": onset,
            "hydrostatic_onset_deg": round(_tilt_for_spill(h, volume, dirn, ONSET_G,
                                                           food.density), 2)}
        cpu += world._cpu
        sim += world._sim_stepped
    out["cpu_s"] = round(cpu, 1)
    out["realtime_factor"] = round(sim / cpu, 3) if cpu > 0 else math.nan
    return out
