"""The noodle model's mechanisms, each alone in MuJoCo beside the physical law it should follow.

A strand (:func:`articutool.sim.food_strands.strand_chain`, the bowl's own builder and
parameters) is put in four small worlds, built with ``MjSpec`` as the feeding world is:

- **capstan** — draped over a fixed horizontal bar, loaded at both ends, one end's load raised
  in steps until the strand slides round the bar. A flexible rope with friction μ holds a
  load ratio up to e^(μπ) over a half turn (Euler–Eytelwein); a frictionless bar holds 1. The
  bar is as wide as the fork (where a twirl winds a strand: round the tines together) and the
  loads make the strand's bending a tenth of its tension (T = 10·E·I/R²), so the rope law
  applies. The same on one tine, loaded with a strand's own weight: there R is far below the
  strand's bending length and a segment's length, so no rope law holds — reported, not tested.
- **cantilever** — a strand clamped level at one end bends under its own weight; its tip
  deflection against the elastica's (:func:`cantilever_tip_deflection`, E·I from the cited
  modulus, exact for large deflections).
- **tack** — a strand lying on the fork's steel (and on another strand) is pulled straight
  up, the pull raised slowly until it comes off; the pull-off force beyond its weight per
  metre of strand against stickiness × band width (:attr:`Strands.tack_per_length`); a
  segment lying across a fixed strand at right angles pulled off the same way, beside
  stickiness × the disk the film wets (:attr:`Strands.tack_per_crossing`); and a settled
  nest's strand–strand contacts, the adhesion MuJoCo applies summed against the film's law
  at each contact's angle (:func:`crossing_tack`) summed.
- **mass and diameter** — of the strand as MuJoCo compiled it, against the cooked strand's.

The contact law of every strand pair is MuJoCo's *effective* one, read from its contacts.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from articutool.sim.food_strands import set_fork_strand, set_strand_geom, strand_chain
from articutool.sim.params import PhysicsParams, Strands
from articutool.sim.world_parts import GeomSetter, sig, sigs, solver_spec
from articutool.spec import Spec

__all__ = [
    "all_pass",
    "cantilever_test",
    "cantilever_tip_deflection",
    "capstan_hold_ratio",
    "capstan_law",
    "contact_tack",
    "crossing_tack",
    "crossing_tack_test",
    "nest_tack_test",
    "run_strand_calibration",
    "strand_contacts",
    "table",
    "tack_test",
]

GRAVITY = 9.81
_RESET_WARNINGS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                   mujoco.mjtWarning.mjWARN_BADQACC)
# Cooked spaghetti, as cited in physics.toml [foods.noodles] (the values to compare with).
COOKED_STRAND_G = 2.0
COOKED_DIAMETER_MM = (2.9, 3.1)
STICKINESS_PA = (400.0, 900.0)
# Tolerances of the calibration table (docs/food.md).
CAPSTAN_TOL = 0.20  # bar: within 20 % of e^(μπ)
FRICTIONLESS_MAX = 1.1
BENDING_TOL = 0.10
TACK_TOL = 0.15
MASS_TOL = 0.05


def capstan_law(mu: float, wrap: float = math.pi) -> float:
    """Euler–Eytelwein: the largest load ratio a flexible rope with friction ``mu`` holds over a
    wrap of ``wrap`` radians."""
    return math.exp(mu * wrap)


def cantilever_tip_deflection(ei: float, q: float, length: float) -> float:
    """m: how far the free end of a rod (bending stiffness ``ei``, weight ``q`` N/m, ``length``)
    clamped level at one end falls under its own weight — the elastica, exact for large
    deflections. θ(s) is the slope below level: E·I·θ'' = −q·(L − s)·cos θ, θ(0) = 0, θ'(L) = 0
    (no moment at the free end), solved by shooting on θ'(0); the tip falls ∫ sin θ ds. For
    small deflections this is q·L⁴ / (8·E·I). For q·L³/(E·I) up to 50 (a strand's 8 cm
    overhang is 33), where the tip's slope stays below a right angle."""
    if not 0 < q * length**3 / ei <= 50:
        raise ValueError(f"q·L³/(E·I) must be in (0, 50]; got {q * length**3 / ei:.3g}")

    def rhs(s: float, y: NDArray[np.float64]) -> list[float]:
        th, dth, _z = y
        return [dth, -q * (length - s) * math.cos(th) / ei, math.sin(th)]

    def end_moment(k0: float) -> float:
        sol = solve_ivp(rhs, (0.0, length), [0.0, k0, 0.0], rtol=1e-9, atol=1e-12)
        return float(sol.y[1, -1])

    # θ'(0) = M(0)/(E·I) ≤ q·L²/(2·E·I), the small-deflection value (cos θ ≤ 1): the root
    # with θ'(0) in that range, bracketed by the first sign change on a grid.
    grid = np.linspace(0.0, q * length**2 / (2 * ei), 17)
    f = [end_moment(k) for k in grid]
    i = next(j for j in range(16) if f[j] <= 0.0 <= f[j + 1])
    k0 = brentq(end_moment, grid[i], grid[i + 1], xtol=1e-14)
    sol = solve_ivp(rhs, (0.0, length), [0.0, k0, 0.0], rtol=1e-9, atol=1e-12)
    return float(sol.y[2, -1])


