"""The dish as a closed triangle mesh: the same dish the world collides with and the
hydrostatics integrates."""

from collections import Counter

import numpy as np
import pytest

from articutool.food.dish import spoon_dish
from articutool.food.dish_mesh import dish_boundary_mesh, dish_cavity_mesh, mesh_volume
from articutool.food.hydrostatics import Hydrostatics
from articutool.spec import load_spec


@pytest.fixture(scope="module")
def soup():
    u = load_spec().utensil("soup_spoon")
    return u, spoon_dish(u)


def _closed(faces: np.ndarray) -> bool:
    edges = Counter()
    for t in faces:
        for i in range(3):
            edges[(int(t[i]), int(t[(i + 1) % 3]))] += 1
    return all(c == 1 and edges[(b, a)] == 1 for (a, b), c in edges.items())


def test_cavity_holds_the_level_capacity(soup):
    u, d = soup
    v, f = dish_cavity_mesh(d, u.tip_x)
    assert _closed(f)
    assert mesh_volume(v, f) == pytest.approx(Hydrostatics(d).level_capacity, rel=1e-6)


def test_shell_is_closed_outward_and_as_thick_as_the_utensil(soup):
    u, d = soup
    v, f = dish_boundary_mesh(d, u.tip_x, u.physics.thickness)
    assert _closed(f)
    vol = mesh_volume(v, f)
    assert vol > 0  # outward normals
    # The shell's volume is about its inner area times the thickness (slope-corrected lip).
    vc, fc = dish_cavity_mesh(d, u.tip_x)
    assert 0.8 * u.physics.thickness < vol / _inner_area(vc, fc) < 1.6 * u.physics.thickness
    # The inner floor lies at tip_x and faces +x (into the liquid).
    floor = np.isclose(v[:, 0], u.tip_x)
    assert floor.sum() >= 64
    tri = f[np.all(floor[f], axis=1)][0]
    n = np.cross(v[tri[1]] - v[tri[0]], v[tri[2]] - v[tri[0]])
    assert n[0] > 0
    # Nothing of the shell is inside the rim above the floor (the liquid's space is free).
    assert v[:, 0].max() == pytest.approx(u.tip_x + d.depth)
    assert v[:, 0].min() < u.tip_x


def _inner_area(v: np.ndarray, f: np.ndarray) -> float:
    a = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    lid = a[:, 0] > 0  # lid triangles face +x... and so do no others
    return float(np.linalg.norm(a[~lid], axis=1).sum() / 2)


def test_bad_arguments_are_refused(soup):
    u, d = soup
    with pytest.raises(ValueError, match="thickness"):
        dish_boundary_mesh(d, u.tip_x, 0.0)
    with pytest.raises(ValueError, match="segments"):
        dish_boundary_mesh(d, u.tip_x, 0.001, segments=4)
