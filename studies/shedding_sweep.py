"""Sweep of Exp. 2c's choosable parameters: the open-loop shedding primitives' and, with the
same budget, the control's transport (thesis §4.4, §5.2.3).

Each candidate runs Exp. 2c's protocol (:func:`articutool.experiments.units.exp2c.exp2c_trial`:
the capacity load placed at the shedding pose over the bowl, the primitive or none, the
transport to Staging) on TUNING seeds — base seed 9 (seeds 9000+r), disjoint from the
experiments' seeds (base 0: 0..999, ``experiments/design.py``). A candidate is an action
library: the packaged one with Exp. 2c's strategy for the food changed — its
``post_acquisition`` primitive (``--condition primitive``) or its ``transport``
(``--condition control``) — run as that condition of the experiment (its ``strategies``
field), so the trial is the experiment's own code.

The candidates. Pecans: VIBRATE_ROLL (frequency, amplitude, duration), 4/8/12 Hz × 50/95 % of
the roll speed limit × 1/3 s (12). Water: TILT (angle, speed, hold), 0.1/0.2/0.35/0.5/0.7 rad
at 0.5 rad/s, held 0.5 s then 2 s (10; ``--limit 5``: the five angles held 0.5 s). Control (no
primitive): what of its transport the strategy chooses, as many candidates as the primitive
gets — the planner and a strict planner's tolerance band: the decoupled planner (shipped),
then strict6 / strict8 at 20°, 5°, 45°, 10°, 30°, 15° in turn. The strategy's ``leveling``
acts only through the food-aware check, which Exp. 2c's transport does not run; the tool's
leveling loop, the arm's speed limits and the plan budget are the spec's and the
experiment's, the same for every condition.

Score, as Exp. 2c scores (:func:`~articutool.experiments.units.exp2c.classify_exp2c`):
meaningful successes (no spill, transport completed, delivered above the food's threshold);
ties broken by the mean delivered grams, then by the grid's order. The load and the threshold
are the experiment's: our capacity mean rounded to 0.01 g and our Exp. 1 Articutool mean
(``--results``; ``--load-g`` / ``--threshold-g`` override them).

    PYTHONPATH=src python studies/shedding_sweep.py --food pecans --condition primitive \\
        --seeds 3 --out studies/results/shedding/sweep_pecans.json --plot

Writes JSON (every trial, every candidate's score and spread, the process' CPU seconds per
trial) and, with ``--plot``, a PNG.
"""

from __future__ import annotations

import argparse
import copy
import itertools
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from articutool.datafile import read_document
from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.design import trial_seed
from articutool.experiments.protocols import json_safe
from articutool.experiments.records import TrialRecord
from articutool.experiments.stats import describe
from articutool.experiments.units.exp2c import Exp2cCondition, classify_exp2c, exp2c_trial
from articutool.feeding.strategies import StrategyError, default_strategies_path
from articutool.spec import load_spec
from articutool.thresholds import DEFAULT_OUT, capacity_means, exp1_means

TUNING_BASE_SEED = 9
# The control's transports in the order they are tried: the shipped decoupled planner, then
# each strict planner at one tolerance after the other, spreading over 5–45° first.
_TOLERANCES_DEG = (20.0, 5.0, 45.0, 10.0, 30.0, 15.0)
CONTROL_TRANSPORTS: tuple[dict[str, Any], ...] = (
    {"planner": "decoupled"},
    *({"planner": p, "tolerance_deg": t}
      for t in _TOLERANCES_DEG for p in ("strict6", "strict8")))


def primitive_candidates(food: str) -> list[dict[str, Any]]:
    """The open-loop primitive's grid (module doc): VIBRATE_ROLL for pecans — amplitudes at
    50 % and 95 % of the roll speed limit at each frequency — TILT for water."""
    if food == "pecans":
        vmax = float(load_spec().wrist.velocity_limits[1])
        return [{"primitive": "VIBRATE_ROLL",
                 "params": [f, round(k * vmax / (2 * math.pi * f), 4), d]}
                for f, k, d in itertools.product((4.0, 8.0, 12.0), (0.5, 0.95), (1.0, 3.0))]
    return [{"primitive": "TILT", "params": [a, 0.5, h]}
            for h, a in itertools.product((0.5, 2.0), (0.1, 0.2, 0.35, 0.5, 0.7))]


def candidates(food: str, condition: str) -> list[dict[str, Any]]:
    """Each candidate's change to the food's Exp. 2c strategy: ``post_acquisition`` (a
    primitive) or ``transport`` (the control), as many for the control as the primitive has."""
    prims = primitive_candidates(food)
    if condition == "primitive":
        return [{"post_acquisition": p} for p in prims]
    return [{"transport": t} for t in CONTROL_TRANSPORTS[: len(prims)]]


