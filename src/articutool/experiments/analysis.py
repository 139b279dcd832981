"""From trial records to each experiment's summary, pure (no I/O).

Outcome classes come from :func:`articutool.feeding.outcomes.classify_bite` (the Exp. 3
hierarchy); Exp. 2c reads it the thesis' way (§5.2.3): meaningful success, trivial success,
transport failure (any spill, table or user), and a trial the tree could not finish
(``failed``). Thresholds are applied here, at analysis time, so a trial never has to be rerun
when Exp. 1's means (Exp. 2c's thresholds) change. Trials whose protocol raised (``error``)
are counted and left out of every statistic; among them, the runs MuJoCo reset after a
numerical instability (``PhysicsResetError``) are counted apart.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from articutool.experiments.design import EXP2C_CONDITIONS
from articutool.experiments.records import (
    BiteOutcome,
    CapacityOutcome,
    Condition,
    Outcome,
    TrialRecord,
)
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
    wilcoxon_paired,
)
from articutool.feeding.outcomes import OUTCOMES, classify_bite

__all__ = ["EXP2C_CLASSES", "by_place", "carried_wrists", "classify_exp2c", "compare_counts",
           "compare_samples", "completeness", "meaningful_at", "representative_trials",
           "staging_attempts", "summarize", "summarize_exp2a"]

EXP2C_CLASSES = ("meaningful_success", "trivial_success", "transport_failure", "failed")


def _ok(records: Iterable[TrialRecord]) -> list[TrialRecord]:
    return [r for r in records if not r.error]


def _where(records: Iterable[TrialRecord], which: Callable[[Any], bool]
           ) -> list[TrialRecord]:
    """The ``records`` whose condition is ``which``."""
    return [r for r in records if which(r.condition)]


def _out(rec: TrialRecord) -> Any:
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
    o = _out(rec)
    return classify_bite(float(o.delivered_g), dict(o.spilled_by_place), threshold_g,
                         bool(o.completed))


def classify_exp2c(rec: TrialRecord, threshold_g: float) -> str:
    """Exp. 2c's class (§5.2.3): a table or user spill is a transport failure."""
    c = classify(rec, threshold_g)
    return "transport_failure" if c in ("table_spill", "user_spill") else c


def _counts(classes: Sequence[str], names: Sequence[str]) -> dict[str, Any]:
    n = len(classes)
    cnt = Counter(classes)
    return {"n": n, "counts": {k: cnt.get(k, 0) for k in names},
            "percent": {k: (100.0 * cnt.get(k, 0) / n if n else None) for k in names}}


def _rate(k: int, n: int) -> dict[str, Any]:
    lo, hi = proportion_ci(k, n)
    return {"k": k, "n": n, "rate": k / n if n else None,
            "ci95": [lo, hi] if n else None}


def _pv(p: float) -> float | None:
    return float(p) if np.isfinite(p) else None


def compare_samples(a: Sequence[float], b: Sequence[float]) -> dict[str, Any]:
    """Group a against group b, every way the report prints: the two-sided p of Welch's
    t-test and of Mann–Whitney's U (``p``), and the difference of means a − b with Welch's
    interval and with the bootstrap's (``effect``). Which of them decides a claim's verdict
    is pre-registered (``experiments.toml [tests]``)."""
    return {"n": [len(a), len(b)],
            "p": {"welch": _pv(welch(a, b).p), "mann_whitney": _pv(mann_whitney(a, b))},
            "effect": {"welch": welch_ci(a, b).to_dict(),
                       "bootstrap": bootstrap_ci(a, b).to_dict()}}


def compare_counts(a_k: int, a_n: int, b_k: int, b_n: int) -> dict[str, Any]:
    """Rate a_k/a_n against b_k/b_n: Fisher's and Boschloo's exact tests (``p``) and the
    difference of the rates with Newcombe's interval (``effect``)."""
    return {"n": [a_n, b_n], "k": [a_k, b_k],
            "p": {"fisher": _pv(fisher(a_k, a_n, b_k, b_n).p),
                  "boschloo": _pv(boschloo(a_k, a_n, b_k, b_n))},
            "effect": {"newcombe": newcombe_ci(a_k, a_n, b_k, b_n).to_dict()}}


