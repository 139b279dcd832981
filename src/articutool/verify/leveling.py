"""Following a leveling solution along samples (thesis Eqs. 4.2–4.3, Alg. 2 line 12): both IK
branches made continuous, shifted by whole turns into the wrist's limits, and the nearest one
followed, switching only where the motors can make the jump. Shared by the verifier (level
against gravity) and the slosh-free wrist (level against the apparent gravity)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from articutool.tool.kinematics import wrap_angle

__all__ = ["branch_curves", "candidate_curves", "follow"]


def branch_curves(u: NDArray[np.float64]) -> NDArray[np.float64]:
    """Both IK branches (Eqs. 4.2–4.3) made continuous along the samples: (2, N, 2)."""
    p_a = np.arctan2(u[:, 2], u[:, 0])
    r_a = np.arcsin(np.clip(u[:, 1], -1.0, 1.0))
    a = np.stack([p_a, r_a], axis=-1)
    b = np.stack([wrap_angle(p_a + np.pi), wrap_angle(np.pi - r_a)], axis=-1)
    return np.unwrap(np.stack([a, b]), axis=1)


def candidate_curves(u: NDArray[np.float64], lim: NDArray[np.float64]) -> NDArray[np.float64]:
    """Every branch curve shifted by whole turns that enters the limits somewhere: (C, N, 2)."""
    base = branch_curves(u)
    out = []
    for curve in base:
        shifts = []
        for j in range(2):
            lo_k = np.ceil((lim[j, 0] - curve[:, j].max()) / (2 * np.pi) - 1e-12)
            hi_k = np.floor((lim[j, 1] - curve[:, j].min()) / (2 * np.pi) + 1e-12)
            shifts.append(2 * np.pi * np.arange(lo_k, hi_k + 1))
        for sp in shifts[0]:
            for sr in shifts[1]:
                out.append(curve + np.array([sp, sr]))
    if not out:
        return np.empty((0,) + u.shape[:1] + (2,))
    return np.stack(out)


def follow(
    curves: NDArray[np.float64],
    valid: NDArray[np.bool_],
    q_start: NDArray[np.float64],
    t: NDArray[np.float64],
    vmax: NDArray[np.float64],
) -> tuple[NDArray[np.float64], int, int | None, str]:
    """Follow the nearest valid solution; returns (q, switches, fail_index, fail_reason).
    Every step, along a curve or across a switch, must fit ``vmax`` × the time step;
    ``fail_reason`` "discontinuity" (a switch) or "discontinuity_along" (along one curve)."""
    n = t.size
    q = np.full((n, 2), np.nan)
    if curves.shape[0] == 0 or not valid[:, 0].any():
        return q, 0, 0, "no_leveling_solution"
    d0 = np.where(valid[:, 0], np.linalg.norm(curves[:, 0] - q_start, axis=-1), np.inf)
    c = int(np.argmin(d0))
    k = 0
    switches = 0
    while True:
        bad = np.flatnonzero(~valid[c, k:])
        end = n if bad.size == 0 else k + int(bad[0])
        q[k:end] = curves[c, k:end]
        fast = np.flatnonzero((np.abs(np.diff(q[k:end], axis=0))
                               > vmax * np.diff(t[k:end])[:, None]).any(axis=-1))
        if fast.size:
            return q, switches, k + int(fast[0]) + 1, "discontinuity_along"
        if end == n:
            return q, switches, None, ""
        if not valid[:, end].any():
            return q, switches, end, "no_leveling_solution"
        prev = q[end - 1]
        d = np.where(valid[:, end], np.linalg.norm(curves[:, end] - prev, axis=-1), np.inf)
        c = int(np.argmin(d))
        jump = np.abs(curves[c, end] - prev)
        switches += 1
        if (jump > vmax * (t[end] - t[end - 1])).any():
            q[end] = curves[c, end]
            return q, switches, end, "discontinuity"
        k = end
