"""An experiment as one registered unit, and the registry the generic modules read.

Each experiment is one module of :mod:`articutool.experiments.units` holding its condition
and typed outcome, the model of its table of ``data/experiments.toml``, its protocol, its
summary, its report section, its claims and their verdicts, and its command-line arguments;
it defines a subclass of :class:`Experiment` and names an instance ``EXPERIMENT``. The
runner, the command line, the record reader, the experiments file's validation, the report
and its verdicts iterate :func:`registry` and hold no experiment's name. Adding an experiment
is one new module there and its table in the data file.
"""

from __future__ import annotations

import argparse
import functools
import importlib
import math
import pkgutil
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from articutool.cli_support import MAX_MASS_G

if TYPE_CHECKING:
    import py_trees

    from articutool.sim.world import FeedingWorld, SettleCache

__all__ = ["MAX_LOAD_G", "Experiment", "Hook", "Visitors", "add_foods_argument",
           "add_physics_argument", "names", "parse_food_grams", "registry", "unit", "usage"]

# The most food a load or a threshold may name (g), as ``meal --threshold`` bounds it.
MAX_LOAD_G = MAX_MASS_G

# The validated experiments file (:class:`articutool.experiments.config.ExperimentsConfig`,
# not imported: the config reads this registry for each experiment's table).
Config = Any
Hook = Callable[["FeedingWorld"], None] | None
Visitors = Sequence["py_trees.visitors.VisitorBase"]


class Experiment:
    """One experiment. A subclass sets the class attributes and overrides what it needs;
    the defaults are an experiment with no inputs beyond its config, no analysis settings,
    no figure and nothing to say beside the thesis."""

    name: ClassVar[str]  # the subcommand, the results folder, a record's ``experiment``
    help: ClassVar[str]  # the subcommand's help
    title: ClassVar[str]  # the report section's title
    order: ClassVar[int]  # the section's place in the report (the thesis' order)
    # Its condition and outcome: subclasses of records.ConditionBase and records.OutcomeBase
    # (named here without importing them: the records' reader imports this registry).
    condition: ClassVar[type[Any]]
    outcome: ClassVar[type[Any]]
    # Its table of ``data/experiments.toml`` (a ``StrictModel``), validated with the file.
    config_model: ClassVar[type[Any]]
    # The kinds of claim it tests (keys of ``experiments.toml [tests]``), with their labels.
    claims: ClassVar[dict[str, str]] = {}
    # The thesis' hypothesis and figure whose claims it tests (None: it tests none).
    hypothesis: ClassVar[str | None] = None
    thesis_figure: ClassVar[str] = ""
    # Why a run may give no verdict (shown when :meth:`verdicts` gives none).
    unjudged: ClassVar[str] = ""
    # What the run's inputs (:meth:`inputs`) note in the summary, kept by the report.
    noted_inputs: ClassVar[tuple[str, ...]] = ()
    # What the analysis settings (:meth:`analysis`) note in the summary.
    noted_settings: ClassVar[tuple[str, ...]] = ()
    # Its trials start with a load placed on the utensil (``load_g``), so they never fill
    # the food's container: the container fill's settings do not bear on them
    # (:func:`~articutool.experiments.runner.data_hash`).
    places_load: ClassVar[bool] = False

    # ------------------------------------------------------------------ command line --
    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        """The experiment's own options of ``articutool experiment NAME``."""

    def add_report_arguments(self, parser: argparse.ArgumentParser) -> None:
        """The experiment's own options of ``articutool experiment report``."""

    def check_arguments(self, args: argparse.Namespace) -> None:
        """Refuse a bad option (:func:`usage`) before the config is read."""

    def inputs(self, args: argparse.Namespace, out: Path, cfg: Config
               ) -> tuple[dict[str, Any], dict[str, Any]]:
        """What the conditions and trials take beyond the config (keyword arguments of
        :meth:`conditions` and :meth:`trial_condition`), and what the summary notes of them
        (where they came from)."""
        return {}, {}

    def analysis(self, args: argparse.Namespace, out: Path, cfg: Config, *,
                 required: bool = True) -> dict[str, Any]:
        """The summary's settings given on the command line or derived from other results
        (keyword arguments of :meth:`summarize`); ``required``: the experiment's trials
        are about to be run or summarised (the report asks with ``False`` and summarises
        only an experiment whose log exists)."""
        return {}

    # ------------------------------------------------------------------------ trials --
    def conditions(self, cfg: Config, **inputs: Any) -> list[Any]:
        """The conditions in a fixed order."""
        raise NotImplementedError

    def trial_condition(self, cond: Any, repeat: int, **inputs: Any) -> Any:
        """The condition of repeat ``repeat`` (the same by default)."""
        return cond

    def run_trial(self, cond: Any, seed: int, cfg: Config, hook: Hook = None,
                  visitors: Visitors = (), settled: SettleCache | None = None) -> Any:
        """The protocol: one trial in the physics world, its outcome."""
        raise NotImplementedError

    # ---------------------------------------------------------------------- analysis --
    def summarize(self, records: Sequence[Any], cfg: Config,
                  **settings: Any) -> dict[str, Any]:
        """The summary's body (pure)."""
        raise NotImplementedError

    def report_extras(self, records: Sequence[Any], cfg: Config
                      ) -> dict[str, Any]:
        """What the report adds to the summary beyond the run's (none by default)."""
        return {}

    # ------------------------------------------------------------------------ report --
    def section(self, summary: Mapping[str, Any], cfg: Config) -> str:
        """The report section's body: our numbers beside the thesis'."""
        raise NotImplementedError

    def differences(self, summary: Mapping[str, Any], cfg: Config) -> list[str]:
        """Where our numbers differ from the thesis', by how much (one line each)."""
        return []

    def verdicts(self, summary: Mapping[str, Any], thesis: Mapping[str, Any], alpha: float,
                 tests: Mapping[str, Any]) -> list[Any]:
        """What our summary says of each claim it tests
        (:class:`~articutool.experiments.verdicts.Verdict`; ``thesis``: its
        ``[thesis.NAME]``, ``tests``: the pre-registered tests)."""
        return []

    def facts(self, summary: Mapping[str, Any] | None, records: Sequence[Any],
              cfg: Config) -> dict[str, str]:
        """The figures the deviations table quotes (``{name}`` in ``experiments.toml
        [[deviations]]``) from this experiment's summary (``None``: not run) and records."""
        return {}

    def figure(self, records: Sequence[Any], summary: Mapping[str, Any],
               cfg: Config, directory: Path) -> Path | None:
        """Write the figure into ``directory`` (``records``: the trials that did not raise);
        None when there is none."""
        return None


