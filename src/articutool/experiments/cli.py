"""``articutool experiment …``: the thesis' physical experiments in the physics world.

* ``experiment NAME [--trials N] [--workers N] [--scheduler ADDR]
  [--out DIR] [--seed S] [--json]``: run (resumable; a progress bar on stderr), then write
  ``DIR/<experiment>/summary.json`` and the figure and print our numbers beside the thesis'.
* ``… --trial K [--video FILE]``: replay trial K alone (its seed is in its record), print its
  record, and say whether it reproduces the logged one.
* ``experiment report [--out DIR]``: one Markdown + HTML page with every table and figure.

Every input is checked before anything runs (bad input: exit 2 naming the field).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import shlex
import sys
import time
from pathlib import Path
from typing import Any

from articutool.experiments.unit import foods_asked, registry, unit, usage

__all__ = ["BOOKKEEPING_FIELDS", "TIMING_FIELDS", "add_commands", "trials_for"]

DEFAULT_OUT = "results/experiments"
# A trial record's fields that a rerun of its seed need not reproduce (the replay check,
# benchmarks/experiment_scaling.py). Plans run in a thread while the world steps, so when a
# plan is ready in simulated time depends on the machine's speed: these may differ slightly
# between runs of one seed (``planning_time_s`` in older records).
TIMING_FIELDS = frozenset({"planning_time_s", "planning_wall_s", "planning_wait_sim_s",
                           "motion_time_s", "sim_time_s", "max_tilt_deg",
                           "transport_max_tilt_deg"})
# Never compared: the run's own bookkeeping (the code version is named separately).
BOOKKEEPING_FIELDS = frozenset({"wall_time_s", "pid", "realtime_factor", "bite_wall_time_s",
                                "traceback", "source"})


def _check_common(args: argparse.Namespace) -> Path:
    from articutool.experiments.design import MAX_TRIALS

    if not 1 <= args.trials <= MAX_TRIALS:
        raise usage(f"--trials must be in [1, {MAX_TRIALS}] per condition; got {args.trials}")
    from articutool.bench.cli import check_workers

    check_workers(args.workers)
    if args.seed < 0:
        raise usage(f"--seed must be >= 0; got {args.seed}")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise usage(f"--out {out} exists and is not a directory")
    if args.video is not None:
        from articutool.cli_support import new_output_file

        if args.trial is None:
            raise usage("--video needs --trial K (a video of one replayed trial)")
        new_output_file("--video", args.video, (".mp4", ".gif"))
    if args.record is not None:
        from articutool.cli_support import new_output_file

        if args.trial is None:
            raise usage("--record needs --trial K (a recording of one replayed trial)")
        new_output_file("--record", args.record, (".mcap",))
    return out


def trials_for(exp: str, args: argparse.Namespace, out: Path, cfg: Any
               ) -> tuple[list[Any], dict[str, Any]]:
    """The trials ``experiment EXP`` runs (``args.trials``, ``args.seed``, and what the
    experiment takes beyond its config: :meth:`~articutool.experiments.unit.Experiment.
    inputs`; a replay, ``--trial K``, takes the conditions its logged run pinned:
    :func:`_pinned_conditions`) and the run's conditions with what they came from."""
    from articutool.experiments.design import make_trials

    u = unit(exp)
    inputs, noted = u.inputs(args, out, cfg)
    conds = u.conditions(cfg, **inputs)
    wanted = foods_asked(args)
    if wanted is not None:
        known = sorted({c.food for c in conds})
        if not wanted or any(f not in known for f in wanted):
            raise usage(f"--foods must name foods of {exp} ({', '.join(known)}), "
                        f"comma-separated; got {args.foods!r}")
        conds = [c for c in conds if c.food in wanted]
    physics = getattr(args, "physics", None)
    if physics is not None:
        from articutool.sim.params import PhysicsError, PhysicsParams

        try:
            params = PhysicsParams.load(physics)
        except PhysicsError as err:
            raise usage(f"--physics: {err}") from None
        missing = sorted({c.food for c in conds} - set(params.foods))
        if missing:
            raise usage(f"--physics {physics}: no parameters for {missing}")
        conds = [c.model_copy(update={"physics": str(Path(physics).resolve())})
                 for c in conds]
    if getattr(args, "trial", None) is not None:
        conds = _pinned_conditions(exp, conds, out, args.seed, cfg)
    return make_trials(exp, conds, args.trials, args.seed, **inputs), {
        "conditions": [c.fields() for c in conds], **noted}


def _machine() -> dict[str, Any]:
    import platform

    return {"host": platform.node(), "platform": platform.platform(),
            "python": platform.python_version(), "cpus": os.cpu_count(),
            "load_avg": [round(x, 2) for x in os.getloadavg()]}


