"""Running an experiment's trials: in parallel processes or on a Dask cluster, resumable.

Every finished trial is appended to ``<out>/<experiment>/trials.jsonl`` as one JSON line,
written and fsync'ed at once (the benchmark runner's log: :func:`articutool.bench.runner.
append_record`); a rerun reads the log and runs only the trials not in it, so a finished trial
is never run again or lost, and a torn last line (a crash mid-write) is cut off. ``run.json``
pins what makes trials comparable (the base seed, the hash of every data file a trial reads,
and the condition list); resuming with other settings is refused. Raising ``--trials`` adds
trials to the same log.

:func:`run_trial` runs one trial from its :class:`~articutool.experiments.design.TrialSpec`
alone and returns its :class:`~articutool.experiments.records.TrialRecord`; :func:`log_trial`
is its log line, top-level and picklable: what a worker process (or Dask worker) returns.
Every trial is sent with the hash of the client's data files (:func:`data_files`) and a
worker whose own differ refuses it (:class:`DataChecked`): every worker of a cluster runs the
same data. Trials share nothing through the process, so a Dask worker runs several at once
in its threads.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import subprocess
import time
import tomllib
import traceback
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from articutool.bench.executors import Executor
from articutool.bench.runner import LogState, read_log, run_logged
from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.design import TrialSpec
from articutool.experiments.records import TrialRecord

if TYPE_CHECKING:
    from articutool.sim.world import SettleCache

__all__ = [
    "DataChecked",
    "DataMismatchError",
    "RunError",
    "RunResult",
    "TrialLog",
    "data_files",
    "data_hash",
    "log_path",
    "log_trial",
    "pin_run",
    "read_trial_log",
    "run_experiment",
    "run_trial",
    "source_version",
]

LOG_NAME = "trials.jsonl"


class RunError(ValueError):
    """A resume with other settings, or an unreadable ``run.json``."""


class DataMismatchError(RuntimeError):
    """A worker's data files are not the client's: the trial was refused, not run."""


def trial_key(rec: dict[str, Any]) -> tuple[str, int]:
    """The trial identity of a record."""
    return (str(rec["experiment"]), int(rec["trial"]))


def log_path(out: str | Path, experiment: str) -> Path:
    """Where an experiment's trials are logged under the results root ``out``."""
    return Path(out) / experiment / LOG_NAME


@dataclass
class TrialLog:
    """An experiment's trial log as read: its records by trial index, and what reading found
    (``state``: lines read, bad lines by number and why, duplicate trials)."""

    records: list[TrialRecord]
    state: LogState


def read_trial_log(out: str | Path, experiment: str) -> TrialLog:
    """Every logged trial of ``experiment`` under ``out`` (empty if none), by trial index,
    and the log's bad lines (:func:`~articutool.bench.runner.read_log`: a line that is not a
    JSON record, holds NaN or an infinity, or is torn is counted and named, not read); a
    record not as the protocols write it raises :class:`~articutool.datafile.ResultsError`
    naming the log, the trial and the field. The log is the run's own file: a link there is
    refused, not followed."""
    path = log_path(out, experiment)
    state = read_log(path, key=trial_key)
    return TrialLog(_records({trial_key(r): r for r in state.records}.values(), path), state)


def _records(lines: Iterable[dict[str, Any]], path: Path) -> list[TrialRecord]:
    """The log ``lines``' records (see :func:`read_trial_log`), by trial index."""
    from pydantic import ValidationError

    from articutool.datafile import ResultsError, format_validation_error

    out = []
    for line in lines:
        try:
            out.append(TrialRecord.from_log(line))
        except ValidationError as err:
            raise ResultsError(format_validation_error(
                err, f"{path}: trial {line.get('trial')}:")) from None
        except ValueError as err:
            raise ResultsError(f"{path}: trial {line.get('trial')}: {err}") from None
    return sorted(out, key=lambda r: r.trial)


