"""The experiments' statistics against scipy and textbook values, and their edge cases."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats as sst

from articutool.experiments.stats import describe, fisher, proportion_ci, welch

finite = st.floats(-100, 100, allow_nan=False, allow_infinity=False)
samples = st.lists(finite, min_size=2, max_size=30)


def test_describe_matches_the_t_interval_of_scipy() -> None:
    x = [1.2, 2.5, 1.9, 3.1, 2.2, 1.7]
    d = describe(x)
    lo, hi = sst.t.interval(0.95, len(x) - 1, loc=np.mean(x), scale=sst.sem(x))
    assert d.n == 6 and d.mean == pytest.approx(np.mean(x))
    assert d.sd == pytest.approx(np.std(x, ddof=1))
    assert (d.ci_low, d.ci_high) == pytest.approx((lo, hi))


def test_describe_degenerate_samples() -> None:
    assert describe([]).n == 0 and math.isnan(describe([]).mean)
    one = describe([2.0])
    assert one.mean == 2.0 and math.isnan(one.sd) and one.to_dict()["sd"] is None
    const = describe([1.0, 1.0, 1.0])
    assert const.sd == 0.0 and const.ci_low == const.ci_high == 1.0
    with pytest.raises(ValueError, match="finite"):
        describe([1.0, math.nan])


@settings(max_examples=60, deadline=None)
@given(samples)
def test_the_mean_lies_inside_its_interval(x: list[float]) -> None:
    d = describe(x)
    assert d.ci_low - 1e-9 <= d.mean <= d.ci_high + 1e-9
    assert d.ci_high - d.mean == pytest.approx(d.mean - d.ci_low, abs=1e-9)


def test_welch_matches_scipy_and_the_welch_satterthwaite_df() -> None:
    a = [1.83, 2.4, 1.1, 2.0, 1.6, 2.9, 1.2]
    b = [1.32, 0.9, 1.5, 1.1, 0.7]
    r = welch(a, b)
    ref = sst.ttest_ind(a, b, equal_var=False)
    assert r.t == pytest.approx(ref.statistic) and r.p == pytest.approx(ref.pvalue)
    va, vb = np.var(a, ddof=1) / 7, np.var(b, ddof=1) / 5
    assert r.df == pytest.approx((va + vb) ** 2 / (va**2 / 6 + vb**2 / 4))


def test_welch_known_value() -> None:
    # Two samples of 3 with means 2 and 5, SD 1 each: t = -3/sqrt(2/3), df = 4.
    r = welch([1, 2, 3], [4, 5, 6])
    assert r.t == pytest.approx(-3.0 / math.sqrt(2.0 / 3.0))
    assert r.df == pytest.approx(4.0)
    assert r.p == pytest.approx(2 * sst.t.sf(abs(r.t), 4))


@pytest.mark.filterwarnings("ignore:Precision loss")  # scipy, on nearly equal samples
@settings(max_examples=40, deadline=None)
@given(samples, samples)
def test_welch_is_symmetric(a: list[float], b: list[float]) -> None:
    r1, r2 = welch(a, b), welch(b, a)
    if math.isnan(r1.p):
        assert math.isnan(r2.p)
    else:
        assert r1.p == pytest.approx(r2.p) and r1.t == pytest.approx(-r2.t)


def test_welch_degenerate_groups_give_nan_with_a_reason() -> None:
    assert "fewer than two" in welch([1.0], [1.0, 2.0]).note
    r = welch([0.0] * 5, [0.0] * 5)
    assert math.isnan(r.p) and "no variance" in r.note and r.to_dict()["p"] is None


def test_fisher_matches_scipy_and_a_known_value() -> None:
    r = fisher(18, 20, 0, 20)  # the thesis' Exp. 2c pecans shape (90 % vs 0 %)
    ref = sst.fisher_exact([[18, 2], [0, 20]])
    assert r.p == pytest.approx(ref.pvalue) and r.table == ((18, 2), (0, 20))
    # Fisher's tea-tasting table [[3, 1], [1, 3]]: two-sided p = 34/70.
    assert fisher(3, 4, 1, 4).p == pytest.approx(34 / 70)
    assert fisher(5, 5, 5, 5).p == pytest.approx(1.0)
    assert math.isnan(fisher(0, 0, 1, 2).p)


def test_fisher_refuses_impossible_tables() -> None:
    with pytest.raises(ValueError, match="exceed"):
        fisher(3, 2, 0, 1)
    with pytest.raises(ValueError, match="a_n"):
        fisher(0, -1, 0, 1)


def test_wilson_interval_known_values() -> None:
    lo, hi = proportion_ci(0, 20)
    assert lo == pytest.approx(0.0, abs=1e-12) and hi == pytest.approx(0.1611, abs=1e-4)
    lo, hi = proportion_ci(14, 20)
    assert (lo, hi) == pytest.approx((0.4810, 0.8545), abs=1e-4)
    assert all(math.isnan(v) for v in proportion_ci(0, 0))