def crossing_tack(theta: float, stickiness_pa: float, radius: float, film: float,
                  length: float) -> float:
    """N: the pull-off force of the starch film between two strands of ``radius`` whose axes
    cross at ``theta`` radians (0 = lying along each other, π/2 = a right angle), over the
    ``length`` of strand one contact point stands for.

    Near their closest point two cylinders stand g = ((n₁·x)² + (n₂·x)²)/(2r) apart, n_i
    the in-plane normal of axis i (each curves across its own axis); the film of thickness
    ``film`` h wets g < h: an ellipse with semi-axes a = √(2rh/(1 − cos θ)) along the axes'
    bisector and b = √(2rh/(1 + cos θ)) across it, area π·a·b = 2π·r·h / sin θ. The contact
    point stands for the part of it within ``length`` L along the bisector: the whole
    ellipse while 2a ≤ L, else the ellipse clipped to |x| ≤ L/2,
    2ab·(u√(1 − u²) + arcsin u) with u = L/(2a), which tends to the band of two parallel
    cylinders, 2√(r·h) wide, over L as θ → 0. Times the stickiness (a force per wetted area).
    Continuous in θ, and non-increasing on [0, π/2] when L ≥ √3 × the parallel band's
    width 2√(r·h) (below, the band's slight widening with θ outgrows the clipping near 0°;
    the noodles' half segment is 2.1× that length)."""
    th = min(abs(theta), math.pi - abs(theta))  # the acute angle between the axes
    rh2 = 2.0 * radius * film
    b = math.sqrt(rh2 / (1.0 + math.cos(th)))
    if th == 0.0:
        return stickiness_pa * 2.0 * b * length
    a = math.sqrt(rh2 / (1.0 - math.cos(th)))
    u = length / (2.0 * a)
    if u >= 1.0:
        return stickiness_pa * math.pi * a * b
    return stickiness_pa * 2.0 * a * b * (u * math.sqrt(1.0 - u * u) + math.asin(u))


def contact_tack(food: Strands, theta: float) -> float:
    """N: :func:`crossing_tack` for ``food``'s strands at ``theta``: its stickiness, radius and
    film (:attr:`Strands.film_thickness`), over half a segment — the length one contact point
    of two strands stands for (two parallel capsules touch at their two ends; along a
    shallow crossing both chains' joints cut the line of contact, one point a piece)."""
    return crossing_tack(theta, food.stickiness_pa, food.strand_radius, food.film_thickness,
                         food.segment_length / 2.0)


@dataclass(frozen=True)
class _Rig:
    """A small world: the strand's chain and what it touches."""

    model: mujoco.MjModel
    data: mujoco.MjData
    first: int  # body id of the strand's segment 0
    n: int


Part = Callable[[mujoco.MjsBody], None]  # adds bodies and geoms to the world body


def _fork_law(food: Strands, tack: bool, frictionless: bool = False) -> GeomSetter:
    """A fork geom's contact toward strands, as the world gives the fork; the frictionless
    variant has the same solref and wins every contact by priority."""
    if not frictionless:
        return lambda g: set_fork_strand(g, food, tack)

    def law(g: mujoco.MjsGeom) -> None:
        g.condim, g.priority, g.friction = 1, 1, [0.0, 0.0, 0.0]
        g.solref = sigs(food.contacts.utensil.solref)
    return law


def _rig(parts: list[Part], params: PhysicsParams, food: Strands, name: str = "s") -> _Rig:
    """A small world of ``parts`` with the feeding world's solver and the food's no-slip
    passes."""
    s = solver_spec(params.world, food)
    s.memory = 64 << 20
    for part in parts:
        part(s.worldbody)
    m = s.compile()
    d = mujoco.MjData(m)
    return _Rig(m, d, m.body(f"{name}/0").id, food.segments)