def _pinned_conditions(exp: str, conds: list[Any], out: Path, seed: int, cfg: Any
                       ) -> list[Any]:
    """For a replay: the conditions the logged run pinned (``out/exp/run.json``) where today's
    inputs give other values for the same conditions (Exp. 2c's loads and target once
    capacity or Exp. 1 ran again), so the trial runs as it was logged; what differs, and data
    that changed since the run, are said on stderr. ``conds`` (today's) otherwise."""
    from articutool.datafile import ResultsError, read_own_json
    from articutool.experiments.runner import data_hash

    try:
        run = read_own_json(out / exp / "run.json", "the run's settings")
    except ResultsError as err:
        print(f"warning: {err}; replaying today's conditions", file=sys.stderr)
        return conds
    if not isinstance(run, dict) or not isinstance(run.get("conditions"), list):
        return conds
    today = [c.fields() for c in conds]
    foods = {c["food"] for c in today}
    if run.get("data_hash") not in (None, data_hash(exp, cfg, foods)):
        print(f"warning: the data a trial of {exp} reads ({', '.join(sorted(foods))}) changed "
              "since the logged run, so the replay may differ from its record", file=sys.stderr)
    if run["conditions"] == today or run.get("seed", seed) != seed:
        return conds
    try:
        pinned = [unit(exp).condition.model_validate(c) for c in run["conditions"]]
    except ValueError:
        return conds
    if [c.group() for c in pinned] != [c.group() for c in conds]:
        print("warning: the logged run pinned other conditions; replaying today's",
              file=sys.stderr)
        return conds
    moved = [f"{'/'.join(a.group())}: {k} {a.fields().get(k)} → {b.fields().get(k)}"
             for a, b in zip(conds, pinned, strict=True)
             for k in sorted(a.fields().keys() | b.fields().keys())
             if a.fields().get(k) != b.fields().get(k)]
    print(f"note: replaying the logged run's conditions where today's inputs differ "
          f"({'; '.join(moved)})", file=sys.stderr)
    return pinned


