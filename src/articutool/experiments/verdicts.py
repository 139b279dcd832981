"""What our simulation says about each of the thesis' hypotheses and figures (pure).

The thesis (Ch. 6) makes comparative claims; each is a direction (the Articutool, the
decoupled planner or a primitive does better) with a size (its difference). For each,
:func:`verdicts` judges our measurement with the test pre-registered for the claim's kind of
measurement (``experiments.toml [tests]``) and the 95 % interval of our difference:

- **reproduced**: our difference has the thesis' direction, the test gives p < α, and the
  thesis' difference lies inside our interval (its edges included);
- **reproduced in sign only**: significant in the thesis' direction, but our interval
  excludes the thesis' difference (or the thesis gives no number to compare);
- **contradicted**: significant the other way;
- **not reproduced**: the test is not significant (the data do not separate the systems);
- **cannot test**: our measurement cannot carry the claim (no food moved in either
  condition, both at the same floor or ceiling, every value constant, or not run).

The thesis' numbers decide only between *reproduced* and *reproduced in sign only*: never
the direction or the significance. The other tests are printed beside the chosen one. α is
``[settings] alpha``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from articutool.feeding.outcomes import OUTCOMES

__all__ = ["TEST_NAMES", "VERDICTS", "Verdict", "code_versions", "decide", "thesis_trials",
           "verdicts"]

VERDICTS = ("reproduced", "reproduced in sign only", "not reproduced", "contradicted",
            "cannot test")
TEST_NAMES = {"welch": "Welch", "mann_whitney": "Mann–Whitney", "wilcoxon": "Wilcoxon "
              "signed-rank (paired)", "fisher": "Fisher", "boschloo": "Boschloo"}
_CI_NAMES = {"welch": "Welch", "bootstrap": "bootstrap", "newcombe": "Newcombe"}


@dataclass(frozen=True)
class Verdict:
    """One claim of the thesis and what our run says about it."""

    hypothesis: str  # "H1", "H2", "H3"
    figure: str  # "Fig. 6.1", …
    claim: str
    thesis: str
    ours: str
    test: str  # the pre-registered test and its p
    size: str  # our difference with its interval, beside the thesis'
    others: str  # the other tests' p, printed beside
    verdict: str  # one of VERDICTS


def decide(effect: float | None, ci: tuple[float, float] | None, thesis: float | None,
           p: float | None, alpha: float, constant: bool = False) -> str:
    """The verdict of one claim from our ``effect`` and its interval ``ci``, oriented so
    that > 0 is the thesis' direction, the thesis' own difference ``thesis`` (same
    orientation and scale; None: not given) and the pre-registered test's ``p``.
    ``constant``: the measurement cannot carry the claim."""
    if effect is None or not math.isfinite(effect) or constant:
        return "cannot test"
    if p is None or not p < alpha or effect == 0:
        return "not reproduced"
    if effect < 0:
        return "contradicted"
    if (thesis is None or ci is None or not all(map(math.isfinite, ci))
            or not ci[0] <= thesis <= ci[1]):
        return "reproduced in sign only"
    return "reproduced"


def _fmt_p(p: float | None) -> str:
    return "n/a" if p is None else (f"{p:.2g}" if p >= 1e-4 else f"{p:.1e}")


def _msd(d: Mapping[str, Any]) -> str:
    if d.get("mean") is None:
        return f"no data (n {d.get('n', 0)})"
    return f"{d['mean']:.2f} ± {d['sd'] or 0.0:.2f} g (n {d['n']})"


def thesis_trials(t: Mapping[str, Any]) -> int:
    """The thesis' Exp. 3 trials of one system: the sum of its outcome counts (§6.3)."""
    return sum(int(t.get(k, 0)) for k in OUTCOMES[:4])


def _attr(pre: Any, name: str) -> str:
    return str(pre[name] if isinstance(pre, Mapping) else getattr(pre, name))


