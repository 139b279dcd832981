"""The statistics of the thesis' experiments, pure (thesis Ch. 6).

scipy.stats is the engine; these functions fix the conventions the thesis uses and return
plain, JSON-ready dataclasses:

- :func:`describe` — mean ± sample SD (ddof = 1) and the 95 % confidence interval of the mean
  from Student's t (the error bars of Fig. 6.1);
- :func:`welch` — Welch's unequal-variance two-sample t-test, two-sided (Exp. 1, Exp. 2b);
- :func:`fisher` — Fisher's exact test on a 2×2 table of successes and failures, two-sided
  (Exp. 2c, Exp. 3);
- :func:`proportion_ci` — the Wilson score interval of a success rate;
- :func:`mann_whitney` — the Mann–Whitney U test, two-sided (skewed or zero-inflated samples);
- :func:`boschloo` — Boschloo's exact test on a 2×2 table, two-sided (printed beside Fisher);
- :func:`wilcoxon_paired` — the Wilcoxon signed-rank test of paired samples, two-sided;
- the size of a difference with its confidence interval (:class:`Effect`):
  :func:`welch_ci` (difference of means, Welch's t), :func:`bootstrap_ci` (difference of
  means or ratio of medians, bias-corrected and accelerated bootstrap) and
  :func:`newcombe_ci` (difference of proportions, Newcombe's hybrid score interval built
  from the two Wilson intervals, his method 10).

Degenerate samples (fewer than two values, zero variance in both groups) give ``nan`` p-values
and intervals rather than errors, and say so in ``note``: an experiment run with one trial per
condition still reports.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np


class _LazyScipyStats:
    """``scipy.stats``, imported on first use: the command line's parser, which registers
    the experiments, builds on an install without scipy (the onboard one)."""

    def __getattr__(self, name: str) -> Any:
        from scipy import stats

        return getattr(stats, name)


_st = _LazyScipyStats()

__all__ = [
    "Describe",
    "Effect",
    "FisherResult",
    "WelchResult",
    "bootstrap_ci",
    "boschloo",
    "describe",
    "fisher",
    "mann_whitney",
    "newcombe_ci",
    "proportion_ci",
    "welch",
    "welch_ci",
    "wilcoxon_paired",
]


def _clean(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


@dataclass(frozen=True)
class Describe:
    """Summary of one sample: n, mean, SD (ddof 1), 95 % CI of the mean (t)."""

    n: int
    mean: float
    sd: float
    ci_low: float
    ci_high: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (``nan`` becomes ``None``)."""
        return {k: (_clean(v) if isinstance(v, float) else v) for k, v in asdict(self).items()}


def describe(values: Sequence[float], confidence: float = 0.95) -> Describe:
    """Mean, sample SD and the t-based ``confidence`` interval of the mean.

    One value: SD and CI are ``nan``; no values: everything is ``nan``. A constant sample
    has a zero-width interval."""
    x = np.asarray(values, dtype=float)
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1); got {confidence}")
    if x.size == 0:
        return Describe(0, math.nan, math.nan, math.nan, math.nan)
    if not np.isfinite(x).all():
        raise ValueError("values must be finite")
    mean = float(x.mean())
    if x.size < 2:
        return Describe(1, mean, math.nan, math.nan, math.nan)
    sd = float(x.std(ddof=1))
    half = float(_st.t.ppf(0.5 + confidence / 2, x.size - 1)) * sd / math.sqrt(x.size)
    return Describe(int(x.size), mean, sd, mean - half, mean + half)


