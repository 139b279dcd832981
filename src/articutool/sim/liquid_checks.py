"""The SPlisHSPlasH liquid (:mod:`articutool.sim.sph_scene`) checked against laws and
measurements that do not come from it.

- :func:`dam_break_check`: a water column twice as high as wide (``n² = 2``) collapsing in a
  box, its surge front against Martin & Moyce (1952) (``data/martin_moyce_1952.toml``).
- :func:`slosh_mode_check`: the first slosh mode of a load in the soup spoon's dish, along
  and across, against the linear model of :mod:`articutool.food.slosh`, and the damping the
  liquid shows;
- :func:`tank_slosh_check`: the first slosh mode of a rectangular tank, where that model's
  formula (linear potential theory) is exact — the liquid's own error, apart from the
  model's;
- :func:`coarse_dam_break_check`: the dam break at a coarser particle (the water bowl's)
  against the same flow at the check's resolution — whether the coarse liquid flows as the
  fine one does (a convergence check, not a law).

Each returns a JSON-ready dict naming the backend and its version, the particle radius and
count, the measured value, the law's value, pass/fail and the CPU seconds of the process it
took (``time.process_time``).
"""

from __future__ import annotations

import itertools
import math
import time
import tomllib
from importlib import resources
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.food.dish import spoon_dish
from articutool.food.dish_fill import dish_pour
from articutool.food.dish_mesh import dish_boundary_mesh
from articutool.food.slosh import SloshModel, rectangular_tank_mode
from articutool.sim.sph_library import library_version
from articutool.sim.sph_scene import (
    Boundary,
    FluidBlock,
    FluidParticles,
    SphLiquid,
    SphSettings,
    box_mesh,
)
from articutool.spec import UtensilSpec, load_spec

__all__ = [
    "coarse_dam_break_check",
    "dam_break_check",
    "fitted_oscillation",
    "martin_moyce_1952",
    "oscillation",
    "slosh_mode_check",
    "tank_slosh_check",
]

G0 = 9.80665  # m/s²
DAM_BREAK_TOLERANCE = 0.10  # the front within 10 % of the measured one ...
DAM_BREAK_Z_LIMIT = 3.0  # ... up to Z = 3
SLOSH_TOLERANCE = 0.10  # the slosh frequency within 10 % of the linear model's
# A coarse liquid's dam-break front within 5 % of the fine one's (half the law's tolerance:
# the resolution may not move the front by as much as the check allows the physics to).
COARSE_FRONT_TOLERANCE = 0.05


def _backend() -> dict[str, str]:
    return {"backend": "SPlisHSPlasH (pysplishsplash)", "version": library_version()}


def martin_moyce_1952() -> dict[str, Any]:
    """The measured surge front (``data/martin_moyce_1952.toml``): its source and one series
    per column width, each ``{"a_m", "t_star", "z_star"}``."""
    path = resources.files("articutool") / "data" / "martin_moyce_1952.toml"
    return tomllib.loads(path.read_text(encoding="utf-8"))


DAM_BREAK_SETTLE_S = 0.2  # s the column rests behind the gate before its release ...
DAM_BREAK_SETTLE_VISCOSITY = 0.01  # m²/s ... in an implicit viscosity that brings it to rest
DAM_BREAK_SETTLE_DT = 5e-4  # s, the settling's longest step: the tiled start's burst (up to
# ~1.5 m/s) outruns 2 ms steps at 32 particles across and blows the liquid up


def _settled_column(tank: tuple[NDArray[np.float64], NDArray[np.int64]], block: FluidBlock,
                    gate: tuple[NDArray[np.float64], NDArray[np.int64]],
                    radius: float) -> tuple[NDArray[np.float64], dict[str, float]]:
    """The column at rest behind a gate: tiled, then left to settle for
    ``DAM_BREAK_SETTLE_S`` in a liquid ``DAM_BREAK_SETTLE_VISCOSITY`` viscous (Weiler et al.
    2018's implicit viscosity; it damps the lattice's start and plays no part after), in steps
    of at most ``DAM_BREAK_SETTLE_DT``, so it
    holds its hydrostatic pressure and no more: (positions of the particles still in the tank,
    the settling's figures)."""
    lo, hi = tank[0].min(axis=0), tank[0].max(axis=0)
    syrup = SphSettings(particle_radius=radius, viscosity=DAM_BREAK_SETTLE_VISCOSITY,
                        boundary_viscosity=DAM_BREAK_SETTLE_VISCOSITY,
                        viscosity_method="weiler2018", max_dt=DAM_BREAK_SETTLE_DT)
    with SphLiquid([Boundary("tank", *tank), Boundary("gate", *gate, animated=True)], [block],
                   syrup, (0.0, 0.0, -G0)) as liq:
        first = float(np.linalg.norm(liq.velocities(), axis=1).max())
        liq.step_to(DAM_BREAK_SETTLE_S)
        x = liq.positions()
        speed = np.linalg.norm(liq.velocities(), axis=1)
    inside = np.all((x > lo) & (x < hi), axis=1)
    return x[inside], {"settle_s": DAM_BREAK_SETTLE_S,
                       "first_step_max_speed_m_s": round(first, 4),
                       "rms_speed_at_release_m_s": round(float(np.sqrt(np.mean(speed ** 2))), 4),
                       "particles_lost_settling": int((~inside).sum())}


