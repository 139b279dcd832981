"""The rotations module: properties that must hold for every rotation, and
agreement with SciPy's ``Rotation`` (an independent implementation, PC extra)."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from articutool.rotations import (
    axis_angle_matrix,
    matrix_to_quaternion,
    quaternion_multiply,
    quaternion_to_matrix,
    rpy_matrix,
)

_c = st.floats(-1.0, 1.0, allow_nan=False)
quats = st.tuples(_c, _c, _c, _c).filter(lambda q: sum(c * c for c in q) > 1e-3)
angles = st.floats(-2 * math.pi, 2 * math.pi, allow_nan=False)
axes = st.tuples(_c, _c, _c).filter(lambda a: sum(c * c for c in a) > 1e-3)


def _unit(q):
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q)


def _same_rotation(q1, q2):  # q and -q are one rotation
    return min(np.abs(_unit(q1) - _unit(q2)).max(), np.abs(_unit(q1) + _unit(q2)).max())


@given(quats)
def test_a_quaternion_gives_a_proper_rotation(q) -> None:
    R = quaternion_to_matrix(q)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)


@given(quats)
def test_quaternion_matrix_round_trip(q) -> None:
    back = matrix_to_quaternion(quaternion_to_matrix(q))
    assert back[0] >= 0.0 and np.linalg.norm(back) == pytest.approx(1.0)
    assert _same_rotation(back, q) < 1e-9


@given(quats, quats)
def test_the_product_is_the_composition(a, b) -> None:
    np.testing.assert_allclose(quaternion_to_matrix(quaternion_multiply(a, b)),
                               quaternion_to_matrix(a) @ quaternion_to_matrix(b), atol=1e-12)


@given(quats)
def test_identity_and_inverse(q) -> None:
    one = (1.0, 0.0, 0.0, 0.0)
    u = _unit(q)
    np.testing.assert_allclose(quaternion_multiply(one, u), u, atol=1e-15)
    conj = u * np.array([1.0, -1.0, -1.0, -1.0])
    np.testing.assert_allclose(quaternion_multiply(u, conj), one, atol=1e-12)
    np.testing.assert_allclose(quaternion_to_matrix(one), np.eye(3), atol=0)
    np.testing.assert_allclose(matrix_to_quaternion(np.eye(3)), one, atol=0)


@given(quats)
def test_quaternions_agree_with_scipy(q) -> None:
    w, x, y, z = _unit(q)
    ref = Rotation.from_quat([x, y, z, w])  # SciPy: scalar last
    np.testing.assert_allclose(quaternion_to_matrix(q), ref.as_matrix(), atol=1e-12)
    rx, ry, rz, rw = Rotation.from_matrix(quaternion_to_matrix(q)).as_quat()
    assert _same_rotation(matrix_to_quaternion(ref.as_matrix()), (rw, rx, ry, rz)) < 1e-9


@given(angles, angles, angles)
def test_rpy_is_fixed_axis_xyz_as_scipy_and_composes_from_single_axes(r, p, y) -> None:
    R = rpy_matrix((r, p, y))
    np.testing.assert_allclose(R, Rotation.from_euler("xyz", [r, p, y]).as_matrix(), atol=1e-12)
    ex, ey, ez = np.eye(3)
    np.testing.assert_allclose(
        R, axis_angle_matrix(ez, y) @ axis_angle_matrix(ey, p) @ axis_angle_matrix(ex, r),
        atol=1e-12)


@given(axes, angles)
def test_axis_angle_agrees_with_scipy_and_inverts(axis, angle) -> None:
    R = axis_angle_matrix(axis, angle)
    np.testing.assert_allclose(R, Rotation.from_rotvec(angle * _unit(axis)).as_matrix(),
                               atol=1e-12)
    np.testing.assert_allclose(R @ axis_angle_matrix(axis, -angle), np.eye(3), atol=1e-12)
    np.testing.assert_allclose(R @ _unit(axis), _unit(axis), atol=1e-12)  # the axis stays


@pytest.mark.parametrize("bad", [(0.0, 0.0, 0.0, 0.0), (1.0, math.nan, 0.0, 0.0), (1.0, 0.0)])
def test_a_bad_quaternion_is_refused(bad) -> None:
    with pytest.raises(ValueError, match="quaternion"):
        quaternion_to_matrix(bad)


def test_a_bad_axis_is_refused() -> None:
    with pytest.raises(ValueError, match="axis"):
        axis_angle_matrix((0.0, 0.0, 0.0), 1.0)
