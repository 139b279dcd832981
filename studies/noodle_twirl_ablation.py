"""Which difference makes the feeding tree's twirled noodle bite win in Exp. 1?

In the committed Exp. 1 the Articutool's ``noodles_twirl`` brought 1.52 ± 1.46 g of noodles to
Resting and the locked fork (``noodles_baseline``) none, while the scripted fork study
(``studies/noodle_twirl.py``) found a twirl lifting no more than a still fork. The two
tree strategies differ by the twirls (TWIRL_CW 1 turn above the nest, TWIRL_CCW 2 turns
inside) *and* by the system: the wrist's tool-only levelling before the lift and the
decoupled transport against the arm-levelled, strict ±20° one. This study adds a third
condition, the Articutool's strategy with both twirl stages set to ``NONE`` (everything else
as shipped), and runs all three through Exp. 1's own protocol (stages ``above, acquire,
resting``, its timeout, plan budget and settling; the mass on the utensil at Resting).

Seeds: 8 000 000 + k (the measurement seeds of ``acquisition_study.py``), disjoint from the
experiments' 0–999 and from every tuning seed; nothing here chooses a parameter.

    PYTHONPATH=src nice .venv/bin/python studies/noodle_twirl_ablation.py --seeds 10
    .venv/bin/python studies/noodle_twirl_ablation.py --table

The JSON (``studies/results/noodle_twirl_ablation.json``) is rewritten after every run, and a rerun
skips the runs already in it.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import tomllib
from pathlib import Path
from typing import Any

from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.records import BiteCondition
from articutool.experiments.stats import describe, welch
from articutool.experiments.units.exp1 import exp1_trial
from articutool.feeding.strategies import default_strategies_path
from noodle_twirl import twirl_vs_still

# The machine block is the benchmarks' (benchmarks/bench_io.py), so every JSON records it alike.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from bench_io import machine

MEASURE_SEED0 = 8_000_000
DEFAULT_JSON = Path("studies/results/noodle_twirl_ablation.json")
# condition → (system, strategy file: None = the shipped one, "no_twirl" = its variant)
CONDITIONS = {"articutool": ("articutool", None),
              "articutool_no_twirl": ("articutool", "no_twirl"),
              "baseline": ("baseline", None)}
TWIRL_STAGES = ("pre_move_into", "post_move_into")


def no_twirl_library(dest: Path) -> Path:
    """The shipped action library with ``noodles_twirl``'s two twirl stages set to NONE."""
    text = default_strategies_path().read_text()
    lines = text.splitlines()
    start = lines.index("[strategies.noodles_twirl]")
    out, section = [], False
    for i, line in enumerate(lines):
        if line.startswith("["):
            section = i == start
        if section and any(line.startswith(f"stages.{s} =") for s in TWIRL_STAGES):
            line = line.split("=", 1)[0] + '= { primitive = "NONE", params = [] }'
        out.append(line)
    doc = tomllib.loads("\n".join(out))  # the variant must still parse, twirls gone
    stages = doc["strategies"]["noodles_twirl"]["stages"]
    if any(stages[s]["primitive"] != "NONE" for s in TWIRL_STAGES):
        raise RuntimeError("the variant still twirls: the strategy file's layout changed")
    dest.write_text("\n".join(out) + "\n")
    return dest


def one(condition: str, seed: int, strategies: Path | None, cfg: ExperimentsConfig
        ) -> dict[str, Any]:
    """One Exp. 1 trial (:func:`~articutool.experiments.units.exp1.exp1_trial`) for
    ``condition``, with ``strategies`` as its action library (None: the shipped one)."""
    cond = BiteCondition(food="noodles", system=CONDITIONS[condition][0],
                         strategies=None if strategies is None else str(strategies))
    return {"condition": condition, "seed": seed, **exp1_trial(cond, seed, cfg).fields()}


