"""Exp. 3 (thesis §5.3, H3): noodles end to end — the whole bite through the feeding tree,
classified at a meaningful-success threshold when it is summarised."""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ClassVar

from pydantic import Field

from articutool.datafile import Positive, StrictModel
from articutool.experiments.analysis import (
    class_counts,
    classify,
    compare_counts,
    compare_samples,
    measured,
    ok_records,
    rate,
)
from articutool.experiments.config import ExperimentsConfig, Names
from articutool.experiments.figures import outcome_bars
from articutool.experiments.markdown import mean_sd, num, p_value, table
from articutool.experiments.protocols import bite
from articutool.experiments.records import BiteCondition, BiteOutcome, TrialRecord
from articutool.experiments.stats import FisherResult, describe, fisher, welch
from articutool.experiments.unit import (
    MAX_LOAD_G,
    Experiment,
    Hook,
    Visitors,
    add_physics_argument,
    usage,
)
from articutool.experiments.verdicts import Verdict, judge, mean_sd_g
from articutool.feeding.outcomes import OUTCOMES

if TYPE_CHECKING:
    from articutool.sim.world import SettleCache

__all__ = [
    "EXPERIMENT",
    "Exp3Config",
    "exp3_trial",
    "meaningful_at",
    "staging_attempts",
    "summarize_exp3",
    "thesis_exp3_no_spill",
]


class Exp3Config(StrictModel):
    """Exp. 3 (§5.3)."""

    food: Annotated[str, Field(min_length=1)]
    systems: Names
    timeout_s: Positive



def exp3_trial(cond: BiteCondition, seed: int, cfg: ExperimentsConfig,
               hook: Hook = None, visitors: Visitors = (),
               settled: SettleCache | None = None) -> BiteOutcome:
    """Exp. 3 (§5.3): the whole bite — above the food, acquire, shed, Resting, Staging,
    present (the simulated user takes it). The outcome class is derived at analysis time,
    at the report's threshold (``outcome`` here is ``None``)."""
    return BiteOutcome.model_validate(bite(
        cond, seed, cfg, hook, ("above", "acquire", "shed", "resting", "staging", "present"),
        cfg.exp3.timeout_s, visitors, settled))



def staging_attempts(rec: TrialRecord) -> int | None:
    """Planning attempts to Staging (the thesis' count, §6.3), or None when the bite never
    planned to Staging (it failed before)."""
    return measured(rec).planning_attempts_by_goal.get("Staging")


def summarize_exp3(records: Sequence[TrialRecord], cfg: Any,
                   threshold_g: float) -> dict[str, Any]:
    """The four outcome classes (and ``failed``) per system at ``threshold_g``; Fisher's
    exact test of meaningful success and of no spill; planning attempts (Welch); every
    comparison the verdicts read (``compare_*``)."""
    ok = ok_records(records)
    systems = list(cfg.exp3.systems)
    out: dict[str, Any] = {"threshold_g": threshold_g, "systems": {}}
    att = {}
    for s in systems:
        rs = [r for r in ok if r.condition.system == s]
        e = class_counts([classify(r, threshold_g) for r in rs], OUTCOMES)
        att[s] = [a for a in map(staging_attempts, rs) if a]
        e["planning_attempts"] = describe(att[s]).to_dict()
        e["delivered_g"] = describe([measured(r).delivered_g for r in rs]).to_dict()
        e["no_spill"] = rate(sum(1 for r in rs if measured(r).spilled_g <= 1e-9), len(rs))
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
    ok = ok_records(records)
    ms = {s: sum(1 for r in ok if r.condition.system == s
                 and classify(r, threshold_g) == "meaningful_success") for s in systems}
    ns = {s: sum(1 for r in ok if r.condition.system == s) for s in systems}
    out: dict[str, Any] = {"threshold_g": float(threshold_g), "meaningful_success": ms,
                           "n": ns}
    if len(systems) >= 2:
        a, b = systems[:2]
        out["fisher"] = fisher(ms[a], ns[a], ms[b], ns[b]).to_dict()
    return out