def _straight(food: Strands, pos: tuple[float, float, float], free: bool = True,
              name: str = "s", tack: bool = True) -> Part:
    eye = [np.eye(3)] * food.segments
    return lambda parent: strand_chain(food, parent, name, pos, eye,
                                       lambda g: set_strand_geom(g, food, tack), free=free)


def _geom(name: str, kind: mujoco.mjtGeom, size: list[float], law: GeomSetter,
          **where: list[float]) -> Part:
    """A part: one geom of the world body carrying ``law``."""
    def part(parent: mujoco.MjsBody) -> None:
        law(parent.add_geom(name=name, type=kind, size=size, **where))
    return part


def _effective(rig: _Rig, geom: int) -> dict[str, Any] | None:
    """MuJoCo's effective law in a contact of ``geom`` with the strand."""
    d = rig.data
    for c in d.contact[:d.ncon]:
        if geom in (c.geom1, c.geom2):
            return {"mu": round(float(c.friction[0]), 6), "condim": int(c.dim),
                    "solref": [round(float(x), 6) for x in c.solref]}
    return None


def _hold(food: Strands, params: PhysicsParams, radius: float, surface: GeomSetter,
          end_load: float,
          ratio: float, settle_s: float = 1.5, ramp_s: float = 1.5, hold_s: float = 3.0
          ) -> tuple[bool, dict[str, Any]]:
    """One capstan trial: the strand draped over a bar of ``radius`` (its ``surface`` law),
    ``end_load`` N hung on both ends; after settling, one end's tension is raised to
    ``ratio`` × the other's over ``ramp_s`` and held. It holds when the strand's middle,
    measured round the bar, no longer moves in the last second (< 1 mm: a polygon of capsules
    may settle by a step as it loads, a sliding strand does not stop)."""
    n, ds, r = food.segments, food.segment_length, food.strand_radius
    rc = radius + r  # the strand's centre line round the bar
    z0 = 0.3
    # Start: a polygon whose segments all stand clear of the bar, bent by at most 1 rad a
    # joint (sharper kinks store energy that throws the strand), legs hanging straight down;
    # the end loads grow during the first half of the settling (hung at once, they pull a
    # strand through a thin tine before its contacts can stop it).
    rs = max(math.sqrt((1.02 * rc) ** 2 + ds**2 / 4), ds)
    dphi = 2 * math.asin(min(ds / (2 * rs), 1.0))
    mid = n // 2
    phis = np.clip((np.arange(n) - mid + 0.5) * dphi, -math.pi / 2, math.pi / 2)
    nodes = np.zeros((n + 1, 2))
    nodes[mid] = (0.0, rs)
    for i in range(mid, n):
        nodes[i + 1] = nodes[i] + ds * np.array([math.cos(phis[i]), -math.sin(phis[i])])
    for i in range(mid - 1, -1, -1):
        nodes[i] = nodes[i + 1] - ds * np.array([math.cos(phis[i]), -math.sin(phis[i])])
    bar = _geom("bar", mujoco.mjtGeom.mjGEOM_CAPSULE, [radius, 0.0, 0.0], surface,
                fromto=[0.0, -0.05, z0, 0.0, 0.05, z0])
    rig = _rig([bar, _straight(food, (0.0, 0.0, 1.0), tack=False)], params, food)
    m, d = rig.model, rig.data
    qa = m.jnt_qposadr

    def about_y(a: float) -> NDArray[np.float64]:
        return np.array([math.cos(a / 2), 0.0, math.sin(a / 2), 0.0])

    d.qpos[qa[0]:qa[0] + 3] = (nodes[0][0], 0.0, z0 + nodes[0][1])
    d.qpos[qa[0] + 3:qa[0] + 7] = about_y(phis[0])
    for i in range(1, n):
        d.qpos[qa[i]:qa[i] + 4] = about_y(phis[i] - phis[i - 1])
    mujoco.mj_forward(m, d)
    first, last = rig.first, rig.first + n - 1
    w = food.piece_mass / food.strand_length * GRAVITY
    t0 = end_load + w * (food.strand_length - math.pi * rc) / 2  # tension leaving the bar
    dt = m.opt.timestep
    bar_id = m.geom("bar").id
    info: dict[str, Any] = {"unstable": False, "fell_off": False}
    a0 = a1 = None
    pen = 0.0
    steps = round((settle_s + ramp_s + hold_s) / dt)
    for step in range(steps):
        t = step * dt
        hung = end_load * min(2 * t / settle_s, 1.0)
        d.xfrc_applied[first, 2] = -hung
        d.xfrc_applied[last, 2] = -(hung + t0 * (ratio - 1)
                                    * min(max(t - settle_s, 0.0) / ramp_s, 1.0))
        mujoco.mj_step(m, d)
        p = d.xpos[rig.first + mid]
        ang = math.atan2(p[0], p[2] - z0)
        if a0 is None and t >= settle_s:
            a0 = ang
            info["effective"] = _effective(rig, bar_id)
            info["penetration_mm"] = round(pen * 1e3, 3)
        if a1 is None and t >= settle_s + ramp_s + hold_s - 1.0:
            a1 = ang
        if a0 is None:
            pen = max([pen] + [-c.dist for c in d.contact[:d.ncon] if bar_id in (c.geom1, c.geom2)])
        if any(d.warning[w].number for w in _RESET_WARNINGS):
            info["unstable"] = True  # MuJoCo reset the state: no measurement
            return False, info
        if a0 is not None and abs(ang - a0) * rc > 0.02:
            return False, info  # slid off
    assert a1 is not None
    touching = any(bar_id in (c.geom1, c.geom2) for c in d.contact[:d.ncon])
    if not touching:
        info["fell_off"] = True  # through or off the bar: it holds nothing
    return touching and abs(ang - a1) * rc < 0.001, info