def _replay(args: argparse.Namespace, exp: str, trials: list[Any], out: Path) -> int:
    from articutool.experiments.runner import read_trial_log, run_trial

    spec = next((t for t in trials if t.trial == args.trial), None)
    if spec is None:
        raise usage(f"--trial must be in [0, {len(trials) - 1}] for --trials {args.trials}; "
                     f"got {args.trial}")
    rec_holder: dict[str, Any] = {}
    visitors: list[Any] = []  # read by the protocol when it builds a tree (after the hook)

    def hook(world: Any) -> None:
        if args.video:
            from articutool.sim.render import Recorder

            # The whole path, and beside it what the utensil holds (it follows the utensil).
            rec_holder["r"] = Recorder(world, fps=15.0, camera=("overview", "follow"),
                                       width=480, height=360)
        if args.record:
            from articutool.sim.mcap_record import WorldMcapRecorder

            rec_holder["mcap"] = WorldMcapRecorder(world, args.record, metadata={
                "experiment": exp, "trial": spec.trial, "seed": spec.seed,
                "condition": json.dumps(dict(sorted(spec.condition.fields().items())),
                                        default=str)})
            visitors.append(rec_holder["mcap"].tree_visitor)

    try:
        record = run_trial(spec, hook if args.video or args.record else None,
                           visitors=visitors)
    finally:
        if "mcap" in rec_holder:  # complete also when the trial failed or was interrupted
            rec_holder["mcap"].close()
    trial_log = read_trial_log(out, exp)
    if not trial_log.state.clean:
        print(f"warning: {trial_log.state.describe()}", file=sys.stderr)
    found = {r.trial: r for r in trial_log.records}.get(spec.trial)
    if record.error:
        print(f"error: trial {spec.trial} failed: {record.error}", file=sys.stderr)
        return 1
    if args.video:
        rec_holder["r"].save(args.video)
    rec = record.to_log()  # compared as logged: field by field
    if found is None:
        verdict = "no logged record to compare with"
    else:
        logged = found.to_log()
        ignored = TIMING_FIELDS | BOOKKEEPING_FIELDS
        diff = sorted(k for k in rec if k not in ignored and logged.get(k) != rec[k])
        verdict = "reproduces the logged record" if not diff else (
            f"differs from the logged record in {diff}")
        moved = [f"{k} {logged.get(k)} → {rec[k]}" for k in sorted(TIMING_FIELDS & rec.keys())
                 if logged.get(k) != rec[k]]
        if moved:
            verdict += f" (timing-dependent: {'; '.join(moved)})"
        if logged.get("source") != rec.get("source"):
            verdict += (f"; logged by code {logged.get('source', 'not recorded')}, "
                        f"replayed by {rec.get('source')}")
    if args.json:
        print(json.dumps({"record": rec, "replay": verdict}, indent=1))
    else:
        print(json.dumps(rec, indent=1))
        print(f"trial {spec.trial} (seed {spec.seed}): {verdict}")
        if args.video:
            print(f"video {args.video}")
        if args.record:
            print(f"recording {args.record}")
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    from articutool.experiments.config import ExperimentsConfig, ExperimentsConfigError
    from articutool.experiments.runner import RunError, data_hash, log_path, pin_run

    exp = args.experiment
    u = unit(exp)
    out = _check_common(args)
    u.check_arguments(args)
    try:
        cfg = ExperimentsConfig.load()
    except ExperimentsConfigError as err:
        raise usage(str(err)) from None
    trials, extra = trials_for(exp, args, out, cfg)
    # Checked before any trial runs; the trials themselves do not depend on it.
    given = u.analysis(args, out, cfg)
    if args.trial is not None:
        return _replay(args, exp, trials, out)
    from articutool.cli_support import output_dir
    from articutool.experiments import report  # scipy.stats: imported once the input is good
    from articutool.experiments.analysis import summarize

    d = output_dir("--out", out, ("run.json", "trials.jsonl", "summary.json", "notes.md",
                                  f"{exp}.png"), own=exp)
    old_summary = report.read_summary(d / "summary.json")  # unreadable: refused before a trial
    foods = {c["food"] for c in extra["conditions"]}
    settings = {"experiment": exp, "seed": args.seed, "data_hash": data_hash(exp, cfg, foods),
                "conditions": extra["conditions"]}
    try:
        pin_run(d / "run.json", settings)
    except RunError as err:
        raise usage(str(err)) from None
    from articutool.bench.cli import make_executor

    executor = make_executor(args)
    load_before = os.getloadavg()
    summary_run = _run_with_progress(trials, log_path(out, exp), executor, exp)
    load_after = os.getloadavg()
    if summary_run.interrupted:
        print(f"interrupted: {summary_run.ran} trial(s) finished now and are logged in "
              f"{log_path(out, exp)}, {len(trials) - summary_run.skipped - summary_run.ran} "
              "not run; run the same command again to resume (no summary written)",
              file=sys.stderr)
        return 130
    records = summary_run.records
    summary = summarize(exp, records, cfg, **given)
    # What this invocation did; with nothing run, the last invocation that ran trials keeps
    # its account (each field it has).
    invocation = dict(
        executor=executor.description, experiment_wall_time_s=round(summary_run.wall_time_s, 1),
        ran_now=summary_run.ran, machine=_machine(),
        date=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        command="articutool " + " ".join(shlex.quote(a) for a in sys.argv[1:])
        if sys.argv[1:2] == ["experiment"] else f"articutool experiment {exp}",
        # The machine's run-queue load averages (os.getloadavg: 1, 5, 15 min) as the run
        # began and ended; the run's own workers are part of the second.
        machine_load={"before": [round(x, 2) for x in load_before],
                      "after": [round(x, 2) for x in load_after]})
    if summary_run.ran == 0 and old_summary is not None:
        invocation.update({k: old_summary["run"][k] for k in invocation
                           if k in old_summary["run"]})
    summary["run"].update(trials_per_condition=args.trials, base_seed=args.seed,
                          data_hash=settings["data_hash"], **invocation)
    summary.update({k: v for k, v in extra.items() if k != "conditions"})
    summary.update({k: given[k] for k in u.noted_settings if k in given})
    from articutool.datafile import replace_own

    replace_own(d / "summary.json", json.dumps(summary, indent=1, allow_nan=False) + "\n")
    figure = report.figure(exp, records, summary, cfg, d)
    md = report.section(exp, summary, cfg, figure.name if figure else None)
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        from rich.console import Console
        from rich.markdown import Markdown

        Console(width=None if sys.stdout.isatty() else 150).print(Markdown(md))
        print(f"wrote {d / 'summary.json'}" + (f", {figure}" if figure else ""))
    if summary_run.lost:
        print(f"{len(summary_run.lost)} trial(s) did not finish (worker failure); run the "
              "same command again to resume them", file=sys.stderr)
        for why in sorted({str(e) for _, e in summary_run.lost})[:3]:
            print(f"  {why}", file=sys.stderr)
        return 1
    return 0