def candidate_library(library: dict[str, Any], strategy: str, change: dict[str, Any]
                      ) -> dict[str, Any]:
    """A copy of the action library ``library`` (as read from its file) with ``strategy``
    changed as a candidate says: its ``post_acquisition`` stage or its ``transport``."""
    lib = copy.deepcopy(library)
    s = lib["strategies"][strategy]
    for key, value in change.items():
        (s["stages"] if key == "post_acquisition" else s)[key] = copy.deepcopy(value)
    return lib


def label(change: dict[str, Any]) -> str:
    """A candidate in a few words."""
    if "transport" in change:
        t = change["transport"]
        return t["planner"] + (f" {t['tolerance_deg']:g}°" if "tolerance_deg" in t else "")
    p = change["post_acquisition"]
    return p["primitive"] + " " + " ".join(f"{x:g}" for x in p["params"])


def spread(values: list[float]) -> dict[str, float | None]:
    """Mean, sample SD (None for one value), min and max, to 3 decimals."""
    d = describe(values).to_dict()
    return {k: None if v is None else round(v, 3)
            for k, v in (("mean", d["mean"]), ("sd", d["sd"]),
                         ("min", min(values)), ("max", max(values)))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--food", choices=("pecans", "water"), required=True)
    ap.add_argument("--condition", choices=("primitive", "control"), default="primitive")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--results", type=Path, default=DEFAULT_OUT,
                    help="the experiments' results (capacity and Exp. 1 summaries)")
    ap.add_argument("--load-g", type=float, default=None,
                    help="default: our capacity mean, as Exp. 2c rounds it")
    ap.add_argument("--threshold-g", type=float, default=None,
                    help="default: our Exp. 1 Articutool mean (Exp. 2c's threshold)")
    ap.add_argument("--limit", type=int, default=0, help="first N candidates only (pilot)")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--plot", action="store_true")
    a = ap.parse_args(argv)
    if a.out.exists() or a.out.is_symlink():
        print(f"--out: {a.out} exists; not overwriting", file=sys.stderr)
        return 2
    if not 1 <= a.seeds <= 100 or a.limit < 0:
        print("--seeds must be in [1, 100] and --limit >= 0", file=sys.stderr)
        return 2
    load, threshold = a.load_g, a.threshold_g
    if load is None:
        load = round((capacity_means(a.results) or {}).get(a.food, 0.0), 2)
    if threshold is None:
        threshold = exp1_means(a.results).get(a.food)
    if not (load and load > 0 and threshold is not None and threshold >= 0):
        print(f"--load-g / --threshold-g: no capacity or Exp. 1 mean for {a.food} in "
              f"{a.results}; pass --load-g G (> 0) and --threshold-g G (>= 0)",
              file=sys.stderr)
        return 2
    cfg = ExperimentsConfig.load()
    name = cfg.exp2c.strategy[a.food]
    try:
        library = read_document(default_strategies_path(), "strategy file", StrategyError)
    except StrategyError as err:
        print(err, file=sys.stderr)
        return 2
    cands = candidates(a.food, a.condition)[: a.limit or None]
    rows: list[dict[str, Any]] = []
    t0, c0 = time.time(), time.process_time()
    with tempfile.TemporaryDirectory(prefix="shedding_sweep_") as tmp:
        for i, change in enumerate(cands):
            path = Path(tmp) / f"candidate_{i}.json"
            path.write_text(json.dumps(candidate_library(library, name, change)))
            cond = Exp2cCondition(food=a.food, condition=a.condition, load_g=load,
                                  strategies=str(path))
            trials = []
            for r in range(a.seeds):
                seed = trial_seed(TUNING_BASE_SEED, r)
                c_start, w_start = time.process_time(), time.time()
                rec = exp2c_trial(cond, seed, cfg)
                cls = classify_exp2c(TrialRecord(
                    experiment="exp2c", trial=r, repeat=0, seed=seed, condition=cond,
                    outcome=rec, wall_time_s=time.time() - w_start, pid=os.getpid(),
                    error=None), threshold)
                trials.append({"seed": seed, "class": cls,
                               "meaningful": cls == "meaningful_success",
                               "cpu_s": round(time.process_time() - c_start, 1),
                               **{k: getattr(rec, k) for k in (
                                   "held_g", "after_primitive_g", "shed_g", "spilled_g",
                                   "spilled_by_place", "delivered_g", "completed",
                                   "failed_stage", "primitive_moved_g", "primitive_message",
                                   "motion_time_s", "realtime_factor")}})
            n_ok = sum(t["meaningful"] for t in trials)
            row = {"candidate": label(change), **change, "meaningful": n_ok,
                   "n": len(trials),
                   **{f"{k}_g": spread([t[f"{k}_g"] for t in trials])
                      for k in ("shed", "spilled", "delivered")},
                   "cpu_s": spread([t["cpu_s"] for t in trials]), "trials": trials}
            rows.append(row)
            write(a, rows, name, load, threshold, t0, c0, argv, complete=False)
            print(f"{row['candidate']}: {n_ok}/{len(trials)} meaningful, delivered "
                  f"{row['delivered_g']['mean']:.2f} g, shed {row['shed_g']['mean']:.2f} g, "
                  f"spilled {row['spilled_g']['mean']:.2f} g "
                  f"({time.time() - t0:.0f} s wall, {time.process_time() - c0:.0f} CPU s)",
                  file=sys.stderr, flush=True)

    out = write(a, rows, name, load, threshold, t0, c0, argv, complete=True)
    if a.plot:
        plot(out, a.out.with_suffix(".png"))
    print(json.dumps(out["best"]))
    return 0