def thesis_exp3_no_spill(thesis_exp3: Mapping[str, Any]) -> FisherResult | None:
    """Fisher's exact test (two-sided) of trials without spill (meaningful + trivial
    success), Articutool against the baseline, recomputed from the thesis' own Exp. 3 counts
    (§6.3, Fig. 6.5; ``[thesis.exp3]`` of experiments.toml). From 14/20 against 7/20 it gives
    p ≈ 0.056, where the thesis prints p < 0.00012. None if a count is missing."""
    counts = []
    for sys_ in ("articutool", "baseline"):
        t = thesis_exp3.get(sys_, {})
        if not all(isinstance(t.get(k), int) for k in OUTCOMES[:4]):
            return None
        counts += [t["meaningful_success"] + t["trivial_success"],
                   sum(t[k] for k in OUTCOMES[:4])]
    return fisher(*counts)


def section_exp3(s: Mapping[str, Any], cfg: Any) -> str:
    """The outcome classes per system beside the thesis', and the tests."""
    th = cfg.thesis["exp3"]
    rows = []
    for sys_, d in s["systems"].items():
        t = th.get(sys_, {})
        rows.append([sys_, d["n"], *(d["counts"][k] for k in OUTCOMES),
                     " / ".join(str(t.get(k, "–")) for k in OUTCOMES[:4]),
                     mean_sd(d["planning_attempts"]), num(t.get("planning_attempts")),
                     mean_sd(d["delivered_g"])])
    out = table(["system", "n", *(k.replace("_", " ") for k in OUTCOMES),
                  "thesis (meaningful / trivial / table / user, of 20)",
                  "planning attempts to Staging", "thesis attempts", "delivered (g)"], rows)
    at = s.get("at_thesis_threshold")
    if at:
        sy = list(at["meaningful_success"])
        out += (f"\n\nAt the thesis' {at['threshold_g']:.1f} g (taken from the bimodal "
                "distribution of its Exp. 3 baseline's bites, §5.3), our meaningful successes "
                "are " + " vs ".join(f"{at['meaningful_success'][x]}/{at['n'][x]}" for x in sy)
                + f" ({' vs '.join(sy)}; Fisher p {p_value(at.get('fisher', {}).get('p'))}). Ours "
                "below is the rule the thesis used for Exp. 2c (our Exp. 1 Articutool mean).")
    ours = (f"\n\nThreshold {s['threshold_g']:g} g. Ours: Fisher p, meaningful success: "
            f"{p_value(s.get('fisher_meaningful', {}).get('p'))}; no spill: "
            f"{p_value(s.get('fisher_no_spill', {}).get('p'))}; Welch p, planning attempts: "
            f"{p_value(s.get('welch_planning_attempts', {}).get('p'))}.")
    printed = th.get("p_no_spill", "not given")
    r = thesis_exp3_no_spill(th)
    if r is None:
        return out + ours + f" The thesis' no-spill p, as printed: {printed}."
    (a, a_no), (b, b_no) = r.table
    return (out + ours + f" The thesis' no-spill p, as printed: {printed}; recomputed here "
            f"from the thesis' own counts ({a}/{a + a_no} vs {b}/{b + b_no} trials without "
            f"spill, Fisher's exact test, two-sided): p = {p_value(r.p)}.")