@functools.cache
def registry() -> dict[str, Experiment]:
    """Every experiment of :mod:`articutool.experiments.units`, by name, in the order of
    the command line (by name)."""
    from articutool.experiments import units

    found: dict[str, Experiment] = {}
    for m in pkgutil.iter_modules(units.__path__):
        exp = getattr(importlib.import_module(f"{units.__name__}.{m.name}"), "EXPERIMENT",
                      None)
        if isinstance(exp, Experiment):
            found[exp.name] = exp
    return dict(sorted(found.items()))


def names() -> tuple[str, ...]:
    """The experiments' names."""
    return tuple(registry())


def unit(name: str) -> Experiment:
    """The experiment ``name`` (``ValueError`` naming the known ones)."""
    try:
        return registry()[name]
    except KeyError:
        raise ValueError(f"experiment must be one of {names()}; got {name!r}") from None


# ---------------------------------------------------------- shared command-line bits --
def usage(msg: str) -> Exception:
    """A bad-input error: the command exits 2 with ``msg``."""
    from articutool.cli_support import UsageError

    return UsageError(msg)


def parse_food_grams(text: str, field: str, most: float) -> dict[str, float]:
    """``"pecans=7,water=20"`` → ``{"pecans": 7.0, "water": 20.0}`` (grams in [0, most])."""
    out: dict[str, float] = {}
    for part in text.split(","):
        if not part.strip():
            continue
        food, sep, val = part.partition("=")
        try:
            g = float(val)
        except ValueError:
            g = math.nan
        if not sep or not food.strip() or not 0 <= g <= most:  # also refuses NaN
            raise usage(f"{field} must be FOOD=GRAMS[,FOOD=GRAMS] with grams in "
                        f"[0, {most:g}]; got {part.strip()!r}")
        out[food.strip()] = g
    return out


def add_physics_argument(parser: argparse.ArgumentParser) -> None:
    """``--physics FILE``: another physics file for a bite's world."""
    parser.add_argument("--physics", metavar="FILE", default=None,
                        help="another physics parameter file for the bite's world (e.g. the "
                             "thesis' 125 g of noodles: docs/food.md); use its own --out")


def add_foods_argument(parser: argparse.ArgumentParser) -> None:
    """``--foods FOOD,…``: a subset of the conditions' foods (:func:`foods_asked`)."""
    parser.add_argument("--foods", metavar="FOOD,…", default=None,
                        help="run only these foods' conditions (same seeds as a full run; "
                             "use its own --out)")


def foods_asked(args: argparse.Namespace) -> list[str] | None:
    """The foods ``--foods`` names, in its order (``None`` without it; ``[]`` if it names
    none)."""
    foods = getattr(args, "foods", None)
    return None if not foods else [f.strip() for f in foods.split(",") if f.strip()]
