"""The liquid in the loop: a placed water load is SPlisHSPlasH in the utensil's frame,
coupled to MuJoCo (sim/liquid_load.py), and the frame's pure mechanics (sim/liquid_frame.py)."""

import os
import subprocess

import numpy as np
import pytest

from articutool.food.dish import spoon_dish
from articutool.sim.liquid_frame import apparent_gravity, outside_dish
from articutool.sim.params import PhysicsParams
from articutool.sim.sph_scene import (
    momentum_balance_force,
    momentum_balance_torque,
    rotating_frame_acceleration,
)
from conftest import CLI, SRC, assert_refused


def test_apparent_gravity_is_gravity_less_the_acceleration_in_the_frame():
    g = np.array([0.0, 0.0, -9.81])
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90° about z
    assert np.allclose(apparent_gravity(R, g, [1.0, 0.0, 0.0]), R.T @ [-1.0, 0.0, -9.81])


def test_a_still_liquid_weighs_its_mass_and_its_torque_is_its_moment():
    x = np.array([[0.01, 0.0, 0.02], [0.01, 0.0, 0.04]])
    g = np.array([-9.81, 0.0, 0.0])
    f = momentum_balance_force(0.008e-3, np.zeros_like(x), g)
    tau = momentum_balance_torque(0.008e-3, x, np.zeros_like(x), g, np.zeros(3))
    assert np.allclose(f, 2 * 0.008e-3 * g)
    assert np.allclose(tau, np.cross(x, 0.008e-3 * g).sum(axis=0))
    # A particle accelerating with its gravity (free fall) puts nothing on the dish.
    f = momentum_balance_force(1.0, np.broadcast_to(g, x.shape), g)
    assert np.allclose(f, 0.0)


def test_rotation_terms_centrifugal_and_coriolis():
    x, v = np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])
    w = np.array([0.0, 0.0, 2.0])
    a = rotating_frame_acceleration(w, np.zeros(3))(x, v)
    # centrifugal ω²r outward along x; Coriolis −2ω×v = −2·(2 ẑ × ŷ) = +4 x̂
    assert np.allclose(a, [[4.0 + 4.0, 0.0, 0.0]])


def test_outside_the_dish_is_beyond_the_rim_or_below_the_shell(spec):
    u = spec.utensil("soup_spoon")
    d = spoon_dish(u)
    pts = np.array([[u.tip_x + 0.005, 0.0, d.zc],  # in the dish
                    [u.tip_x + 0.030, 0.0, d.zc],  # above it, over the dish
                    [u.tip_x + 0.010, 0.0, d.zc + d.a + 0.003],  # past the tip's rim
                    [u.tip_x - 0.010, 0.0, d.zc]])  # under the shell
    assert outside_dish(pts, d, u.tip_x, 0.001, 0.0045).tolist() == [False, False, True, True]


@pytest.fixture(scope="module")
def placed_water():
    from articutool.sim.world import FeedingWorld
    from articutool.tool.api import Mode

    w = FeedingWorld.make("water", load_g=8.0, mouth=False)
    w.tool.set_mode(Mode.LEVELING)
    w.run(1.0)
    w.weighing.tare(settle_s=0.2)
    held = w.placement.place(settle_s=1.0)
    w.run(2.0)  # a still load: the pour's slosh has rung down
    yield w, held
    w.close()


def test_a_placed_liquid_keeps_its_grams_on_the_utensil(placed_water):
    w, held = placed_water
    assert w.placement.liquid is not None  # the default: the SPH liquid
    assert held >= 0.99 * 8.0
    assert w.ledger.masses_g()["utensil"] >= 0.99 * 8.0
    assert w.report().total_g == pytest.approx(8.0, rel=1e-9)  # every particle an item


def test_the_scale_and_the_ft_sensor_weigh_the_liquid(placed_water):
    w, _ = placed_water
    grams = w.ledger.masses_g()["utensil"]
    assert w.weighing.carried_g() == pytest.approx(grams, rel=0.01)
    assert w.weighing.comparable()
    assert w.weighing.ft_mass_g(1.0) == pytest.approx(grams, rel=0.01)


def test_the_spheres_remain_an_option():
    from articutool.sim.world import FeedingWorld

    p = PhysicsParams.load()
    water = p.foods["water"].model_copy(update={"load_model": "spheres"})
    p = p.model_copy(update={"foods": {**p.foods, "water": water}})
    w = FeedingWorld.make("water", params=p, load_g=4.0, mouth=False, settle=False)
    w.placement.place(settle_s=0.2)
    assert w.placement.liquid is None and w.ledger.masses_g()["utensil"] > 0


def test_a_particle_radius_outside_the_validated_range_is_refused(tmp_path):
    r = subprocess.run([*CLI, "sim", "--food", "water", "--load", "8", "--liquid-radius",
                        "0.5"], capture_output=True, text=True, timeout=120, cwd=tmp_path,
                       env={**os.environ, "PYTHONPATH": str(SRC)}, check=False)
    assert_refused(r, "--liquid-radius", "[0.75, 1] mm")
    bad = tmp_path / "physics.toml"
    src = (SRC / "articutool" / "data" / "physics.toml").read_text()
    bad.write_text(src.replace("sph_particle_radius = 0.001", "sph_particle_radius = 0.002"))
    r = subprocess.run([*CLI, "sim", "--food", "water", "--physics", str(bad)],
                       capture_output=True, text=True, timeout=120, cwd=tmp_path,
                       env={**os.environ, "PYTHONPATH": str(SRC)}, check=False)
    assert_refused(r, "sph_particle_radius", "[0.75, 1] mm")


