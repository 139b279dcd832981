"""What our simulation says about each of the thesis' hypotheses and figures (pure).

The thesis (Ch. 6) makes five comparative claims; each is a direction (the Articutool, or a
primitive, does better) backed by a test. For each, :func:`verdicts` compares the direction
and the significance of *our* measurement with the thesis' claim, never its numbers:

- **reproduced**: our difference has the thesis' sign and our test is significant (p < α);
- **contradicted**: our difference has the opposite sign and is significant;
- **not reproduced**: our test is not significant (the data do not separate the conditions);
- **cannot test**: our measurement cannot carry the claim (no food moved in either
  condition, every value constant, or the experiment has not been run).

The thesis' numbers are printed beside ours (from ``experiments.toml [thesis]``) and are
never used to decide a verdict. α is ``[settings] alpha``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from scipy import stats as _st

from articutool.feeding.outcomes import OUTCOMES

__all__ = ["Verdict", "code_versions", "thesis_trials", "verdicts"]


@dataclass(frozen=True)
class Verdict:
    """One claim of the thesis and what our run says about it."""

    hypothesis: str  # "H1", "H2", "H3"
    figure: str  # "Fig. 6.1", …
    claim: str
    thesis: str
    ours: str
    test: str
    verdict: str  # reproduced | contradicted | not reproduced | cannot test


def _decide(diff: float | None, p: float | None, alpha: float, constant: bool) -> str:
    if diff is None or constant:
        return "cannot test"
    if p is None or p >= alpha:
        return "not reproduced"
    return "reproduced" if diff > 0 else "contradicted"


def _fmt_p(p: float | None) -> str:
    return "n/a" if p is None else (f"{p:.2g}" if p >= 1e-4 else f"{p:.1e}")


def _msd(d: Mapping[str, Any]) -> str:
    if d.get("mean") is None:
        return f"no data (n {d.get('n', 0)})"
    return f"{d['mean']:.2f} ± {d['sd'] or 0.0:.2f} g (n {d['n']})"


def _gap(a: Mapping[str, Any], b: Mapping[str, Any]) -> float | None:
    """``a``'s mean minus ``b``'s; None when either has no data."""
    if a.get("mean") is None or b.get("mean") is None:
        return None
    return a["mean"] - b["mean"]


def _welch_from(a: Mapping[str, Any], b: Mapping[str, Any]) -> float | None:
    """Two-sided Welch p from two summaries (n, mean, sd); None when both are constant."""
    if not a.get("n") or not b.get("n") or a.get("sd") is None or b.get("sd") is None \
            or (a["sd"] == 0 and b["sd"] == 0):
        return None
    return float(_st.ttest_ind_from_stats(a["mean"], a["sd"], a["n"], b["mean"], b["sd"],
                                          b["n"], equal_var=False).pvalue)


def thesis_trials(t: Mapping[str, Any]) -> int:
    """The thesis' Exp. 3 trials of one system: the sum of its outcome counts (§6.3)."""
    return sum(int(t.get(k, 0)) for k in OUTCOMES[:4])


def _exp1(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float) -> list[Verdict]:
    out = []
    for food, d in s["acquired_g"].items():
        a, b = d.get("articutool"), d.get("baseline")
        if not a or not b:
            continue
        t = th.get(food, {})
        thesis = (f"{t['articutool'][0]:.2f} vs {t['baseline'][0]:.2f} g, p {t.get('p')}"
                  if "articutool" in t else "not given")
        none_moved = a.get("mean") == 0 and b.get("mean") == 0
        p = d.get("welch", {}).get("p")
        out.append(Verdict(
            "H1", "Fig. 6.1", f"{food}: the Articutool acquires more than the baseline",
            thesis, f"{_msd(a)} vs {_msd(b)}", f"Welch two-sided p {_fmt_p(p)}",
            _decide(_gap(a, b), p, alpha, none_moved or p is None)))
    return out


def _exp2b(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float) -> list[Verdict]:
    out = []
    for food, d in s["spilled_g"].items():
        a, b = d.get("articutool"), d.get("baseline")
        if not a or not b:
            continue
        t = th.get(food, {})
        thesis = (f"{t['articutool']:.2f} vs {t['baseline']:.2f} g spilled, p {t.get('p')}"
                  if "articutool" in t else t.get("note", "not given"))
        p = d.get("welch", {}).get("p")
        fisher = s.get("spill_frequency_fisher", {}).get(food, {})
        out.append(Verdict(
            "H2", "Fig. 6.3", f"{food}: the Articutool spills less in transport than the "
            "locked baseline", thesis, f"{_msd(a)} vs {_msd(b)} spilled",
            f"Welch two-sided p {_fmt_p(p)}; spill frequency Fisher p "
            f"{_fmt_p(fisher.get('p'))}",
            _decide(_gap(b, a), p, alpha, p is None)))
    return out


_EXP2C = {"primitive": ("fisher_meaningful", "the open-loop primitive"),
          "closed_loop": ("fisher_meaningful_closed_loop", "the closed-loop primitive")}


