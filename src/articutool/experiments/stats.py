"""The statistics of the thesis' experiments, pure (thesis Ch. 6).

scipy.stats is the engine; these functions fix the conventions the thesis uses and return
plain, JSON-ready dataclasses:

- :func:`describe` — mean ± sample SD (ddof = 1) and the 95 % confidence interval of the mean
  from Student's t (the error bars of Fig. 6.1);
- :func:`welch` — Welch's unequal-variance two-sample t-test, two-sided (Exp. 1, Exp. 2b);
- :func:`fisher` — Fisher's exact test on a 2×2 table of successes and failures, two-sided
  (Exp. 2c, Exp. 3);
- :func:`proportion_ci` — the Wilson score interval of a success rate.

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
from scipy import stats as _st

__all__ = ["Describe", "FisherResult", "WelchResult", "describe", "fisher", "proportion_ci",
           "welch"]


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
