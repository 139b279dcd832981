"""Every pair of geoms that holds a food item uses exactly the contact law ``physics.toml``
states for that food and that partner — read back from MuJoCo's own contacts, not from
what the builder wrote (MuJoCo mixes two geoms' condim, friction and solref unless their
priority or an explicit pair decides)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from articutool.datafile import read_document
from articutool.sim.params import CONTACT_PARTNERS, PhysicsError, default_physics_path
from articutool.sim.world import FeedingWorld


def _table() -> dict:
    """The per-pair laws as the file writes them (raw TOML, not through the loader)."""
    return read_document(default_physics_path(), "physics parameters", PhysicsError)


def _partner(world: FeedingWorld, g: int, food_geoms: set[int]) -> str:
    """Which partner class a geom is for a food item: food, utensil, container, surface."""
    if g in food_geoms:
        return "food"
    name = world.model.geom(g).name
    if name in world.layout.utensil_geoms:
        return "utensil"
    return "container" if world.layout.places.get(name) == "container" else "surface"


def _food_geoms(world: FeedingWorld) -> dict[int, int]:
    """geom id → its food body's root body id (the body with the free joint)."""
    m, lay = world.model, world.layout
    roots = [m.body(b).id for b in lay.food_bodies]
    roots += [m.body(f"{s}/0").id for s in lay.food_strands]
    out = {}
    for g in range(m.ngeom):
        b = int(m.geom_bodyid[g])
        root = b
        while root not in roots and root != 0:
            root = int(m.body_parentid[root])
        if root in roots:
            out[g] = root
    return out


def _expected(law: dict) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    sl, tor, roll = law["friction"]
    solimp = law.get("solimp", [0.9, 0.95, 0.001, 0.5, 2.0])
    return (law["condim"], np.array([sl, sl, tor, roll, roll]), np.array(law["solref"]),
            np.array(solimp))


def _check(world: FeedingWorld, con: mujoco.MjContact, laws: dict, food_geoms: set[int],
           where: str) -> str:
    g1, g2 = int(con.geom[0]), int(con.geom[1])
    a, b = _partner(world, g1, food_geoms), _partner(world, g2, food_geoms)
    partner = b if a == "food" else a
    dim, fr, ref, imp = _expected(laws[partner])
    names = f"{world.model.geom(g1).name} – {world.model.geom(g2).name} ({where})"
    # In the gap of a sticky pair (strands' starch tack) MuJoCo makes an adhesion contact:
    # the normal pull alone (condim 1); touching, the pair's law applies whole.
    # A pair's adhesion is the higher-priority geom's, or the sum of equal priorities'.
    m = world.model
    p1, p2 = m.geom_priority[g1], m.geom_priority[g2]
    adhesion = (m.geom_adhesion[g1] + m.geom_adhesion[g2] if p1 == p2
                else m.geom_adhesion[g1 if p1 > p2 else g2])
    if con.dist > 0 and adhesion > 0:
        dim = 1
    assert con.dim == dim, f"{names}: condim {con.dim}, file {partner}: {dim}"
    # MuJoCo stores a zero friction as its floor mjMINMU (1e-5).
    assert np.allclose(con.friction, np.maximum(fr, mujoco.mjMINMU), rtol=0, atol=1e-9), \
        f"{names}: friction {con.friction}, file {partner}: {fr}"
    assert np.allclose(con.solref, ref, rtol=0, atol=1e-12), \
        f"{names}: solref {con.solref}, file {partner}: {ref}"
    assert np.allclose(con.solimp, imp, rtol=0, atol=1e-12), \
        f"{names}: solimp {con.solimp}, file {partner}: {imp}"
    return partner


