"""Exp. 1 (thesis §5.1, H1): acquisition — from above the plate, acquire with the system's
strategy and move level to Resting; the mass on the utensil there."""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from articutool.datafile import Positive, StrictModel
from articutool.experiments.analysis import ok_records, summarize_mass
from articutool.experiments.config import ExperimentsConfig, Names
from articutool.experiments.figures import mass_bars
from articutool.experiments.markdown import mass_rows, table
from articutool.experiments.protocols import bite
from articutool.experiments.records import BiteCondition, BiteOutcome, TrialRecord
from articutool.experiments.unit import (
    Experiment,
    Hook,
    Visitors,
    add_foods_argument,
    add_physics_argument,
)
from articutool.experiments.verdicts import Verdict, judge, mean_sd_g

if TYPE_CHECKING:
    from articutool.sim.world import SettleCache

__all__ = ["EXPERIMENT", "Exp1Config", "exp1_trial", "summarize_exp1"]


class Exp1Config(StrictModel):
    """Exp. 1 (§5.1)."""

    foods: Names
    systems: Names
    timeout_s: Positive



def exp1_trial(cond: BiteCondition, seed: int, cfg: ExperimentsConfig,
               hook: Hook = None, visitors: Visitors = (),
               settled: SettleCache | None = None) -> BiteOutcome:
    """Exp. 1 (§5.1): from AbovePlate, acquire with the system's strategy, move
    level-constrained to Resting; the mass on the utensil there (``mass_g``, ground truth;
    ``ft_mass_g`` as the F/T sensor weighs it when comparable)."""
    rec = bite(cond, seed, cfg, hook, ("above", "acquire", "resting"), cfg.exp1.timeout_s,
                visitors, settled)
    rec["mass_g"] = rec["weighed_end_g"]  # as the experimenter weighs it (strands: borne)
    return BiteOutcome.model_validate(rec)



def summarize_exp1(records: Sequence[TrialRecord], cfg: Any) -> dict[str, Any]:
    """Mass on the utensil at Resting per food and system, Welch (§5.1)."""
    return {"acquired_g": summarize_mass(ok_records(records), cfg.exp1.foods, cfg.exp1.systems,
                                         lambda o: o.mass_g)}



def section_exp1(s: Mapping[str, Any], cfg: Any) -> str:
    """The acquired mass per food and system beside the thesis'."""
    th = cfg.thesis["exp1"]

    def cell(f: str, sys_: str, d: Mapping[str, Any]) -> list[str]:
        t = th.get(f, {}).get(sys_)
        return [f"{t[0]:.2f} ± {t[1]:.2f}" if t else "–"]

    rows = mass_rows(s["acquired_g"], cfg.exp1.foods, cfg.exp1.systems, th, cell)
    return table(["food", "system", "n", "acquired (g), mean ± SD", "95 % CI",
                   "thesis (g)", "Welch p (ours)", "p (thesis)"], rows)



def claims_exp1(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float,
              tests: Mapping[str, Any]) -> list[Verdict]:
    """Our summary ``s`` against the thesis' ``th`` on each claim it tests, judged by the
    pre-registered ``tests`` at ``alpha`` (:func:`~articutool.experiments.verdicts.judge`)."""
    out = []
    for food, d in s["acquired_g"].items():
        a, b = d.get("articutool"), d.get("baseline")
        if not a or not b:
            continue
        t = th.get(food, {})
        given = "articutool" in t and "baseline" in t
        thesis = (f"{t['articutool'][0]:.2f} vs {t['baseline'][0]:.2f} g, p {t.get('p')}"
                  if given else "not given")
        none_moved = a.get("mean") == 0 and b.get("mean") == 0
        both_constant = not a.get("sd") and not b.get("sd")
        test, size, others, verdict = judge(
            d.get("compare"), tests["exp1"],
            t["articutool"][0] - t["baseline"][0] if given else None, +1, alpha,
            none_moved or both_constant, "g")
        out.append(Verdict("H1", "Fig. 6.1", f"{food}: the Articutool acquires more than the "
                           "baseline", thesis, f"{mean_sd_g(a)} vs {mean_sd_g(b)}", test, size,
                           others, verdict))
    return out



class Exp1Experiment(Experiment):
    """Exp. 1."""

    name = "exp1"
    help = "acquisition, H1 (§5.1)"
    title = "Exp. 1 — acquisition (H1, §5.1; cf. Fig. 6.1)"
    hypothesis = "H1"
    thesis_figure = "Fig. 6.1"
    order = 10
    condition = BiteCondition
    config_model = Exp1Config
    claims: ClassVar[dict[str, str]] = {"exp1": "Exp. 1 acquired mass (H1)"}
    outcome = BiteOutcome

    run_trial = staticmethod(exp1_trial)
    verdicts = staticmethod(claims_exp1)
    section = staticmethod(section_exp1)

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        add_physics_argument(parser)
        add_foods_argument(parser)

    def conditions(self, cfg: ExperimentsConfig, **inputs: Any) -> list[Any]:
        return [BiteCondition(food=f, system=s) for f in cfg.exp1.foods
                for s in cfg.exp1.systems]

    def summarize(self, records: Sequence[TrialRecord], cfg: ExperimentsConfig,
                  **settings: Any) -> dict[str, Any]:
        return summarize_exp1(records, cfg)

    def differences(self, summary: Mapping[str, Any], cfg: ExperimentsConfig) -> list[str]:
        s, th, out = summary, cfg.thesis, []
        for f in cfg.exp1.foods:
            for sys_ in cfg.exp1.systems:
                m = s["acquired_g"][f][sys_].get("mean")
                t = th["exp1"].get(f, {}).get(sys_)
                if m is not None and t:
                    out.append(f"{f}, {sys_}: {m:.2f} g vs the thesis' {t[0]:.2f} g "
                               f"({m - t[0]:+.2f} g)")
        return out

    def figure(self, records: Sequence[TrialRecord], summary: Mapping[str, Any],
               cfg: ExperimentsConfig, directory: Path) -> Path | None:
        return mass_bars(records, summary["acquired_g"], cfg.exp1.foods, cfg.exp1.systems,
                         lambda o: o.mass_g, "mass on the utensil at Resting (g), mean ± 95% CI",
                         "Exp. 1: acquisition (cf. thesis Fig. 6.1)", directory / "exp1.png")


EXPERIMENT = Exp1Experiment()
