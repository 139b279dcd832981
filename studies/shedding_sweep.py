"""Sweep of the open-loop shedding primitives' parameters (thesis §4.4, §5.2.3).

Each candidate runs Exp. 2c's protocol (:func:`articutool.experiments.units.exp2c.exp2c_trial`:
the capacity load placed at the shedding pose over the bowl, the primitive, the transport to
Staging) on TUNING seeds — base seed 9 (seeds 9000+r), disjoint from the experiments' seeds
(base 0: 0..999, ``experiments/design.py``). The candidate runs in the third condition's slot
(``[exp2c.closed_loop]`` replaced in a copy of the settings), so the trial is the experiment's
own code. Score: meaningful successes (no spill, delivered above the food's threshold), ties
broken by the mean delivered grams.

    PYTHONPATH=src python studies/shedding_sweep.py --food pecans --seeds 3 \\
        --load-g 6.5 --threshold-g 1.47 --out studies/results/shedding/sweep_pecans.json

Writes JSON (every trial, every candidate's score) and, with ``--plot``, a PNG.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import time
from pathlib import Path

from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.design import trial_seed
from articutool.experiments.protocols import json_safe
from articutool.experiments.units.exp2c import Exp2cCondition, ShedPrimitive, exp2c_trial
from articutool.spec import load_spec

TUNING_BASE_SEED = 9


def candidates(food: str) -> list[tuple[str, list[float]]]:
    """The grid: VIBRATE_ROLL (frequency, amplitude, duration) for pecans — amplitudes at
    50 % and 95 % of the roll speed limit at each frequency — and TILT (angle, speed, hold)
    for water."""
    vmax = float(load_spec().wrist.velocity_limits[1])
    if food == "pecans":
        return [("VIBRATE_ROLL", [f, round(k * vmax / (2 * math.pi * f), 4), d])
                for f, k, d in itertools.product((4.0, 8.0, 12.0), (0.5, 0.95), (1.0, 3.0))]
    return [("TILT", [a, v, h])
            for a, v, h in itertools.product((0.2, 0.35, 0.5, 0.7), (0.5, 1.5), (0.5, 2.0))]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--food", choices=("pecans", "water"), required=True)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--load-g", type=float, required=True)
    ap.add_argument("--threshold-g", type=float, required=True)
    ap.add_argument("--limit", type=int, default=0, help="first N candidates only (pilot)")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--plot", action="store_true")
    a = ap.parse_args(argv)
    if a.out.exists():
        print(f"--out: {a.out} exists; not overwriting", file=sys.stderr)
        return 2
    cfg = ExperimentsConfig.load()
    cands = candidates(a.food)[: a.limit or None]
    rows = []
    t0 = time.time()
    for name, params in cands:
        loops = dict(cfg.exp2c.closed_loop)
        loops[a.food] = ShedPrimitive(primitive=name, params=params)
        c = cfg.model_copy(update={"exp2c": cfg.exp2c.model_copy(update={"closed_loop": loops})})
        trials = []
        for r in range(a.seeds):
            seed = trial_seed(TUNING_BASE_SEED, r)
            rec = exp2c_trial(Exp2cCondition(food=a.food, condition="closed_loop",
                                             load_g=a.load_g), seed, c)
            ok = rec.completed and rec.spilled_g <= 1e-9
            trials.append({"seed": seed, "meaningful": bool(ok and rec.delivered_g
                                                             > a.threshold_g),
                           **{k: getattr(rec, k) for k in (
                               "held_g", "after_primitive_g", "shed_g", "spilled_g",
                               "delivered_g", "completed", "primitive_moved_g",
                               "primitive_message", "realtime_factor")}})
        n_ok = sum(t["meaningful"] for t in trials)
        mean_del = sum(t["delivered_g"] for t in trials) / len(trials)
        rows.append({"primitive": name, "params": params, "meaningful": n_ok,
                     "n": len(trials), "mean_delivered_g": round(mean_del, 3),
                     "mean_shed_g": round(sum(t["shed_g"] for t in trials) / len(trials), 3),
                     "mean_spilled_g": round(sum(t["spilled_g"] for t in trials)
                                             / len(trials), 3), "trials": trials})
        print(f"{name} {params}: {n_ok}/{len(trials)} meaningful, delivered "
              f"{mean_del:.2f} g ({time.time() - t0:.0f} s)", file=sys.stderr, flush=True)
    best = max(rows, key=lambda r: (r["meaningful"], r["mean_delivered_g"]))
    out = {"food": a.food, "load_g": a.load_g, "threshold_g": a.threshold_g,
           "tuning_base_seed": TUNING_BASE_SEED, "seeds": a.seeds,
           "command": "PYTHONPATH=src python " + " ".join(["studies/shedding_sweep.py",
                                                           *(argv or sys.argv[1:])]),
           "wall_s": round(time.time() - t0, 1), "best": {k: best[k] for k in
                                                          ("primitive", "params", "meaningful",
                                                           "n", "mean_delivered_g")},
           "candidates": rows}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(json_safe(out), indent=1))
    if a.plot:
        plot(out, a.out.with_suffix(".png"))
    print(json.dumps(out["best"]))
    return 0


def plot(out: dict, path: Path) -> None:
    """Meaningful successes and mean delivered/shed/spilled grams per candidate."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = out["candidates"]
    labels = [" ".join(f"{p:g}" for p in r["params"]) for r in rows]
    x = range(len(rows))
    fig, ax = plt.subplots(2, 1, figsize=(max(6, 0.5 * len(rows)), 6), sharex=True)
    ax[0].bar(x, [r["meaningful"] for r in rows], color="tab:green")
    ax[0].set_ylabel(f"meaningful / {out['seeds']}")
    ax[0].set_title(f"{out['food']}: {rows[0]['primitive']} sweep, load {out['load_g']:g} g, "
                    f"tuning seeds (base {out['tuning_base_seed']})")
    w = 0.27
    for i, (k, c) in enumerate((("mean_delivered_g", "tab:blue"), ("mean_shed_g", "tab:gray"),
                                ("mean_spilled_g", "tab:red"))):
        ax[1].bar([xi + (i - 1) * w for xi in x], [r[k] for r in rows], w, color=c,
                  label=k.replace("mean_", "").replace("_g", ""))
    ax[1].set_ylabel("mean g")
    ax[1].legend()
    ax[1].set_xticks(list(x), labels, rotation=60, ha="right", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
