"""What putting the thesis' 250 g water bowl on the SPlisHSPlasH liquid would cost and give: a
measurement made before building it.

Exp. 1's water is still the bowl's 4 mm frictionless grains (a pile with a yield): the placed
loads of Exp. 2b, 2c and capacity are the SPH liquid (``articutool.sim.liquid_load``), the bowl
is not. This study measures, for the design of a bowl on the liquid, one Exp. 1 acquisition per
system replayed through an SPH bowl:

``record``: one Exp. 1 water acquisition per system through the real feeding tree in the
physics world (stages above and acquire, the grains' world as the experiment builds it), the
utensil body's pose and velocities at every tool tick (50 Hz), and what the grains left on
the utensil. Seeds ``8_500_000 + k``: disjoint from the experiments' (0–999), the searches'
(7 000 000 + k) and the acquisition study's measurement seeds (8 000 000 + k).

``replay``: the scene's bowl (its cylinder and ``container_wall``: the geometry MuJoCo
collides with, as a closed cup mesh) holding the fill's grams of SPH water at particle radius
``r``, settled; the soup spoon's dish (``articutool.food.dish_mesh``, the placed load's
boundary) moved through it as an animated boundary along the recorded poses and velocities
(open loop: the liquid's force does not act back on the arm; the arm is stiff and its path is
the tree's). Reported per radius: the particles and CPU seconds of the fill and the settle,
CPU seconds per simulated second of the scoop, the smallest library step, and the grams in
the dish (inside its rim's ellipse and no farther than a particle above its rim plane or
below its floor) at every recorded tick once the dish is out of the liquid, beside what the
grains gave.

Run (one process, niced): ``PYTHONPATH=src nice python studies/bowl_liquid_scoop.py record
--out studies/results/bowl_liquid_scoop/paths.npz`` then ``... replay --paths
studies/results/bowl_liquid_scoop/paths.npz --radius-mm 2.0 1.5 --out
studies/results/bowl_liquid_scoop/replay.json`` (each replay stops 25 mm above the surface,
``--stop-above-mm``; the JSON names the code that ran and the machine's load).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

SYSTEMS = ("articutool", "baseline")
SEED0 = 8_500_000
STAGES = ("above", "acquire")


# ------------------------------------------------------------------------------ record --
def record(system: str, seed: int) -> dict[str, Any]:
    """One Exp. 1 water acquisition through the tree; the utensil body's path at every tick."""
    import mujoco

    from articutool.meal.bites import make_bite_world, run_bite

    setup = make_bite_world("water", system, seed)
    w = setup.world
    body = w.model.body("utensil").id
    rows: list[NDArray[np.float64]] = []

    def tick(world: Any) -> None:
        v = np.zeros(6)
        mujoco.mj_objectVelocity(world.model, world.data, mujoco.mjtObj.mjOBJ_BODY, body, v, 0)
        rows.append(np.concatenate([[world.data.time], world.data.xpos[body],
                                    world.data.xmat[body], v[3:], v[:3]]))

    w.on_tick.append(tick)
    cpu0 = time.process_time()
    try:
        r = run_bite(setup, stages=STAGES)
    finally:
        setup.arm.close()
    m = w.ledger.masses_g()
    return {"system": system, "seed": seed, "strategy": setup.strategy_name,
            "completed": r.completed, "acquired_g": r.acquired_g,
            "grains_on_utensil_g": round(m.get("utensil", 0.0), 4),
            "cpu_s": round(time.process_time() - cpu0, 1), "path": np.array(rows)}


# ------------------------------------------------------------------------------ replay --
def _poses(path: NDArray[np.float64], t: float) -> tuple[NDArray[np.float64], ...]:
    """The recorded pose and velocities at ``t``, interpolated between ticks (linear in
    position and velocity, spherical in rotation)."""
    from scipy.spatial.transform import Rotation, Slerp

    ts = path[:, 0]
    i = int(np.clip(np.searchsorted(ts, t) - 1, 0, len(ts) - 2))
    u = float(np.clip((t - ts[i]) / (ts[i + 1] - ts[i]), 0.0, 1.0))
    a, b = path[i], path[i + 1]
    rots = Rotation.from_matrix(np.stack([a[4:13].reshape(3, 3), b[4:13].reshape(3, 3)]))
    R = Slerp([0.0, 1.0], rots)(u).as_matrix()
    lerp = (1.0 - u) * a + u * b
    return lerp[1:4], R, lerp[13:16], lerp[16:19]


