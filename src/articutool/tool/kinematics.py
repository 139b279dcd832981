"""Analytic kinematics of the 2-DOF pitch/roll wrist (thesis §4.1).

Pure NumPy; every function accepts any leading batch shape. Joint order is [pitch, roll].

Model (docs/hardware.md §3): the tool-tip "up" axis y expressed in the tool base frame F0 is
Eq. 4.1, ``y = (cos θp cos θr, sin θr, sin θp cos θr)``, and the full tip orientation is
``R_F0←tip = R_y(−θp) R_z(θr) R_z(−π/2)`` whose second column is Eq. 4.1. The Jacobian
``∂y/∂q`` is Eq. 4.4. Its columns are orthogonal with norms |cos θr| and 1, so
``|cos θr|`` is both the manipulability and the singularity measure, and the pseudo-inverse
has a closed form.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "IKSolutions",
    "attitude_jacobian",
    "attitude_solutions",
    "jacobian",
    "jacobian_pinv",
    "joint_rates_for_rotation",
    "leveling_solutions",
    "nearest_attitude_solution",
    "nearest_leveling_solution",
    "rotation",
    "singularity_measure",
    "tilt_from_vertical",
    "up_vector",
    "wrap_angle",
]

TWO_PI = 2.0 * np.pi
_LIMIT_TOL = 1e-12


def _as_q(q: ArrayLike, name: str = "q") -> NDArray[np.float64]:
    a = np.asarray(q, dtype=np.float64)
    if a.ndim == 0 or a.shape[-1] != 2:
        raise ValueError(f"{name} must have shape (..., 2) as [pitch, roll]; got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite (got NaN or inf)")
    return a


def _as_vec3(v: ArrayLike, name: str) -> NDArray[np.float64]:
    a = np.asarray(v, dtype=np.float64)
    if a.ndim == 0 or a.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., 3); got {a.shape}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite (got NaN or inf)")
    return a


def wrap_angle(x: ArrayLike) -> NDArray[np.float64]:
    """Wrap angles to (−π, π]."""
    return np.pi - np.mod(np.pi - np.asarray(x, dtype=np.float64), TWO_PI)


def up_vector(q: ArrayLike) -> NDArray[np.float64]:
    """Tool-tip up vector in F0, Eq. 4.1. ``q``: (..., 2) → (..., 3)."""
    q = _as_q(q)
    p, r = q[..., 0], q[..., 1]
    cr = np.cos(r)
    return np.stack([np.cos(p) * cr, np.sin(r), np.sin(p) * cr], axis=-1)


def tilt_from_vertical(up_world: ArrayLike) -> NDArray[np.float64]:
    """Tilt (rad, in [0, π]) of the utensil: the angle between its up vector (tip y, Eq. 4.1)
    expressed in the world frame and world +z. ``up_world``: (..., 3) → (...).

    The one definition of "tilt" in this project: every reported tilt (controller state,
    simulation, planners, benchmarks) is this angle, whatever constraint bounded the motion.
    Computed as ``atan2(|v × ẑ|, v · ẑ)``, accurate near level where ``arccos`` is not; ``v``
    need not be unit length.
    """
    v = _as_vec3(up_world, "up_world")
    return np.arctan2(np.hypot(v[..., 0], v[..., 1]), v[..., 2])


def rotation(q: ArrayLike) -> NDArray[np.float64]:
    """Full tip orientation ``R_F0←tip`` (docs/hardware.md §3). ``q``: (..., 2) → (..., 3, 3)."""
    q = _as_q(q)
    cp, sp = np.cos(q[..., 0]), np.sin(q[..., 0])
    cr, sr = np.cos(q[..., 1]), np.sin(q[..., 1])
    z = np.zeros_like(cp)
    rows = [
        np.stack([cp * sr, cp * cr, -sp], axis=-1),
        np.stack([-cr, sr, z], axis=-1),
        np.stack([sp * sr, sp * cr, cp], axis=-1),
    ]
    return np.stack(rows, axis=-2)


def jacobian(q: ArrayLike) -> NDArray[np.float64]:
    """Jacobian ``∂y/∂[θp, θr]`` of the up vector, Eq. 4.4. ``q``: (..., 2) → (..., 3, 2)."""
    q = _as_q(q)
    cp, sp = np.cos(q[..., 0]), np.sin(q[..., 0])
    cr, sr = np.cos(q[..., 1]), np.sin(q[..., 1])
    col_p = np.stack([-sp * cr, np.zeros_like(cp), cp * cr], axis=-1)
    col_r = np.stack([-cp * sr, cr, -sp * sr], axis=-1)
    return np.stack([col_p, col_r], axis=-1)


def singularity_measure(q: ArrayLike) -> NDArray[np.float64]:
    """``|cos θr|`` ∈ [0, 1]: the Jacobian's smallest singular value (0 = singular)."""
    q = _as_q(q)
    return np.abs(np.cos(q[..., 1]))


