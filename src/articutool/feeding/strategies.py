"""The action library: food-specific acquisition strategies as validated data (thesis §4.4).

The packaged ``articutool/data/strategies.toml`` holds the thesis' strategies (noodles:
TWIRL_CW before insertion, TWIRL_CCW inside, level, NOODLE_SHED; pecans: tilted scoop,
level, VIBRATE_ROLL; water: tilted dip, level, TILT) and the rigid 6-DOF baseline's (wrist
locked, no primitives, strict ±20° transport). A new strategy is a data entry, never code.

:meth:`StrategyLibrary.load` refuses, naming the field, a malformed file, an unknown
primitive, a wrong parameter count or an out-of-range parameter (each primitive is built once
against the spec at load time, from the level wrist), an unknown utensil, and a baseline that
uses the wrist. :meth:`StrategyLibrary.choose` picks among a food's strategies with their
weights, deterministically for a seed.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, ValidationError, model_validator

from articutool.datafile import (
    NonNegative,
    Positive,
    StrictModel,
    format_validation_error,
    read_document,
)
from articutool.spec import Spec
from articutool.tool.primitive_base import PrimitiveError
from articutool.tool.primitives import make_primitive, primitive_names

__all__ = [
    "ACQUISITION_STAGES",
    "NONE",
    "AcquisitionStages",
    "AttemptLimits",
    "PrimitiveStage",
    "Strategy",
    "StrategyError",
    "StrategyLibrary",
    "default_strategies_path",
]

NONE = "NONE"
ACQUISITION_STAGES = ("pre_move_into", "post_move_into", "post_acquisition")


class StrategyError(ValueError):
    """A strategy file is missing, malformed or holds an invalid strategy."""


class PrimitiveStage(StrictModel):
    """One primitive slot: a registered primitive and its parameters, or ``NONE``."""

    primitive: Annotated[str, Field(min_length=1)]
    params: list[float] = Field(default_factory=list)

    @model_validator(mode="after")
    def _known(self) -> PrimitiveStage:
        if self.primitive == NONE:
            if self.params:
                raise ValueError("NONE takes no params")
            return self
        if self.primitive not in primitive_names():
            raise ValueError(f"unknown primitive {self.primitive!r}; known: "
                             f"{', '.join([NONE, *primitive_names()])}")
        return self

    @property
    def is_none(self) -> bool:
        """True for an empty slot (succeeds at once)."""
        return self.primitive == NONE


class Approach(StrictModel):
    """Where the tip waits above the food."""

    height_m: Positive
    pitch_down_deg: Annotated[float, Field(ge=0, le=90)]


class Insertion(StrictModel):
    """How the utensil goes into the food."""

    # sweep: dip tilted, level in the food while moving drag_m (depth_m is then
    # the dish's lowest point above the floor)
    motion: Literal["scoop", "skewer", "dip", "sweep"]
    depth_m: NonNegative
    pitch_down_deg: Annotated[float, Field(ge=0, le=90)]
    drag_m: NonNegative = 0.0
    # Where in the container, along the heading from its centre (the front of the bowl is
    # where a level utensil is within the arm's reach).
    offset_m: Annotated[float, Field(ge=-0.1, le=0.1)] = 0.0
    # If set: turn to the extraction pitch at this height above the floor, still in the food
    # (a dip that levels in the liquid), then rise; if not, rise while turning.
    level_height_m: Annotated[float, Field(gt=0, le=0.1)] | None = None
    # Pitch at which the arm takes the utensil out (0: the arm levels it; otherwise the
    # wrist levels it after, a tool-only motion, thesis §4.3.1).
    extract_pitch_down_deg: Annotated[float, Field(ge=0, le=90)] = 0.0
    # A sweep's pitch at the end of its turn in the food (0: level). A level utensil low in a
    # bowl rests its handle on the rim behind it: the turn ends where the handle clears it,
    # and the utensil levels as it rises.
    sweep_to_deg: Annotated[float, Field(ge=0, le=90)] = 0.0

    @model_validator(mode="after")
    def _sweep_fields(self) -> Insertion:
        if self.motion == "sweep":
            if self.drag_m <= 0 or self.drag_m > 0.08:
                raise ValueError("a sweep moves along the heading while it levels: drag_m "
                                 f"must be in (0, 0.08] m; got {self.drag_m}")
            if self.depth_m > 0.03:
                raise ValueError("a sweep's depth_m is the dish's lowest point above the "
                                 f"floor: it must be in [0, 0.03] m; got {self.depth_m}")
            if self.level_height_m is not None or self.extract_pitch_down_deg != 0:
                raise ValueError("a sweep levels in the food: level_height_m and "
                                 "extract_pitch_down_deg do not apply")
            if self.sweep_to_deg >= self.pitch_down_deg:
                raise ValueError("a sweep turns towards level: sweep_to_deg must be below "
                                 f"pitch_down_deg ({self.pitch_down_deg}); got "
                                 f"{self.sweep_to_deg}")
        elif self.sweep_to_deg != 0:
            raise ValueError(f"sweep_to_deg applies to a sweep only, not a {self.motion}")
        return self


class AcquisitionStages(StrictModel):
    """The three primitive stages (thesis §4.4)."""

    pre_move_into: PrimitiveStage
    post_move_into: PrimitiveStage
    post_acquisition: PrimitiveStage


class Transport(StrictModel):
    """Which planner carries the bite, its tolerance for the strict ones, and what the
    decoupled wrist levels against: ``gravity`` (the IMU loop, thesis Alg. 1) or ``apparent``
    (slosh-free: the dish square to g − a of the planned motion, a wrist trajectory the tool
    follows, plain leveling when the tool would refuse it)."""

    planner: Literal["decoupled", "strict6", "strict8"]
    tolerance_deg: Annotated[float, Field(gt=0, le=90)] | None = None
    leveling: Literal["gravity", "apparent"] = "gravity"

    @model_validator(mode="after")
    def _tolerance(self) -> Transport:
        if self.planner != "decoupled" and self.tolerance_deg is None:
            raise ValueError(f"{self.planner} needs tolerance_deg")
        if self.planner == "decoupled" and self.tolerance_deg is not None:
            raise ValueError("decoupled takes no tolerance_deg (its constraint is the "
                             "spec's loose band)")
        if self.planner != "decoupled" and self.leveling != "gravity":
            raise ValueError(f"leveling = {self.leveling!r} needs the decoupled planner (a "
                             "strict plan keeps the wrist locked)")
        return self


class AttemptLimits(StrictModel):
    """The most attempts a strategy makes: plans per goal (``plan``) and acquisitions
    (``acquire``)."""

    plan: Annotated[int, Field(ge=1, le=20)]
    acquire: Annotated[int, Field(ge=1, le=10)]


class Strategy(StrictModel):
    """One way to take one bite of ``food`` with ``system``."""

    food: Annotated[str, Field(min_length=1)]
    system: Literal["articutool", "baseline"]
    utensil: Annotated[str, Field(min_length=1)]
    weight: Positive = 1.0
    approach: Approach
    insertion: Insertion
    stages: AcquisitionStages
    transport: Transport
    attempts: AttemptLimits

    @model_validator(mode="after")
    def _baseline_is_rigid(self) -> Strategy:
        if self.system == "baseline":
            used = [n for n in ACQUISITION_STAGES if not getattr(self.stages, n).is_none]
            if used:
                raise ValueError(f"a baseline locks the wrist: stages {used} must be NONE")
            if self.insertion.extract_pitch_down_deg != 0:
                raise ValueError("a baseline levels with the arm: "
                                 "insertion.extract_pitch_down_deg must be 0")
            if self.transport.planner == "decoupled":
                raise ValueError("a baseline cannot use the decoupled planner (no wrist)")
        return self


def default_strategies_path() -> Path:
    """Path of the action library shipped with the package."""
    return Path(str(resources.files("articutool") / "data" / "strategies.toml"))


class StrategyLibrary(StrictModel):
    """The validated action library."""

    version: Annotated[int, Field(ge=1, le=1)] = 1
    strategies: dict[str, Strategy] = Field(min_length=1)

    @classmethod
    def from_dict(cls, data: Any, spec: Spec, source: str = "<dict>") -> StrategyLibrary:
        """Validate a mapping against the schema, the primitive registry and ``spec``."""
        try:
            lib = cls.model_validate(data)
        except ValidationError as err:
            raise StrategyError(
                format_validation_error(err, f"invalid strategy file {source}:")) from None
        for name, s in lib.strategies.items():
            if s.utensil not in spec.utensils:
                raise StrategyError(f"invalid strategy file {source}: strategies.{name}.utensil:"
                                    f" unknown utensil {s.utensil!r}; known: "
                                    f"{sorted(spec.utensils)}")
            for stage in ACQUISITION_STAGES:
                st: PrimitiveStage = getattr(s.stages, stage)
                if st.is_none:
                    continue
                try:  # names, parameter count and ranges, as the tool would check them
                    make_primitive(st.primitive, st.params, spec, np.zeros(2))
                except PrimitiveError as err:
                    raise StrategyError(
                        f"invalid strategy file {source}: strategies.{name}.stages.{stage}: "
                        f"{err}") from None
        return lib

    @classmethod
    def load(cls, spec: Spec, path: str | Path | None = None) -> StrategyLibrary:
        """Load and validate a strategy file; ``None`` loads the packaged library."""
        p = Path(path) if path is not None else default_strategies_path()
        return cls.from_dict(read_document(p, "strategy file", StrategyError), spec, str(p))

    def for_food(self, food: str, system: str) -> dict[str, Strategy]:
        """The strategies for ``food`` and ``system`` (may be empty)."""
        return {n: s for n, s in self.strategies.items()
                if s.food == food and s.system == system}

    def choose(self, food: str, system: str, rng: np.random.Generator) -> tuple[str, Strategy]:
        """One strategy for ``food`` with ``system``, drawn with the strategies' weights from
        ``rng`` (deterministic for a seed); names sorted so file order does not matter."""
        found = self.for_food(food, system)
        if not found:
            foods = sorted({s.food for s in self.strategies.values() if s.system == system})
            raise StrategyError(f"food: no {system} strategy for {food!r}; foods with one: "
                                f"{foods}")
        names = sorted(found)
        w = np.array([found[n].weight for n in names])
        k = int(rng.choice(len(names), p=w / w.sum()))
        return names[k], found[names[k]]
