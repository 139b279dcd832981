"""What a food is, as everything above the data layer reads it: a resolved, frozen value.

A :class:`FoodDefinition` holds a food's name, kind and the physical properties a planner's
model reads — density, a granular food's cited angle of repose, a liquid's kinematic
viscosity, a strand food's stickiness — resolved once from its entry in the physics
parameters (``data/physics.toml``, ``[foods.NAME]``) and passed down by value. The same
entries also hold the simulator's contact numerics (:mod:`articutool.sim.params`), which are
the simulator's alone and are not read here. Bad values are a :class:`FoodError` naming the
file and the field (e.g. ``foods.water.density``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from articutool.datafile import format_validation_error, read_document
from articutool.food.slosh import WATER_KINEMATIC_VISCOSITY

__all__ = ["FOOD_KINDS", "FoodDefinition", "FoodError", "FoodKind", "default_physics_path",
           "food_definition", "load_food_definitions"]

# The mechanisms a food can be: rigid pieces, a liquid, elastic strands.
FoodKind = Literal["granular", "liquid", "strands"]
FOOD_KINDS: tuple[str, ...] = get_args(FoodKind)



class FoodError(ValueError):
    """A food's definition is missing, malformed or holds an invalid value."""


@dataclass(frozen=True)
class FoodDefinition:
    """A food as a planner models it. ``density`` is the material's (kg/m³: a liquid's own, a
    piece's kernel); ``repose_deg`` a granular food's cited angle of repose (NaN for others);
    ``viscosity`` a liquid's kinematic viscosity (m²/s; water's at 20 °C when its entry names
    none; NaN for others); ``stickiness_pa`` a
    strand food's pull-off force per area (N/m², 0 for others); ``utensil`` and ``container``
    the names (``data/hardware.toml``, ``data/scene.toml``) it is served with and eaten by."""

    name: str
    kind: FoodKind
    density: float
    utensil: str
    container: str
    repose_deg: float = math.nan
    viscosity: float = math.nan
    stickiness_pa: float = 0.0


class _Entry(BaseModel):
    """The fields of one ``[foods.NAME]`` entry this layer reads; the rest (contact laws,
    particle sizes) belongs to the simulator, which validates all of it."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    kind: FoodKind
    density: Annotated[float, Field(gt=0, allow_inf_nan=False)]
    utensil: str = Field(min_length=1)
    container: str = Field(min_length=1)
    angle_of_repose_deg: Annotated[float, Field(gt=0, lt=90)] | None = None
    viscosity: Annotated[float, Field(gt=0, allow_inf_nan=False)] | None = None
    stickiness_pa: Annotated[float, Field(ge=0, allow_inf_nan=False)] = 0.0


class _Foods(BaseModel):
    model_config = ConfigDict(extra="ignore", frozen=True)

    foods: dict[str, _Entry] = Field(min_length=1)


def _definition(name: str, e: _Entry, where: str) -> FoodDefinition:
    if not name.isidentifier():
        raise FoodError(f"{where}: foods.{name}: a food name must be an identifier")
    if e.kind == "granular" and e.angle_of_repose_deg is None:
        raise FoodError(f"{where}: foods.{name}.angle_of_repose_deg: a granular food needs "
                        "its cited angle of repose, in (0, 90)°")
    return FoodDefinition(
        name=name, kind=e.kind, density=e.density, utensil=e.utensil, container=e.container,
        repose_deg=(e.angle_of_repose_deg if e.kind == "granular" else math.nan),
        viscosity=((e.viscosity or WATER_KINEMATIC_VISCOSITY) if e.kind == "liquid"
                   else math.nan),
        stickiness_pa=e.stickiness_pa if e.kind == "strands" else 0.0)


def food_definition(name: str, entry: Mapping[str, Any],
                    source: str = "<dict>") -> FoodDefinition:
    """The definition of the food ``name`` from its entry (a ``[foods.NAME]`` table)."""
    try:
        e = _Entry.model_validate(entry)
    except ValidationError as err:
        raise FoodError(format_validation_error(
            err, f"invalid food definition {source}: foods.{name}:")) from None
    return _definition(name, e, source)


def default_physics_path() -> Path:
    """Path of the physics parameters shipped with the package (the foods' entries)."""
    return Path(str(resources.files("articutool") / "data" / "physics.toml"))


def load_food_definitions(path: str | Path | None = None) -> dict[str, FoodDefinition]:
    """Every food of a physics parameter file (``None``: the packaged one) by name."""
    p = Path(path) if path is not None else default_physics_path()
    data = read_document(p, "physics parameters", FoodError)
    try:
        foods = _Foods.model_validate(data).foods
    except ValidationError as err:
        raise FoodError(format_validation_error(err, f"invalid food definitions {p}:")) from None
    return {name: _definition(name, e, str(p)) for name, e in foods.items()}
