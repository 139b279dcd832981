"""The report's per-hypothesis verdicts: the direction and significance of our
measurement by the pre-registered test, and the size against the thesis' difference."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.experiments.analysis import compare_samples
from articutool.experiments.config import ExperimentsConfig, ExperimentsConfigError
from articutool.experiments.exp2a import summarize_exp2a
from articutool.experiments.report import verdicts
from articutool.experiments.stats import describe, welch
from articutool.experiments.verdicts import VERDICTS, decide
from conftest import trial_record

CFG = ExperimentsConfig.load()
ALPHA = CFG.settings.alpha
SIGNED = {"reproduced", "reproduced in sign only"}


def _exp1(a: list[float], b: list[float]) -> dict:
    return {"acquired_g": {"pecans": {"articutool": describe(a).to_dict(),
                                      "baseline": describe(b).to_dict(),
                                      "welch": welch(a, b).to_dict(),
                                      "compare": compare_samples(a, b)}}}


def _thesis(diff: float) -> dict:
    """The packaged thesis numbers with Exp. 1 pecans' difference set to ``diff``."""
    return {**CFG.thesis, "exp1": {"pecans": {"articutool": [1.0 + diff, 0.1],
                                              "baseline": [1.0, 0.1], "p": "0.01"}}}


def _one(summaries: dict, thesis: dict | None = None) -> str:
    rows = [v for v in verdicts(summaries, thesis or CFG.thesis, ALPHA, CFG.tests)
            if v.figure == "Fig. 6.1"]
    assert len(rows) == 1
    return rows[0].verdict


MORE, LESS = [3.0, 3.2, 2.9, 3.1, 3.0], [1.0, 1.1, 0.9, 1.0, 1.2]


def test_a_clear_difference_of_the_thesis_size_is_reproduced_and_reversed_contradicted():
    s = {"exp1": _exp1(MORE, LESS)}  # +2.0 g, Welch interval about [1.8, 2.2]
    assert _one(s, _thesis(2.0)) == "reproduced"
    assert _one({"exp1": _exp1(LESS, MORE)}, _thesis(2.0)) == "contradicted"


def test_significant_in_the_thesis_direction_but_far_from_its_size_is_sign_only():
    # The Exp. 1 water case: ours +2.28 g where the thesis' +4.34 g is outside our interval.
    s = {"exp1": _exp1(MORE, LESS)}
    assert _one(s, _thesis(6.0)) == "reproduced in sign only"
    assert _one(s, _thesis(0.5)) == "reproduced in sign only"


def test_no_food_in_either_system_cannot_test_the_claim():
    assert _one({"exp1": _exp1([0.0] * 5, [0.0] * 5)}) == "cannot test"


def test_overlapping_samples_are_not_reproduced():
    assert _one({"exp1": _exp1([1.0, 2.0, 3.0, 1.5], [1.2, 2.2, 2.8, 1.4])}) == "not reproduced"


def test_a_missing_experiment_is_listed_as_not_run():
    rows = verdicts({}, CFG.thesis, ALPHA, CFG.tests)
    assert {v.hypothesis for v in rows} == {"H1", "H2", "H3"}
    assert {v.figure for v in rows} >= {"Fig. 6.2", "Fig. 6.3"}  # Exp. 2a and 2b
    assert all(v.verdict == "cannot test" and v.ours == "not run" for v in rows)


samples = st.lists(st.floats(0.0, 20.0, allow_nan=False), min_size=3, max_size=12)
diffs = st.floats(-30.0, 30.0, allow_nan=False)


@settings(max_examples=40, deadline=None)  # each example bootstraps twice
@given(samples, samples, diffs)
def test_the_thesis_numbers_decide_only_the_size(a, b, diff):
    # Direction and significance are ours: another thesis difference can only move a claim
    # between reproduced and reproduced in sign only.
    s = {"exp1": _exp1(a, b)}
    one, other = _one(s, _thesis(diff)), _one(s, _thesis(-diff))
    assert one == other or {one, other} <= SIGNED