def capstan_hold_ratio(food: Strands, params: PhysicsParams, radius: float,
                       surface: GeomSetter, end_load: float, hi: float = 16.0, rel_tol: float = 0.02
                       ) -> dict[str, Any]:
    """The largest end-load ratio the draped strand holds (:func:`_hold`), found by bisection
    between 1 and ``hi`` to ``rel_tol``; with MuJoCo's effective μ and e^(μπ) beside it."""
    c0 = time.process_time()
    lo = 1.0
    ok, info = _hold(food, params, radius, surface, end_load, lo)
    unstable = int(info.pop("unstable"))
    # Sliding at equal loads: a neutral balance (a frictionless bar) holds no more than 1.
    info["slides_at_equal_loads"] = not ok
    if ok:
        while hi / lo > 1 + rel_tol:
            mid = math.sqrt(lo * hi)
            held, trial = _hold(food, params, radius, surface, end_load, mid)
            unstable += trial["unstable"]  # counted as not holding
            lo, hi = (mid, hi) if held else (lo, mid)
    mu = (info.get("effective") or {}).get("mu", 0.0)
    rc = radius + food.strand_radius
    t0 = end_load + food.piece_mass / food.strand_length * GRAVITY * (
        food.strand_length - math.pi * rc) / 2
    ei = food.young * math.pi * food.strand_radius**4 / 4
    return {"hold_ratio": round(lo, 3), "law_e_mu_pi": round(capstan_law(mu), 3),
            "bar_radius_mm": round(radius * 1e3, 2), "end_load_N": round(end_load, 4),
            "bending_over_tension": round(ei / (rc**2 * t0), 3), **info,
            "unstable_trials": unstable,
            "cpu_s": round(time.process_time() - c0, 1)}


def cantilever_test(food: Strands, params: PhysicsParams, segments: int,
                    settle_s: float = 4.0) -> dict[str, Any]:
    """A strand clamped level overhanging by ``segments`` jointed segments: the tip's fall
    after ``settle_s`` against the elastica with E·I from the modulus and the strand's weight
    per metre. Each joint stands for the curvature of the ds of rod round it, so the clamp of
    the discrete rod is the middle of its fixed segment 0 (the first joint ds/2 beyond it) and
    the overhang is (segments + ½)·ds; counted from the joint instead, the chain would bend
    (1 + 1/segments)² as much as the rod, from the lumping alone."""
    ds = food.segment_length
    z0 = 0.3
    # The strand cut to the clamped segment and the overhang (same ds, E·I and mass per m).
    sub = food.model_copy(update={"segments": segments + 1,
                                  "strand_length": ds * (segments + 1)})
    rig = _rig([_straight(sub, (0.0, 0.0, z0), free=False)], params, sub)
    m, d = rig.model, rig.data
    assert abs(sub.bend_stiffness - food.bend_stiffness) < 1e-12 * food.bend_stiffness
    mujoco.mj_step(m, d, round(settle_s / m.opt.timestep))
    tip_body = rig.first + segments
    tip = d.xpos[tip_body] + d.xmat[tip_body].reshape(3, 3) @ np.array([ds, 0.0, 0.0])
    fall = z0 - float(tip[2])
    length = ds * (segments + 0.5)
    q = food.piece_mass / food.strand_length * GRAVITY
    ei = food.young * math.pi * food.strand_radius**4 / 4
    law = cantilever_tip_deflection(ei, q, length)
    return {"overhang_mm": round(length * 1e3, 1), "tip_fall_mm": round(fall * 1e3, 2),
            "law_elastica_mm": round(law * 1e3, 2),
            "small_deflection_mm": round(q * length**4 / (8 * ei) * 1e3, 2),
            "error": round(fall / law - 1.0, 3)}