def jacobian_pinv(q: ArrayLike, rcond: float = 1e-3) -> NDArray[np.float64]:
    """Moore–Penrose pseudo-inverse of Eq. 4.4, (..., 2, 3), in closed form.

    The singular values are |cos θr| (pitch column) and 1 (roll column); as in
    ``numpy.linalg.pinv``, a singular value below ``rcond`` times the largest is treated as
    zero, so at the singularity pitch receives no command.
    """
    if not 0.0 < rcond < 1.0:
        raise ValueError(f"rcond must be in (0, 1); got {rcond}")
    J = jacobian(q)
    cr = np.cos(_as_q(q)[..., 1])
    s2 = cr * cr
    keep = np.abs(cr) > rcond
    inv = np.divide(1.0, s2, out=np.zeros_like(s2), where=keep)
    row_p = J[..., :, 0] * inv[..., None]
    row_r = J[..., :, 1]
    return np.stack([row_p, row_r], axis=-2)


def joint_rates_for_rotation(
    q: ArrayLike, omega_local: ArrayLike, rcond: float = 1e-3
) -> NDArray[np.float64]:
    """Joint velocities that rotate the up vector by ``omega_local`` (Eqs. 4.6–4.7).

    ``v = ω × y(q)`` is the up vector's linear velocity; ``q̇ = J⁺(q) v``. ``omega_local`` is
    expressed in F0. Shapes: q (..., 2), omega (..., 3) → (..., 2).
    """
    omega = _as_vec3(omega_local, "omega_local")
    v = np.cross(omega, up_vector(q))
    return np.einsum("...ij,...j->...i", jacobian_pinv(q, rcond), v)


class IKSolutions(NamedTuple):
    """Candidate leveling solutions: ``q`` (..., K, 2) and ``valid`` (..., K).

    Rows with ``valid`` False are placeholders (outside the limits) and must be ignored.
    """

    q: NDArray[np.float64]
    valid: NDArray[np.bool_]


def _as_limits(limits: ArrayLike) -> NDArray[np.float64]:
    lim = np.asarray(limits, dtype=np.float64)
    if lim.shape != (2, 2):
        raise ValueError(
            f"limits must be [[pitch_lo, pitch_hi], [roll_lo, roll_hi]]; got shape {lim.shape}"
        )
    if not np.isfinite(lim).all():
        raise ValueError("limits must be finite")
    for name, (lo, hi) in zip(("pitch", "roll"), lim, strict=True):
        if not lo < hi:
            raise ValueError(f"{name} limits: lower ({lo}) must be below upper ({hi})")
    return lim


def _turn_shifts(lo: float, hi: float) -> NDArray[np.float64]:
    # Every k with (−π, π] + 2πk intersecting [lo, hi].
    k0 = int(np.ceil((lo - np.pi) / TWO_PI - 1e-12))
    k1 = int(np.floor((hi + np.pi) / TWO_PI + 1e-12))
    return TWO_PI * np.arange(k0, k1 + 1, dtype=np.float64)


def leveling_solutions(v: ArrayLike, limits: ArrayLike) -> IKSolutions:
    """Every wrist configuration inside ``limits`` whose up vector points along ``v``.

    Inverts Eq. 4.1 (Eqs. 4.2–4.3) on both branches, ``(atan2(vz, vx), asin(vy))`` and
    ``(θp + π, π − θr)``, plus whole turns of either joint that stay inside the limits.
    ``v`` (..., 3) is expressed in F0 and need not be unit length (it must be non-zero).
    At the singularity (|vy| = 1) pitch is arbitrary; the solution with pitch 0 (or π) is
    returned.
    """
    v = _as_vec3(v, "v")
    lim = _as_limits(limits)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    if (n <= 1e-12).any():
        raise ValueError("v must be a non-zero vector")
    u = v / n
    p_a = np.arctan2(u[..., 2], u[..., 0])
    r_a = np.arcsin(np.clip(u[..., 1], -1.0, 1.0))
    base = np.stack(
        [
            np.stack([p_a, r_a], axis=-1),
            np.stack([wrap_angle(p_a + np.pi), wrap_angle(np.pi - r_a)], axis=-1),
        ],
        axis=-2,
    )  # (..., 2 branches, 2)
    return _within_limits(base, np.ones(base.shape[:-1], dtype=bool), lim)


def _within_limits(base: NDArray[np.float64], ok: NDArray[np.bool_],
                   lim: NDArray[np.float64]) -> IKSolutions:
    """The branch solutions ``base`` (..., B, 2), valid where ``ok`` (..., B), plus whole turns
    of either joint, marked valid where inside ``lim``."""
    sp = _turn_shifts(*lim[0])
    sr = _turn_shifts(*lim[1])
    shifts = np.stack(np.meshgrid(sp, sr, indexing="ij"), axis=-1).reshape(-1, 2)  # (S, 2)
    q = (base[..., :, None, :] + shifts).reshape(*base.shape[:-2], -1, 2)  # (..., B·S, 2)
    inside = (q >= lim[:, 0] - _LIMIT_TOL) & (q <= lim[:, 1] + _LIMIT_TOL)
    valid = inside.all(axis=-1) & np.repeat(ok, len(shifts), axis=-1)
    q = np.clip(q, lim[:, 0], lim[:, 1])
    return IKSolutions(q, valid)


