"""Slosh of a liquid in a spoon's dish: the first sloshing mode per dish axis, driving the
hydrostatics (:mod:`articutool.food.hydrostatics`) to predict what a motion spills.

**Model.** The liquid's free surface is a plane whose slopes relative to the dish,
``p = (p_y, p_z)`` (rise of the surface per unit length across and along the dish), follow one
damped linear oscillator per dish axis — the first-mode equivalent mechanical model of a
liquid in a moving container (a pendulum whose mass is at the liquid's centroid; Abramson,
ed., *The Dynamic Behavior of Liquids in Moving Containers*, NASA SP-106, 1966, ch. 6;
Ibrahim, *Liquid Sloshing Dynamics*, Cambridge University Press, 2005, ch. 7)::

    p̈ + 2ζω ṗ + ω² p = ω² p_eq(t),     p_eq = (g_y, g_z) / (−g_x)

where ``g_app = g − a = (g_x, g_y, g_z)`` is the apparent gravity at the liquid's centroid in
the dish frame (``x`` the dish normal, ``z`` along the dish to the tip). At rest or in slow
motion ``p = p_eq``: the surface is normal to the apparent gravity, which is hydrostatics;
a change of acceleration makes it overshoot (up to twice the step, undamped) and ring at the
mode's frequency. The surface's tilt and direction then give the dish's capacity
(:meth:`Hydrostatics.capacity_fast`), and the running minimum of the capacity what stays.

**Frequency** of the model's own mode shape, a plane free surface, in the dish's real shape.
In shallow water the plane's kinetic and potential energies give Rayleigh's quotient::

    ω₀² = g V / I

with ``V`` the liquid's volume and ``I = ∫ s² dA`` the second moment of the free surface about
the axis it tilts around (an ellipse of semi-axes ``A`` along and ``B`` across at the fill
height: ``I = πA³B/4`` along, ``πAB³/4`` across). For a basin whose depth falls to zero at the
waterline as a paraboloid's does the plane is the exact first mode (Lamb, *Hydrodynamics*,
6th ed., 1932, §193: ``σ² = 2gh₀/a²``, which ``gV/I`` gives for any elliptic paraboloid);
for other basins it bounds the mode from above (Rayleigh's principle). The dish's 45° walls
run the depth to zero at the waterline too. Finite depth lowers it by linear theory's
dispersion, ``ω² = ω₀² tanh(kh)/(kh)`` with ``k = ω₀/√(gh)`` and ``h`` the mean depth
(volume over surface area). For 8 mL in the soup spoon: 2.96 Hz along, 4.09 Hz across
(``dish_mode``); a rectangular tank of the surface's length and the same mean depth
(``rectangular_tank_mode``, ``ω² = (πg/L) tanh(πh/L)``: NASA SP-106 ch. 2, Ibrahim 2005
eq. 2.41) would ring at 2.35 and 3.30 Hz, its cosine mode not the plane.

**Damping** from viscosity alone: the energy the laminar Stokes boundary layers on the floor
and the walls dissipate per cycle, over the mode's energy (Keulegan, "Energy dissipation in
standing waves in rectangular basins", J. Fluid Mech. 6:33–50, 1959; Ibrahim 2005 ch. 5).
For the tank of length ``L``, width ``W`` and depth ``h``, ``k = π/L``, kinematic viscosity
``ν``, integrating ``(ρ/2)·√(νω/2)·|u_wall|²`` of the potential flow over the bottom, the end
walls and the side walls gives::

    ζ = √(ν / 2ω) · [ k (1 − 2h/L) / sinh(2kh) + 1/L + 1/W ]

The dish's mode takes it for the tank of the surface's length and width and the mean
depth, at the dish's frequency (water, 8 mL in the soup spoon: ζ ≈ 0.018 along, 0.013
across). A contact line moving on the spoon and a contaminated surface add damping the
formula leaves out, so the model rings longer than the real liquid: it errs towards
predicting spill.

**Limits, stated.** The frequency is the plane's: a true mode that bends away from a plane
rings somewhat lower (a flat-floored round tank: wavenumber 1.841/R against the plane's 2/R,
4–9 % in frequency from deep to shallow); the whole static response is carried by the first
mode (higher modes, faster and smaller, are left out); the surface is kept a plane; linear
in the slopes (fine below ~30° where everything spills anyway); the frequency is the initial
fill's (liquid that spilled does not change it); the dish's rotation enters through ``p_eq``
and through the acceleration of the centroid it causes (a pendulum whose mass sits at the
centroid), the Coriolis term is second order. No surface tension: a meniscus pinned at the
rim holds a few degrees more.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.food.dish import Dish
from articutool.food.hydrostatics import Hydrostatics

__all__ = [
    "STANDARD_GRAVITY",
    "WATER_KINEMATIC_VISCOSITY",
    "SloshMode",
    "SloshModel",
    "SloshPrediction",
    "apparent_gravity",
    "dish_mode",
    "rectangular_tank_mode",
    "uniform_grid",
]

STANDARD_GRAVITY = 9.80665  # m/s²
# Water at 20 °C: 1.0034 mm²/s (dynamic viscosity 1.0016 mPa·s over density 998.2 kg/m³;
# CRC Handbook of Chemistry and Physics).
WATER_KINEMATIC_VISCOSITY = 1.0e-6  # m²/s
_MIN_VOLUME = 1e-9  # m³: a microlitre, below which there is no liquid to slosh
_MIN_NORMAL_G = 1e-3  # below this fraction of g along the dish normal the liquid has no floor


@lru_cache(maxsize=16)
def _hydrostatics(dish: Dish) -> Hydrostatics:
    """One Hydrostatics (and its capacity table) per dish, shared by every model."""
    return Hydrostatics(dish)


def rectangular_tank_mode(length: float, width: float, depth: float,
                          g: float = STANDARD_GRAVITY,
                          nu: float = WATER_KINEMATIC_VISCOSITY) -> tuple[float, float]:
    """(ω rad/s, ζ) of the first sloshing mode along ``length`` of a rectangular tank
    ``length × width`` filled ``depth`` deep (m): the frequency of linear potential theory and
    the viscous damping of the Stokes boundary layers (see the module doc)."""
    if not (length > 0 and width > 0 and depth > 0 and g > 0 and nu >= 0):
        raise ValueError(f"a tank needs positive length, width, depth and g; got "
                         f"{length}, {width}, {depth}, {g}")
    k = math.pi / length
    omega = math.sqrt(g * k * math.tanh(k * depth))
    return omega, _stokes_damping(omega, length, width, depth, nu)


def _stokes_damping(omega: float, length: float, width: float, depth: float,
                    nu: float) -> float:
    """Keulegan's viscous damping ratio of a tank's first mode along ``length`` ringing at
    ``omega`` (the module doc's formula)."""
    k = math.pi / length
    x = 2.0 * k * depth
    over_sinh = 2.0 * math.exp(-x) / -math.expm1(-2.0 * x)  # 1 / sinh(x), no overflow
    return math.sqrt(nu / (2.0 * omega)) * (
        k * (1.0 - 2.0 * depth / length) * over_sinh + 1.0 / length + 1.0 / width)


def dish_mode(semi_along: float, semi_across: float, volume: float,
              g: float = STANDARD_GRAVITY,
              nu: float = WATER_KINEMATIC_VISCOSITY) -> tuple[float, float]:
    """(ω rad/s, ζ) of a plane free surface tilting along ``semi_along`` — an elliptic
    surface of semi-axes ``semi_along`` × ``semi_across`` (m) over ``volume`` m³ of liquid:
    Rayleigh's shallow-water quotient ``gV/I`` with linear theory's finite-depth correction,
    and the viscous damping of the tank of the surface's extent (see the module doc)."""
    A, B, v = float(semi_along), float(semi_across), float(volume)
    if not (A > 0 and B > 0 and v > 0 and g > 0 and nu >= 0):
        raise ValueError(f"a dish mode needs positive semi-axes, volume and g; got "
                         f"{A}, {B}, {v}, {g}")
    depth = v / (math.pi * A * B)
    omega0 = math.sqrt(g * v / (0.25 * math.pi * A ** 3 * B))
    kh = omega0 * math.sqrt(depth / g)
    omega = omega0 * math.sqrt(math.tanh(kh) / kh)
    return omega, _stokes_damping(omega, 2.0 * A, 2.0 * B, depth, nu)


@dataclass(frozen=True)
class SloshMode:
    """The first mode along one dish axis (``"along"``: z, to the tip; ``"across"``: y)."""

    axis: str
    length_m: float  # the free surface's extent along the axis
    width_m: float  # ... across it
    depth_m: float  # mean depth: volume over surface area
    omega: float  # rad/s
    zeta: float  # damping ratio

    @property
    def frequency_hz(self) -> float:
        """Natural frequency (Hz)."""
        return self.omega / (2.0 * math.pi)


def _second_differences(t: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.float64]:
    """Second time derivative of samples ``p`` (N, 3) at times ``t`` (any spacing), by the
    three-point formula (exact for a quadratic); the ends repeat their neighbours."""
    n = t.size
    a = np.zeros_like(p)
    if n < 3:
        return a
    h0, h1 = np.diff(t)[:-1, None], np.diff(t)[1:, None]
    a[1:-1] = 2.0 * ((p[2:] - p[1:-1]) / h1 - (p[1:-1] - p[:-2]) / h0) / (h0 + h1)
    a[0], a[-1] = a[1], a[-2]
    return a


def apparent_gravity(times: ArrayLike, positions: ArrayLike, rotations: ArrayLike,
                     accelerations: ArrayLike | None = None,
                     g: float = STANDARD_GRAVITY) -> NDArray[np.float64]:
    """Apparent gravity ``Rᵀ (g − a)`` (m/s², (N, 3)) in the dish frame along a pose
    trajectory: ``positions`` (N, 3) of the liquid's centroid in a world frame whose z is up,
    ``rotations`` (N, 3, 3) world ← dish. Without ``accelerations`` (N, 3) they are the second
    differences of the positions (exact for a quadratic; sample a smooth motion densely, a few
    ms apart)."""
    t = np.asarray(times, dtype=float)
    p = np.asarray(positions, dtype=float)
    R = np.asarray(rotations, dtype=float)
    if t.ndim != 1 or p.shape != (t.size, 3) or R.shape != (t.size, 3, 3):
        raise ValueError(f"times (N,), positions (N, 3), rotations (N, 3, 3); got {t.shape}, "
                         f"{p.shape}, {R.shape}")
    if t.size and (not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0)):
        raise ValueError("times must be finite and strictly increasing")
    a = _second_differences(t, p) if accelerations is None else np.asarray(accelerations,
                                                                           dtype=float)
    world = np.array([0.0, 0.0, -g]) - a
    return np.einsum("kji,kj->ki", R, world)


