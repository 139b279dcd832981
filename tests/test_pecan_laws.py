"""The pecan model's mechanisms against their laws: static friction holds a resting piece
(creep), the pile test's heap and how its angle is read, and the test's reruns."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

pytest.importorskip("mujoco")

from articutool.sim.calibrate import (
    CREEP_LIMIT_MM,
    CREEP_SLOPES_DEG,
    FLANK_BIN_M,
    PLATE_RADIUS_M,
    angle_of_repose_deg,
    creep_mm,
    envelope_slope_deg,
    flank_angle_deg,
    pile_test_model,
    surface_envelope,
)
from articutool.sim.params import PhysicsParams


@pytest.fixture(scope="module")
def params() -> PhysicsParams:
    return PhysicsParams.load()


def test_a_pecan_half_rests_on_a_steel_slope_below_its_friction_angle(
        params: PhysicsParams) -> None:
    food = params.food("pecans")
    assert math.degrees(math.atan(food.contacts.utensil.friction[0])) > max(CREEP_SLOPES_DEG)
    for slope in CREEP_SLOPES_DEG:
        assert creep_mm(food, params, slope) < CREEP_LIMIT_MM, slope


def test_soft_contacts_alone_let_the_half_creep(params: PhysicsParams) -> None:
    # The law tells the two apart: MuJoCo's soft friction without the no-slip pass creeps
    # (0.27-0.53 mm at 10-20°, measured).
    soft = params.food("pecans").model_copy(update={"noslip_iterations": 0})
    assert max(creep_mm(soft, params, s) for s in CREEP_SLOPES_DEG) > CREEP_LIMIT_MM


def test_the_flank_angle_is_the_slope_of_the_surface_envelope() -> None:
    # Points under a 30° cone of a 40 mm apex, every 1 mm of radius (none on a ring's edge):
    # the envelope of each ring is its innermost point.
    h0, t = 0.04, math.tan(math.radians(30.0))
    pts = [(r, h0 - r * t - dz) for r in ((x + 0.5) * 1e-3 for x in range(0, 50))
           for dz in (0.0, 0.003)]
    assert flank_angle_deg(pts) == pytest.approx(30.0, abs=0.01)
    # A piece standing 10 mm proud on the apex moves the flank's line (one ring of ten) less
    # than it moves the apex height's angle over the same base.
    apex = math.degrees(math.atan((h0 + 0.01) / 0.05) - math.atan(h0 / 0.05))
    assert 0.0 < flank_angle_deg([*pts, (0.001, h0 + 0.01)]) - 30.0 < apex
    assert flank_angle_deg([(0.01, 0.01)]) == 0.0
    assert FLANK_BIN_M < PLATE_RADIUS_M


def test_every_contact_of_the_pile_test_carries_the_file_s_law(params: PhysicsParams) -> None:
    # What MuJoCo applies after mixing the two geoms' condim, friction, solref and priority:
    # piece-piece, piece-plate and piece-tube contacts of a settling tube of pieces.
    import mujoco

    food = params.food("pecans")
    m, _, _ = pile_test_model(food, params, n=20, seed=0)
    d = mujoco.MjData(m)
    assert m.opt.noslip_iterations == food.noslip_iterations
    seen = set()
    for _ in range(150):
        mujoco.mj_step(m, d)
        for c in d.contact[:d.ncon]:
            if 0 in (c.geom1, c.geom2):  # the ground plane: pieces fallen off the plate
                continue
            plate = m.geom_bodyid[c.geom1] == 0 or m.geom_bodyid[c.geom2] == 0
            tube = 1 in (m.geom_bodyid[c.geom1], m.geom_bodyid[c.geom2])
            law = food.contacts.utensil if plate or tube else food.contacts.food
            sl, tor, roll = law.friction
            assert c.dim == law.condim
            np.testing.assert_allclose(c.friction, (sl, sl, tor, roll, roll))
            np.testing.assert_allclose(c.solref, law.solref)
            np.testing.assert_allclose(c.solimp, law.solimp)
            seen.add("plate" if plate else "tube" if tube else "piece")
    assert {"plate", "piece"} <= seen


@given(st.floats(-60.0, 60.0), st.floats(0.0, 0.05), st.floats(1e-3, 10.0))
def test_an_envelope_s_slope_is_signed_in_any_unit_and_the_flank_clamps_a_rise(
        angle: float, top: float, unit: float) -> None:
    # Ring tops on a line falling outwards at ``angle`` (rising where negative), in m scaled
    # by ``unit``: the slope reads the angle whatever the unit; the flank reads it where the
    # surface falls and 0 where it rises.
    t = math.tan(math.radians(angle))
    env = [(r * unit, (top - r * t) * unit) for r in (0.0025, 0.0075, 0.0125, 0.0175)]
    assert envelope_slope_deg(env) == pytest.approx(angle, abs=1e-6)
    pts = [(r / unit, z / unit) for r, z in env]
    assert flank_angle_deg(pts) == pytest.approx(max(angle, 0.0), abs=1e-6)


def test_the_surface_envelope_keeps_each_ring_s_highest_point_on_the_plate() -> None:
    pts = [(0.001, 0.020), (0.004, 0.025), (0.012, 0.010), (0.013, 0.015), (0.051, 0.030)]
    # Rings of 5 mm: the first ring's highest point, the third's; beyond the plate: none.
    assert surface_envelope(pts) == [(0.0025, 0.025), (0.0125, 0.015)]
    assert surface_envelope([]) == []


def test_the_pile_test_reruns_bit_identically(params: PhysicsParams) -> None:
    food = params.food("pecans")
    a, b = (angle_of_repose_deg(food, params, n=12, seed=1) for _ in range(2))
    assert a["state_sha256"] == b["state_sha256"]
    assert a["angle_deg"] == b["angle_deg"] and a["flank_angle_deg"] == b["flank_angle_deg"]


def test_above_its_friction_angle_the_half_slides(params: PhysicsParams) -> None:
    # The no-slip passes hold static friction without changing the Coulomb coefficient: at 25°
    # (atan 0.45 = 24.2°) the half slides off (325 mm in 1 s, measured).
    assert creep_mm(params.food("pecans"), params, 25.0, hold_s=1.0) > 10.0


def test_the_settled_bowl_sleeps() -> None:
    # The static-friction setting must let a resting pile come to rest below the sleep
    # tolerance: a settled bowl then costs nothing until the spoon touches it (one pass of
    # no-slip, or stiffer friction rows without it, left pieces moving at cm/s: measured).
    from articutool.sim.world import FeedingWorld

    w = FeedingWorld.make("pecans", seed=0)
    w.run(1.0)
    awake = w.data.body_awake[w.ledger.item_body]
    assert not awake.any(), f"{int(awake.sum())} of {awake.size} pieces awake"


def test_the_pile_s_no_slip_passes_follow_the_spoon_s_tip() -> None:
    # While the spoon's tip is in the bowl, below its rim, the pile runs without no-slip
    # passes (``noslip_iterations_digging``); above the rim the food's passes hold the
    # disturbed pile and the spoon's load.
    from articutool.sim.scenes import scoop
    from articutool.sim.world import FeedingWorld

    w = FeedingWorld.make("pecans", seed=3)
    food = w.params.food("pecans")
    box = w.scene.get("bowl")
    rim = box.xyz[2] + box.length / 2
    seen: list[tuple[bool, int]] = []

    def record(world: FeedingWorld) -> None:
        tip = world.data.site_xpos[world.index.tip_site]
        inside = tip[2] < rim and math.dist(tip[:2], box.xyz[:2]) < box.radius
        seen.append((inside, int(world.model.opt.noslip_iterations)))

    w.on_tick.append(record)
    scoop(w)
    assert any(inside for inside, _ in seen) and not seen[-1][0]
    for inside, passes in seen:
        assert passes == (food.noslip_iterations_digging if inside else food.noslip_iterations)
    assert food.noslip_iterations_digging != food.noslip_iterations