def _contact_adhesion(rig: _Rig, geom: int) -> list[float]:
    """The adhesion MuJoCo applies (N, after mixing the two geoms' values by priority) on each
    contact of ``geom``."""
    d = rig.data
    return sorted({sig(float(c.adhesion), 6) for c in d.contact[:d.ncon]
                   if geom in (c.geom1, c.geom2)})


def _cited_range(law: float, food: Strands, digits: int) -> list[float]:
    """``law`` (a force for the food's stickiness) at the cited stickinesses' ends."""
    if food.stickiness_pa <= 0:
        return [0.0, 0.0]
    return [round(s * law / food.stickiness_pa, digits) for s in STICKINESS_PA]


def _pull_off(rig: _Rig, bodies: list[int], limit: float, gap: float,
              ramp_n_per_s: float) -> float:
    """N: after 0.5 s of settling, a pull straight up spread over ``bodies``, raised at
    ``ramp_n_per_s`` until they leave their rest by more than ``gap`` + 0.5 mm (or it reaches
    ``limit``)."""
    m, d = rig.model, rig.data
    dt = m.opt.timestep
    z_rest = float(np.mean(d.xpos[bodies, 2]))
    pull = 0.0
    while pull < limit:
        pull += ramp_n_per_s * dt
        d.xfrc_applied[bodies, 2] = pull / len(bodies)
        mujoco.mj_step(m, d)
        if float(np.mean(d.xpos[bodies, 2])) - z_rest > gap + 0.5e-3:
            break
    return pull


def tack_test(food: Strands, params: PhysicsParams, on: str = "fork", segments: int = 4,
              ramp_n_per_s: float = 0.01) -> dict[str, Any]:
    """A piece of strand (``segments`` segments) lying on the fork's steel (a plate carrying the
    fork's contact attributes) or along another strand (``on="strand"``, the lower one fixed),
    pulled straight up by a force spread over its segments and raised at ``ramp_n_per_s``
    until it leaves the surface by more than the adhesion gap; the pull beyond its weight, per
    metre, against its law: :attr:`Strands.tack_per_length` on steel,
    :attr:`Strands.tack_per_length_parallel` along a strand."""
    ds, r = food.segment_length, food.strand_radius
    sub = food.model_copy(update={"segments": segments, "strand_length": ds * segments})
    z = 0.3
    if on == "fork":
        below = _geom("below", mujoco.mjtGeom.mjGEOM_BOX, [0.05, 0.02, 0.001],
                      _fork_law(food, tack=True), pos=[0.0, 0.0, z - 0.001])
        zc = z + r
        law = food.tack_per_length
    else:
        # A fixed strand below, as long and with the strand geoms' own attributes.
        below = _geom("below", mujoco.mjtGeom.mjGEOM_CAPSULE, [r, 0.0, 0.0],
                      lambda g: set_strand_geom(g, food),
                      fromto=[-0.01, 0.0, z + r, sub.strand_length + 0.01, 0.0, z + r])
        zc = z + 3 * r
        law = food.tack_per_length_parallel
    rig = _rig([below, _straight(sub, (0.0, 0.0, zc))], params, sub)
    m, d = rig.model, rig.data
    bodies = list(range(rig.first, rig.first + segments))
    weight = sub.piece_mass * GRAVITY
    mujoco.mj_step(m, d, round(0.5 / m.opt.timestep))  # settle
    ncon = int(d.ncon)
    adhesion = _contact_adhesion(rig, m.geom("below").id)
    pull = _pull_off(rig, bodies, 50 * (weight + food.tack_per_length * sub.strand_length),
                     food.adhesion_gap, ramp_n_per_s)
    per_m = (pull - weight) / sub.strand_length
    return {"on": on, "contacts_at_rest": ncon, "contact_adhesion_N": adhesion,
            "pull_off_N_per_m": round(per_m, 4), "law_N_per_m": round(law, 4),
            "law_range_N_per_m": _cited_range(law, food, 4),
            "error": round(per_m / law - 1.0, 3) if law > 0 else None}


