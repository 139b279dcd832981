"""The first-mode slosh model: its parameters from geometry and cited physics, the laws its
prediction keeps (no motion spills nothing; slow tilts are hydrostatics; what spilled stays
spilled) and its step response."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.food.dish import spoon_dish
from articutool.food.hydrostatics import SIDE, TIP, up_vector
from articutool.food.slosh import (
    STANDARD_GRAVITY,
    SloshModel,
    apparent_gravity,
    dish_mode,
    rectangular_tank_mode,
)
from conftest import packaged_spec

G = STANDARD_GRAVITY
DISH = spoon_dish(packaged_spec().utensil("soup_spoon"))
MODEL = SloshModel(DISH, 8e-6)


def _tilted(tilt: np.ndarray, direction: float) -> np.ndarray:
    return -G * up_vector(tilt, direction)


def test_the_modes_of_8_ml_in_the_soup_spoon() -> None:
    across, along = MODEL.modes
    assert MODEL.mean_depth * 1e3 == pytest.approx(5.87, abs=0.01)
    assert along.length_m * 1e3 == pytest.approx(49.8, abs=0.1)
    assert along.frequency_hz == pytest.approx(2.96, abs=0.01)
    assert across.frequency_hz == pytest.approx(4.09, abs=0.01)
    assert along.zeta == pytest.approx(0.018, abs=0.001)
    assert across.zeta == pytest.approx(0.013, abs=0.001)


@settings(max_examples=50, deadline=None)
@given(st.floats(0.01, 0.1), st.floats(0.3, 1.0), st.floats(1e-4, 1e-3))
def test_a_paraboloid_basins_tilting_mode_is_lambs(a: float, b_over_a: float,
                                                   h0_over_a: float) -> None:
    """Shallow water in an elliptic paraboloid, depth h0·(1 − x²/a² − y²/b²): the plane is
    the exact first mode, σ² = 2·g·h0/a² (Lamb 1932, §193)."""
    b, h0 = a * b_over_a, a * h0_over_a
    w, _ = dish_mode(a, b, 0.5 * math.pi * a * b * h0)
    assert w ** 2 == pytest.approx(2 * G * h0 / a ** 2, rel=1e-3)


@settings(max_examples=50, deadline=None)
@given(st.floats(0.01, 0.05), st.floats(0.3, 1.0), st.floats(0.05, 0.5), st.floats(0.2, 5.0))
def test_a_dish_mode_scales_as_froude(a: float, b_over_a: float, fill: float,
                                      scale: float) -> None:
    """A geometrically similar dish λ times larger rings 1/√λ as fast (inviscid), finite
    depth lowers the shallow quotient, and the shorter axis rings faster."""
    b, v = a * b_over_a, fill * a ** 3
    w, _ = dish_mode(a, b, v, nu=0.0)
    w_big, zeta = dish_mode(scale * a, scale * b, scale ** 3 * v, nu=0.0)
    assert zeta == 0.0
    assert w_big == pytest.approx(w / math.sqrt(scale), rel=1e-9)
    assert w ** 2 <= G * v / (0.25 * math.pi * a ** 3 * b) * (1 + 1e-12)
    if b_over_a < 0.99:
        assert dish_mode(b, a, v, nu=0.0)[0] > w


def test_the_tank_formula() -> None:
    # deep water: ω² → πg/L; shallow: ω → π√(gh)/L; viscous damping grows as √ν
    w, _ = rectangular_tank_mode(0.05, 0.05, 10.0)
    assert w ** 2 == pytest.approx(math.pi * G / 0.05, rel=1e-9)
    w, _ = rectangular_tank_mode(0.05, 0.05, 1e-5)
    assert w == pytest.approx(math.pi * math.sqrt(G * 1e-5) / 0.05, rel=1e-3)
    z1 = rectangular_tank_mode(0.05, 0.03, 0.006, nu=1e-6)[1]
    z4 = rectangular_tank_mode(0.05, 0.03, 0.006, nu=4e-6)[1]
    assert z4 == pytest.approx(2 * z1, rel=1e-9)
    assert rectangular_tank_mode(0.05, 0.03, 0.006, nu=0.0)[1] == 0.0


@settings(max_examples=25, deadline=None)
@given(st.floats(0.0, 16.0), st.floats(-30.0, 30.0), st.floats(0.0, 20.0))
def test_no_motion_and_no_tilt_spill_nothing(ml: float, yaw_deg: float, dur: float) -> None:
    m = SloshModel(DISH, ml * 1e-6)
    t = np.linspace(0.0, dur + 0.01, 50)
    g = np.tile([-G, 0.0, 0.0], (t.size, 1))
    p = m.predict(t, g)
    assert p.spilled_g == 0.0
    assert p.peak_surface_tilt_deg == pytest.approx(0.0, abs=1e-9)
    # the same still dish seen through a pose trajectory (turned about its normal)
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    R = np.array([[0.0, -s, c], [0.0, c, s], [1.0, 0.0, 0.0]])  # dish x = world up
    pose = m.predict_poses(t, np.tile([0.3, -0.1, 0.5], (t.size, 1)), np.tile(R, (t.size, 1, 1)))
    assert pose.spilled_g == 0.0 and pose.peak_apparent_tilt_deg == pytest.approx(0, abs=1e-9)


@settings(max_examples=25, deadline=None)
@given(st.floats(2.0, 15.0), st.floats(0.0, 30.0), st.floats(-math.pi, math.pi))
def test_a_slow_static_tilt_predicts_what_hydrostatics_gives(ml: float, tilt_deg: float,
                                                             direction: float) -> None:
    m = SloshModel(DISH, ml * 1e-6)
    # ramp over 60 s (ω·T ≫ 1), then hold
    t = np.linspace(0.0, 80.0, 801)
    tilt = np.radians(tilt_deg) * np.clip(t / 60.0, 0.0, 1.0)
    p = m.predict(t, _tilted(tilt, direction))
    static = float(m.hydro.spilled(ml * 1e-6, up_vector(math.radians(tilt_deg), direction)))
    assert p.spilled_g == pytest.approx(static * 1e6, abs=0.01)
    assert p.peak_surface_tilt_deg == pytest.approx(tilt_deg, abs=0.05)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0), st.floats(-3.0, 3.0)),
                min_size=2, max_size=40), st.floats(0.0, 16.0))
def test_what_spilled_stays_spilled_and_mass_is_conserved(acc: list, ml: float) -> None:
    m = SloshModel(DISH, ml * 1e-6)
    a = np.array(acc)
    t = 0.1 * np.arange(len(acc))
    p = m.predict(t, np.array([0.0, 0.0, -G]) @ np.eye(3)[[2, 1, 0]] - a)
    assert np.all(np.diff(p.retained_m3) <= 0)
    assert np.all(p.retained_m3 >= 0) and p.retained_m3[0] <= m.volume
    assert p.spilled_g == pytest.approx((m.volume - p.retained_m3[-1]) * 1e6, abs=1e-12)


def test_a_step_of_acceleration_overshoots_and_rings_at_the_mode() -> None:
    # 0.5 m/s² towards the tip from t = 1 s: quasi-static tilt 2.92°, the surface swings to
    # (1 + e^(−πζ/√(1−ζ²))) times that and rings at the along-mode's frequency.
    t = np.linspace(0.0, 6.0, 601)
    a = np.where(t >= 1.0, 0.5, 0.0)
    g = np.column_stack([np.full(t.size, -G), np.zeros(t.size), -a])
    p = MODEL.predict(t, g)
    along = MODEL.modes[1]
    static = math.degrees(math.atan(0.5 / G))
    overshoot = 1 + math.exp(-math.pi * along.zeta / math.sqrt(1 - along.zeta ** 2))
    assert p.peak_surface_tilt_deg == pytest.approx(static * overshoot, rel=0.01)
    assert p.peak_apparent_tilt_deg == pytest.approx(static, rel=1e-6)
    # its peaks come one period apart
    after = p.t > 1.0
    s = p.surface_tilt_deg[after] - static
    up = np.flatnonzero((s[:-1] < 0) & (s[1:] >= 0))
    period = np.diff(p.t[after][up]).mean()
    assert 1 / period == pytest.approx(along.frequency_hz * math.sqrt(1 - along.zeta ** 2),
                                       rel=0.01)
    assert p.spilled_g == 0.0 and p.min_margin_deg > 0
    # a larger step spills: 1.5 m/s² (8.7° quasi-static, ~17° at its peak)
    g[:, 2] = -3 * a
    big = MODEL.predict(t, g)
    assert big.spilled_g > 0.5 and big.min_margin_deg < 0
    assert big.first_spill_time is not None and 1.0 < big.first_spill_time < 1.5


def test_quasi_static_is_hydrostatics_at_every_sample() -> None:
    m = SloshModel(DISH, 8e-6, dynamic=False)
    tilt = np.radians([0, 5, 12, 9, 15, 3])
    p = m.predict(np.arange(6.0), _tilted(tilt, SIDE))
    caps = m.hydro.capacity_at(np.radians(p.surface_tilt_deg), SIDE)
    expect = np.minimum(8e-6, np.minimum.accumulate(caps))
    np.testing.assert_allclose(p.retained_m3, expect, atol=2e-9)
    assert math.degrees(float(m.onset_tilt(TIP))) == pytest.approx(10.5, abs=0.05)


def test_apparent_gravity_of_a_pose_trajectory() -> None:
    # level dish moving on a parabola: a = 2 m/s² along world x, the dish's z along world x
    t = np.linspace(0.0, 1.0, 101)
    pos = np.column_stack([t ** 2, np.zeros_like(t), np.zeros_like(t)])
    R = np.tile(np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]]), (t.size, 1, 1))
    g = apparent_gravity(t, pos, R)
    np.testing.assert_allclose(g, np.tile([-G, 0.0, -2.0], (t.size, 1)), atol=1e-9)


def test_bad_input_is_refused() -> None:
    with pytest.raises(ValueError, match="level capacity"):
        SloshModel(DISH, 17e-6)
    with pytest.raises(ValueError, match="level capacity"):
        SloshModel(DISH, float("nan"))
    with pytest.raises(ValueError, match="increasing"):
        MODEL.predict([0.0, 0.0], np.tile([-G, 0, 0], (2, 1)))
    with pytest.raises(ValueError, match="finite"):
        MODEL.predict([0.0, 1.0], [[-G, 0, 0], [np.nan, 0, 0]])