def _judge(comp: Mapping[str, Any] | None, pre: Any, thesis: float | None, direction: int,
           alpha: float, constant: bool, unit: str, labels: Mapping[str, str] | None = None
           ) -> tuple[str, str, str, str]:
    """(test, size, others, verdict) of one claim from its comparison (``compare_*`` of
    :mod:`articutool.experiments.analysis`) with the pre-registered test ``pre``.
    ``direction`` is +1 when the thesis claims a > b, −1 when a < b; ``unit``: "g",
    "points" (proportions, shown ×100), "×" (a ratio), "" (a count)."""
    names = {**TEST_NAMES, **(labels or {})}
    test, ci_name = _attr(pre, "test"), _attr(pre, "ci")
    if not comp:
        return names[test], "–", "", "cannot test"
    ps = comp.get("p", {})
    p = ps.get(test)
    eff = (comp.get("effect") or {}).get(ci_name) or {}
    est, lo, hi = eff.get("estimate"), eff.get("ci_low"), eff.get("ci_high")
    ratio = eff.get("kind") == "ratio"

    def orient(x: float | None) -> float | None:
        if x is None or not math.isfinite(x) or (ratio and x <= 0):
            return None
        return direction * (math.log(x) if ratio else x)

    o_est, o_th = orient(est), orient(thesis)
    o_lo, o_hi = orient(lo), orient(hi)
    ci = (min(o_lo, o_hi), max(o_lo, o_hi)) if o_lo is not None and o_hi is not None \
        else None
    verdict = decide(o_est, ci, o_th, p, alpha, constant)

    def show(x: float | None, sign: bool = True) -> str:
        if x is None:
            return "–"
        if unit == "×":
            return f"{x:.1f}×" if x < 10 else f"{x:.0f}×"
        if unit == "points":
            return f"{100 * x:+.1f}" if sign else f"{100 * x:.1f}"
        return f"{x:+.2f}" if sign else f"{x:.2f}"

    u = "" if unit in ("×", "") else f" {unit}"
    size = f"{show(est)}{u}"
    if lo is not None and hi is not None:
        size += f" [{show(lo)}, {show(hi)}] ({_CI_NAMES[ci_name]})"
    size += f"; thesis {show(thesis)}{u}" if thesis is not None else "; thesis: no number"
    others = "; ".join(f"{names[k]} {_fmt_p(v)}" for k, v in ps.items() if k != test)
    return f"{names[test]} {_fmt_p(p)}", size, others, verdict


def _exp1(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float, tests: Mapping[str, Any]
          ) -> list[Verdict]:
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
        test, size, others, verdict = _judge(
            d.get("compare"), tests["exp1"],
            t["articutool"][0] - t["baseline"][0] if given else None, +1, alpha,
            none_moved or both_constant, "g")
        out.append(Verdict("H1", "Fig. 6.1", f"{food}: the Articutool acquires more than the "
                           "baseline", thesis, f"{_msd(a)} vs {_msd(b)}", test, size, others,
                           verdict))
    return out


