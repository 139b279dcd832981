"""The experiments' settings and the thesis' reference numbers: ``data/experiments.toml``,
validated (errors name the field). One file, so no protocol value is restated in code; each
experiment's own table is validated by the model its module declares
(:mod:`articutool.experiments.units`)."""

from __future__ import annotations

import functools
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field, ValidationError, model_validator

from articutool.datafile import Positive, StrictModel, format_validation_error, read_document

__all__ = ["ExperimentsConfig", "ExperimentsConfigError", "Names", "claims",
           "default_experiments_path"]

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


# The tests a claim's verdict can be pre-registered with, and the intervals of the
# difference each can be judged with: a continuous or count measure's tests with a mean's or
# median's interval, a frequency's exact tests with a proportion's.
SAMPLE_TESTS = ("welch", "mann_whitney", "wilcoxon")
COUNT_TESTS = ("fisher", "boschloo")


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


def claims() -> dict[str, str]:
    """Every kind of claim a verdict is given for (a key of ``[tests]``) with its label, in
    the thesis' order: the experiments' (:attr:`~articutool.experiments.unit.Experiment.
    claims`) and the planning benchmark's (:mod:`articutool.experiments.exp2a`)."""
    from articutool.experiments.exp2a import BENCHMARK
    from articutool.experiments.unit import registry

    out: dict[str, str] = {}
    for u in sorted([BENCHMARK, *registry().values()], key=lambda u: u.order):
        out.update(u.claims)
    return out


class ExperimentsConfig(StrictModel):
    """The validated ``experiments.toml``: the shared settings, the pre-registered tests,
    the deviations, the thesis' numbers, and one table per registered experiment (its
    :attr:`~articutool.experiments.unit.Experiment.config_model`, named by the experiment:
    ``cfg.exp2b``). Validating this class validates the file with every experiment's table
    (:func:`_with_experiments`)."""

    version: Annotated[int, Field(ge=1, le=1)] = 1
    settings: Settings
    tests: dict[str, PreRegistered]
    deviations: list[Deviation]
    thesis: dict[str, Any]

    @model_validator(mode="after")
    def _every_claim_preregistered(self) -> ExperimentsConfig:
        kinds = list(claims())
        missing = [c for c in kinds if c not in self.tests]
        unknown = sorted(set(self.tests) - set(kinds))
        if missing or unknown:
            raise ValueError(f"tests: every claim needs its pre-registered test "
                             f"({', '.join(kinds)}); missing {missing}, unknown {unknown}")
        return self

    @classmethod
    def model_validate(cls, obj: Any, **kwargs: Any) -> ExperimentsConfig:  # type: ignore[override]
        """Validate ``obj`` as the whole file: this class with every experiment's table."""
        if cls is ExperimentsConfig:
            return _with_experiments().model_validate(obj, **kwargs)
        return super().model_validate(obj, **kwargs)

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


@functools.cache
def _with_experiments() -> type[ExperimentsConfig]:
    """:class:`ExperimentsConfig` with a field per registered experiment, its table."""
    from pydantic import create_model

    from articutool.experiments.unit import registry

    fields: dict[str, Any] = {u.name: (u.config_model, ...) for u in registry().values()}
    return create_model("ExperimentsConfig", __base__=ExperimentsConfig, **fields)


def default_experiments_path() -> Path:
    """Path of the packaged experiments file."""
    return Path(str(resources.files("articutool") / "data" / "experiments.toml"))