def test_a_broken_liquid_library_is_exit_2_with_the_fix(tmp_path):
    # A pysplishsplash that crashes on import, first on the path: the loader's message.
    fake = tmp_path / "fake"
    fake.mkdir()
    (fake / "pysplishsplash.py").write_text("import os, signal\nos.kill(os.getpid(), "
                                            "signal.SIGSEGV)\n")
    r = subprocess.run([*CLI, "sim-calibrate", "--food", "water", "--load", "8"],
                       capture_output=True, text=True, timeout=300, cwd=tmp_path,
                       env={**os.environ, "PYTHONPATH": f"{fake}{os.pathsep}{SRC}"},
                       check=False)
    assert_refused(r, "pysplishsplash", "pip install")
    assert "signal" in r.stderr


def test_the_liquid_counts_in_the_static_tilt_as_hydrostatics_says(spec):
    """One load, one particle size, over the tip, held at 12° (the smallest spill, the last to
    drain): within 15 % of the ideal liquid (the full sweep: the slow test below and
    docs/food.md), the onset within its tolerance, and the library's step never collapses:
    spilled particles are taken out during the holds too, so none falls away gaining speed
    (unchecked, the CFL step fell from 2 ms to 0.06 ms and the run did not finish)."""
    from articutool.sim.liquid_tilt import GRAMS_TOL, ONSET_TOL_DEG, static_tilt_sph
    from articutool.sim.sph_scene import close_this_threads_liquid

    close_this_threads_liquid()  # the placed load above holds the process's one solver
    res = static_tilt_sph(PhysicsParams.load().food("water"), spec, "soup_spoon", 8.0, "tip",
                          holds_deg=(12.0,))
    (hold,) = res["holds"]
    assert hold["spilled_g"] == pytest.approx(hold["hydrostatic_g"], rel=GRAMS_TOL)
    assert res["kept_g"] == pytest.approx(8.0)
    assert abs(res["onset"]["measured_deg"] - res["onset"]["law_deg"]) <= ONSET_TOL_DEG
    assert res["min_dt_ms"] > 0.5


def test_the_level_capacity_frees_the_solver_for_the_checks_after_it(spec):
    """``sim-calibrate --food water`` measures what the level spoon holds with a placed load,
    then opens its own liquids for the static tilt: SPlisHSPlasH holds one scene per process,
    so the capacity's world frees it once measured, and a liquid opens after it."""
    from articutool.sim.calibrate import level_capacity_g
    from articutool.sim.sph_scene import (
        Boundary,
        FluidBlock,
        SphLiquid,
        SphSettings,
        box_mesh,
        close_this_threads_liquid,
    )

    close_this_threads_liquid()  # a load an earlier test of this process left
    held, loaded = level_capacity_g("water", spec, PhysicsParams.load(), None, load_g=2.0)
    assert 0 < held <= loaded + 1e-9
    with SphLiquid([Boundary("box", *box_mesh((-0.01, -0.01, 0.0), (0.01, 0.01, 0.02)))],
                   [FluidBlock((-0.004, -0.004, 0.001), (0.004, 0.004, 0.005))],
                   SphSettings(particle_radius=0.001)) as liquid:
        assert liquid.n_particles == 32


@pytest.mark.slow
def test_a_locked_carry_spills_the_liquid_and_the_ledger_counts_it():
    """The locked soup spoon tilted 40° by the hand: the liquid leaves the dish, is handed to
    MuJoCo and counted where it lands; mass is conserved."""
    from articutool.sim.scenes import base_tilt_motion
    from articutool.sim.world import FeedingWorld
    from articutool.tool.api import Mode

    w = FeedingWorld.make("water", load_g=8.0, mouth=False)
    try:
        w.tool.set_mode(Mode.LEVELING)
        w.run(1.0)
        held = w.placement.place(settle_s=0.5)
        w.tool.set_mode(Mode.DISABLED)
        w.move_arm(base_tilt_motion(w, 40.0))
        w.run(1.5)
        m = w.ledger.masses_g()
        assert w.placement.liquid.handed_off > 0
        assert m["utensil"] < held - 2.0  # hydrostatics at 40°: most of it runs out
        assert sum(m.values()) == pytest.approx(8.0, rel=1e-9)
    finally:
        w.close()


@pytest.mark.slow
@pytest.mark.parametrize("r", [
    0.001,
    pytest.param(0.00075, marks=pytest.mark.xfail(
        strict=True, reason="measured: at r 0.75 mm the hold just past the onset spills +16 "
        "to +51 % of hydrostatics in five of eight rows, whatever the turning rate or the "
        "counting margin (docs/food.md, docs/notes/2026-11-30-liquid-tilt-rate.md)")),
])
def test_the_static_tilt_sweep_follows_hydrostatics(spec, r):
    """The full sweep of sim-calibrate at one particle radius: 6-12 g, both directions."""
    from articutool.sim.liquid_tilt import (
        ONSET_G,
        TILT_LOADS_G,
        TILT_RADII_M,
        static_tilt_sph,
    )

    assert r in TILT_RADII_M
    fp = PhysicsParams.load().food("water")
    for g in TILT_LOADS_G:
        for d in ("tip", "side"):
            res = static_tilt_sph(fp, spec, "soup_spoon", g, d, r)
            assert res["passes"], res
            # the onset is where ONSET_G had left: at or below the first hold past it
            past = [h["tilt_deg"] for h in res["holds"] if h["spilled_g"] >= ONSET_G]
            assert res["onset"]["measured_deg"] <= min(past) + 1e-9, res