def _probe(world: FeedingWorld, laws: dict) -> set[str]:
    """Put one food item on every geom it can touch (and on another item), one at a time, and
    check the law of the contacts MuJoCo makes; returns the partner classes seen."""
    m = world.model
    geoms = _food_geoms(world)
    food = set(geoms)
    d = mujoco.MjData(m)
    mujoco.mj_copyData(d, m, world.data)
    d.qvel[:] = 0
    roots = sorted(set(geoms.values()))
    probe = roots[0]
    mine = {g for g, r in geoms.items() if r == probe}
    qa = m.jnt_qposadr[m.body_jntadr[probe]]
    seen = set()
    targets = [g for g in range(m.ngeom) if g not in food
               and (m.geom_contype[g] & m.geom_conaffinity[next(iter(mine))]
                    or m.geom_conaffinity[g] & m.geom_contype[next(iter(mine))])]
    targets.append(next(g for g, r in geoms.items() if r == roots[1]))
    for g in targets:
        mujoco.mj_kinematics(m, d)
        d.qpos[qa:qa + 3] = d.geom_xpos[g]
        mujoco.mj_forward(m, d)
        cons = [c for c in d.contact[:d.ncon]
                if {int(c.geom[0]), int(c.geom[1])} & mine and
                ({int(c.geom[0]), int(c.geom[1])} - mine) & ({g} | food - mine)]
        assert cons, f"no contact of {m.body(probe).name} placed on {m.geom(g).name}"
        for c in cons:
            seen.add(_check(world, c, laws, food, "probe"))
    return seen


@pytest.mark.parametrize("food", ["pecans", "water", "noodles"])
def test_every_food_pair_of_a_container_fill_has_the_files_law(food: str) -> None:
    laws = _table()["foods"][food]["contacts"]
    world = FeedingWorld.make(food, seed=0, settle=False)
    assert _probe(world, laws) == set(CONTACT_PARTNERS)
    # And in motion: every contact of the fill a few steps on (with the pile kept awake:
    # MuJoCo makes no contacts for a sleeping pile).
    world.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    world.run(0.02, tick=False)
    food_geoms = set(_food_geoms(world))
    d = world.data
    n = 0
    for c in d.contact[:d.ncon]:
        if {int(c.geom[0]), int(c.geom[1])} & food_geoms:
            _check(world, c, laws, food_geoms, "fill")
            n += 1
    assert n > 0


@pytest.mark.parametrize("food", ["pecans", "water"])
def test_every_food_pair_of_a_placed_load_has_the_files_law(food: str) -> None:
    laws = _table()["foods"][food]["contacts"]
    world = FeedingWorld.make(food, seed=0, load_g=3.0)
    world.placement.place(settle_s=0.1)
    food_geoms = set(_food_geoms(world))
    seen = set()
    for c in world.data.contact[:world.data.ncon]:
        if {int(c.geom[0]), int(c.geom[1])} & food_geoms:
            seen.add(_check(world, c, laws, food_geoms, "load"))
    assert "utensil" in seen
    assert _probe(world, laws) == set(CONTACT_PARTNERS)


def test_the_utensil_scrapes_the_bowl_with_its_own_law_whatever_the_food() -> None:
    law = _table()["world"]["utensil_contact"]
    dim, fr, ref, imp = _expected(law)
    for food in ("pecans", "water"):
        world = FeedingWorld.make(food, seed=0, settle=False)
        m = world.model
        static = {m.geom(n).id for n in world.layout.static_geoms}
        utensil = {m.geom(n).id for n in world.layout.utensil_geoms}
        # Every utensil-static pair is an explicit pair with the law, none left dynamic.
        pairs = {frozenset((int(a), int(b)))
                 for a, b in zip(m.pair_geom1, m.pair_geom2, strict=True)}
        assert pairs == {frozenset((u, s)) for u in utensil for s in static}
        assert np.all(m.pair_dim == dim)
        assert np.allclose(m.pair_friction, np.maximum(fr, mujoco.mjMINMU))
        assert np.allclose(m.pair_solref, ref) and np.allclose(m.pair_solimp, imp)
        for u in utensil:
            for s in static:
                assert not (m.geom_contype[u] & m.geom_conaffinity[s]
                            or m.geom_contype[s] & m.geom_conaffinity[u])
