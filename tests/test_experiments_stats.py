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


# ------------------------------------------------------------ sizes of differences --
def test_newcombe_matches_the_published_hybrid_score_intervals() -> None:
    from articutool.experiments.stats import newcombe_ci

    # Newcombe (1998), Stat. Med. 17:873, Table II, method 10: 56/70 − 48/80 and 9/10 − 3/10.
    e = newcombe_ci(56, 70, 48, 80)
    assert e.estimate == pytest.approx(0.2)
    assert (e.ci_low, e.ci_high) == pytest.approx((0.0524, 0.3339), abs=1e-4)
    e = newcombe_ci(9, 10, 3, 10)
    assert (e.ci_low, e.ci_high) == pytest.approx((0.1705, 0.8090), abs=1e-4)
    # At the floor and the ceiling it keeps width and stays inside [−1, 1].
    e = newcombe_ci(0, 20, 20, 20)
    assert e.ci_low == pytest.approx(-1.0) and -1.0 < e.ci_high < -0.5
    same = newcombe_ci(20, 20, 20, 20)
    assert same.ci_low < 0.0 < same.ci_high


def test_welch_ci_is_scipys_interval_of_the_difference_of_means() -> None:
    from articutool.experiments.stats import welch_ci

    a, b = [3.0, 3.4, 2.8, 3.9, 3.1], [1.0, 1.6, 0.7, 1.1]
    e = welch_ci(a, b)
    ref = sst.ttest_ind(a, b, equal_var=False).confidence_interval()
    assert e.estimate == pytest.approx(np.mean(a) - np.mean(b))
    assert (e.ci_low, e.ci_high) == pytest.approx((ref.low, ref.high))
    const = welch_ci([1.0, 1.0], [0.0, 0.0])
    assert const.ci_low == const.ci_high == 1.0


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(0, 10, allow_nan=False), min_size=3, max_size=15),
       st.lists(st.floats(0, 10, allow_nan=False), min_size=3, max_size=15))
def test_bootstrap_interval_holds_its_estimate_and_is_reproducible(a, b) -> None:
    from articutool.experiments.stats import bootstrap_ci

    e = bootstrap_ci(a, b)
    assert e.estimate == pytest.approx(np.mean(a) - np.mean(b))
    if math.isfinite(e.ci_low):
        assert e.ci_low <= e.estimate + 1e-9 and e.estimate - 1e-9 <= e.ci_high
    assert bootstrap_ci(a, b) == e  # a fixed seed: the same report from the same records


def test_bootstrap_of_a_zero_inflated_spill_and_a_ratio_of_medians() -> None:
    from articutool.experiments.stats import bootstrap_ci

    spills = [0.0] * 9 + [0.02, 0.05, 0.01, 0.13, 0.03, 0.1, 0.04, 0.01, 2.6, 0.06, 0.02, 0.03]
    e = bootstrap_ci([0.0] * 20, spills)
    assert e.ci_high < 0.0 < -e.ci_low and "bootstrap" in e.method
    r = bootstrap_ci([2.0, 4.0, 6.0, 8.0, 10.0], [1.0, 2.0, 3.0, 4.0, 5.0], "median ratio")
    assert r.kind == "ratio" and r.estimate == pytest.approx(2.0)
    assert r.ci_low <= 2.0 <= r.ci_high
    with pytest.raises(ValueError, match="> 0"):
        bootstrap_ci([0.0, 1.0], [1.0, 2.0], "median ratio")


def test_rank_and_exact_tests_against_scipy_and_their_degenerate_cases() -> None:
    from articutool.experiments.stats import boschloo, mann_whitney, wilcoxon_paired

    a, b = [0.0] * 10 + [0.1, 0.4], [0.0] * 3 + [0.2, 0.5, 0.3, 0.9, 0.1, 0.6, 0.2, 0.4, 0.7]
    assert mann_whitney(a, b) == pytest.approx(sst.mannwhitneyu(a, b).pvalue)
    assert math.isnan(mann_whitney([0.0] * 4, [0.0] * 4))  # nothing to rank
    assert boschloo(9, 10, 3, 10) == pytest.approx(
        sst.boschloo_exact([[9, 3], [1, 7]]).pvalue)
    assert boschloo(9, 10, 3, 10) <= fisher(9, 10, 3, 10).p  # Boschloo is at least as strong
    assert math.isnan(boschloo(20, 20, 20, 20))
    assert wilcoxon_paired([1.0, 2.0, 3.5, 4.0], [1.5, 2.5, 3.0, 5.0]) == pytest.approx(
        sst.wilcoxon([1.0, 2.0, 3.5, 4.0], [1.5, 2.5, 3.0, 5.0]).pvalue)
    assert math.isnan(wilcoxon_paired([1.0, 2.0], [1.0, 2.0]))
