"""Does a twirling fork lift more noodle than a still one? Runs the fork's
acquisition (``articutool.sim.scenes.skewer``: into the heaped noodles, pressed to 2 mm above
the bowl's floor, TWIRL_CW ``--turns`` turns through the tool runtime, rise, level, lift 12 cm)
with the twirl and with a still fork (0 turns) on the same study seeds, and writes every run,
mean ± SD per condition, a one-sided Mann–Whitney U test and Welch's t-test (twirl > still),
the runs MuJoCo reset after an instability (detected from its warning counters; never counted)
and the real-time factor (simulated s ÷ CPU s of the simulation thread) as JSON.

Study seeds are ``trial_seed(B, r)`` = 1000·B + r with base seed B = 7 by default (7000–7009):
not seeds of the shipped experiment runs (base seed 0), nor of any earlier noodle study
(5000–5009, 5100–5102, 6000, 8000000–8000009). Runs are submitted interleaved (twirl, still,
next seed) to ``--workers`` processes and the JSON is rewritten after each one finishes, so a
partial study is nearly balanced;
``--resume`` keeps the runs already in ``--out``.

    PYTHONPATH=src nice .venv/bin/python studies/noodle_twirl.py --seeds 10 --workers 2 \
        --out studies/results/noodle_twirl.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from scipy import stats

from articutool.experiments.design import trial_seed
from articutool.experiments.runner import source_version
from articutool.sim.accounting import UTENSIL
from articutool.sim.params import PhysicsParams
from articutool.sim.scenes import max_twirl_turns, skewer
from articutool.sim.world import FeedingWorld
from articutool.spec import load_spec

STUDY_BASE_SEED = 7
# MuJoCo resets the simulation (mj_resetData) after any of these, with a warning count.
_RESET_WARNINGS = ("mjWARN_BADQPOS", "mjWARN_BADQVEL", "mjWARN_BADQACC")


def warnings_of(data: mujoco.MjData) -> dict[str, int]:
    """Every MuJoCo warning raised so far in ``data``, by name, with its count."""
    return {name: int(data.warning[int(w)].number)
            for name, w in mujoco.mjtWarning.__members__.items()
            if int(w) < len(data.warning) and data.warning[int(w)].number > 0}


def one_run(seed: int, turns: float, params: PhysicsParams | None = None,
            prepare: Callable[[FeedingWorld], None] | None = None,
            **skewer_kw: Any) -> dict[str, Any]:
    """One acquisition; what the fork holds after the lift, and whether MuJoCo reset.
    ``params``, ``prepare`` (called on the settled world) and ``skewer_kw``: a variant's
    physics, a change to the built world and the fork motion (studies/noodle_levers.py)."""
    t0 = time.perf_counter()
    w = FeedingWorld.make("noodles", seed=seed, params=params)
    if prepare is not None:
        prepare(w)
    touching: dict[str, int] = {}
    skewer(w, level=True, twirl_turns=turns, on_phase=lambda name: touching.__setitem__(
        name, int(np.sum(w.ledger.item_classes() == UTENSIL))), **skewer_kw)
    warn = warnings_of(w.data)
    classes = w.ledger.item_classes()
    return {"seed": seed, "twirl_turns": turns,
            "lifted_g": round(w.ledger.masses_g()["utensil"], 3),
            "strands_lifted": int(np.sum(classes == UTENSIL)),
            "ft_mass_g": round(w.weighing.ft_mass_g(), 3) if w.weighing.comparable() else None,
            "strands_touching": touching,
            "reset": any(k in warn for k in _RESET_WARNINGS), "warnings": warn,
            "sim_s": round(w.time, 3), "realtime_factor": round(w.realtime_factor, 4),
            "wall_s": round(time.perf_counter() - t0, 1)}


def one_sided_tests(a: list[float], b: list[float]) -> dict[str, Any]:
    """One-sided a > b: Mann–Whitney U, and Welch's t where the samples vary."""
    out: dict[str, Any] = {}
    if len(a) > 1 and len(b) > 1:
        u = stats.mannwhitneyu(a, b, alternative="greater")
        out["mann_whitney_u"] = {"U": float(u.statistic), "p_one_sided": float(u.pvalue)}
        if np.std(a) + np.std(b) > 0:
            t = stats.ttest_ind(a, b, equal_var=False, alternative="greater")
            out["welch_t"] = {"t": float(t.statistic), "p_one_sided": float(t.pvalue)}
    return out


def twirl_vs_still(twirl: dict[int, float], still: dict[int, float]) -> dict[str, Any]:
    """Grams by seed in each condition: :func:`one_sided_tests` (twirl > still) and, as the
    conditions share seeds (the same pile), the paired Wilcoxon test over the seeds in both."""
    out = one_sided_tests(list(twirl.values()), list(still.values()))
    diff = [g - still[k] for k, g in twirl.items() if k in still]
    if sum(d != 0 for d in diff) > 1:
        w = stats.wilcoxon(diff, alternative="greater")
        out["paired_wilcoxon"] = {"pairs": len(diff), "twirl_more": sum(d > 0 for d in diff),
                                  "still_more": sum(d < 0 for d in diff),
                                  "p_one_sided": float(w.pvalue)}
    return out


def _mean_sd(x: list[float]) -> tuple[float, float]:
    return (float(np.mean(x)) if x else math.nan,
            float(np.std(x, ddof=1)) if len(x) > 1 else math.nan)


