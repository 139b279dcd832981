"""The experiments' settings and the thesis' reference numbers: ``data/experiments.toml``,
validated (errors name the field). One file, so no protocol value is restated in code."""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, ValidationError, model_validator

from articutool.datafile import format_validation_error, read_document
from articutool.spec import Positive, StrictModel

__all__ = ["ExperimentsConfig", "ExperimentsConfigError", "default_experiments_path"]

Names = Annotated[list[Annotated[str, Field(min_length=1)]], Field(min_length=1)]


class ExperimentsConfigError(ValueError):
    """The experiments file is missing, malformed or invalid."""


class Settings(StrictModel):
    """Shared by every experiment and both systems."""

    plan_budget_s: Positive
    tree_timeout_s: Positive
    settle_s: Positive
    arm_tolerance_deg: Annotated[float, Field(gt=0, lt=90)]
    alpha: Annotated[float, Field(gt=0, lt=1)] = 0.05


class Exp1(StrictModel):
    """Exp. 1 (§5.1)."""

    foods: Names
    systems: Names
    timeout_s: Positive


class Exp2bVariant(StrictModel):
    """A system of this stack beside the thesis' two: ``system`` (whose planner and tool
    mode it keeps) with the food-aware check before the transport (retimed until predicted
    spill-free, or re-planned) and the wrist leveling against ``leveling`` (``apparent``:
    slosh-free), on ``foods``."""

    system: Literal["articutool", "baseline"]
    food_check: bool = True
    leveling: Literal["gravity", "apparent"] = "gravity"
    foods: Names

    @model_validator(mode="after")
    def _decoupled(self) -> Exp2bVariant:
        if self.leveling == "apparent" and self.system != "articutool":
            raise ValueError("leveling = 'apparent' needs the articutool system (the "
                             "decoupled wrist)")
        return self


class Exp2b(StrictModel):
    """Exp. 2b (§5.2.2): the thesis' ``systems`` and this stack's ``variants`` beside them
    (each named; the name is the trial's ``system``)."""

    foods: Names
    systems: Names
    load_g: dict[str, Positive]
    variants: dict[str, Exp2bVariant] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _names(self) -> Exp2b:
        for name, v in self.variants.items():
            if name in self.systems:
                raise ValueError(f"variants.{name}: the name of a thesis system")
            unknown = [f for f in v.foods if f not in self.foods]
            if unknown:
                raise ValueError(f"variants.{name}.foods: {unknown} not among foods "
                                 f"{self.foods}")
        return self


class ShedPrimitive(StrictModel):
    """A shedding primitive and its parameters (checked against the tool's registry)."""

    primitive: Annotated[str, Field(min_length=1)]
    params: list[float]

    @model_validator(mode="after")
    def _known(self) -> ShedPrimitive:
        import numpy as np

        from articutool.spec import load_spec
        from articutool.tool.primitives import make_primitive

        make_primitive(self.primitive, self.params, load_spec(), np.zeros(2))  # names the field
        return self


class Exp2c(StrictModel):
    """Exp. 2c (§5.2.3): the strategy whose post-acquisition primitive is the open-loop test,
    and the closed-loop (F/T) primitive of the third condition (thesis §7.1.2)."""

    foods: Names
    strategy: dict[str, str]
    closed_loop: dict[str, ShedPrimitive]


class Scoop(StrictModel):
    """The maximal scoop's path: the food's Articutool sweep (strategies.toml) with these
    insertion values (see the data file)."""

    depth_m: Annotated[float, Field(ge=0, le=0.02)]
    drag_m: Annotated[float, Field(ge=0, le=0.2)]
    offset_m: Annotated[float, Field(ge=-0.1, le=0.1)]
    sweep_to_deg: Annotated[float, Field(ge=0, le=90)]


class Capacity(StrictModel):
    """Our "maximum capacity" protocol (see the data file)."""

    foods: Names
    scoop: dict[str, Scoop]

    @model_validator(mode="after")
    def _every_food_scoops(self) -> Capacity:
        missing = [f for f in self.foods if f not in self.scoop]
        if missing:
            raise ValueError(f"scoop: no scoop for {missing}")
        return self


class Exp3(StrictModel):
    """Exp. 3 (§5.3)."""

    food: Annotated[str, Field(min_length=1)]
    systems: Names
    timeout_s: Positive


# The tests a claim's verdict can be pre-registered with, and the intervals of the
# difference each can be judged with: a continuous or count measure's tests with a mean's or
# median's interval, a frequency's exact tests with a proportion's.
SAMPLE_TESTS = ("welch", "mann_whitney", "wilcoxon")
COUNT_TESTS = ("fisher", "boschloo")
CLAIMS = ("exp1", "exp2a_success", "exp2a_time", "exp2b", "exp2c", "exp3_success",
          "exp3_no_spill", "exp3_attempts")


class PreRegistered(StrictModel):
    """The test that decides one kind of claim and the interval of the difference the
    thesis' difference is judged against, chosen from the measurement's type (``measure``)
    with the reason (``why``)."""

    measure: Annotated[str, Field(min_length=1)]
    test: Literal["welch", "mann_whitney", "wilcoxon", "fisher", "boschloo"]
    ci: Literal["welch", "bootstrap", "newcombe"]
    why: Annotated[str, Field(min_length=1)]

    @model_validator(mode="after")
    def _matching(self) -> PreRegistered:
        counts = self.test in COUNT_TESTS
        if counts != (self.ci == "newcombe"):
            raise ValueError(f"ci: {self.ci!r} does not fit the test {self.test!r} (a "
                             "frequency's exact tests take 'newcombe'; a sample's tests "
                             "'welch' or 'bootstrap')")
        return self


class Deviation(StrictModel):
    """One place our protocol differs from the thesis': what the thesis did, what we do,
    why. ``{name}`` in a text is a figure the report computes from the records (see
    ``experiments/report.py`` ``deviation_facts``)."""

    topic: Annotated[str, Field(min_length=1)]
    thesis: Annotated[str, Field(min_length=1)]
    ours: Annotated[str, Field(min_length=1)]
    why: Annotated[str, Field(min_length=1)]


class ExperimentsConfig(StrictModel):
    """The validated ``experiments.toml``."""

    version: Annotated[int, Field(ge=1, le=1)] = 1
    settings: Settings
    exp1: Exp1
    exp2b: Exp2b
    exp2c: Exp2c
    capacity: Capacity
    exp3: Exp3
    tests: dict[str, PreRegistered]
    deviations: list[Deviation]
    thesis: dict[str, Any]

    @model_validator(mode="after")
    def _every_claim_preregistered(self) -> ExperimentsConfig:
        missing = [c for c in CLAIMS if c not in self.tests]
        unknown = sorted(set(self.tests) - set(CLAIMS))
        if missing or unknown:
            raise ValueError(f"tests: every claim needs its pre-registered test "
                             f"({', '.join(CLAIMS)}); missing {missing}, unknown {unknown}")
        return self

    @classmethod
    def load(cls, path: str | Path | None = None) -> ExperimentsConfig:
        """Load and validate; ``None`` loads the packaged file."""
        p = Path(path) if path is not None else default_experiments_path()
        data = read_document(p, "experiments file", ExperimentsConfigError)
        try:
            return cls.model_validate(data)
        except ValidationError as err:
            raise ExperimentsConfigError(
                format_validation_error(err, f"invalid experiments file {p}:")) from None


def default_experiments_path() -> Path:
    """Path of the packaged experiments file."""
    return Path(str(resources.files("articutool") / "data" / "experiments.toml"))
