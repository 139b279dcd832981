"""A load on the utensil as the planner models it: which food, how many grams, and the
physical values its model needs; checked against what the utensil can hold.

:func:`food_load` builds one from a food's resolved definition
(:class:`~articutool.food.definitions.FoodDefinition`, read once from ``data/physics.toml``
by :func:`~articutool.food.definitions.load_food_definitions`): a liquid's density and
viscosity, a granular food's kernel density, angle of repose and the packing of its pieces.
:func:`load_model` gives the model that predicts its spill:
:class:`~articutool.food.slosh.SloshModel` for a liquid, :class:`~articutool.food.pile.PileModel`
for pieces. Anything it cannot model — an unknown or unmodelled food, a fork, a negative, NaN
or too large load — is a :class:`LoadError` naming the field and the allowed range.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from articutool.food.definitions import FoodDefinition
from articutool.food.dish import Dish
from articutool.food.pile import PileModel
from articutool.food.slosh import WATER_KINEMATIC_VISCOSITY, SloshModel

__all__ = [
    "PIECE_PACKING",
    "FoodLoad",
    "LoadError",
    "food_load",
    "load_model",
    "named_load",
    "parse_load",
]

# Volume fraction of a loose heap of irregular pieces: between random loose (0.55) and random
# close (0.64) packing of spheres (Onoda & Liniger, Phys. Rev. Lett. 64:2727, 1990); the
# kernels' measured bulk over true density is 0.59 (556 of ~940 kg/m³, PMC6400730). Approx.
PIECE_PACKING = 0.6


class LoadError(ValueError):
    """A load the planner cannot model; the message names the field and the allowed range."""


@dataclass(frozen=True)
class FoodLoad:
    """A load on the utensil. ``density`` is the load's bulk density as it sits (kg/m³: a
    liquid's own, a pile's kernels × packing); ``repose_deg`` is a granular food's angle of
    repose, ``viscosity`` a liquid's kinematic viscosity (m²/s)."""

    food: str
    kind: str  # "liquid" or "granular"
    grams: float
    density: float
    viscosity: float = WATER_KINEMATIC_VISCOSITY
    repose_deg: float = math.nan

    @property
    def volume_m3(self) -> float:
        """The load's bulk volume (m³)."""
        return self.grams * 1e-3 / self.density

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description."""
        d: dict[str, Any] = {"food": self.food, "kind": self.kind, "grams": self.grams,
                             "density_kg_m3": round(self.density, 3)}
        if self.kind == "liquid":
            d["viscosity_m2_s"] = self.viscosity
        else:
            d["repose_deg"] = self.repose_deg
        return d


def parse_load(text: str) -> tuple[str, float]:
    """``FOOD:GRAMS`` → (food, grams); :class:`LoadError` naming ``--load`` otherwise."""
    food, sep, grams = str(text).partition(":")
    try:
        g = float(grams)
    except ValueError:
        g = math.nan
    if not sep or not food or not math.isfinite(g):
        raise LoadError(f"--load must be FOOD:GRAMS with a finite number of grams (e.g. "
                        f"water:8); got {text!r}")
    return food, g


def food_load(food: FoodDefinition, grams: float) -> FoodLoad:
    """The load ``grams`` of ``food``. Strands are not modelled (a :class:`LoadError`)."""
    g = float(grams)
    if not math.isfinite(g) or g < 0:
        raise LoadError(f"--load grams must be a finite number ≥ 0; got {grams!r}")
    if food.kind == "liquid":
        return FoodLoad(food.name, "liquid", g, food.density, food.viscosity)
    if food.kind == "granular":
        return FoodLoad(food.name, "granular", g, food.density * PIECE_PACKING,
                        repose_deg=food.repose_deg)
    raise LoadError(f"--load food {food.name!r} is {food.kind}: its spill is not modelled "
                    "(a liquid or granular food is)")


def named_load(name: str, grams: float, foods: Mapping[str, FoodDefinition],
               field: str = "--load food") -> FoodLoad:
    """:func:`food_load` of the food ``name`` among ``foods`` (the definitions by name); an
    unknown name is a :class:`LoadError` naming ``field`` and the known ones."""
    if name not in foods:
        raise LoadError(f"{field} must be one of {sorted(foods)}; got {name!r}")
    return food_load(foods[name], grams)


@lru_cache(maxsize=64)
def load_model(dish: Dish | None, load: FoodLoad, utensil: str = "the utensil", *,
               dt: float = 0.004, tail_s: float = 1.0) -> SloshModel | PileModel:
    """The model predicting ``load``'s spill in ``dish`` (``None``: a fork, refused);
    :class:`LoadError` when the load does not fit (names the range in grams). Models are
    immutable once built and cached (a plan's retimings ask for the same one again)."""
    if dish is None:
        raise LoadError(f"--utensil {utensil} has no dish: a load's spill is modelled on a "
                        "spoon")
    try:
        if load.kind == "liquid":
            return SloshModel(dish, load.volume_m3, density=load.density, nu=load.viscosity,
                              dt=dt, tail_s=tail_s)
        return PileModel(dish, load.volume_m3, math.radians(load.repose_deg),
                         density=load.density, dt=dt)
    except ValueError:
        if load.kind == "liquid":
            from articutool.food.slosh import _hydrostatics

            top = _hydrostatics(dish).level_capacity * load.density * 1e3
        else:
            top = PileModel(dish, 0.0, math.radians(load.repose_deg),
                            density=load.density).max_volume * load.density * 1e3
        raise LoadError(f"--load grams of {load.food} on {utensil} must be in [0, {top:.2f}] g "
                        f"(what it holds level{'' if load.kind == 'liquid' else ', heaped'}); "
                        f"got {load.grams:g}") from None