# ------------------------------------------------------------------ per experiment --
def summarize_capacity(records: Sequence[TrialRecord]) -> dict[str, Any]:
    """Per food, the maximal scoops' mass (completed scoops; a scoop whose tree failed is no
    maximal scoop) and, for a liquid, the brim test's; the capacity — Exp. 2c's load — is the
    mean maximal scoop, unless a liquid's scoops do not fill the dish to the brim: then the
    scoop was bounded by the pool it dipped in, not the spoon, and the capacity is the brim."""
    ok = _ok(records)
    foods = list(dict.fromkeys(r.condition.food for r in ok))
    out: dict[str, Any] = {"foods": {}}
    for f in foods:
        rs = [_out(r) for r in ok if r.condition.food == f]
        done = [o for o in rs if o.completed]
        scoop = describe([o.scoop_g for o in done]).to_dict()
        entry: dict[str, Any] = {"utensil": rs[0].utensil, "scoop_g": scoop,
                                 "completed": _rate(len(done), len(rs))}
        brims = [o.brim_g for o in rs if o.brim_g is not None]
        cap, source = scoop, "mean maximal scoop"
        if brims:
            entry["brim_g"] = describe(brims).to_dict()
            if scoop.get("mean") is None or scoop["mean"] < entry["brim_g"]["mean"]:
                cap, source = entry["brim_g"], ("the dish filled to the brim: the scoops "
                                                "were bounded by the pool's depth")
        entry.update(capacity_g=cap, capacity_source=source)
        out["foods"][f] = entry
    return out


def summarize_mass(records: Sequence[TrialRecord], foods: Sequence[str],
                   systems: Sequence[str], value: Callable[[Any], float]) -> dict[str, Any]:
    """Per food: the outcomes' ``value`` per system (mean ± SD, 95 % CI), Welch of the first
    system against the second, and how many trials had a non-zero value."""
    ok = _ok(records)
    out: dict[str, Any] = {}
    for f in foods:
        per = {s: [float(value(_out(r))) for r in _where(ok, _is(f, s))] for s in systems}
        entry: dict[str, Any] = {s: {**describe(v).to_dict(),
                                     "nonzero": _rate(sum(1 for x in v if x > 1e-9), len(v))}
                                 for s, v in per.items()}
        if len(systems) == 2:
            a, b = (per[s] for s in systems)
            entry["welch"] = welch(a, b).to_dict()
            entry["compare"] = compare_samples(a, b)
        out[f] = entry
    return out


def _is(food: str, system: str) -> Callable[[Condition], bool]:
    """Whether a condition is ``food`` by ``system``."""
    return lambda c: c.food == food and c.system == system


def summarize_exp2b(records: Sequence[TrialRecord], cfg: Any) -> dict[str, Any]:
    """Spilled mass per food and system (Welch), spill frequency (Fisher), per goal, and the
    planning and completion figures."""
    ok = _ok(records)
    systems = list(cfg.exp2b.systems)
    out: dict[str, Any] = {"spilled_g": summarize_mass(ok, cfg.exp2b.foods, systems,
                                                       lambda o: o.spilled_g)}
    freq: dict[str, Any] = {}
    per_goal: dict[str, Any] = {}
    plan: dict[str, Any] = {}
    for f in cfg.exp2b.foods:
        rs = {s: _where(ok, _is(f, s)) for s in systems}
        spill = {s: _spills(v) for s, v in rs.items()}
        if len(systems) == 2:
            a, b = systems
            freq[f] = fisher(spill[a], len(rs[a]), spill[b], len(rs[b])).to_dict()
            out["spilled_g"][f]["compare"]["p"]["fisher"] = freq[f]["p"]  # spill frequency
        per_goal[f] = {s: {g: describe([_out(r).spilled_g for r in v
                                        if r.condition.goal == g]).to_dict()
                           for g in dict.fromkeys(r.condition.goal for r in v)}
                       for s, v in rs.items()}
        outs = {s: [_out(r) for r in v] for s, v in rs.items()}
        plan[f] = {s: {"completed": _rate(sum(1 for o in v if o.completed), len(v)),
                       "planning_attempts": describe([o.planning_attempts for o in v]
                                                     ).to_dict(),
                       "max_tilt_deg": describe([o.max_tilt_deg for o in v
                                                 if o.max_tilt_deg is not None]).to_dict(),
                       "held_g": describe([o.held_g for o in v]).to_dict()}
                   for s, v in outs.items()}
    out.update(spill_frequency_fisher=freq, per_goal=per_goal, transport=plan,
               spilled_by_place={f: {sys_: by_place(_where(ok, _is(f, sys_)))
                                     for sys_ in systems} for f in cfg.exp2b.foods},
               variants=summarize_exp2b_variants(ok, cfg))
    return out


