"""A food as a resolved value of the food layer (``articutool.food.definitions``): read once
from the physics parameters' foods, the same values the physics world reads, bad entries
refused naming the file and the field, and passed down to the verifier and the ROS 2
service instead of a name looked up again."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path
from typing import get_args

import pytest

from articutool.food.definitions import (
    FOOD_KINDS,
    FoodDefinition,
    FoodError,
    default_physics_path,
    food_definition,
    load_food_definitions,
)
from articutool.food.loads import LoadError, food_load, named_load
from articutool.sim import params as sim_params
from articutool.sim.params import PhysicsParams
from conftest import assert_refused, run_cli

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
FOODS = load_food_definitions()


def _physics(tmp_path: Path, food: str, field: str, value: str | None) -> Path:
    """The packaged physics file with ``foods.FOOD.FIELD`` set to the TOML ``value`` (None:
    removed), written to ``tmp_path``."""
    lines = default_physics_path().read_text().splitlines()
    start = lines.index(f"[foods.{food}]")
    end = next(i for i in range(start + 1, len(lines)) if lines[i].startswith("["))
    at = [i for i in range(start, end) if lines[i].split("=")[0].strip() == field]
    new = [] if value is None else [f"{field} = {value}"]
    if at:
        lines[at[0]:at[0] + 1] = new
    else:
        lines[start + 1:start + 1] = new
    p = tmp_path / "physics.toml"
    p.write_text("\n".join(lines) + "\n")
    tomllib.loads(p.read_text())
    return p


def test_the_definitions_are_the_physics_worlds_foods() -> None:
    params = PhysicsParams.load()
    assert sorted(FOODS) == sorted(params.foods)
    for name, d in FOODS.items():
        fp = params.food(name)
        assert (d.name, d.kind, d.density, d.utensil, d.container) == (
            name, fp.kind, fp.density, fp.utensil, fp.container)
        assert params.definition(name) == d
    assert FOODS["pecans"].repose_deg == params.food("pecans").angle_of_repose_deg
    assert FOODS["noodles"].stickiness_pa == params.food("noodles").stickiness_pa > 0
    assert FOODS["water"].viscosity > 0 and math.isnan(FOODS["water"].repose_deg)
    assert math.isnan(FOODS["pecans"].viscosity) and FOODS["pecans"].stickiness_pa == 0.0


def test_the_simulators_food_kinds_are_the_food_layers() -> None:
    assert tuple(sim_params.FOOD_KINDS) == FOOD_KINDS
    for model in (sim_params.Granular, sim_params.Liquid, sim_params.Strands):
        (kind,) = get_args(model.model_fields["kind"].annotation)
        assert kind in FOOD_KINDS


def test_a_definition_is_a_frozen_value() -> None:
    d = FOODS["water"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        d.density = 1.0  # type: ignore[misc]
    assert {d: 1}[FOODS["water"]] == 1  # hashable: a cached model's key
    assert food_load(d, 8.0).food == "water"


@pytest.mark.parametrize(("food", "field", "value", "words"), [
    ("water", "density", "-1.0", ("greater than 0",)),
    ("pecans", "angle_of_repose_deg", None, ("(0, 90)",)),
    ("pecans", "angle_of_repose_deg", "95.0", ("less than 90",)),
    ("noodles", "kind", '"jelly"', ("granular",)),
    ("water", "viscosity", "0.0", ("greater than 0",)),
    ("noodles", "stickiness_pa", "-5.0", ("greater than or equal to 0",)),
])
def test_a_bad_entry_is_refused_naming_the_file_and_the_field(
        tmp_path: Path, food: str, field: str, value: str | None,
        words: tuple[str, ...]) -> None:
    p = _physics(tmp_path, food, field, value)
    with pytest.raises(FoodError) as err:
        load_food_definitions(p)
    for w in (str(p), f"foods.{food}.{field}", *words):
        assert w in str(err.value)


def test_a_missing_or_foodless_file_is_refused_naming_it(tmp_path: Path) -> None:
    with pytest.raises(FoodError, match=r"nope\.toml"):
        load_food_definitions(tmp_path / "nope.toml")
    p = tmp_path / "empty.toml"
    p.write_text("version = 2\n")
    with pytest.raises(FoodError, match="foods"):
        load_food_definitions(p)
    with pytest.raises(FoodError, match=r"foods\.x-y"):
        food_definition("x-y", {"kind": "liquid", "density": 1000.0, "utensil": "spoon",
                                "container": "bowl"})


def test_an_unknown_food_lists_the_definitions_known() -> None:
    only = {"water": FOODS["water"]}
    with pytest.raises(LoadError, match=r"food must be one of \['water'\]"):
        named_load("pecans", 3.0, only, "food")


def test_the_ros2_verifier_judges_a_load_with_the_foods_it_was_given() -> None:
    from articutool.ros2.verify_service import Verifier
    from articutool.spec import load_spec
    from test_ros2_verify import _example, _req

    thick = dataclasses.replace(FOODS["water"], name="thick", density=2000.0)
    v = Verifier(load_spec(), "soup_spoon", ("atool_joint1", "atool_joint2"),
                 foods={"thick": thick})
    out = v.answer(_req(_example("transport_feasible.json"), food="water", load_g=8.0))
    assert out["reason"] == "bad_request" and "['thick']" in out["message"]
    # 8 g of a liquid twice as dense as water is a level spoonful of half the volume
    ok = v.answer(_req(_example("transport_feasible.json"), food="thick", load_g=8.0))
    assert ok["spill_checked"], ok["message"]


def test_the_verify_cli_refuses_a_bad_food_file_naming_the_field(tmp_path: Path) -> None:
    bad = _physics(tmp_path, "water", "density", "0.0")
    assert_refused(run_cli("verify", str(EXAMPLES / "transport_feasible.json"), "--utensil",
                           "soup_spoon", "--load", "water:8", "--physics", str(bad)),
                   "--physics", "foods.water.density")


def test_a_definition_of_the_shipped_liquid_is_the_planners_load() -> None:
    water = FOODS["water"]
    assert isinstance(water, FoodDefinition)
    load = food_load(water, 8.0)
    assert (load.kind, load.density, load.viscosity) == ("liquid", water.density,
                                                         water.viscosity)