def summarise(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Per condition: describe() of the mass at Resting and after ``acquire``; Welch's
    two-sided test of the mass at Resting between each pair of conditions; and the study's
    question, twirl > no twirl, one-sided (Welch and Mann–Whitney) and seed by seed."""
    by = {c: [r for r in runs if r["condition"] == c] for c in CONDITIONS}
    out: dict[str, Any] = {c: {"n": len(rs),
                               "mass_g": describe([r["mass_g"] for r in rs]).to_dict(),
                               "acquired_g": describe([r["acquired_g"] for r in rs]).to_dict(),
                               "completed": sum(r["end_state"] == "completed" for r in rs)}
                           for c, rs in by.items() if rs}
    names = [c for c in CONDITIONS if by[c]]
    out["welch_mass"] = {f"{a} vs {b}": welch([r["mass_g"] for r in by[a]],
                                              [r["mass_g"] for r in by[b]]).to_dict()
                         for i, a in enumerate(names) for b in names[i + 1:]}
    out["twirl_vs_no_twirl"] = twirl_vs_still(
        {r["seed"]: r["mass_g"] for r in by["articutool"]},
        {r["seed"]: r["mass_g"] for r in by["articutool_no_twirl"]})
    return out


def table(doc: dict[str, Any]) -> str:
    """Markdown rows: condition, n, mass at Resting and after ``acquire`` (mean ± SD)."""
    rows = ["| condition | n | at Resting, g (mean ± SD) | after `acquire`, g | completed |",
            "|---|---|---|---|---|"]
    s = doc["summary"]
    for c in CONDITIONS:
        if c in s:
            m, a = s[c]["mass_g"], s[c]["acquired_g"]
            rows.append(f"| {c} | {s[c]['n']} | {m['mean']:.2f} ± {m['sd']:.2f} | "
                        f"{a['mean']:.2f} ± {a['sd']:.2f} | {s[c]['completed']}/{s[c]['n']} |")
    rows.append("")
    rows += [f"Welch (two-sided), {k}: p {v['p']:.3g}" if v.get("p") is not None
             else f"Welch, {k}: {v.get('note')}" for k, v in s["welch_mass"].items()]
    t = s["twirl_vs_no_twirl"]
    tests = [f"{name} p {t[key]['p_one_sided']:.3g}" for key, name in
             (("welch_t", "Welch"), ("mann_whitney_u", "Mann–Whitney"),
              ("paired_wilcoxon", "paired Wilcoxon")) if key in t]
    if "paired_wilcoxon" in t:
        pw = t["paired_wilcoxon"]
        tests.append(f"more on {pw['twirl_more']} paired seeds, less on {pw['still_more']}")
    rows.append("twirl > no twirl (one-sided): " + "; ".join(tests))
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--out", type=Path, default=DEFAULT_JSON)
    ap.add_argument("--table", action="store_true", help="print the docs' table; run nothing")
    args = ap.parse_args(argv)
    if args.table:
        print(table(json.loads(args.out.read_text())))
        return 0
    if not 1 <= args.seeds <= 1000:
        print(f"error: --seeds must be in 1..1000 (got {args.seeds})", file=sys.stderr)
        return 2
    cfg = ExperimentsConfig.load()
    doc: dict[str, Any] = (json.loads(args.out.read_text()) if args.out.exists() else
                           {"issue": 26, "command": "PYTHONPATH=src nice .venv/bin/python "
                            "studies/noodle_twirl_ablation.py --seeds " + str(args.seeds),
                            "machine": machine(), "runs": []})
    with tempfile.TemporaryDirectory() as tmp:
        variant = no_twirl_library(Path(tmp) / "strategies.toml")
        for k in range(args.seeds):  # the three conditions on a seed before the next seed
            for c, (_, lib) in CONDITIONS.items():
                seed = MEASURE_SEED0 + k
                if any(r["condition"] == c and r["seed"] == seed for r in doc["runs"]):
                    continue
                run = one(c, seed, variant if lib else None, cfg)
                print(json.dumps(run), flush=True)
                doc["runs"].append(run)
                doc["summary"] = summarise(doc["runs"])
                args.out.parent.mkdir(parents=True, exist_ok=True)
                args.out.write_text(json.dumps(doc, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
