"""Which trials each experiment runs, pure: conditions × repeats, their seeds and indices.

Trials are numbered trial-major: trial ``K = r · C + c`` is repeat ``r`` of condition ``c``
(``C`` conditions). Raising ``--trials`` appends trials and never renumbers the ones run, and a
partial run is balanced across conditions. Repeat ``r`` has the seed ``1000 · S + r`` for base
seed ``S`` in every condition (common random numbers: the systems face the same food placement,
sensor noise and planner seed), so a trial is reproduced alone from its record.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from articutool.experiments.records import ConditionBase
from articutool.experiments.unit import unit

__all__ = ["MAX_TRIALS", "TrialSpec", "conditions", "make_trials", "trial_seed"]

MAX_TRIALS = 1000  # per condition (the seed stride)


@dataclass(frozen=True)
class TrialSpec:
    """One trial: experiment, index ``K``, repeat, seed, and its condition."""

    experiment: str
    trial: int
    repeat: int
    seed: int
    condition: ConditionBase

    @property
    def key(self) -> tuple[str, int]:
        """Identity in the log: ``(experiment, trial)``."""
        return (self.experiment, self.trial)


def trial_seed(base_seed: int, repeat: int) -> int:
    """The seed of repeat ``repeat`` (see module doc)."""
    return MAX_TRIALS * base_seed + repeat


def conditions(experiment: str, cfg: Any, **inputs: Any) -> list[ConditionBase]:
    """The conditions of ``experiment`` in a fixed order (``cfg``: the experiments config;
    ``inputs``: what its conditions take beyond it, :meth:`~articutool.experiments.unit.
    Experiment.inputs`)."""
    return unit(experiment).conditions(cfg, **inputs)


def make_trials(experiment: str, conds: Sequence[ConditionBase], trials: int, seed: int,
                **inputs: Any) -> list[TrialSpec]:
    """``trials`` repeats of every condition (see module doc); a repeat's condition is the
    experiment's for it (:meth:`~articutool.experiments.unit.Experiment.trial_condition`:
    Exp. 2b's goal)."""
    if isinstance(trials, bool) or not isinstance(trials, int) or not 1 <= trials <= MAX_TRIALS:
        raise ValueError(f"trials must be an integer in [1, {MAX_TRIALS}]; got {trials!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0; got {seed!r}")
    exp = unit(experiment)
    out = []
    for r in range(trials):
        for c, cond in enumerate(conds):
            out.append(TrialSpec(experiment, r * len(conds) + c, r, trial_seed(seed, r),
                                 exp.trial_condition(cond, r, **inputs)))
    return out