def _spills(records: Sequence[TrialRecord]) -> int:
    """How many of ``records`` spilled anything in transport."""
    return sum(1 for r in records if _out(r).spilled_g > 1e-9)


def summarize_exp2b_variants(records: Sequence[TrialRecord], cfg: Any
                             ) -> dict[str, dict[str, Any]]:
    """Per variant (this stack's systems beside the thesis') and food: its spills and
    spilled mass against the thesis system it extends (same seeds and goals: Fisher and
    Welch), its motion time beside that system's, and what its food checks did (retimed,
    slosh-free, the speed scale kept)."""
    out: dict[str, dict[str, Any]] = {}
    for name, v in cfg.exp2b.variants.items():
        per: dict[str, Any] = {}
        for f in v.foods:
            rs, base = _where(records, _is(f, name)), _where(records, _is(f, v.system))
            if not rs:
                continue
            checks = [c for r in rs for c in (_out(r).food_checks or [])]
            kept = [c for c in checks if c.executed is not False]
            carried = carried_wrists(v.system)
            per[f] = {
                "base": v.system,
                "spilled_g": describe([_out(r).spilled_g for r in rs]).to_dict(),
                "spills": _rate(_spills(rs), len(rs)),
                "base_spills": _rate(_spills(base), len(base)),
                "fisher_vs_base": (fisher(_spills(rs), len(rs), _spills(base), len(base))
                                   .to_dict() if base else None),
                "welch_vs_base": (welch([_out(r).spilled_g for r in rs],
                                        [_out(r).spilled_g for r in base]).to_dict()
                                  if base else None),
                "completed": _rate(sum(1 for r in rs if _out(r).completed), len(rs)),
                "motion_time_s": describe([_out(r).motion_time_s for r in rs]).to_dict(),
                "base_motion_time_s": describe([_out(r).motion_time_s for r in base]
                                               ).to_dict(),
                "checks": len(checks),
                # checks that modelled the wrist the transport carries (locked for the
                # baseline): a check of another wrist predicts another transport
                "checks_of_carried_wrist": sum(1 for c in checks if c.wrist in carried),
                "retimed": sum(1 for c in kept if c.scale is not None and c.scale < 1.0),
                "slosh_free": sum(1 for c in kept if c.wrist == "slosh_free"),
                "scale": describe([float(c.scale) for c in kept if c.scale is not None]
                                  ).to_dict(),
                "predicted_spill_g": describe([float(c.predicted_spill_g) for c in kept
                                               if c.predicted_spill_g is not None]
                                              ).to_dict(),
                "spilled_by_place": by_place(rs),
            }
        out[name] = per
    return out


def carried_wrists(system: str) -> frozenset[str]:
    """The wrists a food check of ``system``'s transport may model: the locked spoon for the
    baseline, leveling (or slosh-free) for the Articutool."""
    from articutool.feeding.system import System

    return (frozenset({"leveling", "slosh_free"}) if System.of(system).wrist
            else frozenset({"locked"}))


