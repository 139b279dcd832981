"""Food accounting (sim/accounting.py), pure: classification from contacts, spill events
and the one definition of spilled and delivered mass."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.sim import accounting as acc

SURFACES = np.array([acc.CONTAINER, acc.CONTAINER, acc.TABLE, acc.CRITICAL, acc.CRITICAL])


@st.composite
def contact_graphs(draw: st.DrawFn) -> dict:
    n = draw(st.integers(3, 13))
    item = st.integers(0, n - 1)
    pairs = draw(st.lists(st.tuples(item, item).filter(lambda p: p[0] != p[1]),
                          min_size=1, max_size=3 * n))
    utensil = draw(st.lists(item, max_size=3))
    surface = draw(st.lists(st.tuples(item, st.integers(0, len(SURFACES) - 1)), max_size=4))
    asleep = np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    previous = np.array(draw(st.lists(st.sampled_from([acc.AIRBORNE, acc.UTENSIL,
                                                        acc.CONTAINER, acc.TABLE]),
                                      min_size=n, max_size=n)))
    order = draw(st.permutations(range(len(pairs))))
    flips = draw(st.lists(st.booleans(), min_size=len(pairs), max_size=len(pairs)))
    s_order = draw(st.permutations(range(len(surface))))
    u_order = draw(st.permutations(range(len(utensil))))
    return dict(n=n, pairs=pairs, utensil=utensil, surface=surface, asleep=asleep,
                previous=previous, order=order, flips=flips, s_order=s_order, u_order=u_order)


def _classify(n, pairs, utensil, surface, previous, asleep):
    e = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    s = np.array(surface, dtype=np.int64).reshape(-1, 2)
    prev_where = np.where(previous == acc.TABLE, 2, -1)
    return acc.classify_items(n, e, np.array(utensil, dtype=np.int64), s, SURFACES,
                              previous, prev_where, asleep)


@settings(max_examples=1500, deadline=None)
@given(contact_graphs())
def test_an_items_class_does_not_depend_on_the_order_or_direction_of_contacts(g) -> None:
    # The same contact graph listed in another order, each pair either way round, must give
    # every item the same class and surface (a one-pass rule changes 232 of 1500).
    codes, where = _classify(g["n"], g["pairs"], g["utensil"], g["surface"], g["previous"],
                             g["asleep"])
    pairs = [g["pairs"][i][::-1] if g["flips"][i] else g["pairs"][i] for i in g["order"]]
    surface = [g["surface"][i] for i in g["s_order"]]
    utensil = [g["utensil"][i] for i in g["u_order"]]
    codes2, where2 = _classify(g["n"], pairs, utensil, surface, g["previous"], g["asleep"])
    assert codes.tolist() == codes2.tolist()
    assert where.tolist() == where2.tolist()


def test_an_item_takes_the_place_of_its_nearest_holder_then_the_least_severe() -> None:
    # Chain: utensil - 0 - 1 - 2 - 3 - bowl. 1 is one hop from the utensil's item, 2 one hop
    # from the bowl's: each takes its nearest; 4 touches 0 (utensil) and 3 (container) at
    # one hop each: the container wins by precedence.
    n = 5
    pairs = [[0, 1], [1, 2], [2, 3], [4, 0], [3, 4]]
    codes, where = _classify(n, pairs, [0], [[3, 1]], np.full(n, acc.AIRBORNE),
                             np.zeros(n, dtype=bool))
    assert codes.tolist() == [acc.UTENSIL, acc.UTENSIL, acc.CONTAINER, acc.CONTAINER,
                              acc.CONTAINER]
    assert where.tolist() == [-1, -1, 1, 1, 1]


def test_an_item_resting_on_a_sleeping_item_takes_its_place() -> None:
    # 0 sleeps in the bowl (no fresh contacts); 1, awake, rests only on it.
    codes, where = acc.classify_items(
        2, np.array([[1, 0]]), np.zeros(0, dtype=np.int64), np.zeros((0, 2), dtype=np.int64),
        SURFACES, np.array([acc.CONTAINER, acc.UTENSIL]), np.array([0, -1]),
        np.array([True, False]))
    assert codes.tolist() == [acc.CONTAINER, acc.CONTAINER]
    assert where.tolist() == [0, 0]


# ------------------------------------------------------------------------ spills --
DT = 0.02


def _run(tracker: acc.SpillTracker, classes: list[int], place_where: int = 2
         ) -> list[tuple[int, int, int, float]]:
    out = []
    for i, c in enumerate(classes):
        codes = np.array([c])
        where = np.array([place_where if c in (acc.TABLE, acc.CRITICAL) else -1])
        out += tracker.update((i + 1) * DT, DT, codes, where, np.array([True]))
    return out


def test_a_one_tick_flicker_onto_the_table_is_no_spill() -> None:
    u, t, a = acc.UTENSIL, acc.TABLE, acc.AIRBORNE
    tr = acc.SpillTracker(1, 0.1)
    # A tick on the table, back on the spoon; again, and one through the air into the bowl.
    assert _run(tr, [u] * 5 + [t] + [u] * 10 + [t, a, acc.CONTAINER] + [acc.CONTAINER] * 10
                ) == []
    assert tr.worst.tolist() == [0]


def test_a_landing_on_the_table_is_a_spill_from_the_tick_it_landed() -> None:
    u, t, a = acc.UTENSIL, acc.TABLE, acc.AIRBORNE
    tr = acc.SpillTracker(1, 0.1)
    # Falls off the spoon, bounces (airborne between contacts), then rests on the table.
    ev = _run(tr, [u] * 3 + [a] * 4 + [t, t, a, a, t, a, t] + [t] * 20)
    assert len(ev) == 1
    k, code, where, t0 = ev[0]
    assert (k, code, where) == (0, acc.TABLE, 2)
    assert t0 == pytest.approx(8 * DT)  # the step at which it was first seen on the table


def test_a_landing_on_the_user_is_a_critical_spill() -> None:
    tr = acc.SpillTracker(1, 0.1)
    ev = _run(tr, [acc.UTENSIL, acc.AIRBORNE] + [acc.CRITICAL] * 6, place_where=3)
    assert [(e[1], e[2]) for e in ev] == [(acc.CRITICAL, 3)]


def _events(seq: list[tuple[int, int, int, float]]) -> list[acc.SpillEvent]:
    return [acc.SpillEvent(t=t0, mass_g=0.92, place=acc.CLASS_NAMES[c], where="", item=k)
            for k, c, _, t0 in seq]


def test_a_piece_that_lands_on_the_table_and_rolls_to_the_floor_is_spilled_once() -> None:
    tr = acc.SpillTracker(2, 0.1)
    seq: list[tuple[int, int, int, float]] = []
    # Item 0: table, then rolls off to the floor. Item 1: stays on the table.
    for i, (c0, c1) in enumerate([(acc.TABLE, acc.TABLE)] * 10 + [(acc.AIRBORNE, acc.TABLE)] * 3
                                 + [(acc.CRITICAL, acc.TABLE)] * 10):
        seq += tr.update((i + 1) * DT, DT, np.array([c0, c1]), np.array([2, 2]),
                         np.array([True, True]))
    events = _events(seq)
    assert [e.place for e in events if e.item == 0] == ["table", "critical"]  # two events
    assert acc.spilled_by_place(events) == pytest.approx({"table": 0.92, "critical": 0.92})
    # An item counts in the interval where it first spilled, not again in a later one.
    first = 2  # the two first-table events
    assert acc.spilled_by_place(events, since=first) == {"table": 0.0, "critical": 0.0}


def test_delivered_is_on_the_utensil_plus_eaten_in_between() -> None:
    before = {"utensil": 2.0, "eaten": 1.0}
    assert acc.delivered_g(before, {"utensil": 0.5, "eaten": 3.0}) == pytest.approx(2.5)


def test_a_negative_dwell_is_refused() -> None:
    with pytest.raises(ValueError, match="dwell_s"):
        acc.SpillTracker(1, -0.1)


# --------------------------------------------------------------------- transport --
U, C, T, K, A, E = acc.UTENSIL, acc.CONTAINER, acc.TABLE, acc.CRITICAL, acc.AIRBORNE, acc.EATEN


def test_an_item_the_utensil_holds_is_on_it_whatever_else_it_touches() -> None:
    # A strand hanging from the fork onto the table (and one resting on it) has not left the
    # fork: it is carried, not spilled; one on the table alone is on the table.
    codes, where = _classify(3, [[1, 0]], [0], [[0, 2], [2, 2]], np.full(3, A),
                             np.zeros(3, dtype=bool))
    assert codes.tolist() == [U, U, T]
    assert where.tolist() == [-1, -1, 2]


def test_food_that_leaves_the_utensil_in_transport_is_spilled_wherever_it_lands() -> None:
    # Exp. 2b baseline trial 47 (water, seed 11): one 0.42 g particle left the spoon on the
    # way and landed in a container; it scored 0 g spilled. In transport it is a spill,
    # reported apart by place.
    g = np.full(5, 0.42)
    start = np.array([U, U, U, U, C])  # item 4 was already in the bowl
    now = np.array([U, C, T, A, C])
    out = acc.transport_spill(start, now, g, [])
    assert out == pytest.approx({"container": 0.42, "table": 0.42, "airborne": 0.42,
                                 "critical": 0.0})


def test_a_transported_item_counts_once_at_the_worst_place_it_reached() -> None:
    # Item 0 lands on the table (an event), bounces into the plate: table. Item 1 falls on
    # the floor: critical. Item 2 dropped and landed back on the spoon: not lost.
    # Item 3 was eaten: delivered. Item 4 lay on the table before: knocked to the floor in
    # transport it is no new spill; item 5, in the bowl before, knocked onto the table is.
    g = np.array([0.9, 0.8, 0.7, 0.6, 0.5, 0.4])
    start = np.array([U, U, U, U, T, C])
    now = np.array([C, K, U, E, K, T])
    events = [acc.SpillEvent(0.1, 0.5, "table", "table", 4),  # before the transport
              acc.SpillEvent(1.0, 0.9, "table", "table", 0),
              acc.SpillEvent(1.2, 0.7, "table", "table", 2),
              acc.SpillEvent(1.3, 0.5, "critical", "floor", 4),
              acc.SpillEvent(1.4, 0.4, "table", "table", 5)]
    out = acc.transport_spill(start, now, g, events, since=1)
    assert out == pytest.approx({"table": 0.9 + 0.4, "critical": 0.8, "container": 0.0,
                                 "airborne": 0.0})


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([U, C, T, A]), st.sampled_from([U, C, T, K, A, E])),
                min_size=1, max_size=30))
def test_transport_losses_are_what_left_the_utensil(pairs) -> None:
    start, now = (np.array(x) for x in zip(*pairs, strict=True))
    g = np.linspace(0.1, 1.0, len(pairs))
    out = acc.transport_spill(start, now, g, [])
    lost = (start == U) & (now != U) & (now != E)
    assert sum(out.values()) == pytest.approx(float(g[lost].sum()))
    assert all(v >= 0 for v in out.values())