@dataclass(frozen=True)
class WelchResult:
    """Welch's t-test of ``a`` against ``b`` (two-sided)."""

    t: float
    df: float
    p: float
    note: str = ""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (``nan`` becomes ``None``)."""
        return {"t": _clean(self.t), "df": _clean(self.df), "p": _clean(self.p),
                "note": self.note}


def welch(a: Sequence[float], b: Sequence[float]) -> WelchResult:
    """Welch's unequal-variance t-test, two-sided (``scipy.stats.ttest_ind(equal_var=False)``).

    Degrees of freedom by the Welch–Satterthwaite equation. Fewer than two values in a group,
    or no variance in either, gives ``nan`` with a ``note`` (two identical constant groups are
    not different; two different constants are, but no t-test says by how much)."""
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if x.size < 2 or y.size < 2:
        return WelchResult(math.nan, math.nan, math.nan, "fewer than two values in a group")
    vx, vy = x.var(ddof=1) / x.size, y.var(ddof=1) / y.size
    if vx + vy == 0:
        return WelchResult(math.nan, math.nan, math.nan,
                           "no variance in either group (both constant)")
    r = _st.ttest_ind(x, y, equal_var=False)
    df = (vx + vy) ** 2 / (vx**2 / (x.size - 1) + vy**2 / (y.size - 1))
    return WelchResult(float(r.statistic), float(df), float(r.pvalue))


@dataclass(frozen=True)
class FisherResult:
    """Fisher's exact test on ``[[a_success, a_failure], [b_success, b_failure]]``."""

    table: tuple[tuple[int, int], tuple[int, int]]
    odds_ratio: float
    p: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (``inf``/``nan`` become ``None``)."""
        return {"table": [list(r) for r in self.table], "odds_ratio": _clean(self.odds_ratio),
                "p": _clean(self.p)}


def fisher(a_success: int, a_n: int, b_success: int, b_n: int) -> FisherResult:
    """Fisher's exact test (two-sided) of the success rate of group a against group b."""
    for name, v in (("a_success", a_success), ("a_n", a_n), ("b_success", b_success),
                    ("b_n", b_n)):
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 0:
            raise ValueError(f"{name} must be an integer >= 0; got {v!r}")
    if a_success > a_n or b_success > b_n:
        raise ValueError("successes cannot exceed trials")
    table = ((int(a_success), int(a_n - a_success)), (int(b_success), int(b_n - b_success)))
    if a_n == 0 or b_n == 0:
        return FisherResult(table, math.nan, math.nan)
    r = _st.fisher_exact(table, alternative="two-sided")
    return FisherResult(table, float(r.statistic), float(r.pvalue))


