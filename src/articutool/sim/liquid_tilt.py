"""The SPH liquid's checks against its laws: static tilt (hydrostatics) and weighing.

- **Static tilt** (:func:`static_tilt_sph`): a load poured into the soup spoon's dish (the
  world's pour, :func:`articutool.food.dish_fill.dish_pour`, and the world's boundary,
  :func:`articutool.food.dish_mesh.dish_boundary_mesh`) settles level for ``SETTLE_S``; then
  gravity is turned in the dish's frame at ``TILT_RATE`` over the tip or sideways (slow
  beside the liquid's running over the lip, as the law's equilibrium asks: turned at
  0.15 rad/s the onsets read 0.9–1.55° past the law's, at 0.05 rad/s 0.5–1.1°), held
  ``HOLD_S`` at each of ``HOLD_DEG``, long
  enough for the liquid over the lip to drain to rest (the law is an equilibrium: after a 1 s
  hold 8 g over the tip had lost 0.61 g at 12° where it loses 0.86 g by 4 s, hydrostatics
  0.89 g). A particle that leaves the dish (:func:`articutool.sim.liquid_frame.outside_dish`,
  as the world decides it) is taken out and counted spilled, checked every ``CHECK_S`` of simulated
  time, holds included: a particle left to fall away from the dish gains speed without bound
  and the library's CFL step, which follows the fastest particle, shrinks with it (a 1 s hold
  run unchecked took the step from 2 ms to 0.06 ms). The onset is the tilt at which
  ``ONSET_G`` has left (during the turn, or the hold's tilt if it left during a hold),
  beside the tilt at which the ideal liquid of the same volume
  (:class:`articutool.food.hydrostatics.Hydrostatics`) has lost as much; at each hold the
  grams spilled beside the ideal liquid's. Tolerances: onset within ``ONSET_TOL_DEG``,
  grams within ``GRAMS_TOL`` (relative).
- **Weighing** (:func:`weighing_check`): the feeding world with a placed liquid load, the
  wrist leveled, the F/T sensor tared empty; the load at rest weighed by the F/T sensor and
  by the scale (the liquid's momentum-balance force), each within ``WEIGH_TOL``.

The dam-break and slosh-mode checks of :mod:`articutool.sim.liquid_checks` run beside these in
``articutool sim-calibrate --food water`` (:data:`LIQUID_CHECKS`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

from articutool.food.dish import spoon_dish
from articutool.food.dish_fill import dish_pour
from articutool.food.dish_mesh import dish_boundary_mesh
from articutool.food.hydrostatics import SIDE, TIP, Hydrostatics, up_vector
from articutool.sim.liquid_frame import outside_dish
from articutool.sim.params import Liquid, PhysicsParams
from articutool.sim.sph_library import library_version
from articutool.sim.sph_scene import Boundary, FluidParticles, SphLiquid, SphSettings
from articutool.spec import Spec

__all__ = ["GRAMS_TOL", "HOLD_DEG", "HOLD_S", "LIQUID_CHECKS", "ONSET_G", "ONSET_TOL_DEG",
           "TILT_LOADS_G", "TILT_RADII_M", "TILT_RATE", "WEIGH_TOL", "check_passes",
           "liquid_calibration",
           "static_tilt_sph", "weighing_check"]

# The protocol (numerical choices of the test, not of the model).
SETTLE_S = 0.5
TILT_RATE = 0.05  # rad/s
HOLD_DEG = (12.0, 15.0, 20.0, 25.0)
HOLD_S = 4.0
CHECK_S = 0.02  # s: how often particles that left the dish are taken out
ONSET_G = 0.05  # g: the first grams counted as the onset
# The law's tolerances (the task's criteria).
ONSET_TOL_DEG = 1.5
GRAMS_TOL = 0.15
WEIGH_TOL = 0.01


def static_tilt_sph(food: Liquid, spec: Spec, utensil: str, load_g: float, direction: str,
                    radius: float | None = None,
                    holds_deg: tuple[float, ...] = HOLD_DEG) -> dict[str, Any]:
    """The static-tilt test of the SPH liquid (module doc) for one load, direction (``tip``
    or ``side``), particle radius (default the food's) and holds (ascending tilts, °; default
    ``HOLD_DEG``); every value beside its law."""
    u = spec.utensil(utensil)
    dish = spoon_dish(u)
    r = food.sph_particle_radius if radius is None else radius
    settings = SphSettings(particle_radius=r, density0=food.density, viscosity=food.viscosity,
                           boundary_viscosity=food.viscosity)
    n = max(1, round(load_g / 1000.0 / settings.particle_mass))
    verts, faces = dish_boundary_mesh(dish, u.tip_x, u.physics.thickness)
    g = abs(spec.imu.gravity)
    dirn = TIP if direction == "tip" else SIDE
    hyd = Hydrostatics(dish)
    c0 = time.process_time()
    with SphLiquid([Boundary("dish", verts, faces)],
                   [FluidParticles(dish_pour(dish, u.tip_x, r, n))], settings,
                   gravity=(-g, 0.0, 0.0)) as liq:
        mass_g = liq.particle_mass * 1000.0
        spilled = 0
        min_dt = math.inf

        def run_to(t: float) -> None:
            nonlocal spilled, min_dt
            while liq.time < t - 1e-12:
                liq.step_to(min(t, liq.time + CHECK_S))
                min_dt = min(min_dt, liq.last_dt)
                out = outside_dish(liq.positions(), dish, u.tip_x, r,
                                   3.0 * u.physics.thickness)
                spilled += liq.remove_particles(out)

        def tilt_to(t: float, deg: float) -> None:
            liq.set_gravity(-g * up_vector(math.radians(deg), dirn))
            run_to(t)

        t = SETTLE_S
        run_to(t)
        kept_g = liq.n_particles * mass_g
        volume = kept_g / (food.density * 1000.0)
        tilt, step = 0.0, math.degrees(TILT_RATE) * CHECK_S  # one turning step a check
        onset = None
        holds = []
        for target in holds_deg:
            while tilt < target - 1e-9:
                tilt = min(target, tilt + step)
                t += CHECK_S
                tilt_to(t, tilt)
                if onset is None and spilled * mass_g >= ONSET_G:
                    onset = tilt
            t += HOLD_S
            tilt_to(t, tilt)
            if onset is None and spilled * mass_g >= ONSET_G:
                onset = tilt  # it left during the hold, at this tilt
            ideal = float(hyd.spilled(volume, up_vector(math.radians(tilt), dirn)))
            ideal_g = ideal * food.density * 1000.0
            got = spilled * mass_g
            holds.append({"tilt_deg": target, "spilled_g": round(got, 3),
                          "hydrostatic_g": round(ideal_g, 3),
                          "passes": bool(abs(got - ideal_g) <= GRAMS_TOL * ideal_g)})
        # the tilt at which the ideal liquid has lost ONSET_G: where it holds only V − ONSET_G
        law_onset = math.degrees(float(hyd.onset_tilt(
            volume - ONSET_G / (food.density * 1000.0), dirn)))
        return {
            "load_g": load_g, "direction": direction, "particle_radius_mm": r * 1e3,
            "particles": n, "kept_g": round(kept_g, 3), "tilt_rate_rad_s": TILT_RATE,
            "hold_s": HOLD_S,
            "onset": {"measured_deg": onset, "law_deg": round(law_onset, 2),
                      "tolerance_deg": ONSET_TOL_DEG,
                      "passes": onset is not None
                      and abs(onset - law_onset) <= ONSET_TOL_DEG},
            "holds": holds, "grams_tolerance": GRAMS_TOL,
            "passes": (onset is not None and abs(onset - law_onset) <= ONSET_TOL_DEG
                       and all(h["passes"] for h in holds)),
            "min_dt_ms": round(min_dt * 1e3, 4),
            "cpu_s": round(time.process_time() - c0, 1),
        }


def weighing_check(food_name: str, spec: Spec, params: PhysicsParams, utensil: str | None,
                   load_g: float = 8.0, seed: int = 0) -> dict[str, Any]:
    """A still liquid load weighed in the feeding world (module doc)."""
    from articutool.sim.world import FeedingWorld
    from articutool.tool.api import Mode

    world = FeedingWorld.make(food_name, utensil, spec=spec, params=params, seed=seed,
                               load_g=load_g, mouth=False)
    try:
        world.tool.set_mode(Mode.LEVELING)
        world.run(1.0)
        world.weighing.tare(settle_s=0.2)
        held = world.placement.place(settle_s=1.5)
        ft = world.weighing.ft_mass_g(0.5)
        scale = world.weighing.carried_g()
    finally:
        world.close()
    return {"load_g": load_g, "held_g": round(held, 4),
            "ft_sensor_g": round(ft, 4), "scale_g": round(scale, 4),
            "tolerance": WEIGH_TOL,
            "passes": bool(abs(ft - held) <= WEIGH_TOL * held
                           and abs(scale - held) <= WEIGH_TOL * held)}


def _liquid_checks() -> list[Callable[[], dict[str, Any]]]:
    """The dynamic checks of :mod:`articutool.sim.liquid_checks` (the dam break, the slosh
    modes), each a call returning its result beside its law."""
    from articutool.sim import liquid_checks as lc

    return [getattr(lc, name) for name in ("dam_break_check", "slosh_mode_check")
            if hasattr(lc, name)]


# The liquid's dynamic checks run by ``sim-calibrate --food water`` beside the static tilt and
# the weighing: add a check here (a callable returning a dict with ``passes``).
LIQUID_CHECKS: Callable[[], list[Callable[[], dict[str, Any]]]] = _liquid_checks


def backend() -> dict[str, str]:
    """The liquid solver's name and version."""
    return {"backend": "SPlisHSPlasH (pysplishsplash)", "version": library_version()}


