"""Building a feeding world apart from running it; its report under the ledger's names."""

from __future__ import annotations

import pytest

pytest.importorskip("mujoco")

from articutool.sim import accounting as acc
from articutool.sim.build import build_parts
from articutool.sim.world import REPORT_JSON_KEYS, FeedingWorld


def test_wiring_built_parts_steps_nothing() -> None:
    w = FeedingWorld(build_parts(None, "spoon", seed=2))
    assert w.time == 0.0 and w.realtime_factor != w.realtime_factor  # nan: nothing stepped
    assert not w.weighing.comparable()  # never tared
    assert len(w.ft.history) == 0


def test_build_settles_starts_the_tool_and_tares() -> None:
    w = FeedingWorld.build(None, "spoon", seed=2, settle=False)
    assert w.time > 0.4  # 0.2 s of servos settling, 0.2 s of the tool, then the tare
    assert w.weighing.comparable() and not w.ft.tare_pending


def test_the_report_keys_masses_as_the_ledger_and_its_json_as_the_cli() -> None:
    w = FeedingWorld.build(None, "spoon", settle=False)
    r = w.report()
    assert list(r.masses_g) == list(acc.CLASS_NAMES) == list(w.masses_g())
    d = r.to_dict()
    assert list(d) == ["t", "food", "utensil", "on_utensil_g", "in_bowl_g", "table_g",
                       "critical_g", "airborne_g", "eaten_g", "total_g", "spills", "ft_mass_g",
                       "realtime_factor", "arm_tracking_error_rad"]
    assert all(d[REPORT_JSON_KEYS[c]] == r.masses_g[c] for c in acc.CLASS_NAMES)


def test_bad_arguments_are_refused_before_anything_is_built() -> None:
    with pytest.raises(ValueError, match="q_wrist"):
        build_parts(None, "spoon", q_wrist=(0.0,))
    with pytest.raises(ValueError, match="seed"):
        build_parts(None, "spoon", seed=-1)


def test_every_food_kind_has_its_builder_and_each_food_builds_its_bodies() -> None:
    from articutool.arm.scene import Scene
    from articutool.food.definitions import FOOD_KINDS
    from articutool.sim.mjcf import FOOD_BUILDERS, build_mjcf
    from articutool.sim.params import PhysicsParams
    from conftest import packaged_spec

    assert sorted(FOOD_BUILDERS) == sorted(FOOD_KINDS)
    spec, params = packaged_spec(), PhysicsParams.load()
    for name, food in params.foods.items():
        lay = build_mjcf(spec, Scene.load(), params, food.utensil, name, seed=1)
        m = lay.spec.compile()
        items = lay.food_bodies or [f"{s}/{i}" for s in lay.food_strands
                                    for i in range(lay.strand_segments)]
        assert items, name
        assert all(m.body(b).id > 0 for b in items)
        assert lay.container == food.container