@settings(max_examples=40, deadline=None)  # each example bootstraps twice
@given(samples, samples, diffs)
def test_swapping_the_systems_flips_the_sign_verdicts(a, b, diff):
    one, other = _one({"exp1": _exp1(a, b)}, _thesis(diff)), _one({"exp1": _exp1(b, a)},
                                                                  _thesis(diff))
    if one in SIGNED:
        assert other == "contradicted"
    elif one == "contradicted":
        assert other in SIGNED
    else:
        assert other == one


def test_the_thesis_difference_at_the_intervals_edge_is_inside():
    ci = (0.4, 1.2)
    assert decide(0.8, ci, 0.4, 0.01, ALPHA) == "reproduced"
    assert decide(0.8, ci, 1.2, 0.01, ALPHA) == "reproduced"
    assert decide(0.8, ci, math.nextafter(1.2, 2.0), 0.01, ALPHA) == "reproduced in sign only"
    assert decide(0.8, ci, math.nextafter(0.4, 0.0), 0.01, ALPHA) == "reproduced in sign only"
    assert decide(0.8, ci, None, 0.01, ALPHA) == "reproduced in sign only"  # no number
    assert decide(0.8, ci, 0.8, ALPHA, ALPHA) == "not reproduced"  # p = α is not < α


effects = st.floats(-5.0, 5.0, allow_nan=False)
ps = st.floats(0.0, 1.0, allow_nan=False)


@given(effects, st.tuples(effects, effects), effects, ps, ps)
def test_a_smaller_p_never_weakens_a_verdict(eff, ci, thesis, p1, p2):
    lo, hi = sorted(ci)
    low, high = sorted((p1, p2))
    strong, weak = (decide(eff, (lo, hi), thesis, p, ALPHA) for p in (low, high))
    assert weak in (strong, "not reproduced")


@given(effects, st.tuples(effects, effects), st.lists(effects, min_size=3, max_size=3), ps)
def test_the_thesis_values_reproduced_form_our_interval(eff, ci, ts, p):
    lo, hi = sorted(ci)
    t1, t2, t3 = sorted(ts)
    v = [decide(eff, (lo, hi), t, p, ALPHA) for t in (t1, t2, t3)]
    assert all(x in VERDICTS for x in v)
    if v[0] == v[2] == "reproduced":
        assert v[1] == "reproduced"
    if v[1] == "reproduced":
        assert lo <= t2 <= hi


def test_exp2b_is_judged_by_its_pre_registered_rank_test_not_welch():
    # Zero-inflated spills (the Exp. 2b water case): Welch on the means does not separate
    # them, Mann–Whitney does; the pre-registered test decides, Welch is printed beside.
    assert CFG.tests["exp2b"].test == "mann_whitney"
    art, base = [0.0] * 20, [0.0] * 9 + [0.02, 0.05, 0.01, 0.13, 0.03, 0.1, 0.04, 0.01,
                                         2.6, 0.06, 0.02, 0.03]
    s = {"exp2b": {"spilled_g": {"water": {
        "articutool": {**describe(art).to_dict(), "nonzero": {"k": 0}},
        "baseline": {**describe(base).to_dict(), "nonzero": {"k": 11}},
        "compare": compare_samples(art, base)}}}}
    row = next(v for v in verdicts(s, CFG.thesis, ALPHA, CFG.tests) if v.figure == "Fig. 6.3")
    assert row.test.startswith("Mann–Whitney") and "Welch" in row.others
    assert welch(art, base).p > ALPHA
    assert row.verdict == "reproduced in sign only"  # the thesis' −1.31 g is outside
    assert "thesis -1.31 g" in row.size


def _bench(system: str, task: int, ok: bool, t: float) -> dict[str, Any]:
    return {"system": system, "task_id": task, "seed": 0, "tolerance_deg": None,
            "success": ok, "planning_time_s": t}


