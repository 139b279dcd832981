"""``articutool bench``: generate Exp. 2a tasks and run the transport benchmark.

* ``bench tasks --count N --seed S --out FILE``: candidate tasks → common IK-filtered set.
* ``bench transport [--tasks FILE] [--systems …] [--timeout S] [--workers N] [--out DIR]
  [--json] [--planner …] [--seed S] [--scheduler ADDRESS] [--tolerance-sweep]``.

Every input is validated before any work starts (bad input: exit 2). Progress goes to
stderr, results to stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

__all__ = ["add_commands", "check_workers", "make_executor"]


def _usage(msg: str) -> Exception:
    from articutool.cli_support import UsageError

    return UsageError(msg)


def _stderr_console() -> Any:
    from rich.console import Console

    return Console(stderr=True)


# ------------------------------------------------------------------- tasks --
def _cmd_tasks(args: argparse.Namespace) -> int:
    from articutool.cli_support import new_output_file, spec_from_args

    if args.seed < 0:
        raise _usage(f"--seed must be >= 0; got {args.seed}")
    out = new_output_file("--out", args.out, (".json",))
    assert out is not None
    from articutool.bench.tasks import MAX_CANDIDATES  # the IK and the scene: after --out

    if not 1 <= args.count <= MAX_CANDIDATES:
        raise _usage(f"--count must be in [1, {MAX_CANDIDATES}]; got {args.count}")
    spec = spec_from_args(args)
    if args.utensil not in spec.utensils:
        raise _usage(f"--utensil must be one of {sorted(spec.utensils)}; got {args.utensil!r}")

    from rich.progress import Progress

    from articutool.bench.taskfile import TaskFileError, save_task_set
    from articutool.bench.tasks import generate_tasks

    t0 = time.perf_counter()
    with Progress(console=_stderr_console(), transient=True) as bar:
        job = bar.add_task("IK-filtering candidates", total=args.count)
        ts = generate_tasks(spec, args.count, args.seed, utensil=args.utensil,
                            progress=lambda k: bar.update(job, completed=k))
    elapsed = time.perf_counter() - t0
    try:
        save_task_set(ts, out)
    except TaskFileError as err:
        raise _usage(str(err)) from None
    rej = ", ".join(f"{k} {v}" for k, v in ts.ik_rejections.items())
    print(f"kept {len(ts.tasks)} of {ts.candidates} candidates reachable by all three planners "
          f"(IK rejections: {rej}) in {elapsed:.1f} s → {out}")
    return 0


# --------------------------------------------------------------- transport --
def check_workers(workers: int) -> None:
    """``--workers``: local worker processes in [1, MAX_WORKERS] (a larger count is a typo:
    ``100000000000000000000`` overflowed the process pool)."""
    from articutool.bench.executors import MAX_WORKERS

    if not 1 <= workers <= MAX_WORKERS:
        raise _usage(f"--workers must be in [1, {MAX_WORKERS}] processes; got {workers}")


def make_executor(args: argparse.Namespace) -> Any:
    """A Dask executor for ``--scheduler``, else a local pool of ``--workers`` processes
    (a scheduler that cannot be reached is bad input)."""
    from articutool.bench.executors import DaskExecutor, ExecutorError, LocalExecutor

    if args.scheduler:
        try:
            return DaskExecutor(args.scheduler)
        except ExecutorError as err:
            raise _usage(str(err)) from None
    return LocalExecutor(args.workers)


def _tolerances(text: str) -> tuple[float, ...]:
    """``--tolerances``: one or more comma-separated degrees, each in (0, 90) (a strict
    planner's ± pitch/roll band)."""
    parts = [x.strip() for x in text.split(",") if x.strip()]
    try:
        tols = tuple(float(x) for x in parts)
    except ValueError:
        tols = ()
    if not tols or not all(0 < t < 90 for t in tols):  # also refuses NaN
        raise _usage("--tolerances must be one or more comma-separated degrees, each in "
                     f"(0, 90); got {text!r}")
    return tols


def _cmd_transport(args: argparse.Namespace) -> int:
    from articutool.bench import report
    from articutool.bench.runner import (
        RunConfig,
        RunConfigError,
        make_trials,
        run_trials,
        select,
    )
    from articutool.bench.taskfile import TaskFileError, check_task_limits, load_task_set, spec_hash
    from articutool.cli_support import output_dir, spec_from_args

    # ---- validate everything before any work ----
    check_workers(args.workers)
    if args.limit is not None and args.limit < 1:
        raise _usage(f"--limit must be >= 1; got {args.limit}")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise _usage(f"--out {out} exists and is not a directory")
    tolerances = _tolerances(args.tolerances)
    spec = spec_from_args(args)
    try:
        ts = load_task_set(args.tasks)
    except TaskFileError as err:
        raise _usage(str(err)) from None
    if ts.utensil not in spec.utensils:
        raise _usage(f"tasks file utensil {ts.utensil!r} is not in the spec "
                     f"({sorted(spec.utensils)})")
    try:
        check_task_limits(ts, spec)
    except TaskFileError as err:
        raise _usage(f"invalid tasks file {args.tasks or 'packaged'}: {err}") from None
    tasks = list(ts.tasks[: args.limit] if args.limit else ts.tasks)
    if not tasks:
        raise _usage("the tasks file holds no tasks")
    sweep = args.tolerance_sweep
    planners_arg = "strict6" if sweep else args.planners
    try:
        trials = make_trials(tasks, planners_arg.split(","), args.timeout, args.seed,
                             args.algorithm, tolerances if sweep else (None,), ts.utensil,
                             args.spec)
        planners = tuple(dict.fromkeys(t.planner for t in trials))
        config = RunConfig(ts.sha256, float(args.timeout), args.algorithm, ts.utensil,
                           spec_hash(spec))
        output_dir("--out", out, ("run.json", "results.jsonl", "tolerance_sweep.jsonl",
                                  "results.csv", "cactus.png", "tolerance_sweep.csv",
                                  "tolerance_sweep.png", "tolerance_sweep_trials.csv"))
        config.check_or_write(out / "run.json")
    except RunConfigError as err:
        raise _usage(str(err)) from None
    err_console = _stderr_console()
    if ts.spec_hash != spec_hash(spec):
        err_console.print("[yellow]warning:[/] the tasks were generated with another spec "
                          f"(hash {ts.spec_hash}, this spec {spec_hash(spec)})")
    executor = make_executor(args)

    # ---- run ----
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    log = out / ("tolerance_sweep.jsonl" if sweep else "results.jsonl")
    solved = dict.fromkeys(planners, 0)
    t0 = time.perf_counter()
    with Progress("[progress.description]{task.description}", BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(), console=err_console) as bar:
        job = bar.add_task("planning", total=0)

        def started(pending: int, skipped: int) -> None:
            bar.update(job, total=pending)
            err_console.print(f"{len(trials)} trials on {executor.description}: "
                              f"{skipped} already in {log}, {pending} to run")

        def finished(rec: dict) -> None:
            solved[rec["system"]] = solved.get(rec["system"], 0) + bool(rec.get("success"))
            bar.update(job, advance=1, description="solved " + " ".join(
                f"{s} {n}" for s, n in solved.items()))

        try:
            summary_run = run_trials(trials, log, executor, on_result=finished,
                                     on_start=started)
        finally:
            executor.close()
    wall = time.perf_counter() - t0
    if summary_run.interrupted:
        err_console.print(f"interrupted: {summary_run.ran} trial(s) finished now and are "
                          f"logged in {log}; run the same command again to resume (no "
                          "report written)")
        return 130
    if summary_run.log is not None and not summary_run.log.clean:
        err_console.print(f"warning: {summary_run.log.describe()}; the bad lines "
                          "were ignored (a torn last line cut off): a trial one held ran again",
                          markup=False, highlight=False)
    records = select(summary_run.records, trials)

    # ---- report ----
    if sweep:
        by_tol = report.summarize_sweep(records, "strict6")
        report.write_sweep_csv(by_tol, out / "tolerance_sweep.csv")
        report.tolerance_sweep_plot(by_tol, out / "tolerance_sweep.png")
        report.write_results_csv(records, out / "tolerance_sweep_trials.csv")
        if args.json:
            print(json.dumps({"strict6": {f"{k:g}": v for k, v in by_tol.items()}}, indent=1))
        else:
            from rich.console import Console
            from rich.table import Table

            t = Table(title="strict6 tolerance sweep (cf. thesis Fig. 5.1)")
            for c in ("tolerance", "solved", "success", "median", "mean", "p90"):
                t.add_column(c, justify="right")
            for tol, v in by_tol.items():
                t.add_row(f"±{tol:g}°", f"{v['successes']}/{v['trials']}",
                          report._fmt_rate(v["success_rate"]), report._fmt_time(
                              v["median_time_s"]), report._fmt_time(v["mean_time_s"]),
                          report._fmt_time(v["p90_time_s"]))
            Console(width=None if sys.stdout.isatty() else 160).print(t)
            print(f"wrote {out / 'tolerance_sweep.csv'}, {out / 'tolerance_sweep.png'}")
    else:
        summary = report.summarize(records, planners)
        report.write_results_csv(records, out / "results.csv")
        report.cactus_plot(records, planners, out / "cactus.png", timeout_s=args.timeout)
        if args.json:
            print(json.dumps(summary, indent=1))
        else:
            from rich.console import Console

            Console(width=None if sys.stdout.isatty() else 160).print(report.render_table(
                summary, title=f"Exp. 2a transport: {len(tasks)} tasks, {args.algorithm}, "
                               f"timeout {args.timeout:g} s, seed {args.seed}"))
            med = {s: v["median_time_s"] for s, v in summary.items()}
            d = med.get("decoupled")
            for s in ("strict6", "strict8"):
                if d and med.get(s):
                    print(f"median time ratio {s}/decoupled: {med[s] / d:.1f}×")
            print(f"wrote {out / 'results.csv'}, {out / 'cactus.png'}")
    err_console.print(f"ran {summary_run.ran} trials in {wall:.1f} s")
    if summary_run.lost:
        for trial, why in summary_run.lost[:5]:
            err_console.print(f"[red]lost[/] {trial.planner} task {trial.task.task_id}: {why}")
        err_console.print(f"{len(summary_run.lost)} trial(s) did not finish (worker failure); "
                          "run the same command again to resume them")
        return 1
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``bench tasks`` and ``bench transport``."""
    from articutool.bench.executors import MAX_WORKERS
    from articutool.bench.runner import DEFAULT_TOLERANCES_DEG
    from articutool.cli_support import MAX_WAIT_S, add_spec_option, seconds
    from articutool.planning.types import ALGORITHMS

    bench = sub.add_parser("bench", help="Exp. 2a transport benchmark: tasks and runner")
    bsub = bench.add_subparsers(dest="bench_command", required=True, metavar="BENCH_COMMAND")

    p = bsub.add_parser("tasks", help="generate the common IK-filtered transport task set")
    p.add_argument("--count", type=int, default=100, help="candidate tasks (default 100)")
    p.add_argument("--seed", type=int, required=True, help="random seed (recorded in the file)")
    p.add_argument("--out", metavar="FILE", required=True, help="task file to write (JSON)")
    p.add_argument("--utensil", default="spoon", help="utensil on the wrist (default: spoon)")
    add_spec_option(p)
    p.set_defaults(func=_cmd_tasks)

    p = bsub.add_parser("transport", help="run the planners on the tasks (resumable)")
    p.add_argument("--tasks", metavar="FILE", default=None,
                   help="task file (default: the packaged transport_tasks_v1.json)")
    p.add_argument("--systems", dest="planners", metavar="SYSTEMS",
                   default="decoupled,strict6,strict8",
                   help="comma-separated planners, the thesis' systems (default: all three)")
    p.add_argument("--timeout", type=seconds(MAX_WAIT_S), default=30.0, metavar="S",
                   help=f"planning timeout per trial, in (0, {MAX_WAIT_S:g}] s (default 30; "
                        "the thesis used 1000)")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help=f"local worker processes in [1, {MAX_WORKERS}] (default: CPU count)")
    p.add_argument("--out", metavar="DIR", default="bench-results",
                   help="results directory; rerun with the same DIR to resume")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    p.add_argument("--planner", dest="algorithm", choices=ALGORITHMS, default="rrtconnect",
                   help="OMPL search algorithm (default: rrtconnect)")
    p.add_argument("--seed", type=int, default=0, help="planner seed (default 0)")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="run on a Dask distributed cluster at ADDRESS instead of locally")
    p.add_argument("--tolerance-sweep", action="store_true",
                   help="run strict6 over --tolerances instead (thesis Fig. 5.1)")
    tols = ",".join(f"{t:g}" for t in DEFAULT_TOLERANCES_DEG)
    p.add_argument("--tolerances", default=tols,
                   help=f"degrees for --tolerance-sweep (default {tols})")
    p.add_argument("--limit", type=int, default=None, help="only the first N tasks")
    add_spec_option(p)
    p.set_defaults(func=_cmd_transport)