def claims_exp3(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float,
              tests: Mapping[str, Any]) -> list[Verdict]:
    """Our summary ``s`` against the thesis' ``th`` on each claim it tests, judged by the
    pre-registered ``tests`` at ``alpha`` (:func:`~articutool.experiments.verdicts.judge`)."""
    a, b = s["systems"].get("articutool"), s["systems"].get("baseline")
    if not a or not b or not a["n"] or not b["n"]:
        return []
    ta, tb = th.get("articutool", {}), th.get("baseline", {})
    na, nb = thesis_trials(ta), thesis_trials(tb)
    out = []
    ms_a, ms_b = (x["counts"]["meaningful_success"] for x in (a, b))
    no_food = not a["delivered_g"].get("mean") and not b["delivered_g"].get("mean")
    given = bool(na and nb and "meaningful_success" in ta and "meaningful_success" in tb)
    test, size, others, verdict = judge(
        s.get("compare_meaningful"), tests["exp3_success"],
        ta["meaningful_success"] / na - tb["meaningful_success"] / nb if given else None, +1,
        alpha, no_food, "points")
    out.append(Verdict(
        "H3", "Fig. 6.5", "noodles end to end: the Articutool has more meaningful successes",
        f"{ta.get('meaningful_success')}/{na} vs {tb.get('meaningful_success')}/{nb}"
        + (f" (> {th['threshold_g']:g} g)" if "threshold_g" in th else ""),
        f"{ms_a}/{a['n']} vs {ms_b}/{b['n']}"
        + (f" (> {s['threshold_g']:.2f} g)" if s.get("threshold_g") is not None else "")
        + f"; delivered {mean_sd_g(a['delivered_g'])} vs {mean_sd_g(b['delivered_g'])}", test, size,
        others, verdict))
    ok_a = ta.get("meaningful_success", 0) + ta.get("trivial_success", 0)
    ok_b = tb.get("meaningful_success", 0) + tb.get("trivial_success", 0)
    ns_a, ns_b = a["no_spill"]["k"], b["no_spill"]["k"]
    test, size, others, verdict = judge(
        s.get("compare_no_spill"), tests["exp3_no_spill"],
        ok_a / na - ok_b / nb if na and nb else None, +1, alpha, no_food, "points")
    out.append(Verdict(
        "H3", "Fig. 6.5", "noodles end to end: the Articutool spills in fewer bites",
        f"{ok_a}/{na} vs {ok_b}/{nb} without spill",
        f"{ns_a}/{a['n']} vs {ns_b}/{b['n']} without spill", test, size, others, verdict))
    pa, pb = a["planning_attempts"], b["planning_attempts"]
    if pa.get("mean") is None or pb.get("mean") is None:
        return out
    given = "planning_attempts" in ta and "planning_attempts" in tb
    equal_constants = not pa.get("sd") and not pb.get("sd") and pa["mean"] == pb["mean"]
    test, size, others, verdict = judge(
        s.get("compare_planning_attempts"), tests["exp3_attempts"],
        ta["planning_attempts"] - tb["planning_attempts"] if given else None, -1, alpha,
        False, "")
    out.append(Verdict(
        "H3", "attempts", "the Articutool needs fewer planning attempts to Staging",
        f"{ta.get('planning_attempts')} vs {tb.get('planning_attempts')} attempts",
        f"{pa['mean']:.2f} ± {pa['sd'] or 0.0:.2f} vs {pb['mean']:.2f} ± {pb['sd'] or 0.0:.2f}"
        " attempts", test + ("; both constant" if equal_constants else ""), size, others,
        # Equal constants are a measured "no difference", not an untestable claim.
        "not reproduced" if equal_constants else verdict))
    return out



def thesis_trials(t: Mapping[str, Any]) -> int:
    """The thesis' Exp. 3 trials of one system: the sum of its outcome counts (§6.3)."""
    return sum(int(t.get(k, 0)) for k in OUTCOMES[:4])



