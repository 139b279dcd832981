"""Exp. 2a runner: every planner on every task, in parallel, resumable (thesis §5.2.1).

A *trial* is one ``(planner, task, seed, tolerance)``; :func:`run_trial` (top-level, picklable)
plans it with :func:`articutool.planning.api.plan` in a worker process and returns a flat
JSON record. The runner appends each finished trial to a JSON-lines log, flushed and
fsync'ed line by line, so a crash loses no finished trial; on restart it skips the trials
already in the log. A torn last line (the crash hit mid-write) is ignored, counted and cut
off before appending. ``run.json`` beside the log pins the settings that make trials
comparable (task set, timeout, search algorithm, utensil, spec); a resume with other settings is
refused rather than mixing incomparable trials.
"""

from __future__ import annotations

import contextlib
import functools
import json
import math
import os
import signal
import threading
from collections.abc import Callable, Hashable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from articutool.bench.executors import Executor
from articutool.planning.types import ALGORITHMS, PLANNERS, PlanRequest, PlanResult, TransportTask

if TYPE_CHECKING:
    from articutool.spec import Spec

__all__ = [
    "DEFAULT_TOLERANCES_DEG",
    "LogState",
    "RunConfig",
    "RunConfigError",
    "RunSummary",
    "Trial",
    "append_record",
    "make_trials",
    "parse_planners",
    "read_log",
    "record_key",
    "run_logged",
    "run_trial",
    "run_trials",
]

DEFAULT_TOLERANCES_DEG = (5.0, 10.0, 15.0, 20.0, 30.0, 45.0)
# The largest trial log read (a record is ~0.5 kB, one with a traceback a few kB): far above
# any run's, a bound so that a wrong file is refused instead of filling memory.
_MAX_LOG_BYTES = 1 << 30
PlanFn = Callable[[PlanRequest, "Spec"], PlanResult]


class RunConfigError(ValueError):
    """Bad runner input (unknown planner, timeout ≤ 0, …) or a resume with other settings."""


# ----------------------------------------------------------------- trials --
@dataclass(frozen=True)
class Trial:
    """One planning run: a planner on a task with a seed (and, for the sweep, a tolerance);
    its record keeps the benchmark's keys (``system``: the planner, ``planner``: the
    algorithm)."""

    planner: str
    task: TransportTask
    seed: int
    timeout_s: float
    algorithm: str = "rrtconnect"
    tolerance_deg: float | None = None
    utensil: str = "spoon"
    wrist_aware_timing: bool = True
    spec_path: str | None = None

    @property
    def key(self) -> tuple[str, int, int, float | None]:
        """Identity in the log: ``(planner, task_id, seed, tolerance_deg)``."""
        return (self.planner, self.task.task_id, self.seed, self.tolerance_deg)


def parse_planners(text: str | Sequence[str]) -> tuple[str, ...]:
    """``"decoupled,strict6"`` → validated, de-duplicated tuple in the given order."""
    names = [s.strip() for s in text.split(",")] if isinstance(text, str) else list(text)
    names = [n for n in names if n]
    if not names:
        raise RunConfigError(f"--systems must name at least one of {', '.join(PLANNERS)}")
    for n in names:
        if n not in PLANNERS:
            raise RunConfigError(f"--systems: unknown system {n!r}; allowed: "
                                 f"{', '.join(PLANNERS)}")
    return tuple(dict.fromkeys(names))


def _check_timeout(timeout_s: float) -> None:
    if (isinstance(timeout_s, bool) or not isinstance(timeout_s, int | float)
            or not math.isfinite(timeout_s) or timeout_s <= 0):
        raise RunConfigError(f"--timeout must be a finite number of seconds > 0; got {timeout_s!r}")