def data_hash(experiment: str, cfg: ExperimentsConfig, foods: Iterable[str],
              data: Path | None = None, systems: Iterable[str] | None = None) -> str:
    """Short SHA-256 over the data a trial of ``experiment`` on ``foods`` reads: the spec,
    scene, physics and strategies files of ``data`` (default: the packaged ones; their parsed
    content: comments do not count) with only ``foods``' tables of the physics file and only
    the strategies for ``foods``, and the experiments file's shared settings and this
    experiment's own section (another food's model or strategies or another experiment's
    section does not matter); with ``systems``, only the strategies of those systems (what
    one condition's trials read). An experiment whose trials place
    their load (:attr:`~articutool.experiments.unit.Experiment.places_load`) does not read
    the container fill's settings (:attr:`~articutool.sim.params.Liquid.BOWL_FIELDS`,
    :attr:`~articutool.sim.params.Granular.BOWL_FIELDS`)."""
    from articutool.experiments.unit import registry
    from articutool.sim.params import Granular, Liquid

    h = hashlib.sha256()
    base = resources.files("articutool") / "data" if data is None else data
    keep = set(foods)
    only = None if systems is None else set(systems)
    unit = registry().get(experiment)
    unread = ({*Liquid.BOWL_FIELDS, *Granular.BOWL_FIELDS}
              if unit is not None and unit.places_load else set())
    for name in ("hardware.toml", "scene.toml", "physics.toml", "strategies.toml"):
        h.update(name.encode())
        content = tomllib.loads((base / name).read_text(encoding="utf-8"))
        if name == "physics.toml":
            content["foods"] = {k: {f: x for f, x in v.items() if f not in unread}
                                for k, v in content["foods"].items() if k in keep}
        if name == "strategies.toml":
            content["strategies"] = {
                k: v for k, v in content["strategies"].items() if v.get("food") in keep
                and (only is None or v.get("system") in only)}
        h.update(json.dumps(content, sort_keys=True).encode())
    own = cfg.model_dump(mode="json", include={"settings", experiment})
    h.update(json.dumps(own, sort_keys=True).encode())
    return h.hexdigest()[:16]


def data_files(data: Path | None = None) -> dict[str, str]:
    """SHA-256 of every file of ``data`` (default: the packaged data directory,
    ``articutool/data``), by name: the bytes a worker's trials read their spec, scene,
    physics, strategies and experiments from."""
    base = resources.files("articutool") / "data" if data is None else data
    return {f.name: hashlib.sha256(f.read_bytes()).hexdigest()
            for f in sorted(base.iterdir(), key=lambda f: f.name) if f.is_file()}


@dataclass(frozen=True)
class DataChecked:
    """``worker`` (a trial's function) run only where the data files are ``expected`` (the
    client's :func:`data_files`, sent with every task): a worker whose own differ (another
    commit, an edited file) raises :class:`DataMismatchError` naming the files and runs
    nothing. Top-level and picklable, as the executors need."""

    worker: Callable[[TrialSpec], dict[str, Any]]
    expected: dict[str, str]
    data: Path | None = None  # the worker's data directory (default: the packaged one)

    def __call__(self, spec: TrialSpec) -> dict[str, Any]:
        own = data_files(self.data)
        differ = sorted(n for n in self.expected.keys() & own.keys()
                        if self.expected[n] != own[n])
        missing = sorted(self.expected.keys() - own.keys())
        extra = sorted(own.keys() - self.expected.keys())
        if differ or missing or extra:
            import socket

            parts = ([f"differ: {', '.join(differ)}"] if differ else []) + (
                [f"missing on the worker: {', '.join(missing)}"] if missing else []) + (
                [f"only on the worker: {', '.join(extra)}"] if extra else [])
            raise DataMismatchError(
                f"worker {socket.gethostname()} (pid {os.getpid()}) refused trial "
                f"{spec.trial}: its data files are not the client's ({'; '.join(parts)}); "
                "install the same commit of articutool on every worker")
        return self.worker(spec)


@functools.cache
def source_version(root: Path | None = None) -> str:
    """The code a trial ran: the last commit on the checked-out line (first parents: a merge,
    not the merged branch's own commits, whose trees lack this line's) that changed ``src/``
    (``+modified`` when ``src/`` differs from it; commits of results or docs do not count), or
    ``articutool <version>`` outside a git checkout. ``root``: the checkout (default: this
    package's). Recorded in every trial, because a resumed log may span commits, which
    ``run.json`` does not pin."""
    from articutool import __version__

    if root is None:
        pkg = Path(__file__).resolve().parents[1]
        root = pkg.parents[1]
        if pkg != root / "src" / "articutool":  # an installed copy, not a source checkout
            return f"articutool {__version__}"
    try:
        head = subprocess.run(["git", "-C", str(root), "log", "-1", "--first-parent",
                               "--format=%h", "--abbrev=12", "--", "src"],
                              capture_output=True, text=True, timeout=10, check=True)
        dirty = subprocess.run(["git", "-C", str(root), "diff", "--quiet", "HEAD", "--",
                                "src"], capture_output=True, timeout=10).returncode != 0
    except (OSError, subprocess.SubprocessError):
        return f"articutool {__version__}"
    return head.stdout.strip() + ("+modified" if dirty else "")


