"""Orientation constraints of the three transport planners (thesis §5.2, Exp. 2a) — pure math.

Conventions (arm base frame, z up = against gravity):

* **Tip tilt** (strict6, strict8). The utensil tip frame has y = the up vector (Eq. 4.1),
  z = along the utensil shaft (the roll axis) and x = lateral. With ``w = Rᵀ ẑ`` the world up
  direction in the tip frame, the tip's **pitch** is the shaft's elevation above the horizontal,
  ``asin(w_z)``, and its **roll** the lateral axis' elevation, ``asin(w_x)`` (the tilt an
  accelerometer on the tip reads). The tip is level when both are 0 and ``w_y > 0``; the strict
  constraint is ``|pitch| ≤ tol`` and ``|roll| ≤ tol``, i.e. ``|w_z|, |w_x| ≤ sin(tol)``: a
  *per-axis* tolerance, as MoveIt's orientation constraints (and so the thesis' baselines)
  bound each axis separately. With both axes at the bound the utensil is tilted up to
  ``acos(√(1 − 2 sin² tol))`` from vertical (14.2° for ±10°), so every *reported* tilt is the true
  angle between the utensil's up vector and vertical (:func:`tip_tilt_deg`, built on
  :func:`articutool.tool.kinematics.tilt_from_vertical`); :func:`tip_axis_tilt_deg` is the
  per-axis quantity the tolerance bounds.
* **Tool base tilt** (decoupled). With ``u = R_F0ᵀ ẑ`` the up direction in F0, the wrist
  angles that level the tool are Eqs. 4.2–4.3: ``θp = atan2(u_z, u_x)``, ``θr = asin(u_y)``
  (branch A; branch B is ``(θp + π, π − θr)``). These *leveling angles* are F0's pitch and roll
  relative to gravity — yaw about gravity leaves them unchanged (yaw free). The "level"
  reference is the leveling solution at the start configuration (the rotation that puts the
  tool level there; ``(0, 0)`` when the tool is level with the wrist at zero). The loose
  constraint keeps ``|θp − θp_ref| ≤ pitch_tol`` and ``|θr − θr_ref| ≤ roll_tol`` along the
  path (thesis: ±90° pitch, ±45° roll), using the reference's branch — and keeps that
  branch's pitch ``θp_ref + Δθp`` inside the wrist's pitch range. The ±90° band is about the
  start's reference, so from a start whose wrist is already pitched it reaches past the pitch
  stop; there the leveling solution can only continue on the other branch, a jump the
  motors cannot make, and the verifier (§4.3.2) rejects the plan.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.tool.kinematics import tilt_from_vertical, wrap_angle

__all__ = [
    "LooseConstraint",
    "StrictConstraint",
    "f0_leveling_angles",
    "tip_axis_tilt_deg",
    "tip_tilt",
    "tip_tilt_deg",
]



def tip_tilt(R_tip: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                        NDArray[np.bool_]]:
    """Pitch, roll (rad) and upright flag of tip rotations ``R_base←tip`` (..., 3, 3)."""
    R = np.asarray(R_tip, dtype=np.float64)
    w = R[..., 2, :]  # Rᵀ ẑ = third row of R
    pitch = np.arcsin(np.clip(w[..., 2], -1.0, 1.0))
    roll = np.arcsin(np.clip(w[..., 0], -1.0, 1.0))
    return pitch, roll, w[..., 1] > 0.0


def tip_axis_tilt_deg(R_tip: ArrayLike) -> NDArray[np.float64]:
    """``max(|pitch|, |roll|)`` in degrees, the per-axis quantity the strict tolerance bounds.

    An upside-down tip (``w_y ≤ 0``) reports 180°. Not a tilt angle: report
    :func:`tip_tilt_deg`.
    """
    pitch, roll, up = tip_tilt(R_tip)
    t = np.degrees(np.maximum(np.abs(pitch), np.abs(roll)))
    return np.where(up, t, 180.0)


def tip_tilt_deg(R_tip: ArrayLike) -> NDArray[np.float64]:
    """Tilt (deg) of tip rotations ``R_base←tip`` (..., 3, 3): the angle between the
    utensil's up vector (tip y) and vertical
    (:func:`~articutool.tool.kinematics.tilt_from_vertical`)."""
    R = np.asarray(R_tip, dtype=np.float64)
    return np.degrees(tilt_from_vertical(R[..., :, 1]))


def f0_leveling_angles(R_f0: ArrayLike, branch: int = 0) -> NDArray[np.float64]:
    """Leveling angles ``[θp, θr]`` (Eqs. 4.2–4.3) of tool-base rotations (..., 3, 3) → (..., 2).

    ``branch`` 0 is ``(atan2(u_z, u_x), asin(u_y))``, 1 is ``(θp + π, π − θr)`` (wrapped).
    """
    R = np.asarray(R_f0, dtype=np.float64)
    u = R[..., 2, :]  # R_F0ᵀ ẑ
    p = np.arctan2(u[..., 2], u[..., 0])
    r = np.arcsin(np.clip(u[..., 1], -1.0, 1.0))
    if branch:
        p, r = wrap_angle(p + np.pi), wrap_angle(np.pi - r)
    return np.stack([p, r], axis=-1)


@dataclass(frozen=True)
class StrictConstraint:
    """Tip within ±``tol`` (rad) pitch and roll of level (module docstring)."""

    tol: float

    def __post_init__(self) -> None:
        if not 0.0 < self.tol < np.pi / 2:
            raise ValueError(f"tolerance must be in (0, 90) degrees; got {np.degrees(self.tol)}")

    @property
    def bound(self) -> float:
        """Bound on ``|w_x|`` and ``|w_z|``: ``sin(tol)``."""
        return float(np.sin(self.tol))

    def satisfied(self, R_tip: ArrayLike, slack: float = 0.0) -> NDArray[np.bool_]:
        """True where the tip is upright and ``|w_x|, |w_z| ≤ sin(tol) + slack``."""
        w = np.asarray(R_tip, dtype=np.float64)[..., 2, :]
        b = self.bound + slack
        return (np.abs(w[..., 0]) <= b) & (np.abs(w[..., 2]) <= b) & (w[..., 1] > 0.0)

    def deadzone(self, R_tip: NDArray[np.float64]) -> NDArray[np.float64]:
        """Dead-zone residual ``sign(w_i)·max(0, |w_i| − sin tol)`` for i ∈ (z, x): (2,).

        Zero inside the tolerance band, so projection (Newton on this function) moves a
        configuration only onto the band's boundary, never to exact level.
        """
        w = R_tip[2]
        e = np.array([w[2], w[0]])
        return np.sign(e) * np.maximum(np.abs(e) - self.bound, 0.0)

    def deadzone_jacobian(
        self, R_tip: NDArray[np.float64], J_angular: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """Jacobian (2, n) of :meth:`deadzone` from the tip's world angular Jacobian (3, n).

        ``d(Rᵀẑ)/dt = Rᵀ (ẑ × ω)``; rows of satisfied components are zero.
        """
        # Rᵀ [ẑ]× J: [ẑ]× J has rows (−J_y, J_x, 0), so only R's first two rows contribute.
        Jx, Jy = J_angular[0], J_angular[1]
        w = R_tip[2]
        b = self.bound
        out = np.zeros((2, J_angular.shape[1]))
        if abs(w[2]) > b:  # d w_z = column z of R · (ẑ × ω)
            out[0] = -R_tip[0, 2] * Jy + R_tip[1, 2] * Jx
        if abs(w[0]) > b:
            out[1] = -R_tip[0, 0] * Jy + R_tip[1, 0] * Jx
        return out


@dataclass(frozen=True)
class LooseConstraint:
    """Tool base F0 within ±``pitch_tol``/±``roll_tol`` (rad) of its level reference."""

    pitch_tol: float
    roll_tol: float
    reference: tuple[float, float] = (0.0, 0.0)  # leveling angles [θp, θr] at the start
    branch: int = 0
    pitch_limits: tuple[float, float] = (-np.inf, np.inf)  # the wrist's pitch range (rad)

    def deviation(self, R_f0: ArrayLike) -> NDArray[np.float64]:
        """Leveling-angle deviation from the reference (..., 2), pitch wrapped to (−π, π]."""
        a = f0_leveling_angles(R_f0, self.branch) - np.asarray(self.reference)
        return np.stack([wrap_angle(a[..., 0]), wrap_angle(a[..., 1])], axis=-1)

    def satisfied(self, R_f0: ArrayLike) -> NDArray[np.bool_]:
        """True where both deviations are within tolerance and the leveling pitch is inside
        the wrist's pitch range."""
        d = self.deviation(R_f0)
        p = self.reference[0] + d[..., 0]
        lo, hi = self.pitch_limits
        return ((np.abs(d[..., 0]) <= self.pitch_tol) & (np.abs(d[..., 1]) <= self.roll_tol)
                & (p >= lo) & (p <= hi))

    @staticmethod
    def from_start(
        R_f0_start: ArrayLike, q_wrist_start: ArrayLike, pitch_tol: float, roll_tol: float,
        pitch_limits: tuple[float, float] = (-np.inf, np.inf),
    ) -> LooseConstraint:
        """Reference = the branch of the start's leveling solution nearest ``q_wrist_start``;
        ``pitch_limits``: the wrist's pitch range (``spec.wrist.pitch_limits``)."""
        qs = np.asarray(q_wrist_start, dtype=np.float64)
        cands = [f0_leveling_angles(R_f0_start, b) for b in (0, 1)]
        d = [np.linalg.norm(wrap_angle(c - qs)) for c in cands]
        b = int(np.argmin(d))
        ref = cands[b]
        lo, hi = pitch_limits
        return LooseConstraint(pitch_tol, roll_tol, (float(ref[0]), float(ref[1])), b,
                               (float(lo), float(hi)))