# The sweep of ``sim-calibrate --food water``: loads (g) and particle radii (m), the two
# radii spanning the validated range (convergence).
TILT_LOADS_G = (6.0, 8.0, 10.0, 12.0)
TILT_RADII_M = (0.001, 0.00075)


def liquid_calibration(food_name: str, spec: Spec, params: PhysicsParams,
                       utensil: str | None, loads: tuple[float, ...] = TILT_LOADS_G,
                       radii: tuple[float, ...] = TILT_RADII_M,
                       on_result: Callable[[dict[str, Any]], None] | None = None
                       ) -> dict[str, Any]:
    """Every check of the SPH liquid beside its law (module doc): the static tilt over
    ``loads`` × ``radii`` × both directions, the weighing, the dynamic checks; each result
    is passed to ``on_result`` as it comes (a long sweep can be saved as it runs)."""
    food = params.food(food_name)
    if not isinstance(food, Liquid):
        raise ValueError(f"food: the liquid's checks need a liquid; {food_name!r} is "
                         f"{food.kind}")
    uname = utensil or food.utensil
    tilts = []
    for r in radii:
        for g in loads:
            for dn in ("tip", "side"):
                tilts.append(static_tilt_sph(food, spec, uname, g, dn, r))
                if on_result is not None:
                    on_result(tilts[-1])
    weigh = weighing_check(food_name, spec, params, uname)
    dynamic = [check() for check in LIQUID_CHECKS()]
    out: dict[str, Any] = {
        **backend(), "particle_radius_mm": food.sph_particle_radius * 1e3,
        "particle_radii_checked_mm": [r * 1e3 for r in radii],
        "static_tilt": tilts, "static_tilt_passes": all(t["passes"] for t in tilts),
        "weighing": weigh, "dynamic": dynamic,
        "passes": all(t["passes"] for t in tilts) and weigh["passes"]
        and all(check_passes(d) for d in dynamic)}
    for d in dynamic:
        if d.get("check") == "dam_break":  # the surge front, T = n·t·√(g/a), Z = x/a
            out["dam_break"] = {"t_star": d["t_star"], "z_star": d["z_star"],
                                "reference": d["reference"]}
            if food.load_model == "sph":  # the bowl's coarser liquid flows as the fine one
                from articutool.sim.liquid_checks import coarse_dam_break_check

                bowl = coarse_dam_break_check(food.sph_bowl_particle_radius, d)
                out["bowl_resolution"] = bowl
                out["passes"] = out["passes"] and bowl["pass"]
    return out


def check_passes(result: dict[str, Any]) -> bool:
    """A check's verdict (the dynamic checks say ``pass``, the static ones ``passes``)."""
    return bool(result.get("pass", result.get("passes", False)))