def uniform_grid(times: ArrayLike, g_app: ArrayLike, dt: float, tail_s: float
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``g_app`` (N, 3) at ``times`` (N,) checked and interpolated linearly onto a grid ``dt``
    apart from the first time to ``tail_s`` after the last (the last sample held): the grid
    (M,) and the three components (3, M)."""
    t_in = np.asarray(times, dtype=float)
    g_in = np.asarray(g_app, dtype=float)
    if t_in.ndim != 1 or g_in.shape != (t_in.size, 3) or t_in.size == 0:
        raise ValueError(f"times (N,) and g_app (N, 3), N ≥ 1; got {t_in.shape}, {g_in.shape}")
    if not (np.all(np.isfinite(t_in)) and np.all(np.isfinite(g_in))):
        raise ValueError("times and g_app must be finite")
    if np.any(np.diff(t_in) <= 0):
        raise ValueError("times must be strictly increasing")
    n = math.ceil((t_in[-1] - t_in[0] + tail_s) / dt - 1e-9) + 1
    t = t_in[0] + dt * np.arange(n)
    return t, np.stack([np.interp(t, t_in, g_in[:, j]) for j in range(3)])


@dataclass(frozen=True)
class SloshPrediction:
    """What the liquid does along a motion, on the model's uniform time grid.

    Angles in degrees, volumes in m³, masses in g. ``margin_deg`` is the spill onset tilt of
    the initial volume in the surface's direction minus the surface's tilt: negative while
    liquid runs out. ``apparent_*`` is the quasi-static surface (normal to ``g − a``),
    ``surface_*`` the sloshing one.
    """

    t: NDArray[np.float64] = field(repr=False)
    apparent_tilt_deg: NDArray[np.float64] = field(repr=False)
    surface_tilt_deg: NDArray[np.float64] = field(repr=False)
    surface_direction_deg: NDArray[np.float64] = field(repr=False)
    margin_deg: NDArray[np.float64] = field(repr=False)
    retained_m3: NDArray[np.float64] = field(repr=False)
    volume_m3: float
    density: float

    @property
    def spilled_g_series(self) -> NDArray[np.float64]:
        """Grams spilled so far at each grid time."""
        return (self.volume_m3 - self.retained_m3) * self.density * 1e3

    @property
    def spilled_g(self) -> float:
        """Grams spilled over the whole motion (and the settling tail)."""
        return float(self.spilled_g_series[-1]) if self.t.size else 0.0

    @property
    def peak_apparent_tilt_deg(self) -> float:
        """Largest tilt of the apparent gravity from the dish normal."""
        return float(self.apparent_tilt_deg.max()) if self.t.size else 0.0

    @property
    def peak_surface_tilt_deg(self) -> float:
        """Largest tilt of the sloshing surface from the dish's rim plane."""
        return float(self.surface_tilt_deg.max()) if self.t.size else 0.0

    @property
    def min_margin_deg(self) -> float:
        """Smallest margin to the first spill (negative: it spills)."""
        return float(self.margin_deg.min()) if self.t.size else math.inf

    @property
    def first_spill_time(self) -> float | None:
        """When liquid first runs out (s), or None."""
        out = np.flatnonzero(self.retained_m3 < self.volume_m3 * (1.0 - 1e-9))
        return float(self.t[out[0]]) if out.size else None

    def summary(self) -> dict[str, float | None]:
        """The figures a report carries (JSON-ready)."""
        return {"peak_apparent_tilt_deg": round(self.peak_apparent_tilt_deg, 3),
                "peak_surface_tilt_deg": round(self.peak_surface_tilt_deg, 3),
                "min_margin_deg": round(self.min_margin_deg, 3),
                "spilled_g": round(self.spilled_g, 4),
                "first_spill_time_s": (None if self.first_spill_time is None
                                       else round(self.first_spill_time, 4))}


class SloshModel:
    """The first sloshing modes of ``volume`` m³ of a liquid in ``dish``, driving its
    hydrostatics (see the module doc).

    ``dt`` is the uniform grid the oscillators run on (exact first-order-hold discretisation;
    the motion's apparent gravity is interpolated linearly onto it); ``tail_s`` of stillness
    after the motion's end lets the surface ring out (its largest swing comes within half a
    period). ``dynamic=False`` keeps the surface normal to the apparent gravity (quasi-static).
    """

    def __init__(self, dish: Dish, volume: float, *, density: float = 1000.0,
                 nu: float = WATER_KINEMATIC_VISCOSITY, g: float = STANDARD_GRAVITY,
                 dt: float = 0.004, tail_s: float = 1.0, dynamic: bool = True) -> None:
        self.hydro = _hydrostatics(dish)
        cap = self.hydro.level_capacity
        v = float(volume)
        if not (math.isfinite(v) and 0.0 <= v <= cap):
            raise ValueError(f"volume {v * 1e6:.4g} mL outside [0, {cap * 1e6:.4g}] mL "
                             "(the dish's level capacity)")
        if not (0 < dt <= 0.02 and tail_s >= 0 and density > 0):
            raise ValueError(f"dt must be in (0, 0.02] s, tail_s ≥ 0, density > 0; got {dt}, "
                             f"{tail_s}, {density}")
        self.dish, self.volume, self.density = dish, v, float(density)
        self.dt, self.tail_s, self.dynamic, self.g = float(dt), float(tail_s), dynamic, g
        self.fill_height = self.hydro.fill_height(v)
        A, B = (float(x) for x in dish.semi_axes(self.fill_height))
        self.mean_depth = v / (math.pi * A * B)
        self.modes: tuple[SloshMode, SloshMode] | None = None
        self._filters: list[tuple[NDArray[np.float64], NDArray[np.float64]]] = []
        if v > _MIN_VOLUME:
            self.modes = (
                SloshMode("across", 2 * B, 2 * A, self.mean_depth, *dish_mode(B, A, v, g, nu)),
                SloshMode("along", 2 * A, 2 * B, self.mean_depth, *dish_mode(A, B, v, g, nu)))
            from scipy.signal import cont2discrete

            for m in self.modes:
                w2 = m.omega ** 2
                num, den, _ = cont2discrete(([w2], [1.0, 2.0 * m.zeta * m.omega, w2]), self.dt,
                                            method="foh")
                self._filters.append((np.ravel(num), np.ravel(den)))
        # Onset tilt of this volume per direction (0..π/2, folded by the dish's symmetry),
        # inverted from the same table the capacity is read from.
        table = self.hydro._table
        tilts = np.arange(table.shape[0]) * math.radians(0.25)
        self._onset = np.array([np.interp(v, table[::-1, j], tilts[::-1])
                                for j in range(table.shape[1])])

    def onset_tilt(self, direction: ArrayLike) -> NDArray[np.float64]:
        """Tilt (rad) at which the volume starts to spill, towards ``direction`` (rad)."""
        p = np.abs(np.asarray(direction, dtype=float))
        p = np.where(p > 0.5 * math.pi, math.pi - p, p)
        return np.interp(p, np.linspace(0.0, 0.5 * math.pi, self._onset.size), self._onset)

    def predict(self, times: ArrayLike, g_app: ArrayLike) -> SloshPrediction:
        """The surface and the spill along a motion given by its apparent gravity ``g_app``
        (N, 3) in the dish frame at ``times`` (N,), s; the liquid starts at rest in
        equilibrium with the first sample and the last is held ``tail_s`` longer."""
        t, (gx, gy, gz) = uniform_grid(times, g_app, self.dt, self.tail_s)
        n = t.size
        gn = np.hypot(gx, np.hypot(gy, gz))
        # A floor under the liquid needs apparent gravity into the dish; without one the
        # slopes are taken as if nearly vertical (everything runs out).
        down = np.maximum(-gx, _MIN_NORMAL_G * np.maximum(gn, self.g))
        p_eq = (gy / down, gz / down)
        apparent = np.degrees(np.arctan2(np.hypot(gy, gz), -gx))
        if self.dynamic and self._filters:
            from scipy.signal import lfilter

            p = tuple(lfilter(b, a, u - u[0]) + u[0]
                      for (b, a), u in zip(self._filters, p_eq, strict=True))
        else:
            p = p_eq
        slope = np.hypot(p[0], p[1])
        tilt = np.arctan(slope)
        direction = np.arctan2(p[0], p[1])
        if self.volume > 0:
            cap = self.hydro.capacity_fast(tilt, direction)
            retained = np.minimum(self.volume, np.minimum.accumulate(cap))
        else:
            retained = np.zeros(n)
        return SloshPrediction(
            t=t, apparent_tilt_deg=apparent, surface_tilt_deg=np.degrees(tilt),
            surface_direction_deg=np.degrees(direction),
            margin_deg=np.degrees(self.onset_tilt(direction) - tilt),
            retained_m3=retained, volume_m3=self.volume, density=self.density)

    def predict_poses(self, times: ArrayLike, positions: ArrayLike, rotations: ArrayLike,
                      accelerations: ArrayLike | None = None) -> SloshPrediction:
        """:meth:`predict` along a pose trajectory of the liquid's centroid (see
        :func:`apparent_gravity`)."""
        return self.predict(times, apparent_gravity(times, positions, rotations,
                                                    accelerations, self.g))

    def summary(self) -> dict[str, float | list[dict[str, float]]]:
        """The model's parameters (JSON-ready)."""
        return {"volume_ml": round(self.volume * 1e6, 4),
                "fill_height_mm": round(self.fill_height * 1e3, 3),
                "mean_depth_mm": round(self.mean_depth * 1e3, 3),
                "onset_tip_deg": round(math.degrees(float(self.onset_tilt(0.0))), 3),
                "onset_side_deg": round(math.degrees(float(self.onset_tilt(0.5 * math.pi))), 3),
                "modes": [{"axis": m.axis, "length_mm": round(m.length_m * 1e3, 3),
                           "frequency_hz": round(m.frequency_hz, 4),
                           "damping_ratio": round(m.zeta, 5)} for m in (self.modes or ())]}