def crossing_tack_test(food: Strands, params: PhysicsParams,
                       ramp_n_per_s: float = 1e-4) -> dict[str, Any]:
    """One segment of strand lying across a fixed strand at right angles, crossing at its
    middle, on a carriage that only slides vertically (a lone capsule balanced on a crossing
    would roll off it), pulled straight up by a force raised at ``ramp_n_per_s`` until it
    leaves by more than the adhesion gap; the pull beyond its weight beside the right angle's
    law, :attr:`Strands.tack_per_crossing`, with the adhesion MuJoCo applies on the contact
    (the strand geoms carry the law's mean over a nest's angles, so it is above)."""
    ds, r = food.segment_length, food.strand_radius
    sub = food.model_copy(update={"segments": 1, "strand_length": ds})
    z = 0.3
    below = _geom("below", mujoco.mjtGeom.mjGEOM_CAPSULE, [r, 0.0, 0.0],
                  lambda g: set_strand_geom(g, food), fromto=[0.0, -ds, z, 0.0, ds, z])

    def upper(parent: mujoco.MjsBody) -> None:
        car = parent.add_body(name="carriage", pos=[0.0, 0.0, z + 2 * r])
        car.add_joint(type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0.0, 0.0, 1.0])
        strand_chain(sub, car, "s", (-ds / 2, 0.0, 0.0), [np.eye(3)],
                     lambda g: set_strand_geom(g, food), free=False)

    rig = _rig([below, upper], params, sub)
    m, d = rig.model, rig.data
    weight = float(m.body_subtreemass[m.body("carriage").id]) * GRAVITY
    mujoco.mj_step(m, d, round(0.5 / m.opt.timestep))  # settle
    ncon = int(d.ncon)
    adhesion = _contact_adhesion(rig, m.geom("below").id)
    law = food.tack_per_crossing
    pull = _pull_off(rig, [rig.first], 50 * (weight + law), food.adhesion_gap, ramp_n_per_s)
    return {"contacts_at_rest": ncon, "contact_adhesion_N": adhesion,
            "pull_off_N": round(pull - weight, 7), "law_N": round(law, 7),
            "law_range_N": _cited_range(law, food, 7),
            "film_thickness_um": round(food.film_thickness * 1e6, 1),
            "error": round((pull - weight) / law - 1.0, 3) if law > 0 else None}


