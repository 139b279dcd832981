"""Building a feeding world apart from running it; its report under the ledger's names."""

from __future__ import annotations

import pytest

pytest.importorskip("mujoco")

from articutool.sim import accounting as acc
from articutool.sim.build import WorldConfig, build_parts
from articutool.sim.world import REPORT_JSON_KEYS, FeedingWorld


def test_wiring_built_parts_steps_nothing() -> None:
    w = FeedingWorld(build_parts(WorldConfig(None, "spoon", seed=2)))
    assert w.time == 0.0 and w.realtime_factor != w.realtime_factor  # nan: nothing stepped
    assert not w.weighing.comparable()  # never tared
    assert len(w.ft.history) == 0


def test_build_settles_starts_the_tool_and_tares() -> None:
    w = FeedingWorld.make(None, "spoon", seed=2, settle=False)
    assert w.time > 0.4  # 0.2 s of servos settling, 0.2 s of the tool, then the tare
    assert w.weighing.comparable() and not w.ft.tare_pending


def test_the_report_keys_masses_as_the_ledger_and_its_json_as_the_cli() -> None:
    w = FeedingWorld.make(None, "spoon", settle=False)
    r = w.report()
    assert list(r.masses_g) == list(acc.CLASS_NAMES) == list(w.ledger.masses_g())
    d = r.to_dict()
    assert list(d) == ["t", "food", "utensil", "on_utensil_g", "in_bowl_g", "table_g",
                       "critical_g", "airborne_g", "eaten_g", "total_g", "spills", "ft_mass_g",
                       "realtime_factor", "arm_tracking_error_rad"]
    assert all(d[REPORT_JSON_KEYS[c]] == r.masses_g[c] for c in acc.CLASS_NAMES)


def test_bad_fields_are_refused_when_the_config_is_made() -> None:
    with pytest.raises(ValueError, match="q_wrist"):
        WorldConfig(None, "spoon", q_wrist=(0.0,))
    with pytest.raises(ValueError, match="seed"):
        WorldConfig(None, "spoon", seed=-1)
    with pytest.raises(ValueError, match=r"q_arm\[0\] = .* outside the joint's range"):
        WorldConfig(None, "spoon", q_arm=(100.0, 0, 0, 0, 0, 0))


def test_the_config_holds_what_the_world_uses_and_the_world_keeps_it() -> None:
    c = WorldConfig("pecans", seed=3, q_wrist=[0.1, -0.2])
    assert c.utensil == "spoon" and c.q_wrist == (0.1, -0.2) and len(c.q_arm or ()) == 6
    with pytest.raises(AttributeError):
        c.seed = 4  # type: ignore[misc]
    w = FeedingWorld(build_parts(WorldConfig(None, "spoon", seed=2)))
    assert w.config == WorldConfig(None, "spoon", seed=2, spec=w.spec, scene=w.scene,
                                   params=w.params)
    assert (w.seed, w.utensil) == (2, "spoon")


def test_every_food_kind_has_its_builder_and_each_food_builds_its_bodies() -> None:
    from articutool.arm.scene import Scene
    from articutool.food.definitions import FOOD_KINDS
    from articutool.sim.params import PhysicsParams
    from articutool.sim.world_spec import FOOD_BUILDERS, build_world_spec
    from conftest import packaged_spec

    assert sorted(FOOD_BUILDERS) == sorted(FOOD_KINDS)
    spec, params = packaged_spec(), PhysicsParams.load()
    for name, food in params.foods.items():
        lay = build_world_spec(spec, Scene.load(), params, food.utensil, name, seed=1)
        m = lay.spec.compile()
        items = lay.food_bodies or [f"{s}/{i}" for s in lay.food_strands
                                    for i in range(lay.strand_segments)]
        assert items, name
        assert all(m.body(b).id > 0 for b in items)
        assert lay.container == food.container


def test_the_config_loads_its_defaults_when_made(monkeypatch: pytest.MonkeyPatch) -> None:
    from articutool.sim import params as sim_params

    loaded = sim_params.PhysicsParams.load()
    monkeypatch.setattr(sim_params.PhysicsParams, "load", classmethod(lambda cls: loaded))
    assert WorldConfig(None, "spoon").params is loaded
