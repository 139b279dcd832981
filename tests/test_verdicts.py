"""The report's per-hypothesis verdicts: decided from our measurement's direction and
test, never from the thesis' numbers."""

from __future__ import annotations

import dataclasses
from typing import Any

from hypothesis import given
from hypothesis import strategies as st

from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.stats import describe, welch
from articutool.experiments.verdicts import verdicts
from conftest import trial_record

CFG = ExperimentsConfig.load()
ALPHA = CFG.settings.alpha


def _exp1(a: list[float], b: list[float]) -> dict:
    w = welch(a, b)
    return {"acquired_g": {"pecans": {"articutool": describe(a).to_dict(),
                                      "baseline": describe(b).to_dict(),
                                      "welch": w.to_dict()}}}


def _one(summaries: dict, exp: str = "exp1") -> str:
    rows = [v for v in verdicts(summaries, CFG.thesis, ALPHA) if v.figure == "Fig. 6.1"]
    assert len(rows) == 1
    return rows[0].verdict


def test_clear_difference_in_the_thesis_direction_is_reproduced_and_reversed_is_contradicted():
    more, less = [3.0, 3.2, 2.9, 3.1, 3.0], [1.0, 1.1, 0.9, 1.0, 1.2]
    assert _one({"exp1": _exp1(more, less)}) == "reproduced"
    assert _one({"exp1": _exp1(less, more)}) == "contradicted"


def test_no_food_in_either_system_cannot_test_the_claim():
    assert _one({"exp1": _exp1([0.0] * 5, [0.0] * 5)}) == "cannot test"


def test_overlapping_samples_are_not_reproduced():
    assert _one({"exp1": _exp1([1.0, 2.0, 3.0, 1.5], [1.2, 2.2, 2.8, 1.4])}) == "not reproduced"


def test_a_missing_experiment_is_listed_as_not_run():
    rows = verdicts({}, CFG.thesis, ALPHA)
    assert {v.hypothesis for v in rows} == {"H1", "H2", "H3"}
    assert all(v.verdict == "cannot test" and v.ours == "not run" for v in rows)


def test_the_thesis_numbers_never_decide():
    s = {"exp1": _exp1([3.0, 3.2, 2.9, 3.1], [1.0, 1.1, 0.9, 1.0])}
    flipped = {k: dict(v) for k, v in CFG.thesis.items()}
    flipped["exp1"] = {"pecans": {"articutool": [0.1, 0.0], "baseline": [99.0, 1.0], "p": "1"}}
    a = [dataclasses.replace(v, thesis="") for v in verdicts(s, CFG.thesis, ALPHA)]
    b = [dataclasses.replace(v, thesis="") for v in verdicts(s, flipped, ALPHA)]
    assert a == b


samples = st.lists(st.floats(0.0, 20.0, allow_nan=False), min_size=3, max_size=12)


@given(samples, samples)
def test_swapping_the_systems_swaps_reproduced_and_contradicted(a, b):
    one, other = _one({"exp1": _exp1(a, b)}), _one({"exp1": _exp1(b, a)})
    swap = {"reproduced": "contradicted", "contradicted": "reproduced"}
    assert other == swap.get(one, one)


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
    row = next(v for v in verdicts(s, CFG.thesis, ALPHA) if v.figure == "Fig. 6.4")
    assert row.verdict == "cannot test" and "thresholds" in row.ours


def test_the_thesis_exp3_counts_are_read_out_of_its_own_trials_not_out_of_20():
    from articutool.experiments.verdicts import thesis_trials

    th = {"articutool": {"meaningful_success": 6, "trivial_success": 1, "table_spill": 2,
                         "user_spill": 1, "planning_attempts": 1.2},
          "baseline": {"meaningful_success": 1, "trivial_success": 3, "table_spill": 4,
                       "user_spill": 2, "planning_attempts": 2.0}}
    assert thesis_trials(th["articutool"]) == 10
    side = {"n": 4, "counts": {"meaningful_success": 2}, "no_spill": {"k": 4},
            "delivered_g": {"mean": 1.0, "sd": 0.0, "n": 4}, "planning_attempts": {"mean": None}}
    s = {"exp3": {"systems": {"articutool": side, "baseline": side}}}
    rows = [v for v in verdicts(s, {**CFG.thesis, "exp3": th}, ALPHA) if v.figure == "Fig. 6.5"]
    assert rows[0].thesis == "6/10 vs 1/10"
    assert rows[1].thesis == "7/10 vs 4/10 without spill"
