"""Does the dam break's lead over Martin & Moyce (1952) belong to SPlisHSPlasH's solver?

The dam-break check (:func:`articutool.sim.liquid_checks.dam_break_check`) reads its surge
front 13–20 % ahead of Martin & Moyce's with the liquid's settings: DFSPH (Bender & Koschier
2015), boundary particles (Akinci et al. 2012), the CFL step up to 2 ms. This runs the check
itself (its column, settling, release and front) with one of those choices changed at a time,
among the library's own alternatives: its other incompressible solver (IISPH, Ihmsen et al.
2014), its density-map boundaries (Koschier & Bender 2017), release steps capped at 0.1 ms,
and its weakly compressible solver (WCSPH, Becker & Teschner 2007: Tait's equation with
exponent 7, ``stiffness`` B, sound speed c = √(7B/ρ₀); the library's CFL reads the particles'
speed, not sound's, so the step is capped at 0.4·h/c with h = 4r). Each run logs the settled
column's height and the released liquid's mechanical energy at every sample: with free-slip
walls and water's viscosity (its laminar dissipation is negligible over the 0.17 s run), an
incompressible column converts the potential energy it releases into kinetic energy, so a
solver that loses or makes energy is the solver, not the water.

The variants reach the library through the study's one seam, the scene file
(``sph_scene._scene_json``, wrapped here), and the check's liquid is the project's
:class:`~articutool.sim.sph_scene.SphLiquid` with a sampling hook; nothing in ``src`` changes.

    PYTHONPATH=src .venv/bin/python studies/dam_break_solvers.py \\
        --out studies/results/dam_break_solvers.json
    PYTHONPATH=src .venv/bin/python studies/dam_break_solvers.py --table \\
        --out studies/results/dam_break_solvers.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

RHO0 = 1000.0  # kg/m³, the liquid's rest density (SphSettings' default)
ACROSS = 20  # particles across the column: the check's own resolution (r = a/40)
# (name, what it changes, the library's simulation method id, boundary method id,
# cap on the release's step (s) or None, WCSPH stiffness B (Pa) or None). Ids: the library's
# scene-file ids (simulationMethod 0 WCSPH, 3 IISPH, 4 DFSPH; boundaryHandlingMethod 0
# particles, 1 density maps).
VARIANTS: tuple[tuple[str, str, int, int, float | None, float | None], ...] = (
    ("check", "the check as shipped: DFSPH, boundary particles", 4, 0, None, None),
    ("iisph", "IISPH for DFSPH", 3, 0, None, None),
    ("density_maps", "density-map boundaries for particles", 4, 1, None, None),
    ("release_dt_0.1ms", "the release's steps at most 0.1 ms", 4, 0, 1e-4, None),
    ("wcsph", "WCSPH, B = 50 kPa (c = 18.7 m/s)", 0, 0, None, 5.0e4),
    ("wcsph_stiff", "WCSPH, B = 500 kPa (c = 59.2 m/s)", 0, 0, None, 5.0e5),
)
DENSITY_MAP_RESOLUTION = [40, 20, 30]  # cells along x, y, z of each boundary's map


def sound_speed(stiffness: float) -> float:
    """m/s: Tait's equation's sound speed at rest, √(7B/ρ₀)."""
    return math.sqrt(7.0 * stiffness / RHO0)


def energy_balance(samples: list[tuple[float, float, float]]) -> dict[str, list[float]]:
    """From samples ``(t, kinetic J, potential J)`` of a liquid released from rest: the
    potential energy released since the first sample, the kinetic energy, and the share of
    the released energy not found as kinetic (lost where positive, made where negative;
    NaN until 1 % of the last sample's release)."""
    t = np.array([s[0] for s in samples])
    kin = np.array([s[1] for s in samples])
    pot = np.array([s[2] for s in samples])
    released = pot[0] - pot
    kin = kin - kin[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        lost = np.where(released > 0.01 * released[-1], (released - kin) / released, np.nan)
    return {"t_s": [round(float(x), 5) for x in t],
            "released_j": [round(float(x), 6) for x in released],
            "kinetic_j": [round(float(x), 6) for x in kin],
            "lost_share": [None if math.isnan(x) else round(float(x), 4) for x in lost]}


def run_variant(name: str, change: str, method: int, boundary: int, release_dt: float | None,
                stiffness: float | None) -> dict[str, Any]:
    """The check at :data:`ACROSS` across with one variant: its front against Martin &
    Moyce, the settled column's height (in column widths) and the release's energy."""
    import articutool.sim.liquid_checks as lc
    import articutool.sim.sph_scene as sc

    scene_json = sc._scene_json
    liquid = sc.SphLiquid
    settled_column = lc._settled_column
    samples: list[tuple[float, float, float]] = []
    column: dict[str, float] = {}

    def settling(scene: dict[str, Any]) -> bool:  # the settling's syrup, not water
        return any(isinstance(v, dict) and v.get("viscosity", 0.0) >= 1e-3
                   for v in scene["Materials"][0].values())

    def variant_scene(*a: Any, **k: Any) -> dict[str, Any]:
        scene = scene_json(*a, **k)
        c = scene["Configuration"]
        c["simulationMethod"], c["boundaryHandlingMethod"] = method, boundary
        caps = [] if settling(scene) or release_dt is None else [release_dt]
        if stiffness is not None:
            c["stiffness"], c["exponent"] = stiffness, 7.0
            caps.append(0.4 * 4.0 * c["particleRadius"] / sound_speed(stiffness))
        for cap in caps:
            c["cflMaxTimeStepSize"] = min(c["cflMaxTimeStepSize"], cap)
            c["timeStepSize"] = min(c["timeStepSize"], cap)
        if boundary == 1:
            for i, rb in enumerate(scene["RigidBodies"]):
                rb.update(mapInvert=i == 0, mapThickness=0.0,  # the tank (first) holds it
                          mapResolution=DENSITY_MAP_RESOLUTION)
        return scene

    class Sampled(liquid):  # type: ignore[misc, valid-type]
        def __init__(self, *a: Any, **k: Any) -> None:
            super().__init__(*a, **k)
            self.sample()  # the release: the settled column at rest

        def sample(self) -> None:
            if self.settings.viscosity < 1e-3:  # the release, in water's settings
                x, v = self.positions(), self.velocities()
                m = self.particle_mass
                samples.append((self.time, float(0.5 * m * (v ** 2).sum()),
                                float(m * lc.G0 * x[:, 2].sum())))

        def step_to(self, t: float) -> int:
            n = super().step_to(t)
            self.sample()
            return n

    def measured_column(*a: Any, **k: Any) -> tuple[np.ndarray, dict[str, float]]:
        x, info = settled_column(*a, **k)
        column.update(top_m=float(np.sort(x[:, 2])[-20:].mean()),
                      mean_height_m=float(x[:, 2].mean()), particles=len(x))
        return x, info

    sc._scene_json, lc.SphLiquid, lc._settled_column = variant_scene, Sampled, measured_column
    try:
        r = lc.dam_break_check(radius=0.05715 / (2 * ACROSS))
    finally:
        sc._scene_json, lc.SphLiquid, lc._settled_column = scene_json, liquid, settled_column
    a = r["column_width_m"]
    return {
        "variant": name, "change": change, "simulation_method": method, "boundary_method": boundary,
        "release_max_dt_s": release_dt, "stiffness_pa": stiffness,
        "sound_speed_m_s": round(sound_speed(stiffness), 2) if stiffness else None,
        "particles": r["particles"], "settling": r["settling"],
        "column_top_widths": round(column["top_m"] / a, 3),
        "column_mean_height_widths": round(column["mean_height_m"] / a, 3),
        "compared_at_t_star": r["compared_at_t_star"],
        "measured_z_star": r["measured_z_star"], "law_z_star": r["law_z_star"],
        "rel_error": [round((s - m) / m, 4) for s, m in zip(r["measured_z_star"],
                                                            r["law_z_star"], strict=True)],
        "max_rel_error_to_Z3": r["max_rel_error_to_Z3"], "pass": r["pass"],
        "t_star": r["t_star"], "z_star": r["z_star"],
        "t_scale_s": 1.0 / math.sqrt(2.0 * 9.80665 / a),
        "energy": energy_balance(samples),
        "cpu_s": r["cpu_s"],
    }


def _cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo``), or the architecture where it is not there."""
    import platform

    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.machine()


def table(doc: dict[str, Any]) -> str:
    """The study's table (Markdown): per variant the front's errors at Martin & Moyce's
    times, the settled column's height and the share of the released energy lost."""
    rows = ["| variant | Z at T = 0.83 / 1.22 / 2.00 / 2.55 (M&M 1.217 / 1.474 / 2.292 / "
            "2.995) | error | column top (a) | energy lost at T ≈ 1.6 / at the end | CPU s |",
            "|---|---|---|---|---|---|"]
    for v in doc["runs"]:
        e = v["energy"]
        t_star = np.array(e["t_s"]) / v["t_scale_s"]
        k = int(np.argmin(np.abs(t_star - 1.6)))
        z = " / ".join(f"{x:.3f}" for x in v["measured_z_star"])
        err = " / ".join(f"{100 * x:+.1f}" for x in v["rel_error"])
        rows.append(f"| {v['variant']} | {z} | {err} % | {v['column_top_widths']:.2f} | "
                    f"{100 * e['lost_share'][k]:+.1f} / {100 * e['lost_share'][-1]:+.1f} % | "
                    f"{v['cpu_s']:.0f} |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--table", action="store_true", help="print the table of --out")
    ap.add_argument("--only", nargs="*", help="the variants to run (default: all)")
    a = ap.parse_args(argv)
    if a.table:
        print(table(json.loads(a.out.read_text())))
        return 0
    import os

    from articutool.experiments.runner import source_version
    from articutool.sim.liquid_checks import martin_moyce_1952

    runs = [run_variant(*v) for v in VARIANTS if not a.only or v[0] in a.only]
    doc = {"question": __doc__.splitlines()[0], "source": source_version(),
           "machine": {"cpu": _cpu_model(),
                       "load_average": [round(x, 2) for x in os.getloadavg()]},
           "clock": "process CPU (time.process_time)", "across": ACROSS,
           "reference": martin_moyce_1952()["source"], "runs": runs}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(doc, indent=1) + "\n")
    print(table(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
