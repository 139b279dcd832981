"""``articutool experiment …``: the thesis' physical experiments in the physics world.

* ``experiment capacity|exp1|exp2b|exp2c|exp3 [--trials N] [--workers N] [--scheduler ADDR]
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
import math
import os
import shlex
import sys
import time
from pathlib import Path
from typing import Any

__all__ = ["BOOKKEEPING_FIELDS", "TIMING_FIELDS", "add_commands", "trials_for"]

RUN_EXPERIMENTS = ("capacity", "exp1", "exp2b", "exp2c", "exp3")
DEFAULT_OUT = "results/experiments"
# The most food a load or a threshold may name (g): more than any utensil of the spec holds
# (a soup spoon's capacity is ~15 g), as ``sim --load`` and ``meal --threshold`` bound it.
MAX_LOAD_G = 100.0
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


BITE_EXPERIMENTS = ("exp1", "exp3")


def _usage(msg: str) -> Exception:
    from articutool.cli_support import UsageError

    return UsageError(msg)


def _parse_food_grams(text: str, field: str, most: float) -> dict[str, float]:
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
            raise _usage(f"{field} must be FOOD=GRAMS[,FOOD=GRAMS] with grams in "
                         f"[0, {most:g}]; got {part.strip()!r}")
        out[food.strip()] = g
    return out


def _check_common(args: argparse.Namespace) -> Path:
    from articutool.experiments.design import MAX_TRIALS

    if not 1 <= args.trials <= MAX_TRIALS:
        raise _usage(f"--trials must be in [1, {MAX_TRIALS}] per condition; got {args.trials}")
    from articutool.bench.cli import check_workers

    check_workers(args.workers)
    if args.seed < 0:
        raise _usage(f"--seed must be >= 0; got {args.seed}")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise _usage(f"--out {out} exists and is not a directory")
    if args.video is not None:
        from articutool.cli_support import new_output_file

        if args.trial is None:
            raise _usage("--video needs --trial K (a video of one replayed trial)")
        new_output_file("--video", args.video, (".mp4", ".gif"))
    if args.record is not None:
        from articutool.cli_support import new_output_file

        if args.trial is None:
            raise _usage("--record needs --trial K (a recording of one replayed trial)")
        new_output_file("--record", args.record, (".mcap",))
    return out


def _thresholds(args: argparse.Namespace, out: Path, cfg: Any) -> tuple[dict[str, float] | None,
                                                                         str]:
    """Exp. 2c's thresholds: ``--thresholds-g``, else OUR Exp. 1 Articutool means (the thesis
    took its own Exp. 1 means), else none (only spill / no spill is reported)."""
    from articutool.thresholds import exp1_means

    if getattr(args, "thresholds_g", None):
        th = _parse_food_grams(args.thresholds_g, "--thresholds-g", MAX_LOAD_G)
        other = sorted(set(th) - set(cfg.exp2c.foods))
        if other or not th:
            raise _usage(f"--thresholds-g must give grams for foods of Exp. 2c "
                         f"({', '.join(cfg.exp2c.foods)}); got {args.thresholds_g!r}")
        return th, "--thresholds-g"
    means = exp1_means(out)
    th = {f: means[f] for f in cfg.exp2c.foods if f in means}
    if th:
        return th, f"our Exp. 1 Articutool means ({out / 'exp1' / 'summary.json'})"
    return None, "none: run exp1 first or pass --thresholds-g"


def _check_threshold_g(args: argparse.Namespace) -> None:
    v = getattr(args, "threshold_g", None)
    if v is not None and not 0 <= v <= MAX_LOAD_G:  # also refuses NaN
        raise _usage(f"--threshold-g must be a mass in [0, {MAX_LOAD_G:g}] g; got {v}")


def _exp3_threshold(args: argparse.Namespace, out: Path, cfg: Any) -> float:
    """Exp. 3's threshold: ``--threshold-g``, else our Exp. 1 Articutool mean for its food
    (the rule the thesis used for Exp. 2c; its Exp. 3's 3.0 g came from the bimodal
    distribution of its baseline's bites, §5.3, and the report classifies ours at it too)."""
    from articutool.thresholds import exp1_means

    if getattr(args, "threshold_g", None) is not None:
        return float(args.threshold_g)
    mean = exp1_means(out).get(cfg.exp3.food)
    if mean is None:
        raise _usage(f"--threshold-g: no Exp. 1 result for {cfg.exp3.food} under {out} to "
                     "derive it from; run `articutool experiment exp1` first or pass it")
    return mean


def _exp2c_loads(args: argparse.Namespace, out: Path, cfg: Any) -> tuple[dict[str, float], str]:
    from articutool.thresholds import capacity_means

    if args.load_g:
        loads = _parse_food_grams(args.load_g, "--load-g", MAX_LOAD_G)
        src = "--load-g"
    else:
        loads = capacity_means(out)
        p = out / "capacity" / "summary.json"
        if loads is None:
            raise _usage(f"exp2c needs the capacity load: run `articutool experiment capacity "
                         f"--out {out}` first, or pass --load-g pecans=G,water=G")
        src = f"our capacity means ({p})"
    missing = [f for f in cfg.exp2c.foods if f not in loads or loads[f] <= 0]
    if missing:
        raise _usage(f"--load-g: no load > 0 g for {missing}")
    unknown = sorted(set(loads) - set(cfg.exp2c.foods))
    if unknown:
        raise _usage(f"--load-g: unknown foods {unknown}; Exp. 2c's foods: "
                     f"{', '.join(cfg.exp2c.foods)}")
    _check_loads(loads, cfg, "--load-g" if args.load_g else f"the capacity summary {src}")
    return loads, src


def _check_loads(loads: dict[str, float], cfg: Any, field: str) -> None:
    """Every load within what its food's Exp. 2c utensil can hold (exit 2 naming the range)."""
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.sim.params import PhysicsParams
    from articutool.sim.placement import capacity_bound_reason, utensil_capacity_bound_g
    from articutool.spec import load_spec

    spec, params = load_spec(), PhysicsParams.load()
    lib = StrategyLibrary.load(spec)
    for food, g in loads.items():
        utensil = lib.strategies[cfg.exp2c.strategy[food]].utensil
        most = utensil_capacity_bound_g(spec, params, food, utensil)
        if not g <= most:
            raise _usage(f"{field}: {food} must be in (0, {most:.2f}] g, the most the "
                         f"{utensil} can hold ({capacity_bound_reason(params.food(food))}); "
                         f"got {g:g}")


def _closed_loop_targets(thresholds: dict[str, float], cfg: Any) -> dict[str, float]:
    """Per food with a load-targeting closed-loop primitive, its target from the food's
    meaningful-success threshold (:func:`~articutool.experiments.protocols.
    closed_loop_target_g`): one item's mass (the physics' food model) and the noise of one
    weighing (the F/T sensor's per-sample noise over the primitive's window)."""
    from articutool.experiments.protocols import closed_loop_target_g
    from articutool.sim.params import Liquid, PhysicsParams
    from articutool.spec import load_spec
    from articutool.tool.primitives import get_primitive

    spec, params = load_spec(), PhysicsParams.load()
    out = {}
    for food, shed in cfg.exp2c.closed_loop.items():
        names = get_primitive(shed.primitive).parameter_names
        if "target_load_g" not in names or food not in thresholds:
            continue
        window = shed.params[names.index("window_s")] if "window_s" in names else 0.0
        n = max(1, round(window * spec.ft.rate_hz))
        noise_g = spec.ft.force_noise_n / spec.imu.gravity * 1000.0 / math.sqrt(n)
        fp = params.food(food)
        # One item of a placed load: a load particle of a liquid, a piece otherwise.
        item = fp.load_item_mass if isinstance(fp, Liquid) else fp.piece_mass
        out[food] = round(closed_loop_target_g(thresholds[food], item * 1000.0, noise_g), 3)
    return out


def trials_for(exp: str, args: argparse.Namespace, out: Path, cfg: Any
               ) -> tuple[list[Any], dict[str, Any]]:
    """The trials ``experiment EXP`` runs (``args.trials``, ``args.seed``; for exp2c
    ``args.load_g`` or the capacity summary under ``out``) and the run's conditions with what
    they came from."""
    from articutool.experiments.design import conditions, make_trials

    goals: list[str] = []
    extra: dict[str, Any] = {}
    loads = None
    if exp == "exp2b":
        from articutool.arm.scene import Scene

        sset = Scene.load().staging_set
        if sset is None:
            raise _usage("the scene has no [staging_set] (Exp. 2b's start and goals)")
        goals = [g.name for g in sset.goals]
        extra["goals"] = goals
    targets = None
    if exp == "exp2c":
        loads, src = _exp2c_loads(args, out, cfg)
        th, _ = _thresholds(args, out, cfg)
        if th is None or any(f not in th for f in cfg.exp2c.foods):
            raise _usage("exp2c needs each food's meaningful-success threshold (its "
                         "closed-loop target is derived from it): run `articutool experiment "
                         f"exp1 --out {out}` first, or pass --thresholds-g "
                         + ",".join(f"{f}=G" for f in cfg.exp2c.foods))
        targets = _closed_loop_targets(th, cfg)
        extra.update(load_g=loads, load_source=src, closed_loop_target_g=targets)
    conds = conditions(exp, cfg, goals=goals, load_g=loads, target_g=targets)
    foods = getattr(args, "foods", None)
    if foods:
        wanted = [f.strip() for f in foods.split(",") if f.strip()]
        known = sorted({c.food for c in conds})
        if not wanted or any(f not in known for f in wanted):
            raise _usage(f"--foods must name foods of {exp} ({', '.join(known)}), "
                         f"comma-separated; got {foods!r}")
        conds = [c for c in conds if c.food in wanted]
    physics = getattr(args, "physics", None)
    if physics is not None:
        from articutool.sim.params import PhysicsError, PhysicsParams

        try:
            params = PhysicsParams.load(physics)
        except PhysicsError as err:
            raise _usage(f"--physics: {err}") from None
        missing = sorted({c.food for c in conds} - set(params.foods))
        if missing:
            raise _usage(f"--physics {physics}: no parameters for {missing}")
        conds = [c.model_copy(update={"physics": str(Path(physics).resolve())})
                 for c in conds]
    return make_trials(exp, conds, args.trials, args.seed, goals=goals), {
        "conditions": [c.fields() for c in conds], **extra}


def _machine() -> dict[str, Any]:
    import platform

    return {"host": platform.node(), "platform": platform.platform(),
            "python": platform.python_version(), "cpus": os.cpu_count(),
            "load_avg": [round(x, 2) for x in os.getloadavg()]}


def _replay(args: argparse.Namespace, exp: str, trials: list[Any], out: Path) -> int:
    from articutool.experiments.runner import read_trial_log, run_trial

    spec = next((t for t in trials if t.trial == args.trial), None)
    if spec is None:
        raise _usage(f"--trial must be in [0, {len(trials) - 1}] for --trials {args.trials}; "
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
    out = _check_common(args)
    _check_threshold_g(args)
    try:
        cfg = ExperimentsConfig.load()
    except ExperimentsConfigError as err:
        raise _usage(str(err)) from None
    trials, extra = trials_for(exp, args, out, cfg)
    # Checked before any trial runs; the trials themselves do not depend on it.
    threshold = _exp3_threshold(args, out, cfg) if exp == "exp3" else None
    th, th_src = _thresholds(args, out, cfg) if exp == "exp2c" else (None, "")
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
        raise _usage(str(err)) from None
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
    summary = summarize(exp, records, cfg, thresholds_g=th, threshold_g=threshold)
    summary["run"].update(
        trials_per_condition=args.trials, base_seed=args.seed, executor=executor.description,
        experiment_wall_time_s=round(summary_run.wall_time_s, 1), ran_now=summary_run.ran,
        machine=_machine(), date=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        command="articutool " + " ".join(shlex.quote(a) for a in sys.argv[1:])
        if sys.argv[1:2] == ["experiment"] else f"articutool experiment {exp}",
        data_hash=settings["data_hash"],
        # The machine's run-queue load averages (os.getloadavg: 1, 5, 15 min) as the run
        # began and ended; the run's own workers are part of the second.
        machine_load={"before": [round(x, 2) for x in load_before],
                      "after": [round(x, 2) for x in load_after]})
    if summary_run.ran == 0 and old_summary is not None:  # nothing ran: keep when and how
        for k in ("experiment_wall_time_s", "executor", "machine", "date", "command",
                  "machine_load"):
            if k in old_summary["run"]:
                summary["run"][k] = old_summary["run"][k]
    summary.update({k: v for k, v in extra.items() if k != "conditions"})
    if exp == "exp2c":
        summary["thresholds_source"] = th_src
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
        raise _usage(f"--out {out} is not a directory of experiment results")
    _check_threshold_g(args)
    cfg = ExperimentsConfig.load()
    th, src = _thresholds(args, out, cfg)
    threshold = (_exp3_threshold(args, out, cfg) if (out / "exp3" / "trials.jsonl").exists()
                 else None)
    def kept(path: Path, copy: Path) -> None:
        print(f"note: {path} was not as `articutool experiment report` wrote it (edited?): "
              f"kept it as {copy}", file=sys.stderr)

    exp2a = Path(args.exp2a) if args.exp2a is not None else out.parent / "exp2a"
    if args.exp2a is not None and not exp2a.is_dir():
        raise _usage(f"--exp2a {exp2a} is not a directory of `bench transport` results")
    checks: list[report.LogCheck] = []
    md, html = report.write_report(out, cfg, thresholds_g=th, thresholds_source=src,
                                   threshold_g=threshold, on_kept=kept, exp2a=exp2a,
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
    helps = {"capacity": "maximum-capacity loads (Exp. 2c's load)",
             "exp1": "acquisition, H1 (§5.1)",
             "exp2b": "transport of placed loads to five Staging goals, H2 (§5.2.2)",
             "exp2c": "shedding primitives vs control, H2 (§5.2.3)",
             "exp3": "noodles end to end, H3 (§5.3)"}
    for name in RUN_EXPERIMENTS:
        p = esub.add_parser(name, help=helps[name])
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
        if name in BITE_EXPERIMENTS:
            p.add_argument("--physics", metavar="FILE", default=None,
                           help="another physics parameter file for the bite's world (e.g. the "
                                "thesis' 125 g of noodles: docs/food.md); use its own --out")
        if name != "exp3":
            p.add_argument("--foods", metavar="FOOD,…", default=None,
                           help="run only these foods' conditions (same seeds as a full run; "
                                "use its own --out)")
        if name == "exp2c":
            p.add_argument("--load-g", default=None, metavar="FOOD=G,…",
                           help="the load per food (default: our capacity means)")
            p.add_argument("--thresholds-g", default=None, metavar="FOOD=G,…",
                           help="meaningful-success thresholds (default: our Exp. 1 "
                                "Articutool means)")
        if name == "exp3":
            p.add_argument("--threshold-g", type=float, default=None,
                           help="meaningful-success threshold (default: our Exp. 1 Articutool "
                                "mean for the food, the thesis' rule for Exp. 2c; the thesis' "
                                "Exp. 3 took 3.0 g from its baseline's bimodal bites)")
        p.set_defaults(func=_cmd_run)
    p = esub.add_parser("report", help="one Markdown + HTML page with every experiment")
    p.add_argument("--out", metavar="DIR", default=DEFAULT_OUT,
                   help=f"results root (default {DEFAULT_OUT})")
    p.add_argument("--thresholds-g", default=None, metavar="FOOD=G,…",
                   help="Exp. 2c thresholds (default: our Exp. 1 Articutool means)")
    p.add_argument("--threshold-g", type=float, default=None,
                   help="Exp. 3 threshold (default: our Exp. 1 Articutool mean)")
    p.add_argument("--exp2a", metavar="DIR", default=None,
                   help="the transport planning benchmark's results (bench transport "
                        "--out; default: the exp2a folder beside --out)")
    p.set_defaults(func=_cmd_report)