def strand_contacts(model: mujoco.MjModel, data: mujoco.MjData
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The strand–strand contact points of a world's state: each one's angle between the two
    capsules' axes (rad, in [0, π/2]), the adhesion MuJoCo applies on it (N) and the distance
    between the two surfaces (m; MuJoCo lists a pair out to the sum of its geoms' gaps). Read on a
    copy of ``data`` collided with sleeping off, so that a settled nest's sleeping strands
    list their contacts too (``model``'s flags are restored)."""
    d = mujoco.MjData(model)
    mujoco.mj_copyData(d, model, data)
    flags = model.opt.enableflags
    model.opt.enableflags = flags & ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    try:
        mujoco.mj_forward(model, d)
    finally:
        model.opt.enableflags = flags
    strand = np.array([model.geom(g).name.startswith("strand") for g in range(model.ngeom)])
    ang, adh, dist = [], [], []
    for c in d.contact[:d.ncon]:
        if strand[c.geom1] and strand[c.geom2]:
            a1 = d.geom_xmat[c.geom1].reshape(3, 3)[:, 2]
            a2 = d.geom_xmat[c.geom2].reshape(3, 3)[:, 2]
            ang.append(math.acos(min(abs(float(a1 @ a2)), 1.0)))
            adh.append(float(c.adhesion))
            dist.append(float(c.dist))
    return np.array(ang), np.array(adh), np.array(dist)


# The settled nest of the calibration's summed tack check: a seed no experiment (base 0, seeds
# 0-999), tuning search or the study that chose Strands.crossing_factor
# (studies/noodle_crossings.py, seeds 8100-8102) uses.
NEST_SEED = 8200


def nest_tack_test(food_name: str, spec: Spec, params: PhysicsParams,
                   utensil: str | None = None, seed: int = NEST_SEED) -> dict[str, Any]:
    """The default nest built and settled as an experiment's world settles it
    (:meth:`FeedingWorld.make`), seed ``seed``: the adhesion MuJoCo applies, summed over every
    strand–strand contact point, against the film's law (:func:`contact_tack`) summed over the
    same points at their angles."""
    from articutool.sim.world import FeedingWorld

    c0 = time.process_time()
    w = FeedingWorld.make(food_name, utensil, spec=spec, params=params, seed=seed)
    food = params.food(food_name)
    assert isinstance(food, Strands)
    ang, adh, dist = strand_contacts(w.model, w.data)
    law = np.array([contact_tack(food, a) for a in ang])
    deg = np.degrees(ang)
    return {"seed": seed, "settled_s": round(w.time, 2), "strand_contacts": len(ang),
            "beyond_adhesion_gap": int((dist > food.adhesion_gap).sum()),
            "angle_deg_quantiles_10_25_50_75_90":
                np.percentile(deg, [10, 25, 50, 75, 90]).round(1).tolist() if len(ang) else [],
            "adhesion_sum_N": round(float(adh.sum()), 7), "law_sum_N": round(float(law.sum()), 7),
            "error": round(float(adh.sum() / law.sum()) - 1.0, 3) if law.sum() > 0 else None,
            "cpu_s": round(time.process_time() - c0, 1)}


def fork_half_width(spec: Spec, utensil: str) -> float:
    """Half the width across a fork's outer tines (m): the radius a wrap round the tines
    winds on."""
    ph = spec.utensil(utensil).physics
    if not (ph.tines and ph.tine_pitch and ph.tine_radius):
        raise ValueError(f"--utensil: {utensil!r} is not a fork (no tines)")
    return ((ph.tines - 1) * ph.tine_pitch + 2 * ph.tine_radius) / 2


def all_pass(rows: dict[str, Any]) -> bool:
    """Whether no check of a calibration failed: a reported row (``pass`` None) neither passes
    nor fails, and a row without a verdict is not a check."""
    return all(v.get("pass") is not False for v in rows.values() if isinstance(v, dict))


def run_strand_calibration(food: Strands, params: PhysicsParams, spec: Spec,
                           utensil: str, food_name: str = "noodles") -> dict[str, Any]:
    """Every strand calibration experiment, each beside its law and whether it passes
    (``food_name``: the food's name in ``params``, whose nest the summed tack check settles)."""
    ph = spec.utensil(utensil).physics
    if not (ph.tines and ph.tine_pitch and ph.tine_radius):
        raise ValueError(f"--utensil: the strand calibration needs a fork (its tines); got "
                         f"{utensil!r}")
    out: dict[str, Any] = {}
    # Mass and diameter of the strand as MuJoCo compiled it.
    rig = _rig([_straight(food, (0.0, 0.0, 0.3))], params, food)
    mass_g = float(sum(rig.model.body_mass[rig.first:rig.first + food.segments])) * 1e3
    dia = 2e3 * float(rig.model.geom_size[rig.model.body_geomadr[rig.first]][0])
    out["strand"] = {
        "mass_g": round(mass_g, 3), "cited_mass_g": COOKED_STRAND_G,
        "diameter_mm": round(dia, 2), "cited_diameter_mm": list(COOKED_DIAMETER_MM),
        "segments": food.segments, "segment_mm": round(food.segment_length * 1e3, 2),
        "pass": abs(mass_g / COOKED_STRAND_G - 1) <= MASS_TOL
        and COOKED_DIAMETER_MM[0] <= dia <= COOKED_DIAMETER_MM[1]}
    # Capstan on a bar as wide as the fork, loads where bending is a tenth of the tension.
    bar = fork_half_width(spec, utensil)
    ei = food.young * math.pi * food.strand_radius**4 / 4
    rc = bar + food.strand_radius
    w_hang = food.piece_mass / food.strand_length * GRAVITY * (food.strand_length
                                                                - math.pi * rc) / 2
    load = max(10 * ei / rc**2 - w_hang, 0.0)
    cap = capstan_hold_ratio(food, params, bar, _fork_law(food, tack=False), load)
    cap["pass"] = abs(cap["hold_ratio"] / cap["law_e_mu_pi"] - 1) <= CAPSTAN_TOL
    out["capstan_bar"] = cap
    fl = capstan_hold_ratio(food, params, bar, _fork_law(food, False, frictionless=True),
                            load)
    fl["law_e_mu_pi"] = 1.0
    fl["pass"] = 0 < fl["hold_ratio"] <= FRICTIONLESS_MAX
    out["capstan_bar_frictionless"] = fl
    # On one tine, with a strand's own weight hung on each end (no rope law applies).
    strand_w = food.piece_mass * GRAVITY
    out["capstan_tine"] = capstan_hold_ratio(food, params, ph.tine_radius,
                                             _fork_law(food, tack=False), strand_w)
    out["capstan_tine_frictionless"] = capstan_hold_ratio(
        food, params, ph.tine_radius, _fork_law(food, False, frictionless=True), strand_w)
    # Bending: cantilevers of 3 and 5 segments.
    bends = [cantilever_test(food, params, k) for k in (3, 5, 8)]
    out["cantilever"] = {"overhangs": bends,
                         "pass": all(abs(b["error"]) <= BENDING_TOL for b in bends)}
    # Tack on the fork's steel (the law) and over a settled nest's strand–strand contacts (the
    # film's law at each one's angle, summed). A right-angle crossing alone and two strands
    # lying along each other are reported: the strand geoms carry one value, the law's mean
    # over a nest's angles, which over-pulls the one and under-pulls the other (docs/food.md).
    if food.stickiness_pa > 0:
        tacks = [tack_test(food, params, on) for on in ("fork", "strand")]
        tacks[0]["pass"] = abs(tacks[0]["error"]) <= TACK_TOL
        tacks[1]["pass"] = None
        cross = crossing_tack_test(food, params)
        cross["pass"] = None
        out["tack"] = {"tests": tacks, "per_contact_N": round(food.tack_per_contact, 7),
                       "pass": tacks[0]["pass"]}
        out["tack_crossing"] = cross
        nest = nest_tack_test(food_name, spec, params, utensil)
        nest["pass"] = nest["error"] is not None and abs(nest["error"]) <= TACK_TOL
        out["tack_nest"] = nest
    out["all_pass"] = all_pass(out)
    return out


def table(cal: dict[str, Any]) -> str:
    """The calibration as a Markdown table: mechanism, measured, law, tolerance, pass."""
    rows = ["| mechanism | measured | law | tolerance | passes |", "|---|---|---|---|---|"]

    def yes(v: bool | None) -> str:
        return "reported" if v is None else ("yes" if v else "**no**")

    s = cal["strand"]
    rows.append(f"| strand mass | {s['mass_g']:.2f} g | {s['cited_mass_g']:.1f} g (cooked) | "
                f"±{MASS_TOL:.0%} | {yes(s['pass'])} |")
    rows.append(f"| strand diameter | {s['diameter_mm']:.2f} mm | "
                f"{s['cited_diameter_mm'][0]}–{s['cited_diameter_mm'][1]} mm | range | "
                f"{yes(s['pass'])} |")
    for key, what, tol in (
            ("capstan_bar", "capstan, fork-wide bar", f"±{CAPSTAN_TOL:.0%}"),
            ("capstan_bar_frictionless", "capstan, frictionless bar", f"≤ {FRICTIONLESS_MAX}"),
            ("capstan_tine", "capstan, one tine (strand-weight loads)", "none (no rope law)"),
            ("capstan_tine_frictionless", "capstan, one frictionless tine", "none")):
        c = cal[key]
        eff = c.get("effective") or {}
        rows.append(f"| {what} (R {c['bar_radius_mm']} mm, μ_eff {eff.get('mu', '?')}, "
                    f"EI/(R²T) {c['bending_over_tension']}) | hold ratio {c['hold_ratio']} | "
                    f"{c['law_e_mu_pi']} | {tol} | {yes(c.get('pass'))} |")
    for b in cal["cantilever"]["overhangs"]:
        rows.append(f"| bending, cantilever {b['overhang_mm']} mm | tip falls "
                    f"{b['tip_fall_mm']} mm | elastica {b['law_elastica_mm']} mm | "
                    f"±{BENDING_TOL:.0%} | "
                    f"{yes(abs(b['error']) <= BENDING_TOL)} |")
    for t in cal.get("tack", {}).get("tests", []):
        lo, hi = t["law_range_N_per_m"]
        rows.append(f"| tack on {t['on']} | {t['pull_off_N_per_m']} N/m | {t['law_N_per_m']} N/m "
                    f"(cited {lo}–{hi}) | ±{TACK_TOL:.0%} | "
                    f"{yes(t.get('pass'))} |")
    c = cal.get("tack_crossing")
    if c:
        lo, hi = c["law_range_N"]
        rows.append(f"| tack across a strand (90°, adhesion {c['contact_adhesion_N']} N) | "
                    f"{c['pull_off_N'] * 1e3:.3f} mN | {c['law_N'] * 1e3:.3f} mN "
                    f"(cited {lo * 1e3:.3f}–{hi * 1e3:.3f}) | ±{TACK_TOL:.0%} | "
                    f"{yes(c['pass'])} |")
    n = cal.get("tack_nest")
    if n:
        rows.append(f"| tack of a settled nest's {n['strand_contacts']} strand–strand contacts "
                    f"(seed {n['seed']}, median {n['angle_deg_quantiles_10_25_50_75_90'][2]}°), "
                    f"summed | {n['adhesion_sum_N'] * 1e3:.2f} mN | "
                    f"{n['law_sum_N'] * 1e3:.2f} mN (the film's law at each angle) | "
                    f"±{TACK_TOL:.0%} | {yes(n['pass'])} |")
    return "\n".join(rows)