def proportion_ci(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of ``successes / n`` (``(nan, nan)`` for n = 0)."""
    if n == 0:
        return (math.nan, math.nan)
    if not 0 <= successes <= n:
        raise ValueError(f"successes must be in [0, {n}]; got {successes}")
    r = _st.binomtest(int(successes), int(n)).proportion_ci(confidence_level=confidence,
                                                             method="wilson")
    return (float(r.low), float(r.high))


# ------------------------------------------------------------ sizes of differences --
BOOTSTRAP_RESAMPLES = 9999
BOOTSTRAP_SEED = 0  # fixed, so a report regenerated from the same records is the same


@dataclass(frozen=True)
class Effect:
    """The size of a difference between group a and group b, with its ``confidence``
    interval: ``kind`` is ``"difference"`` (a − b: means or proportions) or ``"ratio"``
    (a / b: medians); ``method`` says how the interval was formed. ``nan`` where it cannot
    be formed (a group empty, or both constant for an interval that needs spread)."""

    kind: str
    estimate: float
    ci_low: float
    ci_high: float
    method: str
    confidence: float = 0.95

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (``nan`` becomes ``None``)."""
        return {k: (_clean(v) if isinstance(v, float) else v) for k, v in asdict(self).items()}


def _two(a: Sequence[float], b: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise ValueError("values must be finite")
    return x, y


def welch_ci(a: Sequence[float], b: Sequence[float], confidence: float = 0.95) -> Effect:
    """Mean of ``a`` minus mean of ``b`` with Welch's t interval (unequal variances;
    ``scipy.stats.ttest_ind(equal_var=False).confidence_interval``). Two constant groups
    give a zero-width interval at their difference; fewer than two values in a group,
    ``nan``."""
    x, y = _two(a, b)
    method = "Welch's t (unequal variances)"
    if x.size < 2 or y.size < 2:
        est = float(x.mean() - y.mean()) if x.size and y.size else math.nan
        return Effect("difference", est, math.nan, math.nan, method, confidence)
    est = float(x.mean() - y.mean())
    if x.var() == 0 and y.var() == 0:
        return Effect("difference", est, est, est, method, confidence)
    ci = _st.ttest_ind(x, y, equal_var=False).confidence_interval(confidence_level=confidence)
    return Effect("difference", est, float(ci.low), float(ci.high), method, confidence)


def _mean_diff(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.mean(x, axis=axis) - np.mean(y, axis=axis)


def _log_median_ratio(x: np.ndarray, y: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.log(np.median(x, axis=axis)) - np.log(np.median(y, axis=axis))


def bootstrap_ci(a: Sequence[float], b: Sequence[float], statistic: str = "mean difference",
                 confidence: float = 0.95) -> Effect:
    """The bootstrap interval (``scipy.stats.bootstrap``, bias-corrected and accelerated,
    9 999 resamples of each group apart, a fixed seed) of ``statistic``: ``"mean
    difference"`` (mean of a − mean of b) or ``"median ratio"`` (median of a / median of
    b, resampled on the log scale; values must be > 0). Where BCa cannot be formed (a
    degenerate resample distribution) the percentile interval is used and ``method`` says
    so; constant groups give a zero-width interval; an empty group or a group of one value
    (with spread in the other), ``nan``."""
    x, y = _two(a, b)
    if statistic == "mean difference":
        kind, fn, back = "difference", _mean_diff, (lambda v: v)
    elif statistic == "median ratio":
        if (x <= 0).any() or (y <= 0).any():
            raise ValueError("a median ratio needs values > 0")
        kind, fn, back = "ratio", _log_median_ratio, math.exp
    else:
        raise ValueError(f"statistic must be 'mean difference' or 'median ratio'; got "
                         f"{statistic!r}")
    if x.size == 0 or y.size == 0:
        return Effect(kind, math.nan, math.nan, math.nan, "bootstrap", confidence)
    est = back(float(fn(x, y)))
    if np.ptp(x) == 0 and np.ptp(y) == 0:
        return Effect(kind, est, est, est, "constant groups: no spread to resample",
                      confidence)
    if x.size < 2 or y.size < 2:
        return Effect(kind, est, math.nan, math.nan, "bootstrap: a group of one value",
                      confidence)
    import warnings

    for method in ("BCa", "percentile"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a degenerate BCa says so; percentile follows
            r = _st.bootstrap((x, y), fn, vectorized=True, paired=False, method=method,
                              n_resamples=BOOTSTRAP_RESAMPLES, confidence_level=confidence,
                              rng=np.random.default_rng(BOOTSTRAP_SEED))
        lo, hi = float(r.confidence_interval.low), float(r.confidence_interval.high)
        if math.isfinite(lo) and math.isfinite(hi):
            name = ("bootstrap BCa" if method == "BCa" else "bootstrap percentile (BCa "
                    "degenerate)")
            return Effect(kind, est, back(lo), back(hi),
                          f"{name}, {BOOTSTRAP_RESAMPLES} resamples", confidence)
    return Effect(kind, est, math.nan, math.nan, "bootstrap (degenerate)", confidence)


def newcombe_ci(a_success: int, a_n: int, b_success: int, b_n: int,
                confidence: float = 0.95) -> Effect:
    """Rate of a minus rate of b with Newcombe's hybrid score interval (1998, method 10):
    from the Wilson intervals [l, u] of each rate (:func:`proportion_ci`),
    d − √((p_a − l_a)² + (u_b − p_b)²) to d + √((u_a − p_a)² + (p_b − l_b)²). It keeps
    within [−1, 1] and has width at 0/n and n/n, where Wald's interval collapses."""
    if a_n <= 0 or b_n <= 0:
        return Effect("difference", math.nan, math.nan, math.nan,
                      "Newcombe hybrid score (Wilson)", confidence)
    pa, pb = a_success / a_n, b_success / b_n
    la, ua = proportion_ci(a_success, a_n, confidence)
    lb, ub = proportion_ci(b_success, b_n, confidence)
    d = pa - pb
    return Effect("difference", d, d - math.hypot(pa - la, ub - pb),
                  d + math.hypot(ua - pa, pb - lb), "Newcombe hybrid score (Wilson)",
                  confidence)


def mann_whitney(a: Sequence[float], b: Sequence[float]) -> float:
    """Two-sided p of the Mann–Whitney U test (``scipy.stats.mannwhitneyu``, exact for
    small samples without ties, else the normal approximation with the tie correction);
    ``nan`` for an empty group or when every value of both groups is the same."""
    x, y = _two(a, b)
    if x.size == 0 or y.size == 0 or np.ptp(np.concatenate([x, y])) == 0:
        return math.nan
    return float(_st.mannwhitneyu(x, y, alternative="two-sided").pvalue)


def boschloo(a_success: int, a_n: int, b_success: int, b_n: int) -> float:
    """Two-sided p of Boschloo's exact test (``scipy.stats.boschloo_exact``), uniformly
    more powerful than Fisher's; ``nan`` when a group is empty or both rates are 0 or 1."""
    if a_n == 0 or b_n == 0 or a_success + b_success in (0, a_n + b_n):
        return math.nan
    table = [[a_success, b_success], [a_n - a_success, b_n - b_success]]
    return float(_st.boschloo_exact(table, alternative="two-sided").pvalue)


def wilcoxon_paired(a: Sequence[float], b: Sequence[float]) -> float:
    """Two-sided p of the Wilcoxon signed-rank test of the pairs (a[i], b[i])
    (``scipy.stats.wilcoxon``, zero differences dropped); ``nan`` when no pair differs."""
    x, y = _two(a, b)
    if x.size != y.size:
        raise ValueError("paired samples must have the same length")
    if not (x != y).any():
        return math.nan
    return float(_st.wilcoxon(x, y, alternative="two-sided").pvalue)