def _exp2a(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float, tests: Mapping[str, Any]
           ) -> list[Verdict]:
    out = []
    dec = "decoupled"
    tdec = th.get(dec, {})
    sysd = s.get("planners", {})
    for base, v in s.get("against", {}).items():
        tb = th.get(base, {})
        ours_d, ours_b = sysd.get(dec, {}), sysd.get(base, {})
        comp = v["success"]
        k = comp.get("k", [0, 0])
        n = comp.get("n", [0, 0])
        at_bound = k[0] * n[1] == k[1] * n[0] and k[0] in (0, n[0])
        given = "success" in tdec and "success" in tb
        test, size, others, verdict = _judge(
            comp, tests["exp2a_success"],
            (tdec["success"] - tb["success"]) / 100 if given else None, +1, alpha,
            at_bound or not n[0] or not n[1], "points")
        timeout = s.get("timeout_s")
        out.append(Verdict(
            "H2", "Fig. 6.2", f"transport planning: the decoupled planner solves more tasks "
            f"than {base} (±10°)",
            f"{tdec.get('success', '–')} % vs {tb.get('success', '–')} % solved "
            f"({th.get('timeout_s', '?'):g} s)" if given else "not given",
            f"{k[0]}/{n[0]} vs {k[1]}/{n[1]} solved ({timeout:g} s)" if timeout else
            f"{k[0]}/{n[0]} vs {k[1]}/{n[1]} solved", test, size, others, verdict))
        given = "median_s" in tdec and "median_s" in tb
        md, mb = ours_d.get("median_s"), ours_b.get("median_s")
        test, size, others, verdict = _judge(
            v["time"], tests["exp2a_time"],
            tb["median_s"] / tdec["median_s"] if given else None, +1, alpha,
            md is None or mb is None, "×")
        out.append(Verdict(
            "H2", "Fig. 6.2", f"transport planning: the decoupled planner plans faster than "
            f"{base} ({base} / decoupled median)",
            f"median {tdec['median_s']:g} vs {tb['median_s']:g} s" if given else "not given",
            f"median {md * 1e3:.1f} vs {mb * 1e3:.1f} ms" if md is not None and mb is not None
            else "no solved task", test, size, others, verdict))
    return out


def _exp2b(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float, tests: Mapping[str, Any]
           ) -> list[Verdict]:
    out = []
    for food, d in s["spilled_g"].items():
        a, b = d.get("articutool"), d.get("baseline")
        if not a or not b:
            continue
        t = th.get(food, {})
        given = isinstance(t.get("articutool"), float | int) and isinstance(
            t.get("baseline"), float | int)
        thesis = (f"{t['articutool']:.2f} vs {t['baseline']:.2f} g spilled, p {t.get('p')}"
                  if given else t.get("note", "not given"))
        nz = (a.get("nonzero", {}).get("k"), b.get("nonzero", {}).get("k"))
        test, size, others, verdict = _judge(
            d.get("compare"), tests["exp2b"],
            t["articutool"] - t["baseline"] if given else None, -1, alpha,
            not a.get("sd") and not b.get("sd"), "g",
            labels={"fisher": "Fisher (spill frequency)"})
        spills = (f"; spilled in {nz[0]}/{a['n']} vs {nz[1]}/{b['n']}"
                  if None not in nz else "")
        out.append(Verdict(
            "H2", "Fig. 6.3", f"{food}: the Articutool spills less in transport than the "
            "locked baseline", thesis, f"{_msd(a)} vs {_msd(b)} spilled{spills}", test, size,
            others, verdict))
    return out


_EXP2C = {"primitive": ("", "the open-loop primitive"),
          "closed_loop": ("_closed_loop", "the closed-loop primitive")}


def _exp2c(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float, tests: Mapping[str, Any]
           ) -> list[Verdict]:
    if not s.get("thresholds_g"):
        return []
    out = []
    for food, d in s["foods"].items():
        ctrl = d.get("control")
        if not ctrl:
            continue
        for cond, (suffix, name) in _EXP2C.items():
            c = d.get(cond)
            comp = d.get("compare_meaningful" + suffix)
            if not c or comp is None:
                continue
            ms_c = ctrl["percent"].get("meaningful_success", 0.0)
            ms_p = c["percent"].get("meaningful_success", 0.0)
            tc = th.get(f"{food}_control", {}).get("meaningful_success", 0.0)
            tp = th.get(f"{food}_primitive", {}).get("meaningful_success")
            thesis = (f"meaningful success {tp:g} % with the primitive vs {tc:g} % control"
                      if tp is not None else "not given")
            constant = ms_c == ms_p and ms_c in (0.0, 100.0)
            test, size, others, verdict = _judge(
                comp, tests["exp2c"], (tp - tc) / 100 if tp is not None else None, +1,
                alpha, constant, "points")
            out.append(Verdict(
                "H2", "Fig. 6.4", f"{food}: {name} raises meaningful success over control",
                thesis + (" (open loop; the thesis had no closed loop)"
                          if cond == "closed_loop" else ""),
                f"{ms_p:.0f} % vs {ms_c:.0f} % (n {c['n']} / {ctrl['n']})", test, size,
                others, verdict))
    return out


