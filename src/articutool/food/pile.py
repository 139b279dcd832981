"""A pile of pieces (pecans) in a spoon's dish: what it keeps under an apparent tilt, from its
angle of repose.

**Criterion.** A cohesionless pile at rest can hold its free surface at any slope up to its
angle of repose ``θr`` (the Mohr–Coulomb limit of a granular surface; Nedderman, *Statics and
Kinematics of Granular Materials*, Cambridge University Press, 1992, ch. 2). In a dish whose
rim plane is tilted by ``θ`` from the apparent horizontal (normal to ``g − a``):

- ``θ ≤ θr``: everything below the rim plane stays (the rim plane itself slopes less than the
  repose angle), plus a heap above the rim whose surface slopes at most ``θr − θ`` from the
  rim plane — the heap that a tilt towards its steep side starts to shed;
- ``θ > θr``: the surface can lean back by at most ``θr``, so the dish keeps what a liquid
  keeps at the tilt ``θ − θr`` (:class:`~articutool.food.hydrostatics.Hydrostatics`).

The capacity ``C(θ)`` falls monotonically with the tilt; a load of bulk volume ``V`` keeps
``min(V, C)``, and along a motion the running minimum (pieces that left do not come back).
Pieces do not slosh: the surface follows the apparent gravity at once. The heap above the rim
is the sand-pile over the rim ellipse, slope × ∫ distance-to-the-rim dA.

**Limits, stated.** A spoonful is a handful of pieces 10–30 mm across on a 60 mm dish, so the
pile is a continuum only roughly and a spill comes in pieces of ~1 g; the heap's uniform slope
``θr − θ`` is the downhill side's (the uphill side could hold more), so the criterion errs
towards predicting spill; a lone piece on the floor slides at ``atan μ`` of apparent tilt
against the dish, but the 45° walls stop it, so sliding on the floor is not a spill; no
dynamics: pieces sliding on at the kinetic friction after the tilt returns are left out.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.food.dish import Dish
from articutool.food.hydrostatics import Hydrostatics
from articutool.food.slosh import SloshPrediction, uniform_grid

__all__ = ["PileModel", "heap_integral"]


@lru_cache(maxsize=16)
def heap_integral(dish: Dish, n: int = 200) -> float:
    """``∫ dist(p, rim) dA`` over the rim ellipse (m³ per unit slope): the volume of the
    steepest heap at slope 1 (midpoint rule on an ``n × n`` grid; distances to 4 000 points of
    the rim, ≤ 0.05 mm apart, by a k-d tree)."""
    from scipy.spatial import cKDTree

    phi = np.linspace(0.0, 2 * math.pi, 4000, endpoint=False)
    rim = cKDTree(np.column_stack([dish.b * np.sin(phi), dish.a * np.cos(phi)]))
    y = ((np.arange(n) + 0.5) / n * 2 - 1) * dish.b
    z = ((np.arange(n) + 0.5) / n * 2 - 1) * dish.a
    Y, Z = np.meshgrid(y, z, indexing="ij")
    inside = (Y / dish.b) ** 2 + (Z / dish.a) ** 2 < 1
    dist, _ = rim.query(np.column_stack([Y[inside], Z[inside]]))
    return float(dist.sum() * (2 * dish.a / n) * (2 * dish.b / n))


class PileModel:
    """A pile of ``volume`` m³ (bulk) of pieces with angle of repose ``repose`` (rad) in
    ``dish`` (see the module doc). ``density`` is the bulk density (kg/m³) that turns volume
    into grams; ``dt``/``tail_s`` as :class:`~articutool.food.slosh.SloshModel`'s grid."""

    def __init__(self, dish: Dish, volume: float, repose: float, *, density: float,
                 dt: float = 0.004, tail_s: float = 0.0) -> None:
        if not (math.isfinite(repose) and 0.0 < repose < 0.5 * math.pi):
            raise ValueError(f"angle of repose must be in (0, 90)°; got {math.degrees(repose)}")
        self.hydro = Hydrostatics(dish)
        self.dish, self.repose, self.density = dish, float(repose), float(density)
        self.dt, self.tail_s = float(dt), float(tail_s)
        self._heap = heap_integral(dish)
        cap = self.capacity_at(0.0)
        v = float(volume)
        if not (math.isfinite(v) and 0.0 <= v <= float(cap)):
            raise ValueError(f"volume {v * 1e6:.4g} mL outside [0, {float(cap) * 1e6:.4g}] mL "
                             "(what the dish holds heaped at the angle of repose)")
        self.volume = v
        self._dirs = np.linspace(0.0, 0.5 * math.pi, 19)
        self._onset = self.onset_tilt(self._dirs)

    @property
    def max_volume(self) -> float:
        """The largest bulk volume (m³) the level dish holds: full and heaped at repose."""
        return float(self.capacity_at(0.0))

    def capacity_at(self, tilt: ArrayLike, direction: ArrayLike = 0.0) -> NDArray[np.float64]:
        """Bulk volume (m³) the dish keeps at an apparent tilt ``θ`` towards ``φ`` (rad)."""
        t = np.asarray(tilt, dtype=float)
        below = self.hydro.capacity_fast(np.maximum(t - self.repose, 0.0), direction)
        heap = self._heap * np.tan(np.clip(self.repose - t, 0.0, None))
        return below + heap

    def onset_tilt(self, direction: ArrayLike = 0.0) -> NDArray[np.float64]:
        """Apparent tilt (rad) towards ``direction`` at which the load starts to leave."""
        d = np.asarray(direction, dtype=float)
        lo, hi = np.zeros(d.shape), np.full(d.shape, math.pi)
        if self.volume >= self.max_volume:
            return lo
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            holds = self.capacity_at(mid, d) >= self.volume
            lo, hi = np.where(holds, mid, lo), np.where(holds, hi, mid)
        return 0.5 * (lo + hi)

    def predict(self, times: ArrayLike, g_app: ArrayLike) -> SloshPrediction:
        """What the pile keeps along a motion (apparent gravity ``g_app`` (N, 3) in the dish
        frame at ``times``), on the same uniform grid as the slosh model; the surface is the
        apparent one (no slosh)."""
        t, g = uniform_grid(times, g_app, self.dt, self.tail_s)
        tilt = np.arctan2(np.hypot(g[1], g[2]), -g[0])
        direction = np.arctan2(g[1], g[2])
        cap = self.capacity_at(tilt, direction)
        retained = np.minimum(self.volume, np.minimum.accumulate(cap))
        # the onset in the tilt's direction, |φ| folded into [0, π/2] by the dish's symmetry
        p = np.abs(direction)
        p = np.where(p > 0.5 * math.pi, math.pi - p, p)
        onset_t = np.interp(p, self._dirs, self._onset)
        deg = np.degrees(tilt)
        return SloshPrediction(t=t, apparent_tilt_deg=deg, surface_tilt_deg=deg,
                               surface_direction_deg=np.degrees(direction),
                               margin_deg=np.degrees(onset_t - tilt), retained_m3=retained,
                               volume_m3=self.volume, density=self.density)

    def summary(self) -> dict[str, float]:
        """The model's parameters (JSON-ready)."""
        onset = self._onset[[0, -1]]
        return {"volume_ml": round(self.volume * 1e6, 4),
                "repose_deg": round(math.degrees(self.repose), 3),
                "max_volume_ml": round(self.max_volume * 1e6, 4),
                "onset_tip_deg": round(math.degrees(float(onset[0])), 3),
                "onset_side_deg": round(math.degrees(float(onset[1])), 3)}
