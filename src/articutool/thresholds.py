"""Outcome thresholds derived from our own data (thesis §5.3: the thesis took its Exp. 2c and
Exp. 3 thresholds from its own Exp. 1 means; we take ours from ours, never borrow its numbers).

A neutral module below ``feeding`` (``articutool meal``) and ``experiments`` (Exp. 2c, Exp. 3),
which both read it; it only reads the summary Exp. 1 wrote, through the validated reader of a
run's own files (:func:`articutool.datafile.read_own_json`): a summary that is not as
articutool writes it (garbage, another shape, a NaN mean, a link, a FIFO) is refused with
:class:`~articutool.datafile.ResultsError` naming the file and the field, never used.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

__all__ = ["DEFAULT_OUT", "Grams", "Stat", "capacity_means", "exp1_means"]

DEFAULT_OUT = Path("results/experiments")  # the experiments' results root

# A mass in a summary: a JSON number (not a string or a boolean), finite, >= 0.
Grams = Annotated[float, Field(strict=True, allow_inf_nan=False, ge=0)]


class _Open(BaseModel):
    model_config = ConfigDict(extra="allow", frozen=True)


class Stat(_Open):
    """A summary statistic as :func:`articutool.experiments.stats.describe` writes it: only
    the mean is read (absent or null when no trial measured it)."""

    mean: Grams | None = None


class _Exp1Arms(_Open):
    articutool: Stat | None = None


class _Exp1Summary(_Open):
    acquired_g: dict[str, _Exp1Arms] = Field(default_factory=dict)


def exp1_means(out: Path = DEFAULT_OUT) -> dict[str, float]:
    """Our Exp. 1 Articutool mean acquisition per food (g), from ``out/exp1/summary.json``
    (empty if it has not run). The outcome thresholds of Exp. 2c, Exp. 3 and ``articutool
    meal`` come from here, as the thesis took its thresholds from its own data."""
    from articutool.datafile import read_own_json

    s = read_own_json(Path(out) / "exp1" / "summary.json", "Exp. 1 summary", _Exp1Summary)
    if s is None:
        return {}
    return {f: float(v.articutool.mean) for f, v in s.acquired_g.items()
            if v.articutool is not None and v.articutool.mean is not None}


class _CapacityFood(_Open):
    capacity_g: Stat


class _CapacitySummary(_Open):
    foods: dict[str, _CapacityFood]


def capacity_means(out: Path = DEFAULT_OUT) -> dict[str, float] | None:
    """Our capacity experiment's mean load per food (g) from ``out/capacity/summary.json``
    (``None`` if it has not run; foods without a mean are left out): Exp. 2c's default
    load, read and checked like :func:`exp1_means`."""
    from articutool.datafile import read_own_json

    s = read_own_json(Path(out) / "capacity" / "summary.json", "capacity summary",
                      _CapacitySummary)
    if s is None:
        return None
    return {f: float(v.capacity_g.mean) for f, v in s.foods.items()
            if v.capacity_g.mean is not None}
