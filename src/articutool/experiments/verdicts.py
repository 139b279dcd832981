"""What our simulation says about each of the thesis' hypotheses and figures (pure): the
rules every claim is judged by.

The thesis (Ch. 6) makes comparative claims; each is a direction (the Articutool, the
decoupled planner or a primitive does better) with a size (its difference). Each experiment's
``verdicts`` (:meth:`articutool.experiments.unit.Experiment.verdicts`, gathered by
:func:`articutool.experiments.report.verdicts`) judges our measurement with :func:`judge`: the
test pre-registered for the claim's kind of measurement (``experiments.toml [tests]``) and the
95 % interval of our difference:

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

__all__ = ["TEST_NAMES", "VERDICTS", "Verdict", "code_versions", "decide", "judge",
           "mean_sd_g"]

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


def mean_sd_g(d: Mapping[str, Any]) -> str:
    """A summary statistic of grams as a claim's row shows it."""
    if d.get("mean") is None:
        return f"no data (n {d.get('n', 0)})"
    return f"{d['mean']:.2f} ± {d['sd'] or 0.0:.2f} g (n {d['n']})"


def _attr(pre: Any, name: str) -> str:
    return str(pre[name] if isinstance(pre, Mapping) else getattr(pre, name))


def judge(comp: Mapping[str, Any] | None, pre: Any, thesis: float | None, direction: int,
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


def code_versions(summaries: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, int]]:
    """Per experiment, how many trials ran on each code version (``run.sources``)."""
    return {exp: dict(s.get("run", {}).get("sources", {})) for exp, s in summaries.items()}