def front_errors(t_star: ArrayLike, z_star: ArrayLike, t_ref: ArrayLike, z_ref: ArrayLike,
                 z_limit: float = DAM_BREAK_Z_LIMIT
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                            NDArray[np.float64]]:
    """A simulated surge front ``Z(T)`` (samples ``t_star``, ``z_star``) against measured
    points, at those with ``0 < T`` within the simulated run and ``Z ≤ z_limit``: (their T,
    their Z, the simulated Z at their T, its relative error, signed: positive ahead)."""
    t_sim = np.asarray(t_star, dtype=float)
    tr, zr = np.asarray(t_ref, dtype=float), np.asarray(z_ref, dtype=float)
    use = (tr > 0) & (tr <= t_sim[-1]) & (zr <= z_limit)
    tr, zr = tr[use], zr[use]
    z_at = np.interp(tr, t_sim, np.asarray(z_star, dtype=float))
    return tr, zr, z_at, (z_at - zr) / zr


def dam_break_check(radius: float = 0.05715 / 40, *, width: float = 0.05715,
                    depth_particles: int = 4, t_star_end: float = 3.2,
                    sample_t_star: float = 0.05) -> dict[str, Any]:
    """A column ``width`` (a) wide and ``2a`` high collapses along +x in a box ``5a`` long;
    its surge front ``Z = x/a`` at ``T = n t √(g/a)`` (n = √2) against Martin & Moyce's series
    of the same width (default 2.25 in, their larger column).

    The box is ``depth_particles`` particles deep across (the measurement is a 2-D flow; the
    walls across are free-slip only to the boundary viscosity). The column's particles tile
    ``[r, a + r] × [r, 2a + r]`` from the back wall and the floor (their centres are ``2r``
    off the walls, the spacing the boundary particles keep). A lattice so close to the
    boundary particles is denser than water next to every wall (the boundary's share of the
    density is too large there), so the column first rests behind a gate ``2r`` past its face
    (:func:`_settled_column`) and is released from rest, as the experiment's was: the gate is
    gone at ``T = 0``. The front is the foremost particle's centre plus ``r`` (the face of its
    cube), measured from the column's back face (``r``), so ``Z ≈ 1`` at release. Passes when
    the front is within 10 % of the measured one at every measured time with ``Z ≤ 3``."""
    t_cpu = time.process_time()
    a, r = float(width), float(radius)
    if not (0 < r < a / 8 and depth_particles >= 2 and 0 < t_star_end <= 10):
        raise ValueError(f"dam break: radius must be in (0, a/8), depth_particles >= 2, "
                         f"t_star_end in (0, 10]; got {r}, {depth_particles}, {t_star_end}")
    n_across = round(a / (2 * r))
    half = depth_particles * r  # the block's half-depth across (y)
    block = FluidBlock((r, -half, r), (r + 2 * r * n_across, half, r + 4 * r * n_across))
    a_eff = 2 * r * n_across  # the column's width as tiled
    box = box_mesh((0.0, -half - r, 0.0), (5.0 * a_eff + 2 * r, half + r, 3.0 * a_eff))
    gate = box_mesh((a_eff + 2 * r, -half - 3 * r, 0.5 * r),
                    (a_eff + 6 * r, half + 3 * r, 2.8 * a_eff))
    settings = SphSettings(particle_radius=r)
    column, settling = _settled_column(box, block, gate, r)
    t_scale = 1.0 / math.sqrt(2.0 * G0 / a_eff)  # t = T · t_scale
    t_star: list[float] = []
    z_star: list[float] = []
    with SphLiquid([Boundary("tank", *box)], [FluidParticles(column)], settings,
                   (0.0, 0.0, -G0)) as liq:
        n = liq.n_particles
        k = 0
        while True:
            T = k * sample_t_star
            if t_star_end + 1e-9 < T:
                break
            if T > 0:
                liq.step_to(T * t_scale)
            front = float(liq.positions()[:, 0].max())  # its cube face (+r) less the back face (r)
            t_star.append(round(liq.time / t_scale if T > 0 else 0.0, 4))
            z_star.append(round(front / a_eff, 4))
            k += 1
    ref = martin_moyce_1952()
    series = min(ref["series"], key=lambda s: abs(s["a_m"] - a))
    tr, zr, z_sim, err = front_errors(t_star, z_star, series["t_star"], series["z_star"])
    rel = np.abs(err)
    worst = float(rel.max()) if rel.size else math.nan
    others = {}
    for s in ref["series"]:
        e = np.abs(front_errors(t_star, z_star, s["t_star"], s["z_star"])[3])
        if e.size:
            others[f"{s['a_m']:.6g}"] = round(float(e.max()), 4)
    return {
        "check": "dam_break",
        **_backend(),
        "particle_radius_m": r,
        "particles": n,
        "settling": settling,
        "particles_across_column": n_across,
        "column_width_m": a_eff,
        "t_star": t_star,
        "z_star": z_star,
        "reference": {"t_star": series["t_star"], "z_star": series["z_star"],
                      "a_m": series["a_m"], "source": ref["source"]},
        "compared_at_t_star": [float(x) for x in tr],
        "measured_z_star": [round(float(x), 4) for x in z_sim],
        "law_z_star": [float(x) for x in zr],
        "max_rel_error_to_Z3": round(worst, 4),
        "max_rel_error_by_series": others,
        "tolerance": DAM_BREAK_TOLERANCE,
        "pass": bool(rel.size > 0 and worst <= DAM_BREAK_TOLERANCE),
        "cpu_s": round(time.process_time() - t_cpu, 2),
    }