def by_place(records: Sequence[TrialRecord]) -> dict[str, dict[str, float]]:
    """Grams spilled over ``records`` per place (a container and the air apart from the
    table and the user: accounting.transport_spill), and in how many trials."""
    out: dict[str, dict[str, float]] = {}
    for r in records:
        for place, g in _out(r).spilled_by_place.items():
            e = out.setdefault(place, {"g": 0.0, "trials": 0})
            e["g"] = round(e["g"] + float(g), 4)
            e["trials"] += int(float(g) > 1e-9)
    return out


def summarize_exp2c(records: Sequence[TrialRecord], cfg: Any,
                    thresholds_g: Mapping[str, float] | None) -> dict[str, Any]:
    """Outcome classes per food and condition at ``thresholds_g`` (per food); Fisher's exact
    test of meaningful success, each primitive condition against control and closed loop
    against open loop (``fisher_meaningful``, ``…_closed_loop``, ``…_closed_vs_open``).
    Without thresholds only the spill/no-spill split is given."""
    ok = _ok(records)
    out: dict[str, Any] = {"thresholds_g": dict(thresholds_g) if thresholds_g else None,
                           "foods": {}}
    for f in cfg.exp2c.foods:
        entry: dict[str, Any] = {}
        for c in EXP2C_CONDITIONS:
            rs = _where(ok, _in(f, c))
            outs = [_out(r) for r in rs]
            e: dict[str, Any] = {
                "spill": _rate(sum(1 for o in outs if o.spilled_g > 1e-9), len(rs)),
                "delivered_g": describe([o.delivered_g for o in outs]).to_dict(),
                "held_g": describe([o.held_g for o in outs]).to_dict(),
                "shed_g": describe([o.shed_g for o in outs]).to_dict(),
                "spilled_by_place": by_place(rs)}
            if thresholds_g and f in thresholds_g:
                e.update(_counts([classify_exp2c(r, thresholds_g[f]) for r in rs],
                                 EXP2C_CLASSES))
            entry[c] = e
        # Each primitive condition against control, and closed loop against open loop.
        for suffix, (a, b) in {"": ("primitive", "control"),
                               "_closed_loop": ("closed_loop", "control"),
                               "_closed_vs_open": ("closed_loop", "primitive")}.items():
            ta, tb = entry[a], entry[b]
            if thresholds_g and f in thresholds_g:
                counts = (ta["counts"]["meaningful_success"], ta["n"],
                          tb["counts"]["meaningful_success"], tb["n"])
                entry["fisher_meaningful" + suffix] = fisher(*counts).to_dict()
                entry["compare_meaningful" + suffix] = compare_counts(*counts)
            a_rs, b_rs = (_where(ok, _in(f, k)) for k in (a, b))
            entry["fisher_no_spill" + suffix] = fisher(
                sum(1 for r in a_rs if _out(r).spilled_g <= 1e-9), len(a_rs),
                sum(1 for r in b_rs if _out(r).spilled_g <= 1e-9), len(b_rs)).to_dict()
        out["foods"][f] = entry
    return out


def _in(food: str, condition: str) -> Callable[[Condition], bool]:
    """Whether a condition is Exp. 2c's ``condition`` with ``food``."""
    return lambda c: c.food == food and c.condition == condition


def summarize_exp1(records: Sequence[TrialRecord], cfg: Any) -> dict[str, Any]:
    """Mass on the utensil at Resting per food and system, Welch (§5.1)."""
    return {"acquired_g": summarize_mass(_ok(records), cfg.exp1.foods, cfg.exp1.systems,
                                         lambda o: o.mass_g)}


def staging_attempts(rec: TrialRecord) -> int | None:
    """Planning attempts to Staging (the thesis' count, §6.3), or None when the bite never
    planned to Staging (it failed before)."""
    return _out(rec).planning_attempts_by_goal.get("Staging")