def pin_run(path: Path, settings: dict[str, Any]) -> None:
    """Write ``run.json`` on a fresh run; on a resume refuse different settings."""
    from articutool.datafile import ResultsError, read_own_json, replace_own

    try:
        old = read_own_json(path, "the run's settings")
    except ResultsError as err:
        raise RunError(f"{err}; use another --out") from None
    if old is None:
        path.parent.mkdir(parents=True, exist_ok=True)
        replace_own(path, json.dumps(settings, indent=1) + "\n")
        return
    if not isinstance(old, dict):
        raise RunError(f"{path} is not a JSON object of settings; use another --out")
    diff = [k for k in settings if old.get(k) != settings[k]]
    if diff:
        parts = "; ".join(f"{k}: {old.get(k)!r} → {settings[k]!r}" for k in diff)
        raise RunError(f"{path.parent} holds trials run with other settings ({parts}); "
                       "use the same settings to resume, or another --out")


@functools.cache
def trial_settles() -> SettleCache:
    """The settled worlds of this process's trials, owned by the runner (one per worker
    process): an experiment's conditions share a repeat's seed (common random numbers,
    :mod:`articutool.experiments.design`), so they share its settled food; a restored settle
    is bit-identical to a fresh one (:class:`articutool.sim.world.SettleCache`)."""
    from articutool.sim.world import SettleCache

    return SettleCache(keep=4)


def run_trial(spec: TrialSpec, hook: Any = None, config_path: str | None = None,
              visitors: Sequence[Any] = ()) -> TrialRecord:
    """Run one trial and return its record: the trial's identity, condition and seed, every
    quantity the protocol measured, the wall time, and ``error`` (the exception, if the
    protocol raised one: the trial is then recorded as an error, with its traceback and no
    outcome, not rerun). ``hook`` and ``visitors`` (py_trees visitors for the trial's
    feeding trees, read after the hook ran) go to the protocol
    (the experiment's :meth:`~articutool.experiments.unit.Experiment.run_trial`)."""
    from articutool.experiments.unit import unit

    cfg = ExperimentsConfig.load(config_path)
    exp = unit(spec.experiment)
    t0 = time.perf_counter()
    failed: dict[str, Any] = {}
    outcome = None
    try:
        outcome = exp.run_trial(spec.condition, spec.seed, cfg, hook, visitors=visitors,
                                settled=trial_settles())
    except Exception as err:  # a trial that crashes is reported, not silently dropped
        failed = {"error": f"{type(err).__name__}: {err}",
                  "traceback": traceback.format_exc(limit=6)}
    finally:  # the process's one liquid solver is free for the next trial, in any thread
        from articutool.sim.sph_scene import close_this_threads_liquid

        close_this_threads_liquid()
    return TrialRecord.model_validate({
        "experiment": spec.experiment, "trial": spec.trial, "repeat": spec.repeat,
        "seed": spec.seed, "condition": spec.condition, "outcome": outcome,
        "wall_time_s": round(time.perf_counter() - t0, 3), "pid": os.getpid(),
        "source": source_version(), "error": None, **failed})


def log_trial(spec: TrialSpec) -> dict[str, Any]:
    """Run one trial (:func:`run_trial`) and return its line of the trial log."""
    return run_trial(spec).to_log()


def run_experiment(trials: Sequence[TrialSpec], log: str | Path, executor: Executor, *,
                   worker: Callable[[TrialSpec], dict[str, Any]] | None = None,
                   on_start: Callable[[int, int], None] | None = None,
                   on_result: Callable[[dict[str, Any]], None] | None = None) -> RunResult:
    """Run the trials not yet in ``log`` on ``executor`` (the benchmark's
    :func:`~articutool.bench.runner.run_logged`), appending each line as it finishes (given
    to ``on_result``); the result's records are the requested trials' (old and new), by
    index (:func:`read_trial_log`), and ``log`` what reading the log found first.

    ``worker`` (default :func:`log_trial`) returns a log line and must be picklable for
    process executors; it runs checked (:class:`DataChecked`) against this process's data
    files: a worker with others refuses the trial, which is then lost (not logged; its error
    names the files)."""
    t0 = time.perf_counter()
    checked = DataChecked(worker or log_trial, data_files())
    res = run_logged(trials, log, executor, checked, trial_key, on_result, on_start)
    wanted = {t.key for t in trials}
    records = _records({trial_key(r): r for r in res.records
                        if trial_key(r) in wanted}.values(), Path(log))
    return RunResult(records, res.ran, res.skipped, res.torn, res.corrupt, res.lost,
                     time.perf_counter() - t0, res.interrupted, res.log)


@dataclass
class RunResult:
    """What :func:`run_experiment` did."""

    records: list[TrialRecord]  # the requested trials' records (old and new), by index
    ran: int
    skipped: int
    torn: int  # torn last lines cut off
    corrupt: int  # unreadable lines ignored
    lost: list[tuple[Any, str]]  # trials whose worker failed (not logged; a rerun resumes)
    wall_time_s: float
    interrupted: bool = False  # SIGINT/SIGTERM stopped it (the finished trials are logged)
    log: LogState | None = None  # the log as read before the run (its bad lines by number)
