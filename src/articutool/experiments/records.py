"""The experiments' trial contracts: each experiment's condition, what its protocol measures,
and the trial record that joins them to the trial's identity and bookkeeping.

A trial's record is one flat JSON line of ``<out>/<experiment>/trials.jsonl``: its identity
(``experiment``, ``trial``, ``repeat``, ``seed``), its condition's fields (sorted by name),
what the protocol measured (in the protocol's order; only the fields it set), then the run's
bookkeeping (``wall_time_s``, ``pid``, ``source``, ``error``). :meth:`TrialRecord.to_log`
writes that line's object and :meth:`TrialRecord.from_log` reads it back, validated: a field
missing, unknown or of the wrong type is named. A trial whose protocol raised has no outcome,
only its ``traceback``.
"""

from __future__ import annotations

from typing import Any, Literal

from articutool.spec import StrictModel

__all__ = ["CONDITIONS", "OUTCOMES", "BiteCondition", "BiteOutcome", "CapacityCondition",
           "CapacityOutcome", "Condition", "Exp2bCondition", "Exp2bOutcome", "Exp2cArm",
           "Exp2cCondition", "Exp2cOutcome", "FoodCheck", "Outcome", "TrialRecord"]

# Exp. 2c's conditions: no primitive, the strategy's open-loop primitive, the closed-loop
# (F/T) one.
Exp2cArm = Literal["control", "primitive", "closed_loop"]


# ---------------------------------------------------------------------- conditions --
class _Condition(StrictModel):
    food: str

    def fields(self) -> dict[str, Any]:
        """The condition as ``run.json`` pins it (an optional field not given is left out)."""
        return self.model_dump(exclude_none=True)

    def group(self) -> tuple[str, ...]:
        """What the analysis groups trials by: the food, and the system or Exp. 2c
        condition (not an Exp. 2b goal, a load or another data file)."""
        return (self.food,)


class CapacityCondition(_Condition):
    """A maximal scoop of ``food``."""


class BiteCondition(_Condition):
    """A bite of Exp. 1 or 3: ``food`` by ``system``; ``strategies``: another action-library
    file; ``physics``: another physics parameter file."""

    system: str
    strategies: str | None = None
    physics: str | None = None

    def group(self) -> tuple[str, ...]:
        """The food and the system."""
        return (self.food, self.system)


class Exp2bCondition(_Condition):
    """Exp. 2b: a placed load of ``food`` carried by ``system`` (a thesis system or a variant)
    to the staging-set ``goal`` (each trial's; a run's condition list has none)."""

    system: str
    goal: str | None = None

    def group(self) -> tuple[str, ...]:
        """The food and the system (a thesis system or a variant)."""
        return (self.food, self.system)


class Exp2cCondition(_Condition):
    """Exp. 2c: ``load_g`` of ``food`` over the bowl, then ``condition``; ``target_g``: the
    closed-loop primitive's load target."""

    condition: Exp2cArm
    load_g: float
    target_g: float | None = None

    def group(self) -> tuple[str, ...]:
        """The food and the condition."""
        return (self.food, self.condition)


Condition = CapacityCondition | BiteCondition | Exp2bCondition | Exp2cCondition
CONDITIONS: dict[str, type[Condition]] = {
    "capacity": CapacityCondition, "exp1": BiteCondition, "exp2b": Exp2bCondition,
    "exp2c": Exp2cCondition, "exp3": BiteCondition}


# ------------------------------------------------------------------------ outcomes --
class _Outcome(StrictModel):
    """What a protocol measured. Each type declares its fields in the order its protocol
    logs them (Exp. 2b's and 2c's transport fields sit between their own, so they are
    declared in each rather than inherited, which would move them in the log line)."""

    def fields(self) -> dict[str, Any]:
        """What the protocol measured, as logged: the fields it set, in declaration order."""
        return self.model_dump(exclude_unset=True)


class CapacityOutcome(_Outcome):
    """One maximal scoop (:func:`~articutool.experiments.protocols.capacity_trial`); a
    liquid's also ``brim_poured_g`` and ``brim_g``."""

    utensil: str
    completed: bool
    failed_stage: str
    scoop_g: float
    items_g: float
    ft_mass_g: float | None
    tilt_deg: float
    spilled_g: float
    realtime_factor: float
    brim_poured_g: float | None = None
    brim_g: float | None = None


class FoodCheck(StrictModel):
    """What one food check before a transport decided (the fields it recorded)."""

    wrist: str | None = None
    scale: float | None = None
    predicted_spill_g: float | None = None
    planned_duration_s: float | None = None
    duration_s: float | None = None
    min_margin_deg: float | None = None
    executed: bool | None = None
    slosh_free_fallback: str | None = None


class Exp2bOutcome(_Outcome):
    """A placed load carried to a goal (:func:`~articutool.experiments.protocols.
    exp2b_trial`); ``food_checks`` with the food-aware check only."""

    load_g: float
    held_g: float
    planner: str
    tolerance_deg: float | None
    completed: bool
    planning_attempts: int
    planning_wall_s: float
    planning_wait_sim_s: float
    motion_time_s: float
    failed_stage: str
    max_tilt_deg: float | None
    food_checks: list[FoodCheck] | None = None
    spilled_by_place: dict[str, float]
    spilled_g: float
    delivered_g: float
    airborne_g: float
    weighed_g: float
    masses_after_g: dict[str, float]
    realtime_factor: float


class Exp2cOutcome(_Outcome):
    """A load shed over the bowl (or not), then carried to Staging
    (:func:`~articutool.experiments.protocols.exp2c_trial`); the primitive's parameters,
    success and message when one ran."""

    load_g: float
    held_g: float
    primitive: str | None
    primitive_params: list[float] | None = None
    primitive_ok: bool | None = None
    primitive_message: str | None = None
    primitive_moved_g: dict[str, float]
    after_primitive_g: float
    shed_g: float
    completed: bool
    planning_attempts: int
    planning_wall_s: float
    planning_wait_sim_s: float
    motion_time_s: float
    failed_stage: str
    max_tilt_deg: float | None
    spilled_by_place: dict[str, float]
    spilled_g: float
    delivered_g: float
    airborne_g: float
    weighed_g: float
    masses_after_g: dict[str, float]
    realtime_factor: float


class BiteOutcome(_Outcome):
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


Outcome = CapacityOutcome | BiteOutcome | Exp2bOutcome | Exp2cOutcome
OUTCOMES: dict[str, type[Outcome]] = {
    "capacity": CapacityOutcome, "exp1": BiteOutcome, "exp2b": Exp2bOutcome,
    "exp2c": Exp2cOutcome, "exp3": BiteOutcome}

_IDENTITY = ("experiment", "trial", "repeat", "seed")
_BOOKKEEPING = ("traceback", "wall_time_s", "pid", "source", "error")


# -------------------------------------------------------------------------- record --
class TrialRecord(StrictModel):
    """One trial: identity, condition, outcome (``None`` when the protocol raised: then
    ``error`` and ``traceback`` say what), and the run's bookkeeping (``source``: the code
    it ran, :func:`~articutool.experiments.runner.source_version`)."""

    experiment: Literal["capacity", "exp1", "exp2b", "exp2c", "exp3"]
    trial: int
    repeat: int
    seed: int
    condition: Condition
    outcome: Outcome | None
    traceback: str | None = None
    wall_time_s: float
    pid: int
    source: str | None = None
    error: str | None

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
        exp = line.get("experiment")
        if exp not in CONDITIONS:
            return cls.model_validate(line)  # names the experiment field
        cond_type, out_type = CONDITIONS[exp], OUTCOMES[exp]
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
