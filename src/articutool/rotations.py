"""Rotations: one small NumPy module for the rotation and quaternion formulas the tool and the
arm share, so neither depends on the other. Core install (the Pi has NumPy only, no SciPy);
scalar floats, since these run once per 50 Hz tick on 3x3 matrices, where NumPy's vector
machinery costs more than it saves.

Conventions: quaternions are Hamilton ``(w, x, y, z)``, scalar first (the IMU filter's output,
thesis §4.2; docs/hardware.md §4; ``scene.toml``'s ``wxyz``); ``rpy`` is URDF's fixed-axis
roll-pitch-yaw, ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (thesis §4.1, the arm's joint table).
The IMU filter keeps its own quaternion arithmetic on purpose: it transcribes the C++
reference operation by operation, to agree with it bit for bit (``tool/filter.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "axis_angle_matrix",
    "matrix_to_quaternion",
    "quaternion_multiply",
    "quaternion_to_matrix",
    "rpy_matrix",
]


def quaternion_to_matrix(wxyz: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix of a Hamilton quaternion ``(w, x, y, z)`` (normalised first).

    With the filter's output (sensor in the gravity-aligned world, docs/hardware.md §4) this is
    ``R_world←imu``. ``ValueError`` for anything but 4 finite numbers, not all zero.
    """
    q = np.asarray(wxyz, dtype=np.float64)
    if q.shape != (4,) or not np.isfinite(q).all():
        raise ValueError(f"quaternion must be 4 finite numbers (w, x, y, z); got {q!r}")
    n = math.sqrt(float(q @ q))
    if n < 1e-9:
        raise ValueError("quaternion must be non-zero")
    w, x, y, z = (q / n).tolist()
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quaternion(R: ArrayLike) -> NDArray[np.float64]:
    """Unit Hamilton quaternion ``(w, x, y, z)`` of a rotation matrix, with ``w >= 0``
    (Shepperd's method: the largest of the four squares is taken from the diagonal, so no
    branch divides by a small number)."""
    m = np.asarray(R, dtype=np.float64)
    if m.shape != (3, 3) or not np.isfinite(m).all():
        raise ValueError(f"R must be a finite (3, 3) rotation matrix; got shape {m.shape}")
    t = float(m[0, 0] + m[1, 1] + m[2, 2])
    d = (t, float(m[0, 0]), float(m[1, 1]), float(m[2, 2]))
    k = max(range(4), key=d.__getitem__)
    if k == 0:
        s = 2.0 * math.sqrt(max(1.0 + t, 0.0))
        q = (0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s)
    elif k == 1:
        s = 2.0 * math.sqrt(max(1.0 + m[0, 0] - m[1, 1] - m[2, 2], 0.0))
        q = ((m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s)
    elif k == 2:
        s = 2.0 * math.sqrt(max(1.0 + m[1, 1] - m[0, 0] - m[2, 2], 0.0))
        q = ((m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s)
    else:
        s = 2.0 * math.sqrt(max(1.0 + m[2, 2] - m[0, 0] - m[1, 1], 0.0))
        q = ((m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s)
    out = np.array(q, dtype=np.float64)
    out /= np.linalg.norm(out)
    return -out if out[0] < 0 else out


def quaternion_multiply(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Hamilton product ``a ⊗ b`` (rotate by ``b``, then by ``a``): the quaternion of
    ``quaternion_to_matrix(a) @ quaternion_to_matrix(b)``."""
    w1, x1, y1, z1 = (float(c) for c in np.asarray(a, dtype=np.float64))
    w2, x2, y2, z2 = (float(c) for c in np.asarray(b, dtype=np.float64))
    return np.array([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ])


def rpy_matrix(rpy: ArrayLike | tuple[float, float, float]) -> NDArray[np.float64]:
    """URDF fixed-axis roll-pitch-yaw to a rotation matrix: ``Rz(y) @ Ry(p) @ Rx(r)``."""
    r, p, y = (float(a) for a in rpy)  # type: ignore[union-attr]
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p),
                              math.cos(y), math.sin(y))
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def axis_angle_matrix(axis: ArrayLike, angle: float) -> NDArray[np.float64]:
    """Rodrigues' formula: rotation by ``angle`` (rad) about the unit-normalised ``axis``."""
    a = np.asarray(axis, dtype=np.float64)
    n = np.linalg.norm(a)
    if a.shape != (3,) or not np.isfinite(a).all() or n == 0.0:
        raise ValueError(f"axis must be a finite non-zero 3-vector; got {axis!r}")
    x, y, z = a / n
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)
