"""The Exp. 3 outcome hierarchy at its boundaries."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from articutool.feeding.outcomes import OUTCOMES, classify_bite


def test_exactly_at_the_threshold_is_trivial_and_just_above_is_meaningful() -> None:
    assert classify_bite(3.0, {}, 3.0) == "trivial_success"
    assert classify_bite(3.0 + 1e-6, {}, 3.0) == "meaningful_success"


def test_one_piece_on_the_table_is_a_table_spill_whatever_was_delivered() -> None:
    assert classify_bite(9.0, {"table": 0.92}, 3.0) == "table_spill"


def test_user_spill_dominates_table_spill_and_failure() -> None:
    assert classify_bite(9.0, {"table": 5.0, "critical": 0.42}, 3.0) == "user_spill"
    assert classify_bite(0.0, {"critical": 0.42}, 3.0, completed=False) == "user_spill"


def test_food_shed_into_the_bowl_is_no_spill() -> None:
    # A primitive's shed never enters spilled_g: a bite that shed 3 g and spilled nothing.
    assert classify_bite(4.0, {"table": 0.0, "critical": 0.0}, 3.0) == "meaningful_success"


def test_food_lost_into_a_container_in_transport_is_a_non_critical_spill() -> None:
    # One particle that left the spoon on the way to the user and landed in the plate.
    assert classify_bite(7.5, {"table": 0.0, "critical": 0.0, "container": 0.42}, 3.0) \
        == "table_spill"
    assert classify_bite(7.5, {"airborne": 0.42}, 3.0) == "table_spill"


def test_an_unknown_spill_place_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown places"):
        classify_bite(1.0, {"bowl": 0.5}, 3.0)


def test_an_incomplete_bite_without_spill_failed() -> None:
    assert classify_bite(5.0, {}, 3.0, completed=False) == "failed"


def test_negative_masses_are_refused() -> None:
    with pytest.raises(ValueError):
        classify_bite(-1.0, {}, 3.0)
    with pytest.raises(ValueError):
        classify_bite(1.0, {"table": -0.1}, 3.0)


@given(st.floats(0, 50), st.floats(0, 5), st.floats(0, 5), st.floats(0, 10), st.booleans())
def test_outcome_is_monotone_in_severity(d: float, table: float, crit: float, thr: float,
                                         done: bool) -> None:
    out = classify_bite(d, {"table": table, "critical": crit}, thr, done)
    assert out in OUTCOMES
    # Adding a spill on the user never makes the outcome better than a user spill.
    assert classify_bite(d, {"table": table, "critical": crit + 0.42}, thr, done) == "user_spill"
    if crit == 0 and table == 0 and done:
        assert out == ("meaningful_success" if d > thr else "trivial_success")