def test_exp2a_success_and_time_claims_join_the_table():
    recs = ([_bench("decoupled", k, True, 0.010 + 1e-4 * k) for k in range(30)]
            + [_bench("strict6", k, k >= 3, 0.100 + 1e-3 * k) for k in range(30)])
    s = summarize_exp2a(recs, 60.0)
    rows = [v for v in verdicts({"exp2a": s}, CFG.thesis, ALPHA, CFG.tests)
            if v.figure == "Fig. 6.2"]
    assert [r.claim.split(": ")[1].split(" than")[0] for r in rows] == [
        "the decoupled planner solves more tasks", "the decoupled planner plans faster"]
    time = rows[1]
    assert time.test.startswith("Mann–Whitney") and "Wilcoxon" in time.others
    assert time.size.startswith("10×")  # strict6's median over the decoupled one's
    assert time.verdict == "reproduced in sign only"  # the thesis' 7.7× is outside
    assert rows[0].thesis.startswith("96.0 % vs 86.0 %")


def test_a_pre_registration_must_fit_its_test_and_cover_every_claim(tmp_path):
    from articutool.experiments.config import default_experiments_path

    text = default_experiments_path().read_text()
    bad = text.replace('test = "fisher"\nci = "newcombe"', 'test = "fisher"\nci = "welch"', 1)
    assert bad != text
    (tmp_path / "bad.toml").write_text(bad)
    with pytest.raises(ExperimentsConfigError, match="ci"):
        ExperimentsConfig.load(tmp_path / "bad.toml")
    gone = text.replace("[tests.exp3_attempts]", "[tests.exp3_attempts_old]")
    (tmp_path / "gone.toml").write_text(gone)
    with pytest.raises(ExperimentsConfigError, match="exp3_attempts"):
        ExperimentsConfig.load(tmp_path / "gone.toml")


def _rec(trial: int, food_g: float, spilled: float, system: str = "articutool") -> Any:
    return trial_record("exp1", trial, food="water", system=system, acquired_g=food_g,
                        spilled_g=spilled)


@given(st.permutations(list(range(7))))
def test_replay_picks_do_not_depend_on_the_logs_order(order):
    from articutool.experiments.analysis import representative_trials

    recs = [_rec(0, 1.0, 0.0), _rec(1, 2.0, 0.0), _rec(2, 3.0, 0.5), _rec(3, 2.0, 0.0),
            _rec(4, 9.0, 0.0), _rec(5, 0.0, 0.5), _rec(6, 1.0, 0.0, "baseline")]
    picks = representative_trials([recs[i] for i in order])
    # median 2.0 g: trials 1 and 3 tie, the lower number wins; the worst spilled most
    # (trials 2 and 5 spilled 0.5 g) and, of those, kept the least food.
    assert picks["water articutool"] == {"typical": 1, "worst": 5}
    assert picks["water baseline"] == {"typical": 6, "worst": 6}


def test_exp2c_without_thresholds_says_so_rather_than_not_run():
    s = {"exp2c": {"thresholds_g": None, "foods": {}}}
    row = next(v for v in verdicts(s, CFG.thesis, ALPHA, CFG.tests) if v.figure == "Fig. 6.4")
    assert row.verdict == "cannot test" and "thresholds" in row.ours


def test_the_thesis_exp3_counts_are_read_out_of_its_own_trials_not_out_of_20():
    from articutool.experiments.units.exp3 import thesis_trials

    th = {"articutool": {"meaningful_success": 6, "trivial_success": 1, "table_spill": 2,
                         "user_spill": 1, "planning_attempts": 1.2},
          "baseline": {"meaningful_success": 1, "trivial_success": 3, "table_spill": 4,
                       "user_spill": 2, "planning_attempts": 2.0}}
    assert thesis_trials(th["articutool"]) == 10
    side = {"n": 4, "counts": {"meaningful_success": 2}, "no_spill": {"k": 4},
            "delivered_g": {"mean": 1.0, "sd": 0.0, "n": 4}, "planning_attempts": {"mean": None}}
    s = {"exp3": {"systems": {"articutool": side, "baseline": side}}}
    rows = [v for v in verdicts(s, {**CFG.thesis, "exp3": th}, ALPHA, CFG.tests)
            if v.figure == "Fig. 6.5"]
    assert rows[0].thesis == "6/10 vs 1/10"
    assert rows[1].thesis == "7/10 vs 4/10 without spill"