class Exp3Experiment(Experiment):
    """Exp. 3."""

    name = "exp3"
    help = "noodles end to end, H3 (§5.3)"
    title = "Exp. 3 — noodles end to end (H3, §5.3; cf. Fig. 6.5)"
    hypothesis = "H3"
    thesis_figure = "Fig. 6.5"
    order = 40
    condition = BiteCondition
    config_model = Exp3Config
    claims: ClassVar[dict[str, str]] = {
        "exp3_success": "Exp. 3 meaningful success (H3)",
        "exp3_no_spill": "Exp. 3 bites without spill (H3)",
        "exp3_attempts": "Exp. 3 planning attempts (H3)"}
    outcome = BiteOutcome

    run_trial = staticmethod(exp3_trial)
    verdicts = staticmethod(claims_exp3)
    section = staticmethod(section_exp3)

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        add_physics_argument(parser)
        parser.add_argument("--threshold-g", type=float, default=None,
                            help="meaningful-success threshold (default: our Exp. 1 "
                                 "Articutool mean for the food, the thesis' rule for Exp. 2c; "
                                 "the thesis' Exp. 3 took 3.0 g from its baseline's bimodal "
                                 "bites)")

    def add_report_arguments(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--threshold-g", type=float, default=None,
                            help="Exp. 3 threshold (default: our Exp. 1 Articutool mean)")

    def check_arguments(self, args: argparse.Namespace) -> None:
        v = getattr(args, "threshold_g", None)
        if v is not None and not 0 <= v <= MAX_LOAD_G:  # also refuses NaN
            raise usage(f"--threshold-g must be a mass in [0, {MAX_LOAD_G:g}] g; got {v}")

    def analysis(self, args: argparse.Namespace, out: Path, cfg: ExperimentsConfig, *,
                 required: bool = True) -> dict[str, Any]:
        """The threshold: ``--threshold-g``, else our Exp. 1 Articutool mean for the food
        (the rule the thesis used for Exp. 2c; its Exp. 3's 3.0 g came from the bimodal
        distribution of its baseline's bites, §5.3, and the report classifies ours at it
        too)."""
        from articutool.experiments.runner import log_path
        from articutool.thresholds import exp1_means

        if not required and not log_path(out, self.name).exists():
            return {"threshold_g": None}
        if getattr(args, "threshold_g", None) is not None:
            return {"threshold_g": float(args.threshold_g)}
        mean = exp1_means(out).get(cfg.exp3.food)
        if mean is None:
            raise usage(f"--threshold-g: no Exp. 1 result for {cfg.exp3.food} under {out} "
                        "to derive it from; run `articutool experiment exp1` first or pass it")
        return {"threshold_g": mean}

    def conditions(self, cfg: ExperimentsConfig, **inputs: Any) -> list[Any]:
        return [BiteCondition(food=cfg.exp3.food, system=s) for s in cfg.exp3.systems]

    def summarize(self, records: Sequence[TrialRecord], cfg: ExperimentsConfig,
                  threshold_g: float | None = None, **settings: Any) -> dict[str, Any]:
        if threshold_g is None:
            raise ValueError("exp3 needs threshold_g (our Exp. 1 mean, or --threshold-g)")
        return summarize_exp3(records, cfg, threshold_g)

    def report_extras(self, records: Sequence[TrialRecord], cfg: ExperimentsConfig
                      ) -> dict[str, Any]:
        """Our bites at the thesis' own threshold too."""
        theirs = cfg.thesis.get("exp3", {}).get("threshold_g")
        if theirs is None:
            return {}
        return {"at_thesis_threshold": meaningful_at(records, cfg.exp3.systems, theirs)}

    def differences(self, summary: Mapping[str, Any], cfg: ExperimentsConfig) -> list[str]:
        s, th, out = summary, cfg.thesis, []
        for sys_, d in s["systems"].items():
            t = th["exp3"].get(sys_, {})
            if d["n"]:
                ms = 100.0 * d["counts"]["meaningful_success"] / d["n"]
                tms = 100.0 * t.get("meaningful_success", 0) / max(thesis_trials(t), 1)
                out.append(f"{sys_}: meaningful success {ms:.0f} % vs the thesis' {tms:.0f} % "
                           f"({ms - tms:+.0f} points)")
            a = d["planning_attempts"].get("mean")
            if a is not None and "planning_attempts" in t:
                out.append(f"{sys_}: {a:.2f} planning attempts to Staging vs the thesis' "
                           f"{t['planning_attempts']:.2f}")
        return out

    def figure(self, records: Sequence[TrialRecord], summary: Mapping[str, Any],
               cfg: ExperimentsConfig, directory: Path) -> Path | None:
        groups = {s: v["counts"] for s, v in summary["systems"].items()}
        return outcome_bars(groups, OUTCOMES, f"Exp. 3: noodles end to end, threshold "
                            f"{summary['threshold_g']:g} g (cf. thesis Fig. 6.5)",
                            directory / "exp3.png")

    def facts(self, summary: Mapping[str, Any] | None, records: Sequence[TrialRecord],
              cfg: ExperimentsConfig) -> dict[str, str]:
        """The threshold, our bites at the thesis' one, the baseline's delivered mass, and the
        thesis' no-spill p recomputed from its own counts."""
        f: dict[str, str] = {}
        e3 = summary
        if e3:
            f["exp3_threshold"] = f"{e3['threshold_g']:.2f} g"
            at = e3.get("at_thesis_threshold")
            if at:
                f["exp3_at_thesis_threshold"] = " vs ".join(
                    f"{at['meaningful_success'][x]}/{at['n'][x]}"
                    for x in at["meaningful_success"])
            base = e3["systems"].get("baseline", {}).get("delivered_g")
            if base and base.get("mean") is not None:
                f["exp3_baseline_delivered"] = (f"{mean_sd(base)} g in {base['n']} bites")
        r = thesis_exp3_no_spill(cfg.thesis.get("exp3", {}))
        if r is not None:
            f["thesis_exp3_no_spill_p"] = p_value(r.p)
        return f


EXPERIMENT = Exp3Experiment()