def summarise(runs: list[dict[str, Any]], turns: float) -> dict[str, Any]:
    """Mean ± SD per condition over the runs MuJoCo did not reset, and the one-sided tests
    (twirl > still) of the grams lifted (primary: whole strands touching the fork and no
    surface) and of the F/T sensor's mass (secondary: it also weighs strands that hang from
    the fork while their ends still touch the bowl)."""
    out: dict[str, Any] = {}
    kept: dict[str, list[dict[str, Any]]] = {}
    for name, t in (("twirl", turns), ("still", 0.0)):
        cond = [r for r in runs if r["twirl_turns"] == t]
        kept[name] = [r for r in cond if not r["reset"]]
        g = [r["lifted_g"] for r in kept[name]]
        ft = [r["ft_mass_g"] for r in kept[name] if r.get("ft_mass_g") is not None]
        rtf = [r["realtime_factor"] for r in cond]
        m, sd = _mean_sd(g)
        fm, fsd = _mean_sd(ft)
        out[name] = {"twirl_turns": t, "runs": len(cond), "reset": len(cond) - len(g),
                     "n": len(g), "mean_g": m, "sd_g": sd, "lifted_any": sum(x > 0 for x in g),
                     "ft_n": len(ft), "ft_mean_g": fm, "ft_sd_g": fsd,
                     "rtf_mean": float(np.mean(rtf)) if rtf else math.nan}
    out.update(twirl_vs_still({r["seed"]: r["lifted_g"] for r in kept["twirl"]},
                              {r["seed"]: r["lifted_g"] for r in kept["still"]}))
    ft_tests = one_sided_tests(
        [r["ft_mass_g"] for r in kept["twirl"] if r.get("ft_mass_g") is not None],
        [r["ft_mass_g"] for r in kept["still"] if r.get("ft_mass_g") is not None])
    if ft_tests:
        out["ft_mass"] = ft_tests
    return out


def table(summary: dict[str, Any]) -> str:
    """The README's table (markdown) of a study's summary."""
    rows = ["| condition | runs (reset, excluded) | lifted, mean ± SD (g) | runs lifting any "
            "| F/T mass, mean ± SD (g) | real-time factor |", "|---|---|---|---|---|---|"]
    for name in ("twirl", "still"):
        c = summary[name]
        rows.append(f"| {name} ({c['twirl_turns']:g} turns) | {c['runs']} ({c['reset']}) | "
                    f"{c['mean_g']:.2f} ± {c['sd_g']:.2f} | {c['lifted_any']} of {c['n']} | "
                    f"{c['ft_mean_g']:.2f} ± {c['ft_sd_g']:.2f} | {c['rtf_mean']:.2f}× |")

    def ps(d: dict[str, Any]) -> str:
        return ", ".join(f"{k.replace('_', ' ')} p = {v['p_one_sided']:.3g}"
                         for k, v in d.items() if isinstance(v, dict) and "p_one_sided" in v)

    return ("\n".join(rows) + f"\n\nOne-sided, twirl > still: lifted — {ps(summary)}; "
            f"F/T mass — {ps(summary.get('ft_mass', {}))}.")


def write_study(path: Path, runs: list[dict[str, Any]], turns: float,
                argv: list[str] | None, script: str = "studies/noodle_twirl.py") -> None:
    """The study's JSON: the command, the commit, MuJoCo's version, the machine's load
    (1-minute average when written), the summary and every run in seed order."""
    runs = sorted(runs, key=lambda r: (r["seed"], -r["twirl_turns"]))
    out = {"command": f"{script} " + " ".join(sys.argv[1:] if argv is None else argv),
           "commit": source_version(), "mujoco": mujoco.__version__, "cpus": os.cpu_count(),
           "load_1min": round(os.getloadavg()[0], 2),
           "summary": summarise(runs, turns), "runs": runs}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--base-seed", type=int, default=STUDY_BASE_SEED,
                    help=f"study seeds trial_seed(B, r) = 1000·B + r (default {STUDY_BASE_SEED})")
    ap.add_argument("--workers", type=int, default=1, help="worker processes (default 1)")
    ap.add_argument("--turns", type=float, default=None,
                    help="twirl turns (default: the cable budget less 0.1 turn)")
    ap.add_argument("--out", default="studies/results/noodle_twirl.json")
    ap.add_argument("--resume", action="store_true", help="keep the runs already in --out")
    ap.add_argument("--table", action="store_true",
                    help="print the README's table of the study in --out; run nothing")
    args = ap.parse_args(argv)
    if args.table:
        print(table(json.loads(Path(args.out).read_text())["summary"]))
        return 0
    hi = max_twirl_turns(load_spec())
    turns = hi if args.turns is None else args.turns
    if not 0 < turns <= hi:
        ap.error(f"--turns must be in (0, {hi:g}]; got {turns}")
    if not 1 <= args.base_seed <= 9999:
        ap.error(f"--base-seed must be in [1, 9999]; got {args.base_seed}")
    if args.seeds < 2:
        ap.error(f"--seeds must be >= 2; got {args.seeds}")
    if not 1 <= args.workers <= 64:
        ap.error(f"--workers must be in [1, 64]; got {args.workers}")
    out_path = Path(args.out)
    runs: list[dict[str, Any]] = []
    if args.resume and out_path.exists():
        runs = json.loads(out_path.read_text())["runs"]
    done = {(r["seed"], r["twirl_turns"]) for r in runs}
    todo = [(trial_seed(args.base_seed, r), t) for r in range(args.seeds)
            for t in (turns, 0.0) if (trial_seed(args.base_seed, r), t) not in done]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        for fut in as_completed([pool.submit(one_run, seed, t) for seed, t in todo]):
            runs.append(fut.result())
            print(json.dumps(runs[-1]), flush=True)
            write_study(out_path, runs, turns, argv)
    write_study(out_path, runs, turns, argv)  # with --resume: the summary by this code
    print(json.dumps(summarise(runs, turns), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