def replay(paths: dict[str, Any], r: float, settle_s: float, stop_above: float,
           systems: tuple[str, ...] = SYSTEMS, sub_dt: float = 0.005) -> dict[str, Any]:
    """Both systems' recorded acquisitions through an SPH bowl of particle radius ``r``, each
    until its dish, having been in the liquid, is ``stop_above`` (m) above the ideal surface
    (or the path ends)."""
    from articutool.arm.scene import Cylinder, Scene
    from articutool.food.container_liquid import container_boundary_mesh, container_fill
    from articutool.food.dish import spoon_dish
    from articutool.food.dish_mesh import dish_boundary_mesh
    from articutool.sim.liquid_frame import outside_dish
    from articutool.sim.params import PhysicsParams
    from articutool.sim.sph_scene import Boundary, FluidParticles, SphLiquid, SphSettings
    from articutool.spec import load_spec

    spec = load_spec()
    u = spec.utensil("soup_spoon")
    dish, x0, thick = spoon_dish(u), u.tip_x, u.physics.thickness
    dv, df = dish_boundary_mesh(dish, x0, thick)
    bowl = Scene.load().get("bowl")
    assert isinstance(bowl, Cylinder) and bowl.container_wall is not None
    if not np.allclose(bowl.rotation, np.eye(3)):
        raise SystemExit("the study assumes an upright bowl")
    bv, bf = container_boundary_mesh(bowl.radius, bowl.length, bowl.container_wall)
    bv = bv + np.asarray(bowl.xyz)
    water = PhysicsParams.load().food("water")
    st = SphSettings(particle_radius=r, density0=water.density, viscosity=water.viscosity,
                     boundary_viscosity=water.viscosity)
    floor_z = float(bowl.inner_floor()[2])
    ri = bowl.radius - bowl.container_wall
    count = round(water.fill_g / 1000.0 / (water.density * (2.0 * r) ** 3))
    fill = container_fill(ri, floor_z, count, r) + np.array([bowl.xyz[0], bowl.xyz[1], 0.0])
    surface = floor_z + water.fill_g / 1e6 / (math.pi * ri ** 2)
    out: dict[str, Any] = {"particle_radius_mm": r * 1e3, "particles": len(fill),
                           "fill_g": round(len(fill) * st.particle_mass * 1e3, 3),
                           "ideal_surface_above_floor_mm": round((surface - floor_z) * 1e3, 2),
                           "systems": {}}
    meta = {m["system"]: m for m in json.loads(str(paths["meta"]))}
    for system in systems:
        path = paths[f"path_{system}"]
        world = [(dv @ row[4:13].reshape(3, 3).T + row[1:4]) for row in path]
        low = np.array([wv[:, 2].min() for wv in world])
        near = np.flatnonzero(low < surface + 0.03)
        if len(near) == 0:
            out["systems"][system] = {"error": "the dish never comes near the liquid"}
            continue
        i0 = int(near[0])
        t0 = float(path[i0, 0])
        cpu0 = time.process_time()
        p, R, v, w = _poses(path, t0)
        liq = SphLiquid([Boundary("bowl", bv, bf), Boundary("dish", dv, df, animated=True)],
                        [FluidParticles(fill)], st)
        try:
            liq.set_boundary_pose("dish", p, R)
            build_cpu = time.process_time() - cpu0
            cpu0 = time.process_time()
            leaked = 0

            def drop_leavers(liq: SphLiquid = liq) -> int:
                """Take out particles that left the bowl (through or over its wall): one
                falling free would collapse the CFL step."""
                x = liq.positions() - np.asarray(bowl.xyz)
                out = (x[:, 2] < -bowl.length / 2 - 0.005) | (
                    np.hypot(x[:, 0], x[:, 1]) > bowl.radius + 0.005)
                return liq.remove_particles(out) if out.any() else 0

            for k in range(1, round(settle_s / 0.05) + 1):
                liq.step_to(0.05 * k)
                leaked += drop_leavers()
            print(f"  settled in {time.process_time() - cpu0:.0f} CPU s, {leaked} left the "
                  f"bowl, last step {liq.last_dt * 1e3:.3f} ms", file=sys.stderr, flush=True)
            x = liq.positions()
            settled = {"cpu_s": round(time.process_time() - cpu0, 1),
                       "surface_above_floor_mm": round(
                           (np.percentile(x[:, 2], 99) + r - floor_z) * 1e3, 2),
                       "max_speed_m_s": round(float(np.abs(liq.velocities()).max()), 4)}
            shift = liq.time - t0  # liquid time = path time + shift
            cpu0, min_dt, steps, submerged = time.process_time(), math.inf, 0, False
            series = []
            for i in range(i0 + 1, len(path)):
                t_end = float(path[i, 0])
                t = float(path[i - 1, 0])
                while t < t_end - 1e-9:
                    t = min(t + sub_dt, t_end)
                    p, R, v, w = _poses(path, t)
                    liq.set_boundary_pose("dish", p, R, v, w)
                    steps += liq.step_to(t + shift)
                    min_dt = min(min_dt, liq.last_dt)
                leaked += drop_leavers()
                xu = (liq.positions() - p) @ R
                inn = ~outside_dish(xu, dish, x0, margin=r, floor_below=thick * 3.0)
                inn &= xu[:, 0] <= x0 + dish.depth + 2.0 * r
                series.append((round(t_end - t0, 3), round((low[i] - surface) * 1e3, 2),
                               round(float(inn.sum()) * st.particle_mass * 1e3, 3)))
                if i % 25 == 0:
                    print(f"  {system} r {r * 1e3:g} mm: t {t_end - t0:.2f} s, dish "
                          f"{series[-1][1]:+.1f} mm, {series[-1][2]:.2f} g in it, last step "
                          f"{liq.last_dt * 1e3:.3f} ms, {time.process_time() - cpu0:.0f} CPU s, "
                          f"{leaked} left the bowl", file=sys.stderr, flush=True)
                submerged = submerged or low[i] < surface
                if submerged and low[i] - surface > stop_above:
                    break
            sim_s = t_end - t0
            scoop_cpu = time.process_time() - cpu0
            out_of = [g for (_, above, g) in series[np.argmin([a for _, a, _ in series]):]
                      if above > 2e3 * r]
            out["systems"][system] = {
                "build_cpu_s": round(build_cpu, 1), "settle": settled,
                "scoop_sim_s": round(sim_s, 3), "scoop_cpu_s": round(scoop_cpu, 1),
                "cpu_s_per_sim_s": round(scoop_cpu / sim_s, 1), "library_steps": steps,
                "min_dt_ms": round(min_dt * 1e3, 3), "left_the_bowl": leaked,
                "in_dish_g_at_end": series[-1][2],
                "in_dish_g_once_out": {"first": out_of[0] if out_of else None,
                                       "last": out_of[-1] if out_of else None},
                "grains_acquired_g": meta[system]["acquired_g"],
                "series_t_s_dish_above_surface_mm_in_dish_g": series}
        finally:
            liq.close()
        print(json.dumps({k: v for k, v in out["systems"][system].items()
                          if not k.startswith("series")}), file=sys.stderr, flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    rec = sub.add_parser("record")
    rec.add_argument("--out", type=Path, required=True)
    rec.add_argument("--k", type=int, default=0)
    rep = sub.add_parser("replay")
    rep.add_argument("--paths", type=Path, required=True)
    rep.add_argument("--radius-mm", type=float, nargs="+", default=[2.0, 1.5])
    rep.add_argument("--settle-s", type=float, default=0.5)
    rep.add_argument("--stop-above-mm", type=float, default=25.0)
    rep.add_argument("--systems", nargs="+", choices=SYSTEMS, default=list(SYSTEMS))
    rep.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    if a.cmd == "record":
        if a.out.exists():
            print(f"{a.out} exists: not overwritten", file=sys.stderr)
            return 2
        a.out.parent.mkdir(parents=True, exist_ok=True)
        from articutool.experiments.runner import source_version

        runs = [{**record(s, SEED0 + a.k), "source": source_version()} for s in SYSTEMS]
        meta = [{k: v for k, v in x.items() if k != "path"} for x in runs]
        np.savez_compressed(a.out, meta=json.dumps(meta),
                            **{f"path_{x['system']}": x["path"] for x in runs})
        print(json.dumps(meta, indent=1))
        return 0
    from articutool.experiments.runner import source_version

    paths = dict(np.load(a.paths))
    out = {"source": source_version(), "load_average_start": round(os.getloadavg()[0], 1),
           "radii": [replay(paths, mm / 1000.0, a.settle_s, a.stop_above_mm / 1000.0,
                            tuple(a.systems))
                     for mm in a.radius_mm]}
    out["load_average_end"] = round(os.getloadavg()[0], 1)
    a.out.write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
