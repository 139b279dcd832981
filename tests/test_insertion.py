"""Acquisition waypoints from a strategy (pure geometry)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.feeding.insertion import acquisition_waypoints, dish_outline, lowest_point
from articutool.feeding.strategies import StrategyLibrary
from articutool.spec import load_spec

LIB = StrategyLibrary.load(load_spec())
FLOOR = np.array([0.45, -0.45, 0.004])
HEADING = np.array([0.0, -1.0, 0.0])


def _with(name: str, **insertion: float) -> object:
    s = LIB.strategies[name]
    return s.model_copy(update={"insertion": s.insertion.model_copy(update=insertion)})


NOT_SWEEPS = sorted(n for n, s in LIB.strategies.items() if s.insertion.motion != "sweep")
SWEEPS = sorted(n for n, s in LIB.strategies.items() if s.insertion.motion == "sweep")


@pytest.mark.parametrize("name", NOT_SWEEPS)
def test_phases_chain_and_the_deepest_point_is_the_strategy_depth(name: str) -> None:
    s = LIB.strategies[name]
    w = acquisition_waypoints(s, FLOOR, HEADING)
    assert w["into"][0] == w["above"][-1] and w["out"][0] == w["into"][-1]
    deepest = min(p.position[2] for ph in w.values() for p in ph)
    assert deepest == pytest.approx(FLOOR[2] + s.insertion.depth_m)
    assert w["into"][-1].pitch_down == pytest.approx(math.radians(s.insertion.pitch_down_deg))
    assert w["out"][-1].pitch_down == pytest.approx(
        math.radians(s.insertion.extract_pitch_down_deg))
    assert all(p.speed > 0 for ph in w.values() for p in ph)


@settings(max_examples=50, deadline=None)
@given(st.floats(0.0, 0.06), st.floats(-0.05, 0.05), st.floats(0.0, 0.03))
def test_a_scoop_drags_its_length_along_the_heading_at_its_depth(drag: float, off: float,
                                                                  depth: float) -> None:
    s = _with("pecans_tilted_scoop", motion="scoop", drag_m=drag, offset_m=off, depth_m=depth,
              sweep_to_deg=0.0)
    w = acquisition_waypoints(s, FLOOR, HEADING)
    in_food = [np.array(p.position) for p in w["into"] if p.position[2] == FLOOR[2] + depth]
    travel = in_food[-1] - in_food[0]
    assert np.linalg.norm(travel) == pytest.approx(drag, abs=1e-12)
    mid = (in_food[0] + in_food[-1]) / 2
    np.testing.assert_allclose(mid[:2], (FLOOR + HEADING * off)[:2], atol=1e-12)


def test_a_skewer_goes_straight_down_and_a_dip_can_level_in_the_food() -> None:
    w = acquisition_waypoints(LIB.strategies["noodles_twirl"], FLOOR, HEADING)
    xy = {tuple(np.round(p.position[:2], 12)) for p in w["into"][1:]}
    assert len(xy) == 1  # straight down below the pre-entry point
    s = _with("water_tilted_dip", motion="dip", drag_m=0.0, level_height_m=0.02,
              sweep_to_deg=0.0, depth_m=0.006)
    out = acquisition_waypoints(s, FLOOR, HEADING)["out"]
    assert out[1].pitch_down == 0.0 and out[1].position[2] == pytest.approx(FLOOR[2] + 0.02)
    assert out[2].position[2] > out[1].position[2]


@pytest.mark.parametrize("name", SWEEPS)
@settings(max_examples=40, deadline=None)
@given(a=st.floats(10.0, 80.0), frac=st.floats(0.0, 0.9), drag=st.floats(0.005, 0.08),
       depth=st.floats(0.0, 0.03), off=st.floats(-0.05, 0.05))
def test_a_sweep_keeps_the_dish_above_the_floor_and_the_wrist_makes_its_turn(
        spec, name: str, a: float, frac: float, drag: float, depth: float, off: float) -> None:
    s = _with(name, pitch_down_deg=a, sweep_to_deg=a * frac, drag_m=drag, depth_m=depth,
              offset_m=off)
    outline = dish_outline(spec, s.utensil)
    w = acquisition_waypoints(s, FLOOR, HEADING, outline)
    assert w["into"][0] == w["above"][-1] and w["out"][0] == w["into"][-1]
    pts = [p for ph in w.values() for p in ph]
    # No point of the dish's outline below depth_m above the floor, at any waypoint; the
    # dish touches that height (within the piecewise pivot) while it turns.
    lows = [p.position[2] + lowest_point(outline, p.pitch_down) - FLOOR[2] for p in pts]
    assert min(lows) == pytest.approx(depth, abs=1e-12)
    turn = [p for p in w["into"] if p.wrist]
    assert all(lo == pytest.approx(depth, abs=1e-12) for p, lo in zip(pts, lows, strict=True)
               if p in turn)
    # The turn goes from the dip's pitch to sweep_to_deg while moving drag_m along the heading.
    start = w["into"][w["into"].index(turn[0]) - 1]
    assert start.pitch_down == pytest.approx(math.radians(a))
    assert turn[-1].pitch_down == pytest.approx(math.radians(a * frac))
    travel = np.array(turn[-1].position) - np.array(start.position)
    assert float(travel @ HEADING) == pytest.approx(drag)
    assert np.all(np.diff([p.pitch_down for p in [start, *turn]]) <= 0)
    # Then out level, above the food.
    assert w["out"][-1].pitch_down == 0.0 and w["out"][-1].position[2] > FLOOR[2] + 0.05


def test_a_sweep_needs_the_utensil_outline() -> None:
    with pytest.raises(ValueError, match="outline"):
        acquisition_waypoints(LIB.strategies[SWEEPS[0]], FLOOR, HEADING)
