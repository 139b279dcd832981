"""Which trials each experiment runs, pure: conditions × repeats, their seeds and indices.

Trials are numbered trial-major: trial ``K = r · C + c`` is repeat ``r`` of condition ``c``
(``C`` conditions). Raising ``--trials`` appends trials and never renumbers the ones run, and a
partial run is balanced across conditions. Repeat ``r`` has the seed ``1000 · S + r`` for base
seed ``S`` in every condition (common random numbers: the systems face the same food placement,
sensor noise and planner seed), so a trial is reproduced alone from its record.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, get_args

from articutool.experiments.records import (
    BiteCondition,
    CapacityCondition,
    Condition,
    Exp2bCondition,
    Exp2cArm,
    Exp2cCondition,
)

__all__ = ["EXP2C_CONDITIONS", "EXPERIMENTS", "MAX_TRIALS", "TrialSpec", "conditions",
           "make_trials", "trial_seed"]

EXPERIMENTS = ("capacity", "exp1", "exp2b", "exp2c", "exp3")
MAX_TRIALS = 1000  # per condition (the seed stride)
# Exp. 2c: no primitive, the strategy's open-loop primitive, the closed-loop (F/T) one.
EXP2C_CONDITIONS: tuple[Exp2cArm, ...] = get_args(Exp2cArm)


@dataclass(frozen=True)
class TrialSpec:
    """One trial: experiment, index ``K``, repeat, seed, and its condition."""

    experiment: str
    trial: int
    repeat: int
    seed: int
    condition: Condition

    @property
    def key(self) -> tuple[str, int]:
        """Identity in the log: ``(experiment, trial)``."""
        return (self.experiment, self.trial)


def trial_seed(base_seed: int, repeat: int) -> int:
    """The seed of repeat ``repeat`` (see module doc)."""
    return MAX_TRIALS * base_seed + repeat


def conditions(experiment: str, cfg: Any, *, goals: Sequence[str] = (),
               load_g: Mapping[str, float] | None = None,
               target_g: Mapping[str, float] | None = None) -> list[Condition]:
    """The conditions of ``experiment`` in a fixed order (``cfg``: the experiments config;
    ``goals``: the staging set's goal names for exp2b; ``load_g``: exp2c's load per food;
    ``target_g``: exp2c's closed-loop load target per food, derived from the food's
    meaningful-success threshold — :func:`articutool.experiments.protocols.
    closed_loop_target_g`)."""
    if experiment == "capacity":
        return [CapacityCondition(food=f) for f in cfg.capacity.foods]
    if experiment == "exp1":
        return [BiteCondition(food=f, system=s) for f in cfg.exp1.foods
                for s in cfg.exp1.systems]
    if experiment == "exp2b":
        thesis = [Exp2bCondition(food=f, system=s) for f in cfg.exp2b.foods
                  for s in cfg.exp2b.systems]
        return thesis + [Exp2bCondition(food=f, system=name)
                         for name, v in cfg.exp2b.variants.items() for f in v.foods]
    if experiment == "exp2c":
        if load_g is None:
            raise ValueError("exp2c needs the load per food (the capacity)")
        return [Exp2cCondition(food=f, condition=c, load_g=round(float(load_g[f]), 2),
                               target_g=round(float(target_g[f]), 3)
                               if c == "closed_loop" and target_g is not None
                               and f in target_g else None)
                for f in cfg.exp2c.foods for c in EXP2C_CONDITIONS]
    if experiment == "exp3":
        return [BiteCondition(food=cfg.exp3.food, system=s) for s in cfg.exp3.systems]
    raise ValueError(f"experiment must be one of {EXPERIMENTS}; got {experiment!r}")


def make_trials(experiment: str, conds: Sequence[Condition], trials: int, seed: int,
                *, goals: Sequence[str] = ()) -> list[TrialSpec]:
    """``trials`` repeats of every condition (see module doc). Exp. 2b spreads repeats over
    the ``goals`` in turn (repeat ``r`` → goal ``r mod len(goals)``: 20 trials = 4 per goal)."""
    if isinstance(trials, bool) or not isinstance(trials, int) or not 1 <= trials <= MAX_TRIALS:
        raise ValueError(f"trials must be an integer in [1, {MAX_TRIALS}]; got {trials!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0; got {seed!r}")
    if experiment == "exp2b" and not goals:
        raise ValueError("exp2b needs the staging set's goals")
    out = []
    for r in range(trials):
        for c, cond in enumerate(conds):
            if experiment == "exp2b":
                cond = cond.model_copy(update={"goal": goals[r % len(goals)]})
            out.append(TrialSpec(experiment, r * len(conds) + c, r, trial_seed(seed, r), cond))
    return out
