"""One tilt: the angle between the utensil's up vector and vertical."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from articutool.planning.constraints import StrictConstraint, tip_axis_tilt_deg, tip_tilt_deg
from articutool.tool.kinematics import tilt_from_vertical

unit = st.tuples(*[st.floats(-1, 1, allow_nan=False)] * 3).filter(
    lambda v: math.hypot(*v) > 1e-3)


def _rot(axis: np.ndarray, a: float) -> np.ndarray:
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


# A level tip: y axis up (columns x̂, ẑ, −ŷ).
_LEVEL = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


@given(unit)
def test_tilt_is_the_angle_to_vertical(v: tuple[float, float, float]) -> None:
    a = np.array(v)
    expect = math.acos(np.clip(a[2] / np.linalg.norm(a), -1, 1))
    assert abs(float(tilt_from_vertical(a)) - expect) < 1e-6
    assert 0.0 <= float(tilt_from_vertical(a)) <= math.pi


@given(st.floats(-math.pi, math.pi), st.floats(0, math.pi), st.floats(-math.pi, math.pi))
def test_tip_tilt_is_yaw_invariant_and_equals_the_rotation_off_vertical(
    yaw: float, tilt: float, axis_angle: float
) -> None:
    # Tilt the level tip by `tilt` about a horizontal axis, then yaw it: tilt is `tilt`.
    axis = np.array([math.cos(axis_angle), math.sin(axis_angle), 0.0])
    R = _rot(np.array([0.0, 0.0, 1.0]), yaw) @ _rot(axis, tilt) @ _LEVEL
    assert abs(float(tip_tilt_deg(R)) - math.degrees(tilt)) < 1e-6


def test_per_axis_band_corner_reports_the_true_tilt() -> None:
    # Pitch and roll both at the ±10° per-axis bound: inside the strict band, but the
    # utensil is tilted 14.1° from vertical — the number a tilt report must give.
    s = math.sin(math.radians(10.0))
    w = np.array([s, math.sqrt(1 - 2 * s * s), s])  # world up in the tip frame: Rᵀ ẑ
    y = np.cross(w, [1.0, 0.0, 0.0])
    x = np.cross(y, w)
    x, y = x / np.linalg.norm(x), y / np.linalg.norm(y)
    # Build R with third row w (Rᵀ ẑ = w) from an orthonormal frame whose rows are (·, ·, w).
    R = np.vstack([x, y, w])
    R = R if np.linalg.det(R) > 0 else np.vstack([y, x, w])
    assert StrictConstraint(math.radians(10.0)).satisfied(R)
    assert abs(float(tip_axis_tilt_deg(R)) - 10.0) < 1e-9
    true = math.degrees(math.acos(math.sqrt(1 - 2 * s * s)))
    assert abs(float(tip_tilt_deg(R)) - true) < 1e-9
    assert 14.1 < float(tip_tilt_deg(R)) < 14.3
