"""The experiments' trial contracts: the base types of a condition and of what a protocol
measures (each experiment's own are in its module, :mod:`articutool.experiments.units`),
the bite's and the food check's shared by several, and the trial record that joins them to
the trial's identity and bookkeeping.

A trial's record is one flat JSON line of ``<out>/<experiment>/trials.jsonl``: its identity
(``experiment``, ``trial``, ``repeat``, ``seed``), its condition's fields (sorted by name),
what the protocol measured (in the protocol's order; only the fields it set), then the run's
bookkeeping (``wall_time_s``, ``pid``, ``source``, ``error``). :meth:`TrialRecord.to_log`
writes that line's object and :meth:`TrialRecord.from_log` reads it back, validated: a field
missing, unknown or of the wrong type is named. A trial whose protocol raised has no outcome,
only its ``traceback``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pydantic import field_validator, model_validator

from articutool.datafile import StrictModel

__all__ = ["BiteCondition", "BiteOutcome", "ConditionBase", "FoodCheck", "OutcomeBase",
           "TrialRecord"]


# ---------------------------------------------------------------------- conditions --
class ConditionBase(StrictModel):
    """A trial's condition: at least its ``food``."""

    food: str

    def fields(self) -> dict[str, Any]:
        """The condition as ``run.json`` pins it (an optional field not given is left out)."""
        return self.model_dump(exclude_none=True)

    def group(self) -> tuple[str, ...]:
        """What the analysis groups trials by: the food, and what the experiment compares
        (not what varies within a condition, as a goal, a load or another data file)."""
        return (self.food,)


class BiteCondition(ConditionBase):
    """A bite of Exp. 1 or 3: ``food`` by ``system``; ``strategies``: another action-library
    file; ``physics``: another physics parameter file."""

    system: str
    strategies: str | None = None
    physics: str | None = None

    def group(self) -> tuple[str, ...]:
        """The food and the system."""
        return (self.food, self.system)


# ------------------------------------------------------------------------ outcomes --
class OutcomeBase(StrictModel):
    """What a protocol measured. Each type declares its fields in the order its protocol
    logs them (Exp. 2b's and 2c's transport fields sit between their own, so they are
    declared in each rather than inherited, which would move them in the log line)."""

    def fields(self) -> dict[str, Any]:
        """What the protocol measured, as logged: the fields it set, in declaration order."""
        return self.model_dump(exclude_unset=True)

    def food_g(self) -> float:
        """The food the trial ends with (the report's typical trial): delivered."""
        return float(self.delivered_g)  # type: ignore[attr-defined]


class FoodCheck(StrictModel):
    """What one food check before a transport decided, as a trial records it: the fields of
    the arm's check record (:meth:`articutool.planning.pc_arm.PCArm.check_food`) that a
    summary reads (the full record stays in the bite's log)."""

    wrist: str | None = None
    scale: float | None = None
    predicted_spill_g: float | None = None
    planned_duration_s: float | None = None
    duration_s: float | None = None
    min_margin_deg: float | None = None
    executed: bool | None = None
    slosh_free_fallback: str | None = None

    @classmethod
    def of(cls, check: Mapping[str, Any]) -> FoodCheck:
        """The arm's check record ``check`` as a trial records it: the wrist it modelled (for
        a plan it refused, the wrist of its last try), the speed scale it kept, the spill it
        predicted."""
        out = {k: check[k] for k in cls.model_fields if k in check}
        modelled = [t["wrist"] for t in check.get("tried", ()) if "wrist" in t]
        if "wrist" not in out and modelled:  # a refused plan: the wrist its last try modelled
            out["wrist"] = modelled[-1]
        return cls.model_validate(out)


