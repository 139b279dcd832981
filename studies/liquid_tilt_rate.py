"""Do the SPH liquid's static-tilt results depend on how fast the dish is turned, or on where
a particle is counted out?

The static-tilt check (`articutool.sim.liquid_tilt.static_tilt_sph`) turns gravity in the
dish's frame at `TILT_RATE` and counts a particle spilled once it is `r` past the rim's
ellipse (`liquid_frame.outside_dish`). This study runs the check's own function with the rate
set (`--rate`, rad/s) and the counting rule's margin widened (`--extra-margin-mm`: counted out
only that much further past the rim, e.g. the lip's 1.5 mm width), for one load, direction,
particle radius and set of holds, and appends one row to `--out`. Deterministic (no seed: the
boundary is sampled regularly). Commands of the committed JSON
(`studies/results/liquid_tilt_rate.json`):

    PYTHONPATH=src python studies/liquid_tilt_rate.py --rate 0.025 --load 10 --direction side \
        --radius-mm 1.0 --out studies/results/liquid_tilt_rate.json
    PYTHONPATH=src python studies/liquid_tilt_rate.py --rate 0.05 --extra-margin-mm 1.5 \
        --load 8 --direction tip --radius-mm 0.75 --holds 12 15 \
        --out studies/results/liquid_tilt_rate.json
    (the same with --radius-mm 1.0)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path


def run(rate: float, extra_margin_m: float, load_g: float, direction: str, radius_m: float,
        holds: tuple[float, ...]) -> dict[str, object]:
    """One static tilt with the rate and the counting margin set (module doc)."""
    import articutool.sim.liquid_tilt as lt
    from articutool.sim.liquid_frame import outside_dish
    from articutool.sim.params import PhysicsParams
    from articutool.spec import load_spec

    lt.TILT_RATE = rate
    lt.outside_dish = lambda x, dish, x0, margin, below: outside_dish(  # type: ignore[assignment]
        x, dish, x0, margin + extra_margin_m, below)
    res = lt.static_tilt_sph(PhysicsParams.load().food("water"), load_spec(), "soup_spoon",
                             load_g, direction, radius_m, holds_deg=holds)
    return {**res, "tilt_rate_rad_s": rate, "extra_margin_mm": extra_margin_m * 1e3}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, required=True, help="rad/s")
    ap.add_argument("--extra-margin-mm", type=float, default=0.0)
    ap.add_argument("--load", type=float, required=True, help="g")
    ap.add_argument("--direction", choices=("tip", "side"), required=True)
    ap.add_argument("--radius-mm", type=float, required=True)
    ap.add_argument("--holds", type=float, nargs="+", default=[12.0, 15.0, 20.0, 25.0])
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    from articutool.datafile import replace_own
    from articutool.experiments.runner import source_version

    row = {**run(a.rate, a.extra_margin_mm * 1e-3, a.load, a.direction, a.radius_mm * 1e-3,
                 tuple(a.holds)),
           "command": "python studies/liquid_tilt_rate.py " + " ".join(
               argv if argv is not None else sys.argv[1:]),
           "source": source_version(), "load_average": round(os.getloadavg()[0], 1)}
    doc = json.loads(a.out.read_text()) if a.out.exists() else {"runs": []}
    doc["runs"].append(row)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    replace_own(a.out, json.dumps(doc, indent=1) + "\n")
    print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