def _exp3(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float, tests: Mapping[str, Any]
          ) -> list[Verdict]:
    a, b = s["systems"].get("articutool"), s["systems"].get("baseline")
    if not a or not b or not a["n"] or not b["n"]:
        return []
    ta, tb = th.get("articutool", {}), th.get("baseline", {})
    na, nb = thesis_trials(ta), thesis_trials(tb)
    out = []
    ms_a, ms_b = (x["counts"]["meaningful_success"] for x in (a, b))
    no_food = not a["delivered_g"].get("mean") and not b["delivered_g"].get("mean")
    given = bool(na and nb and "meaningful_success" in ta and "meaningful_success" in tb)
    test, size, others, verdict = _judge(
        s.get("compare_meaningful"), tests["exp3_success"],
        ta["meaningful_success"] / na - tb["meaningful_success"] / nb if given else None, +1,
        alpha, no_food, "points")
    out.append(Verdict(
        "H3", "Fig. 6.5", "noodles end to end: the Articutool has more meaningful successes",
        f"{ta.get('meaningful_success')}/{na} vs {tb.get('meaningful_success')}/{nb}"
        + (f" (> {th['threshold_g']:g} g)" if "threshold_g" in th else ""),
        f"{ms_a}/{a['n']} vs {ms_b}/{b['n']}"
        + (f" (> {s['threshold_g']:.2f} g)" if s.get("threshold_g") is not None else "")
        + f"; delivered {_msd(a['delivered_g'])} vs {_msd(b['delivered_g'])}", test, size,
        others, verdict))
    ok_a = ta.get("meaningful_success", 0) + ta.get("trivial_success", 0)
    ok_b = tb.get("meaningful_success", 0) + tb.get("trivial_success", 0)
    ns_a, ns_b = a["no_spill"]["k"], b["no_spill"]["k"]
    test, size, others, verdict = _judge(
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
    test, size, others, verdict = _judge(
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


def verdicts(summaries: Mapping[str, Mapping[str, Any]], thesis: Mapping[str, Any],
             alpha: float, tests: Mapping[str, Any]) -> list[Verdict]:
    """One :class:`Verdict` per claim, in the thesis' order (H1, H2, H3). ``summaries`` maps
    an experiment (``exp1``, ``exp2a``, ``exp2b``, ``exp2c``, ``exp3``) to its summary
    (:mod:`articutool.experiments.analysis`); ``tests`` is ``experiments.toml [tests]``, the
    pre-registered test of each kind of claim. A missing experiment gives one "cannot test"
    row saying so."""
    rules = (("exp1", "H1", "Fig. 6.1", _exp1), ("exp2a", "H2", "Fig. 6.2", _exp2a),
             ("exp2b", "H2", "Fig. 6.3", _exp2b), ("exp2c", "H2", "Fig. 6.4", _exp2c),
             ("exp3", "H3", "Fig. 6.5", _exp3))
    out: list[Verdict] = []
    for exp, h, fig, rule in rules:
        s = summaries.get(exp)
        rows = rule(s, thesis.get(exp, {}), alpha, tests) if s else []
        why = ("not run" if not s else "run, but no comparison could be formed (Exp. 2c "
               "needs outcome thresholds: Exp. 1's means or --thresholds-g)")
        out += rows or [Verdict(h, fig, f"{exp}'s claims", "", why, "", "", "",
                                "cannot test")]
    return out


def code_versions(summaries: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, int]]:
    """Per experiment, how many trials ran on each code version (``run.sources``)."""
    return {exp: dict(s.get("run", {}).get("sources", {})) for exp, s in summaries.items()}
