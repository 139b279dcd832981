"""Property tests for the wrist kinematics (thesis Eqs. 4.1–4.4)."""

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from articutool.tool.kinematics import (
    jacobian,
    jacobian_pinv,
    joint_rates_for_rotation,
    leveling_solutions,
    nearest_leveling_solution,
    rotation,
    singularity_measure,
    up_vector,
    wrap_angle,
)
from conftest import packaged_spec

SPEC = packaged_spec()
LIMITS = SPEC.wrist.limits
angles = st.floats(-np.pi, np.pi, allow_nan=False)
big_angles = st.floats(-40.0, 40.0, allow_nan=False)
unit = st.floats(-1.0, 1.0, allow_nan=False)


@st.composite
def limit_boxes(draw):
    """Random joint-limit boxes, from narrow to multi-turn (the roll budget case)."""
    out = []
    for _ in range(2):
        lo = draw(st.floats(-14 * np.pi, 14 * np.pi))
        width = draw(st.floats(0.05, 8 * np.pi))
        out.append([lo, lo + width])
    return np.array(out)


@st.composite
def directions(draw):
    v = np.array([draw(unit), draw(unit), draw(unit)])
    assume(np.linalg.norm(v) > 1e-3)
    return v


def test_up_vector_is_eq_4_1_and_second_column_of_rotation():
    q = np.array([0.3, -1.1])
    cp, sp, cr, sr = np.cos(0.3), np.sin(0.3), np.cos(-1.1), np.sin(-1.1)
    np.testing.assert_allclose(up_vector(q), [cp * cr, sr, sp * cr])
    np.testing.assert_allclose(rotation(q)[:, 1], up_vector(q))
    # At zero the up vector is +x of F0 and the utensil (tip z) extends along +z.
    np.testing.assert_allclose(rotation([0.0, 0.0])[:, 2], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(up_vector([0.0, 0.0]), [1, 0, 0], atol=1e-15)


@given(angles, angles)
def test_rotation_is_proper_and_matches_pitch_then_roll(p, r):
    R = rotation([p, r])
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)

    def Ry(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def Rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    np.testing.assert_allclose(R, Ry(-p) @ Rz(r) @ Rz(-np.pi / 2), atol=1e-12)


@given(big_angles, big_angles)
def test_jacobian_equals_central_differences(p, r):
    q = np.array([p, r])
    h = 1e-6
    fd = np.stack([(up_vector(q + h * e) - up_vector(q - h * e)) / (2 * h) for e in np.eye(2)],
                  axis=-1)
    np.testing.assert_allclose(jacobian(q), fd, atol=1e-8)


@given(angles, angles)
def test_pinv_matches_numpy_and_singularity_measure_is_smallest_singular_value(p, r):
    q = np.array([p, r])
    J = jacobian(q)
    s = np.linalg.svd(J, compute_uv=False)
    assert singularity_measure(q) == pytest.approx(s.min(), abs=1e-12)
    assume(abs(abs(np.cos(r)) - 1e-3) > 1e-6)  # away from the rcond cut itself
    np.testing.assert_allclose(jacobian_pinv(q, 1e-3), np.linalg.pinv(J, rcond=1e-3), atol=1e-7)


@given(angles, st.floats(-1.45, 1.45), directions())
def test_joint_rates_reproduce_the_up_vector_velocity(p, r, w):
    q = np.array([p, r])
    qd = joint_rates_for_rotation(q, w)
    # ω × y is tangent to the sphere at y, which J spans away from the singularity (Eq. 4.6-4.7).
    np.testing.assert_allclose(jacobian(q) @ qd, np.cross(w, up_vector(q)), atol=1e-9)


@given(directions(), limit_boxes())
def test_fk_of_every_solution_is_the_target_and_inside_limits(v, lim):
    sols = leveling_solutions(v, lim)
    q = sols.q[sols.valid]
    assert ((q >= lim[:, 0]) & (q <= lim[:, 1])).all()
    if abs(v[1]) / np.linalg.norm(v) < 1 - 1e-9:
        target = np.broadcast_to(v / np.linalg.norm(v), q.shape[:-1] + (3,))
        np.testing.assert_allclose(up_vector(q), target, atol=1e-9)


@given(big_angles, big_angles, st.lists(st.floats(0.0, 8 * np.pi), min_size=4, max_size=4))
def test_no_valid_solution_is_missed(p, r, widths):
    q = np.array([p, r])
    assume(abs(np.cos(r)) > 1e-6)  # pitch is undefined at the singularity
    assume(widths[0] + widths[1] > 1e-3 and widths[2] + widths[3] > 1e-3)
    lim = np.array([[p - widths[0], p + widths[1]], [r - widths[2], r + widths[3]]])
    sols = leveling_solutions(up_vector(q), lim)
    d = np.linalg.norm(sols.q[sols.valid] - q, axis=-1)
    assert d.size and d.min() < 1e-7


@given(directions(), limit_boxes())
def test_solution_count_matches_brute_force_enumeration(v, lim):
    u = v / np.linalg.norm(v)
    assume(abs(u[1]) < 1 - 1e-6)
    # Independent enumeration: both branches, turns k in a wide range, filtered by the limits.
    pa, ra = np.arctan2(u[2], u[0]), np.arcsin(u[1])
    count = 0
    for bp, br in ((pa, ra), (pa + np.pi, np.pi - ra)):
        for kp in range(-12, 13):
            for kr in range(-12, 13):
                c = np.array([bp + 2 * np.pi * kp, br + 2 * np.pi * kr])
                eps = 1e-9
                if ((c >= lim[:, 0] + eps) & (c <= lim[:, 1] - eps)).all():
                    count += 1
                elif ((c >= lim[:, 0] - eps) & (c <= lim[:, 1] + eps)).all():
                    assume(False)  # on a limit boundary: rounding decides, skip
    assert int(leveling_solutions(v, lim).valid.sum()) == count


def test_second_branch_is_correct_where_the_reference_was_wrong():
    # The reference's second branch (θp, π − θr) gives (−vx, vy, −vz); ours must reproduce v.
    v = np.array([-0.5, 0.3, 0.2])
    v /= np.linalg.norm(v)
    sols = leveling_solutions(v, LIMITS)
    assert sols.valid.sum() == 1  # with |pitch| ≤ π/2 only the second branch fits
    q = sols.q[sols.valid][0]
    np.testing.assert_allclose(up_vector(q), v, atol=1e-12)


def test_batched_shapes():
    rng = np.random.default_rng(0)
    q = rng.uniform(-1, 1, size=(4, 5, 2))
    assert up_vector(q).shape == (4, 5, 3)
    assert rotation(q).shape == (4, 5, 3, 3)
    assert jacobian(q).shape == (4, 5, 3, 2)
    assert jacobian_pinv(q).shape == (4, 5, 2, 3)
    sols = leveling_solutions(up_vector(q), LIMITS)
    assert sols.q.shape[:2] == (4, 5) and sols.valid.shape[:2] == (4, 5)
    qn, found = nearest_leveling_solution(up_vector(q), LIMITS, q)
    assert found.all()
    np.testing.assert_allclose(qn, q, atol=1e-9)


def test_nearest_reports_unreachable():
    lim = np.array([[-0.1, 0.1], [-0.1, 0.1]])
    q, found = nearest_leveling_solution([0.0, 0.0, 1.0], lim, [0.0, 0.0])
    assert not found
    np.testing.assert_array_equal(q, [0.0, 0.0])


@given(st.floats(-100, 100))
def test_wrap_angle_range(x):
    w = wrap_angle(x)
    assert -np.pi < w <= np.pi
    assert np.cos(w) == pytest.approx(np.cos(x), abs=1e-9)


@pytest.mark.parametrize(
    ("fn", "arg", "match"),
    [
        (up_vector, [np.nan, 0.0], "finite"),
        (up_vector, [0.0, 0.0, 0.0], r"shape \(\.\.\., 2\)"),
        (jacobian, [np.inf, 0.0], "finite"),
        (rotation, 1.0, "shape"),
    ],
)
def test_bad_joint_input_is_rejected(fn, arg, match):
    with pytest.raises(ValueError, match=match):
        fn(arg)


def test_bad_ik_input_is_rejected():
    with pytest.raises(ValueError, match="non-zero"):
        leveling_solutions([0.0, 0.0, 0.0], LIMITS)
    with pytest.raises(ValueError, match="finite"):
        leveling_solutions([np.nan, 0.0, 1.0], LIMITS)
    with pytest.raises(ValueError, match="lower"):
        leveling_solutions([0.0, 0.0, 1.0], [[1.0, -1.0], [0.0, 1.0]])
    with pytest.raises(ValueError, match="limits must be"):
        leveling_solutions([0.0, 0.0, 1.0], [1.0, 2.0])
    with pytest.raises(ValueError, match="rcond"):
        jacobian_pinv([0.0, 0.0], rcond=0.0)


@settings(max_examples=50)
@given(arrays(np.float64, (7, 2), elements=st.floats(-3, 3)))
def test_vectorised_equals_pointwise(q):
    np.testing.assert_allclose(jacobian(q), np.stack([jacobian(x) for x in q]))
    np.testing.assert_allclose(up_vector(q), np.stack([up_vector(x) for x in q]))
