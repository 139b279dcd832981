"""The SPlisHSPlasH wrapper: the momentum-balance force (pure, property-tested) and a real
liquid in a box (settles, weighs its grams, follows gravity, a moving wall and a body
acceleration, loses the particles it is told to)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from articutool.sim.sph_scene import (
    Boundary,
    FluidBlock,
    FluidParticles,
    SphLiquid,
    SphSettings,
    box_mesh,
    momentum_balance_force,
    momentum_balance_torque,
    rotating_frame_acceleration,
)

G = np.array([0.0, 0.0, -9.80665])
R = 0.001  # m: the particle radius of the box tests (cheap: a few hundred particles)

finite = st.floats(-50.0, 50.0, allow_nan=False, allow_infinity=False)
vec3 = arrays(np.float64, 3, elements=finite)


def particles(n: int) -> st.SearchStrategy[np.ndarray]:
    return arrays(np.float64, (n, 3), elements=finite)


BOX = box_mesh((-0.01, -0.01, 0.0), (0.01, 0.01, 0.03))
# The water: 18 × 18 × 6 mm, a particle radius (half the lattice) clear of the walls.
BLOCK = FluidBlock((-0.009, -0.009, 0.001), (0.009, 0.009, 0.007))


def box_liquid(**kw: object) -> SphLiquid:
    animated, held = bool(kw.pop("animated", False)), bool(kw.pop("held", False))
    return SphLiquid([Boundary("box", *BOX, animated=animated, held=held)], [BLOCK],
                     SphSettings(particle_radius=R), G, **kw)  # type: ignore[arg-type]


# -- momentum balance (pure) -------------------------------------------------------------------

@settings(max_examples=60, deadline=None)
@given(st.integers(1, 30).flatmap(lambda n: st.tuples(particles(n), particles(n))), vec3,
       st.floats(1e-6, 1.0))
def test_the_force_is_the_weight_less_the_momentum_change(xa, g, m) -> None:
    _, a = xa
    F = momentum_balance_force(m, a, g)
    np.testing.assert_allclose(F, len(a) * m * (g - a.mean(axis=0)), rtol=1e-9, atol=1e-9)
    # a liquid falling freely pushes on nothing
    np.testing.assert_allclose(momentum_balance_force(m, np.tile(g, (len(a), 1)), g), 0.0,
                               atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 30).flatmap(lambda n: st.tuples(particles(n), particles(n))), vec3,
       vec3, vec3)
def test_the_torque_moves_with_its_point_as_a_force_couple_does(xa, g, c, d) -> None:
    x, a = xa
    m = 1e-3
    F = momentum_balance_force(m, a, g)
    t_c = momentum_balance_torque(m, x, a, g, c)
    t_d = momentum_balance_torque(m, x, a, g, d)
    scale = 1.0 + np.abs(t_c).max() + np.abs(t_d).max()
    np.testing.assert_allclose(t_d, t_c + np.cross(c - d, F), atol=1e-9 * scale)


def test_per_particle_masses_weigh_each_particle() -> None:
    a = np.zeros((2, 3))
    np.testing.assert_allclose(momentum_balance_force([1.0, 3.0], a, G), 4.0 * G)
    np.testing.assert_allclose(
        momentum_balance_torque([1.0, 3.0], [[1.0, 0, 0], [0, 1.0, 0]], a, G, np.zeros(3)),
        np.cross([1.0, 0, 0], G) + 3.0 * np.cross([0, 1.0, 0], G))


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 20).flatmap(lambda n: st.tuples(particles(n), particles(n))), vec3)
def test_a_steady_turn_throws_outwards_and_coriolis_does_no_work(xv, w) -> None:
    x, v = xv
    # centrifugal alone (particles at rest in the frame): never towards the axis
    a = rotating_frame_acceleration(w, np.zeros(3))(x, np.zeros_like(x))
    assert np.all(np.einsum("ij,ij->i", a, x) >= -1e-9 * (1 + np.abs(a).max() * 50))
    # Coriolis alone (at the origin): perpendicular to the velocity
    c = rotating_frame_acceleration(w, np.zeros(3))(np.zeros_like(v), v)
    assert np.allclose(np.einsum("ij,ij->i", c, v), 0.0, atol=1e-9 * (1 + np.abs(c).max() * 50))
    still = rotating_frame_acceleration(np.zeros(3), np.zeros(3))(x, v)
    assert np.all(still == 0.0)


# -- settings and input --------------------------------------------------------------------------

@pytest.mark.parametrize("kw", [{"particle_radius": 0.0}, {"particle_radius": 1e-3, "max_dt": 0.0},
                                {"particle_radius": 1e-3, "threads": 0},
                                {"particle_radius": 1e-3, "cfl_factor": 2.0},
                                {"particle_radius": 1e-3, "viscosity_method": "xsph"}])
def test_settings_out_of_range_are_refused_naming_the_field(kw: dict[str, float]) -> None:
    with pytest.raises(ValueError, match="out of range"):
        SphSettings(**kw)  # type: ignore[arg-type]


@pytest.mark.parametrize(("method", "nu"), [("standard", 1.0e-6), ("weiler2018", 0.01)])
def test_the_library_runs_the_viscosity_it_is_given(method: str, nu: float) -> None:
    """The scene file's method id and its parameters' namespace reach the library (a wrong
    namespace would leave the method's default coefficient in place, silently)."""
    with SphLiquid([Boundary("box", *BOX)], [FluidBlock((0.002, 0.002, 0.002),
                                                        (0.01, 0.01, 0.01))],
                   SphSettings(particle_radius=R, viscosity=nu, boundary_viscosity=2 * nu,
                               viscosity_method=method)) as liq:
        fm = liq._fluid
        v = fm.getViscosityBase()
        assert fm.getViscosityMethod() == {"standard": 1, "weiler2018": 6}[method]
        assert v.getValueFloat(v.VISCOSITY_COEFFICIENT) == pytest.approx(nu, rel=1e-6)
        assert v.getValueFloat(v.VISCOSITY_COEFFICIENT_BOUNDARY) == pytest.approx(2 * nu,
                                                                                  rel=1e-6)


def test_a_block_too_thin_for_two_particles_is_refused() -> None:
    with pytest.raises(ValueError, match="fewer than 2 particles"):
        SphLiquid([Boundary("box", *BOX)], [FluidBlock((0, 0, 0.001), (0.01, 0.01, 0.002))],
                  SphSettings(particle_radius=R))


def test_an_open_mesh_index_is_refused() -> None:
    v, f = BOX
    with pytest.raises(ValueError, match="indices"):
        Boundary("bad", v, f + 8)


# -- a real liquid -------------------------------------------------------------------------------

def test_a_box_of_water_settles_and_weighs_its_grams_within_one_percent() -> None:
    with box_liquid() as liq:
        workdir = liq._dir
        lattice = np.round((np.subtract(BLOCK.upper, BLOCK.lower)) / (2 * R)).astype(int)
        assert liq.n_particles == int(np.prod(lattice))
        # the library's particle mass is ρ0 (2r)³, so the block's grams are its volume's
        assert liq.particle_mass == pytest.approx(1000.0 * (2 * R) ** 3, rel=1e-6)
        grams = liq.n_particles * liq.particle_mass * 1e3
        assert grams == pytest.approx(1e6 * np.prod(np.subtract(BLOCK.upper, BLOCK.lower)),
                                      rel=1e-6)
        with pytest.raises(RuntimeError, match="one SphLiquid"):
            box_liquid()
        liq.step_to(0.4)
        v0, t0 = liq.velocities(), liq.time
        liq.step_to(0.5)
        a = (liq.velocities() - v0) / (liq.time - t0)
        F = momentum_balance_force(liq.particle_mass, a, liq.gravity)
        assert -F[2] / 9.80665 * 1e3 == pytest.approx(grams, rel=0.01)
        assert np.hypot(F[0], F[1]) < 0.01 * abs(F[2])
        x = liq.positions()
        assert np.all(np.abs(x[:, :2]) < 0.01) and np.all((x[:, 2] > 0) & (x[:, 2] < 0.03))
        assert liq.backend["version"] == "2.19.0"
    assert not workdir.exists()


def test_the_liquid_runs_downhill_when_gravity_turns() -> None:
    with box_liquid() as liq:
        liq.step_to(0.1)
        x0 = liq.positions().mean(axis=0)
        liq.set_gravity([3.0, 0.0, -9.3])
        liq.step_to(0.4)
        x1 = liq.positions().mean(axis=0)
    assert x1[0] - x0[0] > 1e-3 and abs(x1[1] - x0[1]) < 5e-4


def test_a_body_acceleration_pushes_the_liquid_as_gravity_does() -> None:
    push = np.array([0.0, -3.0, 0.0])
    with box_liquid(extra_acceleration=lambda x, v: np.tile(push, (len(x), 1))) as liq:
        x0 = liq.positions().mean(axis=0)
        liq.step_to(0.3)
        x1 = liq.positions().mean(axis=0)
    assert x0[1] - x1[1] > 1e-3 and abs(x1[0] - x0[0]) < 5e-4


def test_a_moving_animated_wall_carries_the_liquid() -> None:
    speed = 0.05  # m/s along x
    with box_liquid(animated=True) as liq:
        liq.step_to(0.1)
        x0, t0 = liq.positions().mean(axis=0), liq.time
        while liq.time < 0.3:
            dx = speed * (liq.time - t0)
            liq.set_boundary_pose("box", [dx, 0.0, 0.0], np.eye(3), [speed, 0.0, 0.0])
            liq.step()
        moved = liq.positions().mean(axis=0)[0] - x0[0]
        with pytest.raises(ValueError, match="rotation matrix"):
            liq.set_boundary_pose("box", [0, 0, 0], 2 * np.eye(3))
    assert moved == pytest.approx(speed * (0.3 - t0), rel=0.25)


def test_a_held_box_reads_the_weight_of_the_water_it_holds_and_stays_put() -> None:
    with box_liquid(held=True) as liq:
        grams = liq.n_particles * liq.particle_mass * 1e3
        liq.step_to(0.4)
        liq.held_force("box")  # the settling's mean, discarded
        v0, t0 = liq.velocities(), liq.time
        liq.step_to(0.5)
        F = liq.held_force("box")
        a = (liq.velocities() - v0) / (liq.time - t0)
        balance = momentum_balance_force(liq.particle_mass, a, liq.gravity)
        assert np.all(liq.held_force("box") == 0.0)  # nothing since the last read
        x = liq.positions()
    assert -F[2] / 9.80665 * 1e3 == pytest.approx(grams, rel=0.01)
    assert np.abs(F - balance).max() < 0.01 * abs(balance[2])
    assert np.hypot(F[0], F[1]) < 0.01 * abs(F[2])
    # the library's solver moves it in each step (its weight on a 0.12 g body: ~0.6 mm); put
    # back before the next, it holds the water where it stood
    assert np.all(np.abs(x[:, :2]) < 0.01) and np.all((x[:, 2] > 0) & (x[:, 2] < 0.03))


def test_a_boundary_is_animated_or_held_and_only_a_held_one_reads_a_force() -> None:
    with pytest.raises(ValueError, match="animated or held, not both"):
        Boundary("box", *BOX, animated=True, held=True)
    with box_liquid(animated=True) as liq, pytest.raises(ValueError, match="not held"):
        liq.held_force("box")
    with box_liquid() as liq, pytest.raises(ValueError, match="neither animated nor held"):
        liq.set_boundary_pose("box", [0.0, 0.0, 0.0], np.eye(3))


def test_the_forces_on_held_bodies_add_up_to_the_liquids_momentum_balance() -> None:
    """A small block held in the water and moved through it, the box held still: over the
    run, what the library reads on the two is all that acts on the liquid besides gravity,
    and the moving block is pushed back. (Step by step the two differ where the CFL step
    changes size: the library applies the divergence solve's force, computed with the last
    step's size, over this step's.)"""
    speed = 0.02  # m/s along x
    block = box_mesh((-0.003, -0.003, -0.003), (0.003, 0.003, 0.003))
    with SphLiquid([Boundary("box", *BOX, held=True), Boundary("block", *block, held=True)],
                   [FluidBlock((-0.009, -0.009, 0.001), (-0.005, 0.009, 0.007)),
                    FluidBlock((0.005, -0.009, 0.001), (0.009, 0.009, 0.007))],
                   SphSettings(particle_radius=R), G) as liq:
        liq.set_boundary_pose("block", [0.0, 0.0, 0.004], np.eye(3))
        liq.step_to(0.2)
        liq.held_force("box"), liq.held_force("block")
        t0 = liq.time
        v0 = liq.velocities()
        while liq.time < 0.4:
            liq.set_boundary_pose("block", [speed * (liq.time - t0), 0.0, 0.004], np.eye(3),
                                  [speed, 0.0, 0.0])
            liq.step()
        a = (liq.velocities() - v0) / (liq.time - t0)
        balance = momentum_balance_force(liq.particle_mass, a, liq.gravity)
        box_f, block_f = liq.held_force("box"), liq.held_force("block")
        weight = liq.n_particles * liq.particle_mass * 9.80665
    assert np.abs(box_f + block_f - balance).max() < 0.01 * weight
    assert block_f[0] < -0.05 * weight  # drag


def test_removed_particles_leave_the_simulation_and_the_rest_keep_their_ids() -> None:
    with box_liquid() as liq:
        liq.step_to(0.05)
        ids, x = liq.particle_ids(), liq.positions()
        gone = x[:, 0] > 0.0
        assert liq.remove_particles(gone) == int(gone.sum())
        assert liq.n_particles == int((~gone).sum())
        assert sorted(liq.particle_ids()) == sorted(ids[~gone])
        liq.step_to(0.2)
        x = liq.positions()
        assert np.all(np.abs(x) < 0.03)  # no parked particle came back, none escaped


def test_the_box_mesh_is_closed_with_outward_normals() -> None:
    from articutool.food.dish_mesh import mesh_volume

    v, f = box_mesh((0.0, -1.0, 2.0), (1.0, 2.0, 4.0))
    assert mesh_volume(v, f) == pytest.approx(1.0 * 3.0 * 2.0)
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert np.all(counts == 2)  # every edge shared by exactly two triangles


def test_liquid_given_as_positions_starts_there() -> None:
    g = np.mgrid[-3:4, -3:4, 0:3].reshape(3, -1).T * 2 * R + np.array([0.0, 0.0, 2 * R])
    with SphLiquid([Boundary("box", *BOX)], [FluidParticles(g)], SphSettings(particle_radius=R),
                   G) as liq:
        assert liq.n_particles == len(g)
        x = liq.positions()[np.argsort(liq.particle_ids())]
        # one first step (≤ 2 ms) has passed: each particle moved a fraction of its radius
        assert np.abs(x - g).max() < 0.3 * R


def test_a_second_threads_liquid_waits_for_the_first_to_close() -> None:
    """The library keeps one scene per process: a liquid opened in another thread (two
    trials in the threads of one Dask worker) starts once the first is closed, never
    beside it; each then steps its own particles."""
    import threading

    order: list[str] = []
    errors: list[BaseException] = []
    first = box_liquid()
    n_first = first.n_particles

    def second() -> None:
        try:
            with box_liquid() as liq:
                order.append("second opened")
                liq.step_to(0.01)
                assert liq.n_particles == n_first
        except BaseException as err:  # reported below
            errors.append(err)

    t = threading.Thread(target=second)
    t.start()
    first.step_to(0.01)  # the first is stepped while the second thread waits
    order.append("first closed")
    first.close()
    t.join(300)
    assert not t.is_alive() and errors == []
    assert order == ["first closed", "second opened"]


_SAME_SCENE = """
import hashlib
from articutool.sim.sph_scene import Boundary, FluidBlock, SphLiquid, SphSettings, box_mesh
V, F = box_mesh((-0.02, -0.02, -0.002), (0.02, 0.02, 0.04))
with SphLiquid([Boundary("tank", V, F)], [FluidBlock((-0.018, -0.018, 0.0), (0.0, 0.0, 0.012))],
               SphSettings(particle_radius=0.001), (0.0, 0.0, -9.80665)) as q:
    for _ in range(10):
        q.step()
    print(hashlib.sha256(q.positions().tobytes()).hexdigest())
"""


def test_a_scene_gives_the_same_bits_in_two_processes() -> None:
    import subprocess
    import sys

    runs = [subprocess.run([sys.executable, "-c", _SAME_SCENE], capture_output=True, text=True,
                           timeout=300, check=True).stdout.split()[-1] for _ in range(2)]
    assert runs[0] == runs[1]


def test_a_liquid_another_world_closed_keeps_the_state_it_was_closed_in() -> None:
    """SPlisHSPlasH holds one scene a process: opening a world's liquid closes the thread's
    other one, whose state then stays readable (its world keeps it) and whose stepping is
    refused."""
    from articutool.sim.sph_scene import close_this_threads_liquid

    liq = box_liquid()
    liq.step_to(0.02)
    x, v, ids, t = liq.positions(), liq.velocities(), liq.particle_ids(), liq.time
    close_this_threads_liquid()
    assert liq.closed
    assert np.array_equal(liq.positions(), x) and np.array_equal(liq.velocities(), v)
    assert np.array_equal(liq.particle_ids(), ids)
    assert liq.n_particles == len(x) and liq.time == t
    with pytest.raises(RuntimeError, match="closed"):
        liq.step_to(0.04)
    liq.close()  # idempotent