def make_trials(
    tasks: Sequence[TransportTask],
    planners: Sequence[str],
    timeout_s: float,
    seed: int = 0,
    algorithm: str = "rrtconnect",
    tolerances_deg: Sequence[float | None] = (None,),
    utensil: str = "spoon",
    spec_path: str | None = None,
) -> list[Trial]:
    """All trials, task-major (every planner on task 0, then task 1, …) so a partial run is
    balanced across planners. Validates everything first (raises :class:`RunConfigError`)."""
    planners = parse_planners(planners)
    _check_timeout(timeout_s)
    if algorithm not in ALGORITHMS:
        raise RunConfigError(f"--planner must be one of {', '.join(ALGORITHMS)}; "
                             f"got {algorithm!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise RunConfigError(f"--seed must be an integer >= 0; got {seed!r}")
    for tol in tolerances_deg:
        if tol is not None and not (math.isfinite(tol) and 0 < tol < 90):
            raise RunConfigError(f"tolerances must be in (0, 90) degrees; got {tol!r}")
    return [
        Trial(planner, task, seed, float(timeout_s), algorithm, tol, utensil, True, spec_path)
        for tol in tolerances_deg for task in tasks for planner in planners
    ]


# ----------------------------------------------------------------- worker --
@functools.lru_cache(maxsize=4)
def _spec(path: str | None) -> Spec:
    from articutool.spec import load_spec

    return load_spec(path)


def _real_plan(request: PlanRequest, spec: Spec) -> PlanResult:
    from articutool.planning.api import plan

    return plan(request, spec)


def run_trial(trial: Trial, plan_fn: PlanFn | None = None) -> dict[str, Any]:
    """Plan one trial (in a worker process) and return its JSON record.

    Calls :func:`articutool.planning.api.plan` unless ``plan_fn`` is given (tests inject a
    stand-in). A planner exception becomes a failed record with ``error`` set, so one bad
    trial does not stop the benchmark.
    """
    request = PlanRequest(
        planner=trial.planner, task=trial.task, timeout_s=trial.timeout_s,
        algorithm=trial.algorithm,
        seed=trial.seed, tolerance_deg=trial.tolerance_deg,
        wrist_aware_timing=trial.wrist_aware_timing, utensil=trial.utensil,
    )
    fn = plan_fn or _real_plan
    error = None
    try:
        rec = fn(request, _spec(trial.spec_path)).to_record()
    except Exception as err:  # a planner bug must not take the whole benchmark down
        error = f"{type(err).__name__}: {err}"
        rec = {"system": trial.planner, "task_id": trial.task.task_id, "success": False,
               "planning_time_s": None, "attempts": 0, "verification_rejections": 0,
               "path_length": None, "max_tilt_deg": None, "verified": None,
               "message": error, "duration_s": None}
    rec.update({"seed": trial.seed, "tolerance_deg": trial.tolerance_deg,
                "planner": trial.algorithm, "timeout_s": trial.timeout_s, "error": error})
    return rec


# -------------------------------------------------------------------- log --
def record_key(rec: dict[str, Any]) -> tuple[str, int, int, float | None]:
    """The trial identity of a log record (see :attr:`Trial.key`)."""
    tol = rec.get("tolerance_deg")
    return (rec["system"], int(rec["task_id"]), int(rec["seed"]),
            None if tol is None else float(tol))


# How many bad lines a log's description names one by one (the rest are counted).
_NAMED_LINES = 8


@dataclass
class LogState:
    """What :func:`read_log` found: valid records, a torn tail, unreadable middle lines,
    each bad line by its number (from 1) and why it is bad."""

    records: list[dict[str, Any]] = field(default_factory=list)
    torn: int = 0  # an incomplete last line (0 or 1)
    corrupt: int = 0  # complete lines that are not a valid record
    valid_bytes: int = 0  # length of the file up to the end of the last complete line
    key: Callable[[dict[str, Any]], Hashable] = field(default=record_key, repr=False)
    path: Path | None = None
    lines: int = 0  # lines read, the torn tail included
    bad: list[tuple[int, str]] = field(default_factory=list)  # (line, why), the torn tail too
    # (line, first line): a record whose trial an earlier line already holds (the last wins)
    duplicates: list[tuple[int, int]] = field(default_factory=list)

    @property
    def done(self) -> set[Any]:
        """Keys of the finished trials."""
        return {self.key(r) for r in self.records}

    @property
    def clean(self) -> bool:
        """No bad line and no duplicate trial."""
        return not self.bad and not self.duplicates

    def problems(self, most: int = _NAMED_LINES) -> list[str]:
        """Every bad or duplicate line, ``line N: why``: the first ``most`` named, then how
        many more."""
        out = ([f"line {n}: {why}" for n, why in self.bad]
               + [f"line {n}: the same trial as line {first} (the later line is used)"
                  for n, first in self.duplicates])
        return out if len(out) <= most else [*out[:most], f"and {len(out) - most} more"]

    def describe(self) -> str:
        """One line: the file, lines read, records accepted, and every bad or duplicate line
        by number and reason (the first few named, the rest counted)."""
        text = (f"{self.path}: {self.lines} line(s) read, {len(self.records)} record(s) "
                "accepted")
        if not self.clean:
            text += (f", {len(self.bad)} bad line(s)"
                     + (f" and {len(self.duplicates)} duplicate(s)" if self.duplicates else "")
                     + " (" + "; ".join(self.problems()) + ")")
        return text


def read_log(path: str | Path,
             key: Callable[[dict[str, Any]], Hashable] = record_key) -> LogState:
    """Read a results log; a missing file is an empty log. ``key`` gives a record's trial
    identity (a line it cannot key is bad, as is an empty line or one holding NaN, Infinity
    or a number too large for a float, which the runner never writes); other JSON-lines logs
    (the experiments) pass their own. Every bad line is kept with its number and why
    (:attr:`LogState.bad`), as is a trial logged twice (:attr:`LogState.duplicates`). The log is
    a run's own file (:func:`articutool.datafile.read_own_bytes`): a link, FIFO or folder in
    its place raises :class:`~articutool.datafile.ResultsError` — its last line is never cut
    from a file the run did not write."""
    from articutool.datafile import read_own_bytes

    p = Path(path)
    state = LogState(key=key, path=p)
    data = read_own_bytes(p, "results log", max_bytes=_MAX_LOG_BYTES)
    if data is None:
        return state
    end = data.rfind(b"\n") + 1  # everything after the last newline is a torn write
    state.valid_bytes = end
    lines = data[:end].split(b"\n")[:-1]
    state.lines = len(lines) + (end < len(data))
    first: dict[Hashable, int] = {}
    for n, line in enumerate(lines, 1):
        why = _bad_line(line, key)
        if isinstance(why, str):
            state.corrupt += 1
            state.bad.append((n, why))
            continue
        k = key(why)
        if k in first:
            state.duplicates.append((n, first[k]))
        first.setdefault(k, n)
        state.records.append(why)
    if end < len(data):
        state.torn = 1
        state.bad.append((state.lines, f"no newline at its end ({len(data) - end} bytes: a "
                                       "write cut short; a resumed run cuts it off)"))
    return state


def _bad_line(line: bytes, key: Callable[[dict[str, Any]], Hashable]) -> dict[str, Any] | str:
    """The record of one log line, or why it is none."""
    if not line.strip():
        return "empty"
    try:
        rec = json.loads(line, parse_constant=_no_constant, parse_float=_finite_float)
    except UnicodeDecodeError as err:
        return f"not UTF-8 text (byte {err.start})"
    except RecursionError:
        return "nested too deeply"
    except ValueError as err:
        return f"not JSON ({str(err).split(':')[0]})" if isinstance(
            err, json.JSONDecodeError) else str(err)
    if not isinstance(rec, dict):  # JSON, but not a record ([1, 2], 42, null)
        return f"not a record (a JSON {type(rec).__name__})"
    try:
        key(rec)
    except (KeyError, TypeError, ValueError) as err:
        return f"no trial identity ({type(err).__name__}: {err})"
    return rec


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number (a bad record)")


def _finite_float(text: str) -> float:
    v = float(text)
    if not math.isfinite(v):  # 1e400 parses as infinity
        raise ValueError(f"{text} is too large for a float (a bad record)")
    return v


def append_record(fd: int, rec: dict[str, Any]) -> None:
    """Append one record as a JSON line and make it durable (write + fsync)."""
    line = (json.dumps(rec, allow_nan=False) + "\n").encode()
    view = memoryview(line)
    while view:
        view = view[os.write(fd, view):]
    os.fsync(fd)


# ----------------------------------------------------------------- config --
@dataclass(frozen=True)
class RunConfig:
    """Settings that make trials in one log comparable (stored as ``run.json``; its
    ``planner`` is the search algorithm)."""

    tasks_sha256: str
    timeout_s: float
    algorithm: str
    utensil: str
    spec_hash: str

    def to_dict(self) -> dict[str, Any]:
        return {"tasks_sha256": self.tasks_sha256, "timeout_s": self.timeout_s,
                "planner": self.algorithm, "utensil": self.utensil, "spec_hash": self.spec_hash}

    def check_or_write(self, path: Path) -> None:
        """Write ``path`` on a fresh run; on a resume refuse differing settings."""
        from articutool.datafile import ResultsError, read_own_json, replace_own

        try:
            old = read_own_json(path, "the run's settings")
        except ResultsError as err:
            raise RunConfigError(f"{err}; use another --out") from None
        if old is None:
            replace_own(path, json.dumps(self.to_dict(), indent=1) + "\n")
            return
        if not isinstance(old, dict):
            raise RunConfigError(f"{path} is not a JSON object of settings; use another --out")
        new = self.to_dict()
        diff = [k for k in new if old.get(k) != new[k]]
        if diff:
            parts = ", ".join(f"{k} {old.get(k)!r} → {new[k]!r}" for k in diff)
            raise RunConfigError(
                f"{path.parent} holds results of a run with other settings ({parts}); "
                "use the same settings to resume it, or another --out")


# ----------------------------------------------------------------- runner --
@dataclass
class RunSummary:
    """Outcome of :func:`run_trials`."""

    records: list[dict[str, Any]]  # every record in the log (old and new), log order
    ran: int  # trials run now
    skipped: int  # trials already in the log
    torn: int  # torn last lines found (and cut off)
    corrupt: int  # unreadable complete lines (ignored)
    lost: list[tuple[Any, str]]  # trials whose worker failed (not logged; rerun resumes)
    interrupted: bool = False  # SIGINT/SIGTERM stopped the run (the rest: a rerun resumes)
    log: LogState | None = None  # the log as read before the run (its bad lines by number)


@contextlib.contextmanager
def stop_on_signals(stop: threading.Event) -> Iterator[None]:
    """While inside: SIGINT and SIGTERM set ``stop`` instead of raising in the middle of the
    run (a ``KeyboardInterrupt`` inside the pool's machinery could deadlock it, and one
    between a trial's end and its log line would lose the trial). Only in the main thread
    (elsewhere signals cannot be handled: nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: object) -> None:
        stop.set()

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def run_logged(
    items: Sequence[Any],
    log_path: str | Path,
    executor: Executor,
    worker: Callable[[Any], dict[str, Any]],
    key: Callable[[dict[str, Any]], Hashable] = record_key,
    on_result: Callable[[dict[str, Any]], None] | None = None,
    on_start: Callable[[int, int], None] | None = None,
) -> RunSummary:
    """Run ``worker`` on the ``items`` (each with a ``.key`` equal to ``key(record)``) not
    yet in ``log_path`` on ``executor``, appending each record as it finishes.

    ``on_start(pending, skipped)`` is called once before any work, ``on_result(rec)`` after
    each record is durably logged (progress bars). Shared by the Exp. 2a benchmark and the
    physical experiments (``articutool.experiments``).

    SIGINT or SIGTERM (to this process alone, or to its group as Ctrl-C sends) stops the run
    within ``POLL_S``: every trial finished by then is logged, the running ones are abandoned
    with their worker processes, and the summary says ``interrupted``.
    """
    from articutool.datafile import append_own

    log_path = Path(log_path)
    state = read_log(log_path, key=key)
    done = state.done
    pending = [t for t in items if t.key not in done]
    # Unique keys only: a duplicate trial in the input would be run twice.
    pending = list({t.key: t for t in pending}.values())
    skipped = len(items) - len(pending)
    if on_start is not None:
        on_start(len(pending), skipped)
    log_path.parent.mkdir(parents=True, exist_ok=True)
    fd = append_own(log_path)  # never through a link: the log is this run's own file
    lost: list[tuple[Any, str]] = []
    records = list(state.records)
    stop = threading.Event()
    ran = 0
    try:
        if state.torn:
            os.ftruncate(fd, state.valid_bytes)  # drop the torn tail before appending
        with stop_on_signals(stop):
            for item, rec, err in executor.run(worker, pending, stop):
                if err is not None:
                    lost.append((item, f"{type(err).__name__}: {err}"))
                    continue
                append_record(fd, rec)
                records.append(rec)
                ran += 1
                if on_result is not None:
                    on_result(rec)
    finally:
        os.close(fd)
    return RunSummary(records, ran, skipped, state.torn, state.corrupt, lost, stop.is_set(),
                      state)


def run_trials(
    trials: Sequence[Trial],
    log_path: str | Path,
    executor: Executor,
    plan_fn: PlanFn | None = None,
    on_result: Callable[[dict[str, Any]], None] | None = None,
    on_start: Callable[[int, int], None] | None = None,
) -> RunSummary:
    """Run the trials not yet in ``log_path`` on ``executor``, appending each as it finishes
    (:func:`run_logged` with :func:`run_trial`)."""
    worker = run_trial if plan_fn is None else functools.partial(run_trial, plan_fn=plan_fn)
    return run_logged(trials, log_path, executor, worker, record_key, on_result, on_start)


def select(records: Iterable[dict[str, Any]], trials: Sequence[Trial]) -> list[dict[str, Any]]:
    """The records of ``trials`` (a log may hold more, e.g. other seeds or planners)."""
    wanted = {t.key for t in trials}
    out: dict[tuple[str, int, int, float | None], dict[str, Any]] = {}
    for r in records:
        k = record_key(r)
        if k in wanted:
            out[k] = r
    return list(out.values())