def summarize_exp3(records: Sequence[TrialRecord], cfg: Any,
                   threshold_g: float) -> dict[str, Any]:
    """The four outcome classes (and ``failed``) per system at ``threshold_g``; Fisher's
    exact test of meaningful success and of no spill; planning attempts (Welch); every
    comparison the verdicts read (``compare_*``)."""
    ok = _ok(records)
    systems = list(cfg.exp3.systems)
    out: dict[str, Any] = {"threshold_g": threshold_g, "systems": {}}
    att = {}
    for s in systems:
        rs = [r for r in ok if r.condition.system == s]
        e = _counts([classify(r, threshold_g) for r in rs], OUTCOMES)
        att[s] = [a for a in map(staging_attempts, rs) if a]
        e["planning_attempts"] = describe(att[s]).to_dict()
        e["delivered_g"] = describe([_out(r).delivered_g for r in rs]).to_dict()
        e["no_spill"] = _rate(sum(1 for r in rs if _out(r).spilled_g <= 1e-9), len(rs))
        out["systems"][s] = e
    if len(systems) == 2:
        a, b = (out["systems"][s] for s in systems)
        out["fisher_meaningful"] = fisher(a["counts"]["meaningful_success"], a["n"],
                                          b["counts"]["meaningful_success"], b["n"]).to_dict()
        out["fisher_no_spill"] = fisher(a["no_spill"]["k"], a["n"], b["no_spill"]["k"],
                                        b["n"]).to_dict()
        out["welch_planning_attempts"] = welch(*(att[s] for s in systems)).to_dict()
        out["compare_meaningful"] = compare_counts(a["counts"]["meaningful_success"], a["n"],
                                                   b["counts"]["meaningful_success"], b["n"])
        out["compare_no_spill"] = compare_counts(a["no_spill"]["k"], a["n"],
                                                 b["no_spill"]["k"], b["n"])
        out["compare_planning_attempts"] = compare_samples(*(att[s] for s in systems))
    return out


def meaningful_at(records: Sequence[TrialRecord], systems: Sequence[str],
                  threshold_g: float) -> dict[str, Any]:
    """Exp. 3's meaningful successes per system at another ``threshold_g`` (the report's
    view of our bites at the thesis' own threshold), with Fisher's exact test of the
    first two systems."""
    ok = _ok(records)
    ms = {s: sum(1 for r in ok if r.condition.system == s
                 and classify(r, threshold_g) == "meaningful_success") for s in systems}
    ns = {s: sum(1 for r in ok if r.condition.system == s) for s in systems}
    out: dict[str, Any] = {"threshold_g": float(threshold_g), "meaningful_success": ms,
                           "n": ns}
    if len(systems) >= 2:
        a, b = systems[:2]
        out["fisher"] = fisher(ms[a], ns[a], ms[b], ns[b]).to_dict()
    return out


def summarize_exp2a(records: Sequence[Mapping[str, Any]], timeout_s: float,
                    decoupled: str = "decoupled") -> dict[str, Any]:
    """The transport planning benchmark (Exp. 2a, ``articutool bench transport``'s records),
    ``decoupled`` against each strict planner (a record's ``system``): tasks solved (Fisher,
    Boschloo; Newcombe's interval of the difference) and planning time. Times: the ratio of
    the strict planner's
    median to the decoupled one's over the solved tasks (the thesis' medians), with the
    bootstrap interval; Mann–Whitney, Welch and the Wilcoxon signed-rank test (tasks
    paired) over every task, a failed plan counted as taking the whole ``timeout_s``."""
    by: dict[str, dict[int, Mapping[str, Any]]] = {}
    for r in records:
        if r.get("tolerance_deg") is None:  # the benchmark's own ±10°, not a sweep
            by.setdefault(str(r["system"]), {})[int(r["task_id"])] = r

    def time(r: Mapping[str, Any]) -> float:
        return float(r["planning_time_s"]) if r.get("success") else float(timeout_s)

    def solved(rs: Iterable[Mapping[str, Any]]) -> list[float]:
        return [float(r["planning_time_s"]) for r in rs if r.get("success")]

    every = [t for rs in by.values() for t in solved(rs.values())]
    out: dict[str, Any] = {"timeout_s": timeout_s, "planners": {}, "against": {},
                           "max_solved_s": max(every) if every else None}
    for name, rs in by.items():
        t = solved(rs.values())
        out["planners"][name] = {"tasks": len(rs), "solved": len(t),
                                 "median_s": float(np.median(t)) if t else None}
    dec = by.get(decoupled, {})
    for name, rs in by.items():
        if name == decoupled or not dec:
            continue
        tasks = sorted(set(rs) & set(dec))
        a = [time(rs[k]) for k in tasks]
        d = [time(dec[k]) for k in tasks]
        sa, sd = solved(rs[k] for k in tasks), solved(dec[k] for k in tasks)
        times = {"n": [len(a), len(d)],
                 "p": {"mann_whitney": _pv(mann_whitney(a, d)), "welch": _pv(welch(a, d).p),
                       "wilcoxon": _pv(wilcoxon_paired(a, d)) if tasks else None},
                 "effect": {"bootstrap": bootstrap_ci(sa, sd, "median ratio").to_dict()
                            if sa and sd else None}}
        out["against"][name] = {
            "tasks": len(tasks),
            "success": compare_counts(len(sd), len(tasks), len(sa), len(tasks)),
            "time": times}
    return out


