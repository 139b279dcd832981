"""From trial records to summaries, pure (no I/O): what every experiment's summary shares
(the trials that did not raise, rates, comparisons, masses per food and system, spills by
place, the run's figures) and the generic :func:`summarize` (each experiment's own body is
its module's, :mod:`articutool.experiments.units`).

Outcome classes come from :func:`articutool.feeding.outcomes.classify_bite` (the Exp. 3
hierarchy). Thresholds are applied here, at analysis time, so a trial never has to be rerun
when Exp. 1's means (Exp. 2c's thresholds) change. Trials whose protocol raised (``error``)
are counted and left out of every statistic; among them, the runs MuJoCo reset after a
numerical instability (``PhysicsResetError``) are counted apart.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from articutool.experiments.records import ConditionBase, TrialRecord
from articutool.experiments.stats import (
    bootstrap_ci,
    boschloo,
    describe,
    fisher,
    mann_whitney,
    newcombe_ci,
    proportion_ci,
    welch,
    welch_ci,
)
from articutool.feeding.outcomes import classify_bite

__all__ = [
    "by_place",
    "class_counts",
    "classify",
    "compare_counts",
    "compare_samples",
    "completeness",
    "food_system",
    "measured",
    "ok_records",
    "pv",
    "rate",
    "representative_trials",
    "summarize",
    "summarize_mass",
    "where",
]


def ok_records(records: Iterable[TrialRecord]) -> list[TrialRecord]:
    """The ``records`` whose protocol did not raise."""
    return [r for r in records if not r.error]


def where(records: Iterable[TrialRecord], which: Callable[[Any], bool]
           ) -> list[TrialRecord]:
    """The ``records`` whose condition is ``which``."""
    return [r for r in records if which(r.condition)]


def measured(rec: TrialRecord) -> Any:
    """What a trial that did not raise measured (its experiment's outcome type)."""
    assert rec.outcome is not None, "a trial that raised is left out of every statistic"
    return rec.outcome


def _wall(records: Sequence[TrialRecord]) -> dict[str, Any]:
    w = [float(r.wall_time_s) for r in records]
    return {"trials": len(records), "errors": sum(1 for r in records if r.error),
            # of the errors, the trials MuJoCo reset after an instability (never counted)
            "physics_resets": sum(1 for r in records
                                  if (r.error or "").startswith("PhysicsResetError")),
            "wall_time_per_trial_s": describe(w).to_dict() if w else None,
            "wall_time_total_s": round(sum(w), 1),
            # The code each trial ran (trials logged before it was recorded: "not recorded").
            "sources": dict(Counter("not recorded" if r.source is None else r.source
                                    for r in records))}


def classify(rec: TrialRecord, threshold_g: float) -> str:
    """A record's Exp. 3 outcome class (:func:`classify_bite`) at ``threshold_g``."""
    o = measured(rec)
    return classify_bite(float(o.delivered_g), dict(o.spilled_by_place), threshold_g,
                         bool(o.completed))

def class_counts(classes: Sequence[str], names: Sequence[str]) -> dict[str, Any]:
    """How many of ``classes`` fall in each of ``names``, and in percent."""
    n = len(classes)
    cnt = Counter(classes)
    return {"n": n, "counts": {k: cnt.get(k, 0) for k in names},
            "percent": {k: (100.0 * cnt.get(k, 0) / n if n else None) for k in names}}


def rate(k: int, n: int) -> dict[str, Any]:
    """``k`` of ``n`` as a rate with its 95 % (Wilson) interval."""
    lo, hi = proportion_ci(k, n)
    return {"k": k, "n": n, "rate": k / n if n else None,
            "ci95": [lo, hi] if n else None}


def pv(p: float) -> float | None:
    """A p-value for a summary: ``None`` when not finite."""
    return float(p) if np.isfinite(p) else None


def compare_samples(a: Sequence[float], b: Sequence[float]) -> dict[str, Any]:
    """Group a against group b, every way the report prints: the two-sided p of Welch's
    t-test and of Mann–Whitney's U (``p``), and the difference of means a − b with Welch's
    interval and with the bootstrap's (``effect``). Which of them decides a claim's verdict
    is pre-registered (``experiments.toml [tests]``)."""
    return {"n": [len(a), len(b)],
            "p": {"welch": pv(welch(a, b).p), "mann_whitney": pv(mann_whitney(a, b))},
            "effect": {"welch": welch_ci(a, b).to_dict(),
                       "bootstrap": bootstrap_ci(a, b).to_dict()}}


def compare_counts(a_k: int, a_n: int, b_k: int, b_n: int) -> dict[str, Any]:
    """Rate a_k/a_n against b_k/b_n: Fisher's and Boschloo's exact tests (``p``) and the
    difference of the rates with Newcombe's interval (``effect``)."""
    return {"n": [a_n, b_n], "k": [a_k, b_k],
            "p": {"fisher": pv(fisher(a_k, a_n, b_k, b_n).p),
                  "boschloo": pv(boschloo(a_k, a_n, b_k, b_n))},
            "effect": {"newcombe": newcombe_ci(a_k, a_n, b_k, b_n).to_dict()}}




def summarize_mass(records: Sequence[TrialRecord], foods: Sequence[str],
                   systems: Sequence[str], value: Callable[[Any], float]) -> dict[str, Any]:
    """Per food: the outcomes' ``value`` per system (mean ± SD, 95 % CI), Welch of the first
    system against the second, and how many trials had a non-zero value."""
    ok = ok_records(records)
    out: dict[str, Any] = {}
    for f in foods:
        per = {s: [float(value(measured(r))) for r in where(ok, food_system(f, s))]
               for s in systems}
        entry: dict[str, Any] = {s: {**describe(v).to_dict(),
                                     "nonzero": rate(sum(1 for x in v if x > 1e-9), len(v))}
                                 for s, v in per.items()}
        if len(systems) == 2:
            a, b = (per[s] for s in systems)
            entry["welch"] = welch(a, b).to_dict()
            entry["compare"] = compare_samples(a, b)
        out[f] = entry
    return out


def food_system(food: str, system: str) -> Callable[[ConditionBase], bool]:
    """Whether a condition is ``food`` by ``system``."""
    return lambda c: c.food == food and c.system == system


def by_place(records: Sequence[TrialRecord]) -> dict[str, dict[str, float]]:
    """Grams spilled over ``records`` per place (a container and the air apart from the
    table and the user: accounting.transport_spill), and in how many trials."""
    out: dict[str, dict[str, float]] = {}
    for r in records:
        for place, g in measured(r).spilled_by_place.items():
            e = out.setdefault(place, {"g": 0.0, "trials": 0})
            e["g"] = round(e["g"] + float(g), 4)
            e["trials"] += int(float(g) > 1e-9)
    return out


def summarize(experiment: str, records: Sequence[TrialRecord], cfg: Any,
              **settings: Any) -> dict[str, Any]:
    """The summary of ``experiment`` (its :meth:`~articutool.experiments.unit.Experiment.
    summarize` at ``settings``: Exp. 2c's ``thresholds_g``, Exp. 3's ``threshold_g``), with
    run figures."""
    from articutool.experiments.unit import unit

    body = unit(experiment).summarize(records, cfg, **settings)
    seeds = sorted({r.seed for r in records})
    return {"experiment": experiment, **body, "run": {**_wall(records), "seeds": seeds},
            "per_condition_n": dict(Counter("/".join(r.condition.group())
                                            for r in ok_records(records)))}


def completeness(records: Sequence[TrialRecord], per_condition: int,
                 conditions: Sequence[ConditionBase] | None = None) -> dict[str, dict[str, Any]]:
    """Per condition (``food/system``, as ``per_condition_n``): how many of its first
    ``per_condition`` repeats are logged (``found``, a trial that raised included) and, with
    the run's ``conditions`` in their order (``run.json``: trial ``K = r · C + c``,
    :mod:`~articutool.experiments.design`), the indices of the ``missing`` ones. Without them
    the conditions are those the records hold (a condition with no record cannot be
    named)."""
    logged = {r.trial for r in records}
    out: dict[str, dict[str, Any]] = {}
    if conditions is not None:
        n_cond = len(conditions)
        for c, cond in enumerate(conditions):
            want = [r * n_cond + c for r in range(per_condition)]
            missing = [k for k in want if k not in logged]
            out["/".join(cond.group())] = {"found": per_condition - len(missing),
                                           "missing": missing}
        return out
    for r in records:
        d = out.setdefault("/".join(r.condition.group()), {"found": 0, "missing": []})
        d["found"] += r.repeat < per_condition
    return out


def mean_or_none(values: Sequence[float]) -> float | None:
    """Mean of a non-empty sequence, else None."""
    return float(np.mean(values)) if len(values) else None

def representative_trials(records: Sequence[TrialRecord]) -> dict[str, dict[str, int]]:
    """Per condition (food + system or Exp. 2c condition), the trial numbers of a *typical*
    trial (its food mass — acquired, delivered or held — nearest the condition's median) and
    the *worst* (most spilled, then least food), for the report's replays. Ties go
    to the lowest trial number, so the choice does not depend on the log's order."""
    groups: dict[str, list[TrialRecord]] = {}
    for r in ok_records(records):
        groups.setdefault(" ".join(r.condition.group()), []).append(r)

    def food_g(r: TrialRecord) -> float:
        return measured(r).food_g()

    out = {}
    for key, rs in sorted(groups.items()):
        med = float(np.median([food_g(r) for r in rs]))
        typical = min(rs, key=lambda r: (abs(food_g(r) - med), r.trial))
        worst = min(rs, key=lambda r: (-float(measured(r).spilled_g), food_g(r), r.trial))
        out[key] = {"typical": typical.trial, "worst": worst.trial}
    return out