def oscillation(t: ArrayLike, y: ArrayLike, rest: float | None = None) -> dict[str, float]:
    """Frequency (Hz) and damping of a decaying oscillation sampled at ``t`` about ``rest``
    (default: the samples' mean): the mean period between the crossings of ``rest`` (linear
    interpolation), and the logarithmic
    decrement of its successive extrema (half-periods apart: ``δ = 2·mean ln|A_k/A_{k+1}|``),
    as the damping ratio ``ζ = δ / √(4π² + δ²)``. NaN where there are too few crossings."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    y = y - (y.mean() if rest is None else rest)
    s = np.signbit(y)
    k = np.flatnonzero(s[1:] != s[:-1])
    tz = t[k] - y[k] * (t[k + 1] - t[k]) / (y[k + 1] - y[k])
    if len(tz) < 3:
        return {"frequency_hz": math.nan, "damping_ratio": math.nan, "cycles": 0.0}
    half = float(np.mean(np.diff(tz)))
    peaks = np.array([np.abs(y[(t >= a) & (t <= b)]).max() for a, b in itertools.pairwise(tz)])
    ok = peaks > 0
    logs = np.diff(np.log(peaks[ok])) if ok.sum() >= 2 else np.array([math.nan])
    delta = float(-2.0 * np.mean(logs))
    return {"frequency_hz": 1.0 / (2.0 * half),
            "damping_ratio": delta / math.sqrt(4.0 * math.pi ** 2 + delta ** 2),
            "cycles": (len(tz) - 1) / 2.0}


def fitted_oscillation(t: ArrayLike, y: ArrayLike, rest: float | None = None
                       ) -> dict[str, float]:
    """Frequency (Hz) and damping ratio of a decaying oscillation sampled at ``t``, by a
    least-squares fit of ``A·e^(−λt)·cos(ωt + φ) + c + d·t`` to the whole record (offset and
    drift free, so a slowly settling rest does not bias it): ``ω/2π`` and ``λ/ω``. The fit
    starts from :func:`oscillation`'s crossing frequency and from ±10 and ±20 % of it; the
    smallest residual is kept. NaN where no fit converges."""
    from scipy.optimize import curve_fit

    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    y = y - (y.mean() if rest is None else rest)
    f0 = oscillation(t, y, 0.0)["frequency_hz"]
    if not math.isfinite(f0):
        return {"frequency_hz": math.nan, "damping_ratio": math.nan}

    def model(t, a, lam, om, ph, c, d):  # type: ignore[no-untyped-def]
        return a * np.exp(-lam * t) * np.cos(om * t + ph) + c + d * t

    best: tuple[NDArray[np.float64], float] | None = None
    for scale in (1.0, 0.8, 0.9, 1.1, 1.2):
        p0 = [float(np.abs(y).max()), 0.5, 2 * math.pi * f0 * scale, 0.0, 0.0, 0.0]
        try:
            p, _ = curve_fit(model, t, y, p0=p0, maxfev=20000)
        except RuntimeError:
            continue
        res = float(np.sum((model(t, *p) - y) ** 2))
        if best is None or res < best[1]:
            best = (p, res)
    if best is None:
        return {"frequency_hz": math.nan, "damping_ratio": math.nan}
    p = best[0]
    return {"frequency_hz": abs(p[2]) / (2 * math.pi), "damping_ratio": p[1] / abs(p[2])}


def slosh_mode_check(radius: float = 0.001, *, grams: float = 8.0,
                     utensil: UtensilSpec | None = None, settle_s: float = 0.6,
                     pulse_g: float = 0.2, pulse_s: float = 0.04, record_s: float = 2.0,
                     sample_s: float = 0.004) -> dict[str, Any]:
    """The load's first slosh mode along and across the dish against
    :class:`articutool.food.slosh.SloshModel`'s linear model, and its damping.

    ``grams`` of water are poured into the soup spoon's dish (:func:`dish_pour`; the dish's
    closed shell :func:`dish_boundary_mesh` as the boundary, the utensil's frame, the dish
    level), settle ``settle_s``, then feel a lateral apparent-gravity pulse of ``pulse_g``·g
    for ``pulse_s`` towards the tip and the side at once (the two modes are orthogonal by the
    dish's symmetry); the liquid's centre of mass along z and along y then rings at each mode's
    frequency, read over ``record_s`` (:func:`oscillation`). Passes when both frequencies are
    within 10 % of the model's."""
    t_cpu = time.process_time()
    u = utensil if utensil is not None else load_spec().utensil("soup_spoon")
    dish = spoon_dish(u)
    settings = SphSettings(particle_radius=radius)
    count = round(grams * 1e-3 / settings.particle_mass)
    x = dish_pour(dish, u.tip_x, radius, count)
    shell = dish_boundary_mesh(dish, u.tip_x, u.physics.thickness)
    g_level = np.array([-G0, 0.0, 0.0])  # dish level: gravity along −x, the dish normal
    kick = pulse_g * G0 / math.sqrt(2.0)
    with SphLiquid([Boundary("dish", *shell)], [FluidParticles(x)], settings, g_level) as liq:
        n = liq.n_particles
        rest, ts, c = _ring_down(liq, g_level, np.array([0.0, kick, kick]), settle_s, pulse_s,
                                 record_s, sample_s)
        kept = liq.n_particles
    model = SloshModel(dish, count * settings.particle_mass / settings.density0)
    laws = {m.axis: m for m in model.modes or ()}
    result: dict[str, Any] = {"check": "slosh_modes", **_backend(), "particle_radius_m": radius,
                              "particles": n, "grams": round(n * settings.particle_mass * 1e3, 4),
                              "particles_kept": kept}
    ok = True
    for axis, col in (("along", 2), ("across", 1)):
        osc = oscillation(ts, c[:, col], float(rest[col]))
        law = laws[axis]
        err = abs(osc["frequency_hz"] - law.frequency_hz) / law.frequency_hz
        passed = bool(math.isfinite(err) and err <= SLOSH_TOLERANCE)
        ok &= passed
        result[axis] = {"measured_hz": round(osc["frequency_hz"], 4),
                        "law_hz": round(law.frequency_hz, 4), "rel_error": round(err, 4),
                        "measured_damping_ratio": round(osc["damping_ratio"], 4),
                        "law_damping_ratio": round(law.zeta, 4),
                        "cycles": osc["cycles"], "pass": passed}
    result.update({"tolerance": SLOSH_TOLERANCE, "pass": ok,
                   "cpu_s": round(time.process_time() - t_cpu, 2)})
    return result


def _ring_down(liq: SphLiquid, g_level: NDArray[np.float64], kick: NDArray[np.float64],
               settle_s: float, pulse_s: float, record_s: float, sample_s: float
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Settle, pulse the apparent gravity by ``kick`` for ``pulse_s``, record the centre of
    mass: (rest position, sample times from the pulse's end, centres of mass)."""
    liq.step_to(settle_s)
    rest = liq.positions().mean(axis=0)
    liq.set_gravity(g_level + kick)
    liq.step_to(settle_s + pulse_s)
    liq.set_gravity(g_level)
    t0 = liq.time
    ts, com = [], []
    while liq.time < t0 + record_s:
        liq.step_to(liq.time + sample_s)
        ts.append(liq.time - t0)
        com.append(liq.positions().mean(axis=0))
    return rest, np.array(ts), np.array(com)


def tank_slosh_check(radius: float = 0.001, *, length: float = 0.1, depth: float = 0.02,
                     width_particles: int = 8, pulse_g: float = 0.1, pulse_s: float = 0.04,
                     settle_s: float = 0.5, record_s: float = 3.0,
                     sample_s: float = 0.004) -> dict[str, Any]:
    """Water ``depth`` deep in a rectangular tank ``length`` long (a slab
    ``width_particles`` particles wide: the mode is 2-D), rung by a lateral apparent-gravity
    pulse; its centre of mass's frequency against ``rectangular_tank_mode`` (exact here).
    The frequency is read by a fit of the whole ring-down (:func:`fitted_oscillation`; the
    crossings' reading is reported beside it), and the slab is 8 particles wide by default:
    on a 4-wide slab every particle is within a kernel of a side wall, and the crossings'
    figure moves with how long the ring-down is read, each adding about 3 points
    (``docs/notes/2026-11-29-tank-slosh-width.md``). Passes within 10 %."""
    t_cpu = time.process_time()
    r = float(radius)
    w = width_particles * r
    settings = SphSettings(particle_radius=r)
    tank = box_mesh((-r, -w - r, -r), (length + r, w + r, 3.0 * depth))
    g_level = np.array([0.0, 0.0, -G0])
    with SphLiquid([Boundary("tank", *tank)], [FluidBlock((0.0, -w, 0.0), (length, w, depth))],
                   settings, g_level) as liq:
        n = liq.n_particles
        rest, ts, com = _ring_down(liq, g_level, np.array([pulse_g * G0, 0.0, 0.0]), settle_s,
                                   pulse_s, record_s, sample_s)
    crossings = oscillation(ts, com[:, 0], float(rest[0]))
    fit = fitted_oscillation(ts, com[:, 0], float(rest[0]))
    omega, zeta = rectangular_tank_mode(length, 2 * w, depth)
    law = omega / (2 * math.pi)
    err = abs(fit["frequency_hz"] - law) / law
    passed = bool(math.isfinite(err) and err <= SLOSH_TOLERANCE)
    return {"check": "tank_slosh", **_backend(), "particle_radius_m": r, "particles": n,
            "tank_m": [length, 2 * w, depth], "reading": "fit of the ring-down",
            "measured_hz": round(fit["frequency_hz"], 4),
            "crossings_hz": round(crossings["frequency_hz"], 4),
            "law_hz": round(law, 4), "rel_error": round(err, 4),
            "measured_damping_ratio": round(fit["damping_ratio"], 4),
            "crossings_damping_ratio": round(crossings["damping_ratio"], 4),
            "law_damping_ratio": round(zeta, 4), "cycles": crossings["cycles"],
            "settled_depth_m": round(2.0 * float(rest[2]), 6),
            "tolerance": SLOSH_TOLERANCE, "pass": passed,
            "cpu_s": round(time.process_time() - t_cpu, 2)}


def coarse_dam_break_check(radius: float, reference: dict[str, Any] | None = None
                           ) -> dict[str, Any]:
    """The dam break (:func:`dam_break_check`) at ``radius`` against ``reference`` (the check
    at its own resolution; run if not given), compared at the measured times up to Z = 3:
    passes when the coarse front is within :data:`COARSE_FRONT_TOLERANCE` of the fine one at
    each. Both are reported against Martin & Moyce as well."""
    ref = dam_break_check() if reference is None else reference
    coarse = dam_break_check(radius)
    zc, zf = np.asarray(coarse["measured_z_star"]), np.asarray(ref["measured_z_star"])
    if coarse["compared_at_t_star"] != ref["compared_at_t_star"]:
        raise ValueError("the coarse and reference dam breaks compare at different times")
    diff = float(np.max(np.abs(zc / zf - 1.0)))
    return {"check": "coarse_dam_break", **_backend(),
            "particle_radius_m": coarse["particle_radius_m"], "particles": coarse["particles"],
            "reference_particle_radius_m": ref["particle_radius_m"],
            "compared_at_t_star": coarse["compared_at_t_star"],
            "measured_z_star": coarse["measured_z_star"],
            "reference_z_star": ref["measured_z_star"],
            "max_rel_error_to_Z3": coarse["max_rel_error_to_Z3"],
            "max_rel_diff_to_reference": round(diff, 4),
            "tolerance": COARSE_FRONT_TOLERANCE, "pass": diff <= COARSE_FRONT_TOLERANCE,
            "cpu_s": coarse["cpu_s"]}