def summarize(experiment: str, records: Sequence[TrialRecord], cfg: Any, *,
              thresholds_g: Mapping[str, float] | None = None,
              threshold_g: float | None = None) -> dict[str, Any]:
    """The summary of ``experiment`` (see the per-experiment functions), with run figures."""
    if experiment == "capacity":
        body = summarize_capacity(records)
    elif experiment == "exp1":
        body = summarize_exp1(records, cfg)
    elif experiment == "exp2b":
        body = summarize_exp2b(records, cfg)
    elif experiment == "exp2c":
        body = summarize_exp2c(records, cfg, thresholds_g)
    elif experiment == "exp3":
        if threshold_g is None:
            raise ValueError("exp3 needs threshold_g (our Exp. 1 mean, or --threshold-g)")
        body = summarize_exp3(records, cfg, threshold_g)
    else:
        raise ValueError(f"unknown experiment {experiment!r}")
    seeds = sorted({r.seed for r in records})
    return {"experiment": experiment, **body, "run": {**_wall(records), "seeds": seeds},
            "per_condition_n": dict(Counter("/".join(r.condition.group())
                                            for r in _ok(records)))}


def completeness(records: Sequence[TrialRecord], per_condition: int,
                 conditions: Sequence[Condition] | None = None) -> dict[str, dict[str, Any]]:
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


def _food_g(o: Outcome) -> float:
    """The food a trial ends with: acquired (a bite), scooped (a capacity trial), else
    delivered (a transport)."""
    if isinstance(o, BiteOutcome):
        return float(o.acquired_g)
    if isinstance(o, CapacityOutcome):
        return float(o.scoop_g)
    return float(o.delivered_g)


def representative_trials(records: Sequence[TrialRecord]) -> dict[str, dict[str, int]]:
    """Per condition (food + system or Exp. 2c condition), the trial numbers of a *typical*
    trial (its food mass — acquired, delivered or held — nearest the condition's median) and
    the *worst* (most spilled, then least food), for the report's replays. Ties go
    to the lowest trial number, so the choice does not depend on the log's order."""
    groups: dict[str, list[TrialRecord]] = {}
    for r in _ok(records):
        groups.setdefault(" ".join(r.condition.group()), []).append(r)

    def food_g(r: TrialRecord) -> float:
        return _food_g(_out(r))

    out = {}
    for key, rs in sorted(groups.items()):
        med = float(np.median([food_g(r) for r in rs]))
        typical = min(rs, key=lambda r: (abs(food_g(r) - med), r.trial))
        worst = min(rs, key=lambda r: (-float(_out(r).spilled_g), food_g(r), r.trial))
        out[key] = {"typical": typical.trial, "worst": worst.trial}
    return out