def _exp2c(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float) -> list[Verdict]:
    if not s.get("thresholds_g"):
        return []
    out = []
    for food, d in s["foods"].items():
        ctrl = d.get("control")
        if not ctrl:
            continue
        for cond, (key, name) in _EXP2C.items():
            c = d.get(cond)
            if not c or key not in d:
                continue
            ms_c = ctrl["percent"].get("meaningful_success", 0.0)
            ms_p = c["percent"].get("meaningful_success", 0.0)
            tc = th.get(f"{food}_control", {}).get("meaningful_success", 0.0)
            tp = th.get(f"{food}_primitive", {}).get("meaningful_success")
            thesis = (f"meaningful success {tp:g} % with the primitive vs {tc:g} % control"
                      if tp is not None else "not given")
            p = d[key].get("p")
            constant = ms_c == ms_p and ms_c in (0.0, 100.0)
            out.append(Verdict(
                "H2", "Fig. 6.4", f"{food}: {name} raises meaningful success over control",
                thesis + (" (open loop; the thesis had no closed loop)"
                          if cond == "closed_loop" else ""),
                f"{ms_p:.0f} % vs {ms_c:.0f} % (n {c['n']} / {ctrl['n']})",
                f"Fisher two-sided p {_fmt_p(p)}", _decide(ms_p - ms_c, p, alpha, constant)))
    return out


def _exp3(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float) -> list[Verdict]:
    a, b = s["systems"].get("articutool"), s["systems"].get("baseline")
    if not a or not b or not a["n"] or not b["n"]:
        return []
    ta, tb = th.get("articutool", {}), th.get("baseline", {})
    out = []
    ms_a, ms_b = (x["counts"]["meaningful_success"] for x in (a, b))
    p = s.get("fisher_meaningful", {}).get("p")
    no_food = not a["delivered_g"].get("mean") and not b["delivered_g"].get("mean")
    out.append(Verdict(
        "H3", "Fig. 6.5", "noodles end to end: the Articutool has more meaningful successes",
        f"{ta.get('meaningful_success')}/{thesis_trials(ta)} vs "
        f"{tb.get('meaningful_success')}/{thesis_trials(tb)}",
        f"{ms_a}/{a['n']} vs {ms_b}/{b['n']}; delivered {_msd(a['delivered_g'])} vs "
        f"{_msd(b['delivered_g'])}", f"Fisher two-sided p {_fmt_p(p)}",
        _decide(ms_a / a["n"] - ms_b / b["n"], p, alpha, no_food)))
    ns_a, ns_b = a["no_spill"]["k"], b["no_spill"]["k"]
    p = s.get("fisher_no_spill", {}).get("p")
    out.append(Verdict(
        "H3", "Fig. 6.5", "noodles end to end: the Articutool spills in fewer bites",
        f"{ta.get('meaningful_success', 0) + ta.get('trivial_success', 0)}/{thesis_trials(ta)}"
        f" vs {tb.get('meaningful_success', 0) + tb.get('trivial_success', 0)}/"
        f"{thesis_trials(tb)} without spill",
        f"{ns_a}/{a['n']} vs {ns_b}/{b['n']} without spill", f"Fisher two-sided p {_fmt_p(p)}",
        _decide(ns_a / a["n"] - ns_b / b["n"], p, alpha, no_food)))
    pa, pb = a["planning_attempts"], b["planning_attempts"]
    if pa.get("mean") is None or pb.get("mean") is None:
        return out
    p = _welch_from(pa, pb)
    out.append(Verdict(
        "H3", "attempts", "the Articutool needs fewer planning attempts to Staging",
        f"{ta.get('planning_attempts')} vs {tb.get('planning_attempts')} attempts",
        f"{pa['mean']:.2f} ± {pa['sd'] or 0.0:.2f} vs "
        f"{pb['mean']:.2f} ± {pb['sd'] or 0.0:.2f} attempts",
        f"Welch two-sided p {_fmt_p(p)}" if p is not None else "both constant: no test",
        # Equal constants are a measured "no difference", not an untestable claim.
        "not reproduced" if p is None and pa["mean"] == pb["mean"]
        else _decide(pb["mean"] - pa["mean"], p, alpha, False)))
    return out


def verdicts(summaries: Mapping[str, Mapping[str, Any]], thesis: Mapping[str, Any],
             alpha: float) -> list[Verdict]:
    """One :class:`Verdict` per claim, in the thesis' order (H1, H2, H3). ``summaries`` maps
    an experiment (``exp1``, ``exp2b``, ``exp2c``, ``exp3``) to its ``summary.json``; a
    missing experiment gives one "cannot test" row saying so."""
    rules = (("exp1", "H1", "Fig. 6.1", _exp1), ("exp2b", "H2", "Fig. 6.3", _exp2b),
             ("exp2c", "H2", "Fig. 6.4", _exp2c), ("exp3", "H3", "Fig. 6.5", _exp3))
    out: list[Verdict] = []
    for exp, h, fig, rule in rules:
        s = summaries.get(exp)
        rows = rule(s, thesis.get(exp, {}), alpha) if s else []
        why = ("not run" if not s else "run, but no comparison could be formed (Exp. 2c "
               "needs outcome thresholds: Exp. 1's means or --thresholds-g)")
        out += rows or [Verdict(h, fig, f"{exp}'s claims", "", why, "", "cannot test")]
    return out


def code_versions(summaries: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, int]]:
    """Per experiment, how many trials ran on each code version (``run.sources``)."""
    return {exp: dict(s.get("run", {}).get("sources", {})) for exp, s in summaries.items()}