def nearest_leveling_solution(
    v: ArrayLike, limits: ArrayLike, q_ref: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The valid leveling solution closest (Euclidean, in joint space) to ``q_ref``.

    Returns ``(q, found)`` with shapes (..., 2) and (...); where nothing is valid, ``q`` is
    ``q_ref`` and ``found`` is False.
    """
    return _nearest(leveling_solutions(v, limits), q_ref)


def _nearest(sols: IKSolutions, q_ref: ArrayLike
             ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    q_ref = np.broadcast_to(_as_q(q_ref, "q_ref"), sols.q.shape[:-2] + (2,))
    d = np.linalg.norm(sols.q - q_ref[..., None, :], axis=-1)
    d = np.where(sols.valid, d, np.inf)
    idx = np.argmin(d, axis=-1)
    q = np.take_along_axis(sols.q, idx[..., None, None], axis=-2)[..., 0, :]
    found = sols.valid.any(axis=-1)
    return np.where(found[..., None], q, q_ref), found


def _unit(v: ArrayLike, name: str) -> NDArray[np.float64]:
    a = _as_vec3(v, name)
    n = np.linalg.norm(a, axis=-1, keepdims=True)
    if (n <= 1e-12).any():
        raise ValueError(f"{name} must be a non-zero vector")
    return a / n


def attitude_solutions(g: ArrayLike, v: ArrayLike, limits: ArrayLike) -> IKSolutions:
    """Every wrist configuration inside ``limits`` whose tip turns the tip-frame vector ``g``
    (3,) onto the F0 vector ``v`` (..., 3): ``rotation(q) @ g ∥ v``. Leveling is ``g = ŷ``.

    With ``h = R_z(−π/2) g``, roll must give ``R_z(θr) h`` the y component of ``v``:
    ``ρ sin(θr + φ) = v_y`` (``ρ = |h_xy|``, ``φ = atan2(h_y, h_x)``), two branches; pitch
    then turns the x–z part onto ``v``'s. No solution exists where ``|v_y| > ρ``: those rows
    are invalid. Where ``ρ`` is 0 roll is arbitrary (roll 0 is returned); where the turned
    vector lies along the pitch axis, pitch is (pitch 0).
    """
    gu = _unit(g, "g")
    if gu.shape != (3,):
        raise ValueError(f"g must be one vector of shape (3,); got {gu.shape}")
    u = _unit(v, "v")
    lim = _as_limits(limits)
    hx, hy, hz = gu[1], -gu[0], gu[2]  # R_z(−π/2) g
    rho = float(np.hypot(hx, hy))
    phi = float(np.arctan2(hy, hx))
    vy = u[..., 1]
    ok = np.abs(vy) <= rho + 1e-12
    # sin a = v_y / ρ and ρ cos a = ±√(ρ² − v_y²) = ±√(|v_xz|² − h_z²) (both unit vectors):
    # the second form makes the turned vector's x–z length equal v's by construction, and its
    # factors keep their digits where v is nearly along the roll circle's edge.
    vxz = np.hypot(u[..., 0], u[..., 2])
    c2 = np.maximum((vxz - abs(hz)) * (vxz + abs(hz)), 0.0)
    a = np.arctan2(vy, np.sqrt(c2)) if rho > 1e-12 else np.zeros_like(vy)
    branches = []
    for r in (a - phi, np.pi - a - phi):
        wx = hx * np.cos(r) - hy * np.sin(r)
        p = np.arctan2(u[..., 2], u[..., 0]) - np.arctan2(hz, wx)
        p = np.where(np.hypot(wx, hz) < 1e-9, 0.0, p)  # along the pitch axis: any pitch
        branches.append(np.stack([wrap_angle(p), wrap_angle(r)], axis=-1))
    base = np.stack(branches, axis=-2)  # (..., 2 branches, 2)
    return _within_limits(base, np.stack([ok, ok], axis=-1), lim)


def nearest_attitude_solution(
    g: ArrayLike, v: ArrayLike, limits: ArrayLike, q_ref: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The valid :func:`attitude_solutions` row closest (joint space) to ``q_ref``; as
    :func:`nearest_leveling_solution`."""
    return _nearest(attitude_solutions(g, v, limits), q_ref)


def attitude_jacobian(q: ArrayLike, g: ArrayLike) -> NDArray[np.float64]:
    """``∂(rotation(q) g)/∂[θp, θr]`` (3, 2): the pitch axis is −F0 y, the roll axis
    ``R_y(−θp) ẑ``; each column is the axis × the turned vector (Eq. 4.4 for ``g = ŷ``)."""
    qq = _as_q(q)
    if qq.shape != (2,):
        raise ValueError(f"q must be one configuration [pitch, roll]; got shape {qq.shape}")
    a = rotation(qq) @ _as_vec3(g, "g")
    cp, sp = np.cos(qq[0]), np.sin(qq[0])
    col_p = np.array([-a[2], 0.0, a[0]])  # −ŷ × a
    col_r = np.cross(np.array([-sp, 0.0, cp]), a)
    return np.stack([col_p, col_r], axis=-1)
