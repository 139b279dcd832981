"""The liquid's checks against outside laws and measurements: the pure parts (the reading of an
oscillation, the pour into the dish, the dam break's data) always; one cheap dam-break smoke
run; the full dam break and slosh runs are slow."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.food.dish import spoon_dish
from articutool.food.dish_fill import CLEARANCE_RADII, dish_pour
from articutool.sim.liquid_checks import (
    dam_break_check,
    fitted_oscillation,
    martin_moyce_1952,
    oscillation,
    slosh_mode_check,
    tank_slosh_check,
)


@settings(max_examples=40, deadline=None)
@given(st.floats(1.0, 5.0), st.floats(0.0, 0.08), st.floats(0.0, 2 * math.pi))
def test_a_damped_sine_gives_back_its_frequency_and_damping(f, zeta, phase) -> None:
    t = np.arange(0.0, 3.0, 0.002)
    w = 2 * math.pi * f
    wd = w * math.sqrt(1 - zeta ** 2)
    y = 1e-3 * np.exp(-zeta * w * t) * np.cos(wd * t + phase) + 0.05
    osc = oscillation(t, y, rest=0.05)
    assert osc["frequency_hz"] == pytest.approx(wd / (2 * math.pi), rel=0.01)
    assert osc["damping_ratio"] == pytest.approx(zeta, abs=0.006)


@settings(max_examples=25, deadline=None)
@given(st.floats(1.0, 5.0), st.floats(0.0, 0.08), st.floats(0.0, 2 * math.pi),
       st.floats(-2e-4, 2e-4))
def test_a_fit_gives_back_a_drifting_ring_downs_frequency_and_damping(f, zeta, phase,
                                                                      drift) -> None:
    """A ring-down whose rest drifts (a liquid still settling): the fit gives back the
    frequency and damping whatever the drift."""
    t = np.arange(0.0, 3.0, 0.004)
    w = 2 * math.pi * f
    wd = w * math.sqrt(1 - zeta ** 2)
    y = 1e-3 * np.exp(-zeta * w * t) * np.cos(wd * t + phase) + 0.05 + drift * t
    fit = fitted_oscillation(t, y, rest=0.05)
    assert fit["frequency_hz"] == pytest.approx(wd / (2 * math.pi), rel=0.002)
    assert fit["damping_ratio"] == pytest.approx(zeta * w / wd, abs=0.002)


def test_too_few_crossings_read_as_nan() -> None:
    t = np.linspace(0, 1, 100)
    assert math.isnan(oscillation(t, t)["frequency_hz"])
    assert math.isnan(fitted_oscillation(t, t)["frequency_hz"])


def test_the_pour_fills_the_dish_from_the_floor_clear_of_its_walls(spec) -> None:
    u = spec.utensil("soup_spoon")
    d = spoon_dish(u)
    r = 0.001
    x = dish_pour(d, u.tip_x, r, 1000)
    assert x.shape == (1000, 3)
    h = x[:, 0] - u.tip_x
    assert h.min() >= CLEARANCE_RADII * r - 1e-12
    A, B = d.semi_axes(np.clip(h, 0, d.depth))
    assert np.all(((x[:, 2] - d.zc) / A) ** 2 + (x[:, 1] / B) ** 2 < 1.0)
    # lowest first: every layer below the top one is complete in the larger pour
    more = dish_pour(d, u.tip_x, r, 1400)
    below = more[more[:, 0] < x[:, 0].max() - 1e-9]
    assert len(below) <= 1000
    # centres are a lattice of the particle diameter
    d2 = np.sort(np.linalg.norm(x[:50, None] - x[None], axis=-1), axis=1)[:, 1]
    assert d2.min() == pytest.approx(2 * r)
    with pytest.raises(ValueError, match="at most"):
        dish_pour(d, u.tip_x, r, 100_000)


def test_the_dam_break_data_are_the_papers_two_series() -> None:
    ref = martin_moyce_1952()
    assert "Martin & Moyce (1952)" in ref["source"] and ref["n_squared"] == 2.0
    assert [s["a_m"] for s in ref["series"]] == [0.028575, 0.05715]
    for s in ref["series"]:
        assert len(s["t_star"]) == len(s["z_star"])
        assert np.all(np.diff(s["t_star"]) > 0) and np.all(np.diff(s["z_star"]) > 0)
        assert s["z_star"][0] > 1.0


def test_a_coarse_dam_break_runs_and_says_what_it_measured() -> None:
    """Smoke: the JSON's fields and the front's start (the full check is slow)."""
    r = dam_break_check(0.05715 / 16, t_star_end=0.9, sample_t_star=0.3)
    assert r["backend"].startswith("SPlisHSPlasH") and r["version"] == "2.19.0"
    assert r["particles"] + r["settling"]["particles_lost_settling"] == 8 * 16 * 4
    assert r["particles_across_column"] == 8
    assert r["t_star"][0] == 0.0 and r["z_star"][0] == pytest.approx(1.0, abs=0.05)
    assert np.all(np.diff(r["z_star"]) >= 0) and r["z_star"][-1] > 1.05
    assert r["compared_at_t_star"] == [0.832]  # the first measured point, Z ≤ 3
    assert set(r["reference"]) >= {"t_star", "z_star", "source"}
    assert isinstance(r["pass"], bool) and r["cpu_s"] > 0


def test_the_column_is_released_from_rest() -> None:
    """The tiled lattice is denser than water next to the walls (the boundary particles' share
    is too large at 2r), so a column released as tiled bursts out at once; the check lets it
    settle behind a gate first and releases it from rest (this coarse column keeps some jitter;
    the full check's settles to millimetres per second, asserted in the slow test)."""
    r = dam_break_check(0.05715 / 16, t_star_end=0.1, sample_t_star=0.1)
    s = r["settling"]
    assert s["first_step_max_speed_m_s"] > 0.2  # the tiled start: ~10 g·dt and more
    assert s["rms_speed_at_release_m_s"] < s["first_step_max_speed_m_s"] / 20
    assert s["particles_lost_settling"] <= 0.01 * r["particles"]


@pytest.mark.slow
def test_the_dam_break_front_is_reported_against_martin_and_moyce() -> None:
    """The full check (20 particles across). Its front runs 13–20 % ahead of the measurement
    (docs/food.md; the 10 % criterion fails), a lag nearly constant in time; asserted here:
    the physics it must obey whatever the measurement — the front only advances, never faster
    than the inviscid shallow-water front (Ritter: dZ/dT ≤ 2), ahead of the measured one at
    every point (an instant release beside a gate drawn away) but by less than the tiled
    start's 38–50 %, and every measured point up to Z = 3 compared."""
    r = dam_break_check()
    assert r["settling"]["rms_speed_at_release_m_s"] < 0.01
    t, z = np.asarray(r["t_star"]), np.asarray(r["z_star"])
    assert np.all(np.diff(z) >= -1e-3)
    assert np.all(z <= 1.0 + 2.0 * t + 0.05)
    assert r["compared_at_t_star"] == [0.832, 1.219, 1.997, 2.547]
    ahead = np.asarray(r["measured_z_star"]) / np.asarray(r["law_z_star"]) - 1.0
    assert np.all(ahead > 0) and r["max_rel_error_to_Z3"] < 0.3
    assert isinstance(r["pass"], bool) and r["pass"] == (r["max_rel_error_to_Z3"] <= 0.10)


@pytest.mark.slow
def test_the_bowls_coarse_liquid_breaks_the_dam_as_the_fine_one_does() -> None:
    """The water bowl's 2 mm particle (14 across the column) against the check's 20 across:
    the same front within 5 % at every compared time (measured: within 1.2 %), both ahead of
    Martin & Moyce alike."""
    from articutool.sim.liquid_checks import coarse_dam_break_check
    from articutool.sim.params import PhysicsParams

    r = PhysicsParams.load().food("water").sph_bowl_particle_radius
    c = coarse_dam_break_check(r)
    assert c["particle_radius_m"] == pytest.approx(r)
    assert c["pass"] and c["max_rel_diff_to_reference"] <= c["tolerance"] == 0.05
    assert len(c["measured_z_star"]) == len(c["reference_z_star"]) == 4


@pytest.mark.slow
def test_a_tank_sloshes_at_linear_theorys_frequency() -> None:
    """A slab 8 particles wide, read by the fit: within 10 % of linear theory (measured
    +6.7 %, the crossings +8.1 %), faster than the law, as the settled liquid stands higher
    than it was placed."""
    r = tank_slosh_check()
    assert r["pass"], r
    assert r["measured_hz"] > r["law_hz"] and r["settled_depth_m"] > 0.02
    assert 0 < r["measured_damping_ratio"] < 0.3


@pytest.mark.slow
def test_the_dish_slosh_modes_ring_at_the_models_frequencies() -> None:
    """The load keeps every particle; both modes ring within 10 % of the model's plane mode,
    across above along, and damp."""
    r = slosh_mode_check()
    assert r["pass"], r
    assert r["particles_kept"] == r["particles"]
    assert r["across"]["measured_hz"] > r["along"]["measured_hz"]
    for axis in ("along", "across"):
        assert 0 < r[axis]["measured_damping_ratio"] < 0.2