def score(r: dict[str, Any]) -> tuple[int, float]:
    """A candidate's score: its meaningful successes, then its mean delivered grams."""
    return r["meaningful"], r["delivered_g"]["mean"]


def write(a: argparse.Namespace, rows: list[dict[str, Any]], strategy: str, load: float,
          threshold: float, t0: float, c0: float, argv: list[str] | None, *,
          complete: bool) -> dict[str, Any]:
    """Write the candidates so far to ``a.out`` (``complete`` False after each candidate but
    the last, so a stopped sweep keeps what it measured) and return what was written."""
    best = max(rows, key=score)  # the first of equal scores: the grid's order
    out = {"food": a.food, "condition": a.condition, "strategy": strategy, "load_g": load,
           "threshold_g": threshold, "tuning_base_seed": TUNING_BASE_SEED, "seeds": a.seeds,
           "command": "PYTHONPATH=src python " + " ".join(["studies/shedding_sweep.py",
                                                           *(argv or sys.argv[1:])]),
           "complete": complete, "wall_s": round(time.time() - t0, 1),
           "cpu_s": round(time.process_time() - c0, 1),
           "best": {k: best[k] for k in ("candidate", "meaningful", "n", "delivered_g",
                                         "shed_g", "spilled_g")},
           "tied_with_best": [r["candidate"] for r in rows
                              if score(r) == score(best) and r is not best],
           "candidates": rows}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = a.out.with_name(a.out.name + ".tmp")
    tmp.write_text(json.dumps(json_safe(out), indent=1))
    tmp.replace(a.out)
    return out


def plot(out: dict, path: Path) -> None:
    """Meaningful successes, and delivered / shed / spilled grams (mean, min–max) per
    candidate."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = out["candidates"]
    x = list(range(len(rows)))
    fig, ax = plt.subplots(2, 1, figsize=(max(6, 0.55 * len(rows)), 6), sharex=True)
    ax[0].bar(x, [r["meaningful"] for r in rows], color="tab:green")
    ax[0].set_ylabel(f"meaningful / {out['seeds']}")
    ax[0].set_ylim(0, out["seeds"])
    ax[0].set_title(f"{out['food']}, {out['condition']}: load {out['load_g']:g} g, threshold "
                    f"{out['threshold_g']:.2f} g, tuning seeds (base {out['tuning_base_seed']})",
                    fontsize=9)
    w = 0.27
    for i, (k, c) in enumerate((("delivered_g", "tab:blue"), ("shed_g", "tab:gray"),
                                ("spilled_g", "tab:red"))):
        m = [r[k]["mean"] for r in rows]
        err = [[mi - r[k]["min"] for mi, r in zip(m, rows, strict=True)],
               [r[k]["max"] - mi for mi, r in zip(m, rows, strict=True)]]
        ax[1].bar([xi + (i - 1) * w for xi in x], m, w, yerr=err, capsize=2, color=c,
                  label=k.removesuffix("_g"))
    ax[1].axhline(out["threshold_g"], color="k", lw=0.8, ls="--", label="threshold")
    ax[1].set_ylabel("g (mean, min–max)")
    ax[1].legend(fontsize=7)
    ax[1].set_xticks(x, [r["candidate"] for r in rows], rotation=60, ha="right", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