def _run_with_progress(trials: list[Any], log: Path, executor: Any, exp: str) -> Any:
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    from articutool.experiments.runner import run_experiment

    con = Console(stderr=True)
    with Progress("[progress.description]{task.description}", BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(), console=con) as bar:
        job = bar.add_task(exp, total=0)
        t0 = time.perf_counter()

        def started(pending: int, skipped: int) -> None:
            bar.update(job, total=pending)
            con.print(f"{exp}: {len(trials)} trials on {executor.description}: {skipped} "
                      f"already in {log}, {pending} to run")

        def finished(rec: dict[str, Any]) -> None:
            bar.update(job, advance=1, description=(
                f"{exp} (last trial {rec['trial']}: {rec['wall_time_s']:.0f} s"
                f"{', ERROR' if rec.get('error') else ''})"))

        try:
            res = run_experiment(trials, log, executor, on_start=started, on_result=finished)
        finally:
            executor.close()
        con.print(f"{exp}: ran {res.ran} trial(s) in {time.perf_counter() - t0:.1f} s")
        if res.log is not None and not res.log.clean:
            con.print(f"warning: {res.log.describe()}; the bad lines were ignored (a torn "
                      "last line cut off): a trial one held ran again", markup=False,
                      highlight=False)
    return res


def _cmd_report(args: argparse.Namespace) -> int:
    from articutool.experiments import report
    from articutool.experiments.config import ExperimentsConfig

    out = Path(args.out)
    if not out.is_dir():
        raise usage(f"--out {out} is not a directory of experiment results")
    for u in registry().values():
        u.check_arguments(args)
    cfg = ExperimentsConfig.load()
    settings = {u.name: u.analysis(args, out, cfg, required=False)
                for u in registry().values()}
    def kept(path: Path, copy: Path) -> None:
        print(f"note: {path} was not as `articutool experiment report` wrote it (edited?): "
              f"kept it as {copy}", file=sys.stderr)

    exp2a = Path(args.exp2a) if args.exp2a is not None else out.parent / "exp2a"
    if args.exp2a is not None and not exp2a.is_dir():
        raise usage(f"--exp2a {exp2a} is not a directory of `bench transport` results")
    checks: list[report.LogCheck] = []
    md, html = report.write_report(out, cfg, settings=settings, on_kept=kept, exp2a=exp2a,
                                   on_log=checks.append)
    print(f"wrote {md} and {html}")
    for c in checks:
        if c.short or not c.log.state.clean:
            print(f"warning: {c.log.state.describe()}", file=sys.stderr)
    short = [s for c in checks for s in c.shortfalls()]
    for s in short:
        print(f"error: {s}", file=sys.stderr)
    if short:
        print("error: the report is over fewer trials than the runs promised (its page says "
              "so); rerun the experiment with the same --trials to add the missing ones",
              file=sys.stderr)
        return 2
    return 0


def add_commands(sub: argparse._SubParsersAction) -> None:
    """Register ``experiment …``."""
    from articutool.bench.executors import MAX_WORKERS

    p0 = sub.add_parser("experiment", help="the thesis' physical experiments in simulation")
    esub = p0.add_subparsers(dest="experiment", required=True, metavar="EXPERIMENT")
    for u in registry().values():
        p = esub.add_parser(u.name, help=u.help)
        p.add_argument("--trials", type=int, default=20,
                       help="trials per condition (default 20, as the thesis)")
        p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                       help=f"local worker processes in [1, {MAX_WORKERS}] (default: CPU "
                            "count)")
        p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                       help="run on a Dask distributed cluster at ADDRESS")
        p.add_argument("--out", metavar="DIR", default=DEFAULT_OUT,
                       help=f"results root (default {DEFAULT_OUT}); rerun to resume")
        p.add_argument("--seed", type=int, default=0,
                       help="base seed (repeat r has seed 1000·S + r)")
        p.add_argument("--json", action="store_true", help="print the summary as JSON")
        p.add_argument("--trial", type=int, default=None, metavar="K",
                       help="replay trial K alone and print its record")
        p.add_argument("--video", metavar="FILE", default=None,
                       help="with --trial: record a video (.mp4 or .gif)")
        p.add_argument("--record", metavar="FILE.mcap", default=None,
                       help="with --trial: record the trial as ROS 2 messages in MCAP (tool "
                            "telemetry and commands, arm joints, food, the feeding tree's "
                            "status); never overwrites")
        u.add_arguments(p)
        p.set_defaults(func=_cmd_run)
    p = esub.add_parser("report", help="one Markdown + HTML page with every experiment")
    p.add_argument("--out", metavar="DIR", default=DEFAULT_OUT,
                   help=f"results root (default {DEFAULT_OUT})")
    for u in registry().values():
        u.add_report_arguments(p)
    p.add_argument("--exp2a", metavar="DIR", default=None,
                   help="the transport planning benchmark's results (bench transport "
                        "--out; default: the exp2a folder beside --out)")
    p.set_defaults(func=_cmd_report)
