"""Is the dam break's lead over Martin & Moyce (1952) their release, or the liquid's front?

The dam-break check (:func:`articutool.sim.liquid_checks.dam_break_check`) compares its
surge front with Martin & Moyce's for a column twice as high as wide (n² = 2) and reads
13–20 % ahead, a lag in T nearly constant from T ≈ 1.2, which docs/food.md suggested was the
experiment's slow release. A second measurement of the same column shape tells whether that
holds: Koshizuka & Oka (1996), *Nucl. Sci. Eng.* 123:421, the front of a collapsing column
n² = 2 released by a quicker gate, as tabulated by the PySPH project (pypr/pysph,
``pysph/examples/db_exp_data.py``, ``ko_data``: Z = z/L against T = t·√(2g/L), the check's
scaling). This reads the committed calibration's front (``results/experiments/
static_tilt_water.json``, ``liquid.dam_break``: r = a/40, 20 particles across, a = 2.25 in)
against both measurements, without running the liquid: at each measured time the relative
error in Z (the check's metric), and at each measured Z the lag in T (the measured time less
the simulated time the front reached that Z). It also compares the two measurements with
each other, since how far they disagree bounds what either can say about the liquid.

    PYTHONPATH=src .venv/bin/python studies/dam_break_references.py \\
        --out studies/results/dam_break_references.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
CALIBRATION = REPO / "results" / "experiments" / "static_tilt_water.json"

# Koshizuka & Oka (1996), the surge front of a collapsing water column, n² = 2, as tabulated by
# PySPH (pypr/pysph, pysph/examples/db_exp_data.py, ``ko_data``; BSD licence): T, Z.
KOSHIZUKA_OKA_1996 = {
    "source": "Koshizuka & Oka (1996), Nucl. Sci. Eng. 123:421 (n² = 2), as tabulated in "
              "pypr/pysph pysph/examples/db_exp_data.py",
    "t_star": [0.0, 0.381, 0.769, 1.153, 1.537, 1.935, 2.323, 2.719, 3.096],
    "z_star": [1.000, 1.111, 1.252, 1.505, 1.892, 2.241, 2.615, 3.003, 3.624],
}


def compare(t_sim: np.ndarray, z_sim: np.ndarray, t_ref: np.ndarray, z_ref: np.ndarray,
            z_limit: float) -> dict[str, Any]:
    """A front ``(t_sim, z_sim)`` (Z increasing in T) against measured points
    ``(t_ref, z_ref)`` at the points the check compares
    (:func:`~articutool.sim.liquid_checks.front_errors`): the simulated Z at each measured T,
    its relative error, and the lag in T at each measured Z (positive: the simulation got
    there first)."""
    from articutool.sim.liquid_checks import front_errors

    tr, zr, z_at, rel = front_errors(t_sim, z_sim, t_ref, z_ref, z_limit)
    lag = tr - np.interp(zr, np.maximum.accumulate(z_sim), t_sim)
    return {
        "t_star": [float(x) for x in tr],
        "measured_z_star": [float(x) for x in zr],
        "simulated_z_star": [round(float(x), 4) for x in z_at],
        "rel_error": [round(float(x), 4) for x in rel],
        "lag_t_star": [round(float(x), 4) for x in lag],
        "max_abs_rel_error": round(float(np.abs(rel).max()), 4) if rel.size else None,
    }


def main(argv: list[str] | None = None) -> int:
    from articutool.experiments.runner import source_version
    from articutool.sim.liquid_checks import DAM_BREAK_Z_LIMIT, martin_moyce_1952

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    calib = json.loads(CALIBRATION.read_text(encoding="utf-8"))
    dam = calib["liquid"]["dam_break"]
    check = next(c for c in calib["liquid"]["dynamic"] if c.get("check") == "dam_break")
    t_sim, z_sim = np.asarray(dam["t_star"]), np.asarray(dam["z_star"])
    mm_data = martin_moyce_1952()
    refs = {f"Martin & Moyce 1952, a = {s['a_m'] * 1000:.2f} mm": s for s in mm_data["series"]}
    refs["Koshizuka & Oka 1996"] = KOSHIZUKA_OKA_1996
    against = {name: {"source": s.get("source", mm_data["source"]),
                      **compare(t_sim, z_sim, np.asarray(s["t_star"]), np.asarray(s["z_star"]),
                                DAM_BREAK_Z_LIMIT)}
               for name, s in refs.items()}
    # The two measurements against each other: Koshizuka & Oka's front at Martin & Moyce's
    # (larger column's) times, both taken as fronts Z(T) (linear between points).
    mm = refs["Martin & Moyce 1952, a = 57.15 mm"]
    ko_t, ko_z = np.asarray(KOSHIZUKA_OKA_1996["t_star"]), np.asarray(KOSHIZUKA_OKA_1996["z_star"])
    between = compare(ko_t, ko_z, np.asarray(mm["t_star"]), np.asarray(mm["z_star"]),
                      DAM_BREAK_Z_LIMIT)
    early = t_sim <= 0.4
    result = {
        "command": "PYTHONPATH=src .venv/bin/python studies/dam_break_references.py --out "
                   + str(args.out),
        "source": source_version(),
        "calibration": str(CALIBRATION.relative_to(REPO)),
        "particles_across_column": check["particles_across_column"],
        "particle_radius_m": check["particle_radius_m"],
        "z_limit": DAM_BREAK_Z_LIMIT,
        "against": against,
        "koshizuka_oka_as_front_against_martin_moyce_57mm": between,
        "simulated_front_to_t_star_0_4": {"t_star": [float(x) for x in t_sim[early]],
                                          "z_star": [float(x) for x in z_sim[early]]},
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=1) + "\n", encoding="utf-8")
    for name, a in against.items():
        print(f"{name}: max |error| {a['max_abs_rel_error']:.1%} to Z = {DAM_BREAK_Z_LIMIT:g}; "
              f"errors {a['rel_error']}, lags {a['lag_t_star']}")
    print(f"Koshizuka & Oka against Martin & Moyce (57.15 mm): errors {between['rel_error']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
