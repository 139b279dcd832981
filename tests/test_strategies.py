"""The action library: shipped strategies load; bad entries are refused naming the field."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest

from articutool.feeding.strategies import (
    StrategyError,
    StrategyLibrary,
    default_strategies_path,
)

RAW = tomllib.loads(default_strategies_path().read_text())


def test_shipped_library_has_the_thesis_strategies_and_rigid_baselines(spec) -> None:
    lib = StrategyLibrary.load(spec)
    for food, first, shed in (("noodles", "TWIRL_CW", "NOODLE_SHED"),
                              ("pecans", "NONE", "VIBRATE_ROLL"), ("water", "NONE", "TILT")):
        _, s = lib.choose(food, "articutool", np.random.default_rng(0))
        assert s.stages.pre_move_into.primitive == first
        assert s.stages.post_acquisition.primitive == shed
        assert s.transport.planner == "decoupled"
        _, b = lib.choose(food, "baseline", np.random.default_rng(0))
        assert all(getattr(b.stages, n).is_none for n in ("pre_move_into", "post_move_into",
                                                          "post_acquisition"))
        assert b.transport.planner == "strict6" and b.transport.tolerance_deg == 20.0


def _with(edit) -> dict:
    data = copy.deepcopy(RAW)
    edit(data["strategies"]["pecans_tilted_scoop"])
    return data


@pytest.mark.parametrize("edit,field", [
    (lambda s: s["stages"]["post_acquisition"].update(primitive="SHAKE"), "unknown primitive"),
    (lambda s: s["stages"]["post_acquisition"].update(params=[8.0, 0.05]),
     "stages.post_acquisition"),
    (lambda s: s["stages"]["post_acquisition"].update(params=[8.0, 0.05, 1e6]),
     "stages.post_acquisition"),
    (lambda s: s.update(utensil="chopsticks"), "strategies.pecans_tilted_scoop.utensil"),
    (lambda s: s["insertion"].update(motion="stir"), "insertion.motion"),
    (lambda s: s["approach"].update(height_m=float("nan")), "approach.height_m"),
    (lambda s: s.update(system="baseline"), "baseline locks the wrist"),
    (lambda s: s["transport"].update(planner="strict6"), "tolerance_deg"),
    (lambda s: s["attempts"].update(plan=0), "attempts.plan"),
])
def test_bad_strategies_are_refused_naming_the_field(spec, edit, field: str) -> None:
    with pytest.raises(StrategyError, match=field.replace(".", r"\.")):
        StrategyLibrary.from_dict(_with(edit), spec)


@pytest.mark.parametrize("edit,field", [
    (dict(drag_m=0.0), "drag_m"), (dict(drag_m=0.2), "drag_m"), (dict(depth_m=0.05), "depth_m"),
    (dict(level_height_m=0.02), "level_height_m"),
    (dict(extract_pitch_down_deg=30.0), "extract_pitch_down_deg"),
])
def test_a_bad_sweep_is_refused_naming_the_insertion_and_the_field(spec, edit: dict,
                                                                   field: str) -> None:
    # A sweep moves while it levels, stays near the floor and levels in the food.
    data = _with(lambda s: s["insertion"].update(motion="sweep", **edit))
    with pytest.raises(StrategyError, match=r"pecans_tilted_scoop\.insertion") as err:
        StrategyLibrary.from_dict(data, spec)
    assert field in str(err.value)


def test_choice_is_weighted_and_deterministic_for_a_seed(spec) -> None:
    data = copy.deepcopy(RAW)
    alt = copy.deepcopy(data["strategies"]["pecans_tilted_scoop"])
    alt["weight"] = 3.0
    data["strategies"]["pecans_deeper"] = alt
    lib = StrategyLibrary.from_dict(data, spec)
    picks = [lib.choose("pecans", "articutool", np.random.default_rng(s))[0] for s in range(400)]
    again = [lib.choose("pecans", "articutool", np.random.default_rng(s))[0] for s in range(400)]
    assert picks == again
    share = picks.count("pecans_deeper") / len(picks)
    assert 0.68 < share < 0.82  # weight 3 of 4
    with pytest.raises(StrategyError, match="food"):
        lib.choose("soup", "articutool", np.random.default_rng(0))
