"""Hydrostatics of a liquid in a spoon's dish: the laws it must keep (any dish, any tilt, any
fill) and the soup spoon's figures checked by an independent voxel integration."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.food.dish import Dish, spoon_dish
from articutool.food.hydrostatics import SIDE, TIP, Hydrostatics, tilt_direction, up_vector
from conftest import packaged_spec

SPEC = packaged_spec()
SOUP = Hydrostatics(spoon_dish(SPEC.utensil("soup_spoon")))
ML = 1e-6


def _dish(length: float, width: float, depth: float) -> Dish:
    # the spec's rule (45° walls, a floor of a quarter of the rim at least)
    a, b = length / 2, width / 2
    return Dish(0.0, a, b, max(a - depth, a / 4), max(b - depth, b / 4), depth)


dishes = st.builds(_dish, st.floats(0.02, 0.08), st.floats(0.015, 0.06),
                   st.floats(0.003, 0.025)).map(Hydrostatics)
directions = st.floats(-math.pi, math.pi)
fractions = st.floats(0.0, 1.0)


def _voxel_capacity(h: Hydrostatics, up: np.ndarray, n: int = 240) -> float:
    """The capacity counted in voxels: independent of the segment-area integration."""
    d = h.dish
    x = (np.arange(n) + 0.5) / n * d.depth
    y = ((np.arange(n) + 0.5) / n * 2 - 1) * d.b
    z = ((np.arange(n) + 0.5) / n * 2 - 1) * d.a
    X, Y, Z = np.meshgrid(x, y, z, indexing="ij")
    A, B = d.semi_axes(X)
    inside = (Y / B) ** 2 + (Z / A) ** 2 <= 1
    rim = float(h.rim_level(up))
    below = inside & (up[0] * X + up[1] * Y + up[2] * Z <= rim)
    return float(below.sum()) * d.depth * 4 * d.a * d.b / n ** 3


def test_the_soup_spoons_figures() -> None:
    h = SOUP
    assert h.level_capacity / ML == pytest.approx(16.79, abs=0.01)
    assert h.fill_height(8 * ML) * 1e3 == pytest.approx(9.92, abs=0.01)
    assert math.degrees(h.onset_tilt(8 * ML, TIP)) == pytest.approx(10.50, abs=0.02)
    assert math.degrees(h.onset_tilt(8 * ML, SIDE)) == pytest.approx(13.95, abs=0.02)
    tip = [h.spilled(8 * ML, up_vector(math.radians(t), TIP)) / ML for t in (12, 15, 20, 25)]
    side = [h.spilled(8 * ML, up_vector(math.radians(t), SIDE)) / ML for t in (15, 20, 25)]
    assert tip == pytest.approx([0.89, 2.49, 4.64, 6.08], abs=0.01)
    assert side == pytest.approx([0.49, 2.62, 4.45], abs=0.01)


@pytest.mark.parametrize("tilt_deg,direction", [(0, 0), (10.5, TIP), (12, TIP), (20, SIDE),
                                                (30, 0.7), (60, 2.0)])
def test_the_capacity_agrees_with_a_voxel_count(tilt_deg: float, direction: float) -> None:
    up = up_vector(math.radians(tilt_deg), direction)
    assert float(SOUP.capacity(up)) == pytest.approx(_voxel_capacity(SOUP, up), abs=0.01 * ML)


@settings(max_examples=40, deadline=None)
@given(dishes, directions)
def test_capacity_at_zero_tilt_is_the_level_capacity(h: Hydrostatics, direction: float) -> None:
    assert float(h.capacity_at(0.0, direction)) == pytest.approx(h.level_capacity, rel=1e-9)


@settings(max_examples=40, deadline=None)
@given(dishes, st.floats(0.0, 1.0))
def test_the_volume_below_a_level_plane_is_the_closed_form(h: Hydrostatics, f: float) -> None:
    level = f * h.dish.depth
    assert float(h.volume_below([1.0, 0.0, 0.0], level)) == pytest.approx(
        float(h.dish.level_volume(level)), rel=1e-9, abs=1e-15)


@settings(max_examples=40, deadline=None)
@given(dishes, directions)
def test_capacity_falls_as_the_tilt_grows(h: Hydrostatics, direction: float) -> None:
    cap = h.capacity_at(np.linspace(0.0, math.pi, 721), direction)
    assert np.all(np.diff(cap) <= 1e-12 * h.level_capacity)
    assert cap[-1] == pytest.approx(0.0, abs=1e-12)


@settings(max_examples=40, deadline=None)
@given(dishes, st.floats(0.0, 1.5), directions)
def test_the_dish_is_symmetric_about_both_axes(h: Hydrostatics, tilt: float,
                                               direction: float) -> None:
    caps = h.capacity_at(tilt, np.array([direction, -direction, math.pi - direction,
                                         math.pi + direction]))
    assert caps == pytest.approx(np.full(4, caps[0]), rel=1e-9, abs=1e-15)


@settings(max_examples=40, deadline=None)
@given(dishes, st.floats(0.0, 1.5), directions, fractions, fractions)
def test_spill_grows_with_the_fill_and_volume_is_conserved(h: Hydrostatics, tilt: float,
                                                           direction: float, f1: float,
                                                           f2: float) -> None:
    up = up_vector(tilt, direction)
    v1, v2 = sorted((f1 * h.level_capacity, f2 * h.level_capacity))
    for v in (v1, v2):
        assert float(h.retained(v, up) + h.spilled(v, up)) == pytest.approx(v, rel=1e-12)
    assert h.spilled(v1, up) <= h.spilled(v2, up)
    assert h.retained(v1, up) <= h.retained(v2, up)


@settings(max_examples=30, deadline=None)
@given(dishes, fractions, directions, st.floats(0.0, 1.5), st.floats(0.0, 1.5))
def test_spill_grows_with_the_tilt(h: Hydrostatics, f: float, direction: float, t1: float,
                                   t2: float) -> None:
    v = f * h.level_capacity
    lo, hi = sorted((t1, t2))
    assert h.spilled(v, up_vector(lo, direction)) <= h.spilled(v, up_vector(hi, direction))


@settings(max_examples=30, deadline=None)
@given(dishes, fractions, st.lists(st.tuples(st.floats(0.0, 1.2), directions), min_size=1,
                                   max_size=30))
def test_a_tilt_history_never_gains_and_conserves_volume(h: Hydrostatics, f: float,
                                                         path: list) -> None:
    v = f * h.level_capacity
    ups = up_vector(*np.array(path).T)
    kept = h.retained_history(v, ups)
    assert np.all(np.diff(kept) <= 0)
    assert np.all((kept >= 0) & (kept <= v))
    # the path's end state: what stays is what the worst tilt so far allowed
    assert kept[-1] == pytest.approx(min(v, float(h.capacity(ups).min())), rel=1e-12)


@settings(max_examples=30, deadline=None)
@given(dishes, st.floats(0.05, 0.95), directions)
def test_the_onset_is_where_the_capacity_meets_the_volume(h: Hydrostatics, f: float,
                                                          direction: float) -> None:
    v = f * h.level_capacity
    onset = float(h.onset_tilt(v, direction))
    assert h.spilled(v, up_vector(max(onset - 1e-6, 0.0), direction)) <= 1e-9 * v
    assert h.spilled(v, up_vector(onset + 1e-3, direction)) > 0


@settings(max_examples=30, deadline=None)
@given(st.floats(0.0, 1.3), directions, st.floats(0.1, 30.0))
def test_apparent_gravity_is_the_negative_up_vector_at_any_magnitude(tilt: float,
                                                                     direction: float,
                                                                     g: float) -> None:
    up = up_vector(tilt, direction)
    assert float(SOUP.spilled_g(8 * ML, -g * up)) == pytest.approx(
        float(SOUP.spilled(8 * ML, up)), rel=1e-12, abs=1e-18)
    t, d = tilt_direction(up)
    assert float(t) == pytest.approx(tilt, abs=1e-9)
    if tilt > 1e-6:
        assert math.cos(float(d) - direction) == pytest.approx(1.0, abs=1e-9)


def test_the_table_agrees_with_the_integral() -> None:
    rng = np.random.default_rng(0)
    tilt, direction = rng.uniform(0, math.pi, 2000), rng.uniform(-math.pi, math.pi, 2000)
    err = np.abs(SOUP.capacity_fast(tilt, direction) - SOUP.capacity_at(tilt, direction))
    assert err.max() < 0.005 * ML


def test_a_fill_height_outside_the_dish_is_refused() -> None:
    with pytest.raises(ValueError, match="level capacity"):
        SOUP.fill_height(17 * ML)
    with pytest.raises(ValueError, match="level capacity"):
        SOUP.fill_height(-1e-9)
    with pytest.raises(ValueError, match="non-zero"):
        SOUP.capacity([0.0, 0.0, 0.0])
    with pytest.raises(ValueError):
        spoon_dish(SPEC.utensil("fork"))


def test_the_physics_world_builds_the_same_dish() -> None:
    from articutool.sim import world_spec

    assert world_spec.spoon_dish is spoon_dish


def test_the_food_package_needs_only_the_spec_and_data_files() -> None:
    # the verifier and the physics world both build on it, so it imports nothing above the
    # spec and the data files (its definitions are read from physics.toml)
    import ast
    from pathlib import Path

    import articutool.food

    used = set()
    for path in Path(articutool.food.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("articutool"):
                used.add(node.module)
            elif isinstance(node, ast.Import):
                used.update(a.name for a in node.names if a.name.startswith("articutool"))
    assert used <= ({"articutool.spec", "articutool.datafile"}
                    | {m for m in used if m.startswith("articutool.food")})
    assert "articutool.spec" in used