class BiteOutcome(OutcomeBase):
    """A bite through the feeding tree (:class:`~articutool.meal.bites.BiteResult`'s fields,
    its identity left to the record), then what the experimenter weighs; ``mass_g``: Exp. 1's
    mass at Resting."""

    strategy: str
    outcome: str | None
    completed: bool
    acquired_g: float
    shed_g: float
    delivered_g: float
    spilled_g: float
    spilled_by_place: dict[str, float]
    ft_delivered_g: float | None
    planning_attempts: int
    planning_attempts_by_goal: dict[str, int]
    acquisition_attempts: int
    planning_wall_s: float
    planning_wait_sim_s: float
    motion_time_s: float
    sim_time_s: float
    failed_stage: str
    stages: list[str]
    masses_after: dict[str, dict[str, float]]
    transport_max_tilt_deg: float | None
    end_state: str
    last_stage: str
    food_checks: list[dict[str, Any]]
    predicted_spill_g: float | None
    bite_wall_time_s: float
    utensil: str
    masses_end_g: dict[str, float]
    weighed_end_g: float
    realtime_factor: float
    mass_g: float | None = None

    def food_g(self) -> float:
        """The food the trial ends with: acquired."""
        return float(self.acquired_g)


_IDENTITY = ("experiment", "trial", "repeat", "seed")
_BOOKKEEPING = ("traceback", "wall_time_s", "pid", "source", "error")


# -------------------------------------------------------------------------- record --
class TrialRecord(StrictModel):
    """One trial: identity, condition, outcome (``None`` when the protocol raised: then
    ``error`` and ``traceback`` say what), and the run's bookkeeping (``source``: the code
    it ran, :func:`~articutool.experiments.runner.source_version`)."""

    experiment: str
    trial: int
    repeat: int
    seed: int
    condition: ConditionBase
    outcome: OutcomeBase | None
    traceback: str | None = None
    wall_time_s: float
    pid: int
    source: str | None = None
    error: str | None

    @field_validator("experiment")
    @classmethod
    def _registered(cls, name: str) -> str:
        from articutool.experiments.unit import names

        if name not in names():
            raise ValueError(f"must be one of {', '.join(names())}")
        return name

    @model_validator(mode="after")
    def _types(self) -> TrialRecord:
        from articutool.experiments.unit import unit

        u = unit(self.experiment)
        if not isinstance(self.condition, u.condition):
            raise ValueError(f"condition: {self.experiment}'s is a {u.condition.__name__}")
        if self.outcome is not None and not isinstance(self.outcome, u.outcome):
            raise ValueError(f"outcome: {self.experiment}'s is a {u.outcome.__name__}")
        return self

    def to_log(self) -> dict[str, Any]:
        """The record as one line of the trial log (see module doc)."""
        out: dict[str, Any] = {k: getattr(self, k) for k in _IDENTITY}
        out.update(sorted(self.condition.fields().items()))
        if self.outcome is not None:
            out.update(self.outcome.fields())
        out.update({k: getattr(self, k) for k in _BOOKKEEPING
                    if k in self.model_fields_set})
        return out

    @classmethod
    def from_log(cls, line: dict[str, Any]) -> TrialRecord:
        """A trial-log line's record, validated (``pydantic.ValidationError``, a
        ``ValueError``, names the field). The condition's fields are its type's; every other
        field but the identity and the bookkeeping is the outcome's (a field both name, as
        Exp. 2c's ``load_g``, is logged once and read into both). A trial that raised
        (``error``) has no outcome."""
        from articutool.experiments.unit import registry

        exp = registry().get(line.get("experiment"))  # type: ignore[arg-type]
        if exp is None:
            return cls.model_validate(line)  # names the experiment field
        cond_type, out_type = exp.condition, exp.outcome
        own = {*_IDENTITY, *_BOOKKEEPING}
        fields: dict[str, Any] = {k: v for k, v in line.items() if k in own}
        fields["condition"] = cond_type.model_validate(
            {k: v for k, v in line.items() if k in cond_type.model_fields})
        measured = {k: v for k, v in line.items() if k not in own
                    and (k not in cond_type.model_fields or k in out_type.model_fields)}
        if line.get("error"):
            extra = sorted(k for k in measured if k not in cond_type.model_fields)
            if extra:
                raise ValueError(f"a trial that raised has no outcome; got {extra}")
            fields["outcome"] = None
        else:
            fields["outcome"] = out_type.model_validate(measured)
        return cls.model_validate(fields)
