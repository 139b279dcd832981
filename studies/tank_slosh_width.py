"""How much of the liquid's fast tank slosh is the tank check's slab being four particles wide?

The tank check (:func:`articutool.sim.liquid_checks.tank_slosh_check`) rings water 20 mm deep
in a 100 mm tank whose width is ``width_particles`` particles (4: a slab, so that the mode is
2-D) and compares the centre of mass's frequency with linear theory (exact for a rectangular
tank). This runs the same tank, pulse and reading with the slab widened, and also reads the
frequency by a least-squares fit of a damped cosine with offset and drift beside the zero
crossings (:func:`~articutool.sim.liquid_checks.fitted_oscillation`, which the check now
reads by; on the 4- and 8-wide slabs at r 1.25 mm it gives this study's own earlier fit's
figures to 1e-7), and the law at the depth the settled liquid stands at (twice its centre of
mass's height above the floor the block was placed on), so that a width effect, a settled
depth and a reading error can be told apart. Deterministic: no seed.

    PYTHONPATH=src nice .venv/bin/python studies/tank_slosh_width.py --radius-mm 1.25 \\
        --widths 4 8 16 --out studies/results/tank_slosh_width.json
    PYTHONPATH=src nice .venv/bin/python studies/tank_slosh_width.py --radius-mm 1.0 \\
        --widths 4 --out studies/results/tank_slosh_width.json
"""

from __future__ import annotations

import argparse
import inspect
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np


def ring(radius: float, width_particles: int) -> dict[str, object]:
    """The tank check's tank, pulse and settling (its defaults) with the slab
    ``width_particles`` wide, read for the check's ring-down (3 s, as the committed runs
    read it; the check itself read 2.5 s then)."""
    from articutool.food.slosh import rectangular_tank_mode
    from articutool.sim.liquid_checks import (
        G0,
        _ring_down,
        fitted_oscillation,
        oscillation,
        tank_slosh_check,
    )
    from articutool.sim.sph_scene import Boundary, FluidBlock, SphLiquid, SphSettings, box_mesh

    c = {k: v.default for k, v in inspect.signature(tank_slosh_check).parameters.items()}
    length, depth = c["length"], c["depth"]
    t_cpu = time.process_time()
    r, w = radius, width_particles * radius
    tank = box_mesh((-r, -w - r, -r), (length + r, w + r, 3.0 * depth))
    g = np.array([0.0, 0.0, -G0])
    with SphLiquid([Boundary("tank", *tank)], [FluidBlock((0.0, -w, 0.0), (length, w, depth))],
                   SphSettings(particle_radius=r), g) as liq:
        n = liq.n_particles
        rest, t, com = _ring_down(liq, g, np.array([c["pulse_g"] * G0, 0.0, 0.0]),
                                  c["settle_s"], c["pulse_s"], c["record_s"], c["sample_s"])
    x = com[:, 0] - rest[0]
    crossings = oscillation(t, x, 0.0)
    fit = fitted_oscillation(t, x, 0.0)
    law = rectangular_tank_mode(length, 2 * w, depth)[0] / (2 * math.pi)
    settled = 2.0 * float(rest[2])
    law_settled = rectangular_tank_mode(length, 2 * w, settled)[0] / (2 * math.pi)
    return {"radius_mm": r * 1e3, "width_particles": width_particles,
            "width_mm": round(2 * w * 1e3, 2), "particles": n,
            "crossings_hz": round(crossings["frequency_hz"], 4),
            "fit_hz": round(fit["frequency_hz"], 4),
            "fit_damping_ratio": round(fit["damping_ratio"], 4),
            "law_hz": round(law, 4),
            "rel_error_crossings": round(crossings["frequency_hz"] / law - 1, 4),
            "rel_error_fit": round(fit["frequency_hz"] / law - 1, 4),
            "settled_depth_mm": round(settled * 1e3, 3),
            "law_at_settled_depth_hz": round(law_settled, 4),
            "rel_error_fit_settled": round(fit["frequency_hz"] / law_settled - 1, 4),
            "cpu_s": round(time.process_time() - t_cpu, 1)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--radius-mm", type=float, default=1.25)
    ap.add_argument("--widths", type=int, nargs="+", default=[4, 8, 16])
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    from articutool.datafile import replace_own
    from articutool.experiments.runner import source_version

    doc = json.loads(a.out.read_text()) if a.out.exists() else {"runs": []}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    for wp in a.widths:
        row = {**ring(a.radius_mm * 1e-3, wp), "source": source_version(),
               "load_average": round(os.getloadavg()[0], 1)}
        doc["runs"].append(row)
        replace_own(a.out, json.dumps(doc, indent=1) + "\n")
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
