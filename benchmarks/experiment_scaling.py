"""Speed-up per worker of an experiment's trials on a local process pool and on a Dask
cluster: both executors are kept, so both are measured.

The same trials (``--experiment``, ``--trials`` per condition, base seed 0) run, one
configuration after the other, into a fresh temporary results root each (never the user's
``results/experiments``): the local process pool with each of ``--workers`` processes, then a
``distributed.LocalCluster`` (``n_workers=k``, ``threads_per_worker=1``, ``processes=True``)
with the same counts, reached at its scheduler address as ``articutool experiment
--scheduler ADDR`` reaches a cluster. The trials are built and run by the CLI's own code
(:func:`articutool.experiments.cli.trials_for`, :func:`articutool.bench.cli.make_executor`,
:func:`articutool.experiments.runner.run_experiment`); this script only times them.

Per configuration it records:

- ``wall_clock_s``: wall-clock time (``time.perf_counter``) of the whole invocation: the
  executor's start (the local pool's spawned interpreters; a Dask worker's imports on its
  first trial), every trial, and closing the executor. Starting the Dask cluster is not in
  it (``--scheduler`` connects to a running cluster); it is ``cluster_start_s``;
- ``trial_wall_sum_s``: the sum of the trials' own wall times (their records' ``wall_time_s``);
- ``speedup`` = wall clock of the 1-worker local pool ÷ this wall clock, ``efficiency`` =
  speed-up ÷ workers;
- ``outcomes_equal``: every trial's record equals the 1-worker local run's in every field
  but the timing-dependent and bookkeeping ones the replay check (``experiment EXP --trial
  K``) ignores too (``TIMING_FIELDS``, ``BOOKKEEPING_FIELDS``); ``differing`` names what did
  not, ``timing_fields_moved`` the timing-dependent fields that moved (reported, not failed).

exp2c's load is our capacity mean, as in the CLI: unless ``--load-g`` is given, ``experiment
capacity`` runs first (same ``--trials``, untimed) into the temporary root. The machine's
load average is recorded at the start, per configuration and at the end: the speed-up is
only meaningful on an otherwise idle machine.

    nice .venv/bin/python benchmarks/experiment_scaling.py --experiment exp2c --trials 5
    .venv/bin/python benchmarks/experiment_scaling.py --table
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bench_io import machine, write_json

DEFAULT_JSON = "results/experiment_scaling.json"


def _comparable(rec: dict[str, Any], ignored: frozenset[str]) -> dict[str, str]:
    # Compared as JSON text: a NaN in a record equals itself there.
    return {k: json.dumps(v, sort_keys=True) for k, v in rec.items() if k not in ignored}


def compare(reference: Sequence[dict[str, Any]], records: Sequence[dict[str, Any]]
            ) -> dict[str, Any]:
    """Whether ``records`` reproduce ``reference`` trial by trial (see module doc)."""
    from articutool.experiments.cli import BOOKKEEPING_FIELDS, TIMING_FIELDS

    ref = {r["trial"]: r for r in reference}
    got = {r["trial"]: r for r in records}
    differing: dict[str, list[str]] = {}
    moved: dict[str, list[str]] = {}
    for k in sorted(ref.keys() | got.keys()):
        if k not in ref or k not in got:
            differing[str(k)] = ["missing"]
            continue
        a = _comparable(ref[k], TIMING_FIELDS | BOOKKEEPING_FIELDS)
        b = _comparable(got[k], TIMING_FIELDS | BOOKKEEPING_FIELDS)
        diff = sorted(f for f in a.keys() | b.keys() if a.get(f) != b.get(f))
        if diff:
            differing[str(k)] = diff
        t = sorted(f for f in TIMING_FIELDS if ref[k].get(f) != got[k].get(f))
        if t:
            moved[str(k)] = t
    return {"outcomes_equal": not differing, "differing": differing,
            "timing_fields_moved": moved}


def _capacity_first(trials: int, workers: int, root: Path) -> dict[str, Any]:
    """exp2c's load as the CLI takes it: ``experiment capacity`` under ``root``."""
    from articutool.cli import main as cli_main

    argv = ["experiment", "capacity", "--trials", str(trials), "--workers", str(workers),
            "--out", str(root)]
    t0 = time.perf_counter()
    if cli_main(argv) != 0:
        raise RuntimeError(f"articutool {' '.join(argv)} failed")
    return {"command": "articutool " + " ".join(argv),
            "wall_clock_s": round(time.perf_counter() - t0, 2)}


def _one(experiment: str, specs: list[Any], kind: str, workers: int, root: Path
         ) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """Run ``specs`` on one configuration into a fresh ``root``; its row and log lines."""
    from articutool.bench.cli import make_executor
    from articutool.experiments.runner import log_path, run_experiment

    row: dict[str, Any] = {"kind": kind, "workers": workers,
                           "loadavg_start": [round(x, 2) for x in os.getloadavg()]}
    cluster = None
    if kind == "dask":
        from distributed import LocalCluster

        t0 = time.perf_counter()
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None)
        row["cluster_start_s"] = round(time.perf_counter() - t0, 2)
    try:
        ns = argparse.Namespace(scheduler=cluster.scheduler_address if cluster else None,
                                workers=workers)
        t0 = time.perf_counter()
        executor = make_executor(ns)
        try:
            res = run_experiment(specs, log_path(root, experiment), executor)
        finally:
            executor.close()
        wall = time.perf_counter() - t0
    finally:
        if cluster is not None:
            cluster.close()
    if res.interrupted:
        raise KeyboardInterrupt
    desc = executor.description + (f" (LocalCluster, {workers} worker process"
                                   f"{'es' * (workers > 1)})" if cluster else "")
    row.update(executor=desc, trials=len(res.records), ran=res.ran,
               lost=len(res.lost), errors=sum(1 for r in res.records if r.error),
               wall_clock_s=round(wall, 2),
               trial_wall_sum_s=round(sum(r.wall_time_s for r in res.records), 2))
    return row, [r.to_log() for r in res.records]


def measure(experiment: str, trials: int, workers: Sequence[int], *, root: Path,
            load_g: str | None = None, seed: int = 0) -> dict[str, Any]:
    """The whole measurement (see module doc) with results roots under ``root``."""
    from articutool.experiments.cli import trials_for
    from articutool.experiments.config import ExperimentsConfig

    doc: dict[str, Any] = {"machine": machine(), "experiment": experiment,
                           "trials_per_condition": trials, "seed": seed,
                           "timing": "wall clock (time.perf_counter)", "rows": []}
    load_root = root / "load"
    if experiment == "exp2c" and not load_g:
        doc["load_run"] = _capacity_first(trials, max(workers), load_root)
    # Exp. 2c's closed-loop target comes from the thresholds: the committed Exp. 1 means.
    from articutool.thresholds import DEFAULT_OUT, exp1_means

    cfg = ExperimentsConfig.load()
    means = {f: g for f, g in exp1_means(DEFAULT_OUT).items() if f in cfg.exp2c.foods}
    ns = argparse.Namespace(trials=trials, seed=seed, load_g=load_g,
                            thresholds_g=",".join(f"{f}={g}" for f, g in means.items()) or None)
    specs, extra = trials_for(experiment, ns, load_root, cfg)
    doc["conditions"] = extra["conditions"]
    if "load_source" in extra:  # the capacity summary it names was in the temporary root
        doc["load_g"] = extra["load_g"]
        doc["load_source"] = "load_run's capacity means" if load_g is None else "--load-g"
    reference: list[dict[str, Any]] = []
    base_wall = None
    for kind in ("local", "dask"):
        for k in workers:
            row, records = _one(experiment, specs, kind, k, root / f"{kind}-{k}")
            if kind == "local" and k == 1:
                reference, base_wall = records, row["wall_clock_s"]
            row["speedup"] = round(base_wall / row["wall_clock_s"], 3)
            row["efficiency"] = round(row["speedup"] / k, 3)
            row.update(compare(reference, records))
            doc["rows"].append(row)
            print(f"{row['executor']}: {row['trials']} trials, {row['wall_clock_s']} s wall "
                  f"clock, speed-up {row['speedup']}, outcomes equal: "
                  f"{row['outcomes_equal']}", flush=True)
    doc["machine"]["loadavg_end"] = os.getloadavg()
    return doc


def table(doc: dict[str, Any]) -> str:
    """The measurement as a Markdown table."""
    lines = [f"{doc['experiment']}, {doc['trials_per_condition']} trial(s) per condition; "
             f"load average at the start {doc['machine']['loadavg_start'][0]:.2f}",
             "",
             "| executor | workers | trials | wall clock (s) | sum of trial walls (s) | "
             "speed-up | efficiency | outcomes = 1 local worker |",
             "|---|---|---|---|---|---|---|---|"]
    for r in doc["rows"]:
        kind = "Dask LocalCluster" if r["kind"] == "dask" else "local process pool"
        lines.append(f"| {kind} | {r['workers']} | {r['trials']} | {r['wall_clock_s']:.1f} | "
                     f"{r['trial_wall_sum_s']:.1f} | {r['speedup']:.2f} | "
                     f"{r['efficiency']:.2f} | {'yes' if r['outcomes_equal'] else 'NO'} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    from articutool.cli_support import UsageError
    from articutool.experiments.design import MAX_TRIALS
    from articutool.experiments.unit import names

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--experiment", default="exp2c", choices=names())
    ap.add_argument("--trials", type=int, default=5, help="trials per condition (default 5)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2],
                    help="worker counts, each run locally and on Dask (default: 1 2)")
    ap.add_argument("--load-g", default=None, metavar="FOOD=G,…",
                    help="exp2c's load (default: run `experiment capacity` first)")
    ap.add_argument("--out-json", default=DEFAULT_JSON, help=f"default {DEFAULT_JSON}")
    ap.add_argument("--table", action="store_true",
                    help="print the Markdown table of --out-json and exit")
    args = ap.parse_args(argv)
    if args.table:
        try:
            print(table(json.loads(Path(args.out_json).read_text(encoding="utf-8"))))
        except (OSError, ValueError, KeyError) as err:
            ap.error(f"--out-json {args.out_json} is not this benchmark's JSON: {err}")
        return 0
    if not 1 <= args.trials <= MAX_TRIALS:
        ap.error(f"--trials must be in [1, {MAX_TRIALS}]; got {args.trials}")
    if 1 not in args.workers or min(args.workers) < 1:
        ap.error(f"--workers must be counts >= 1 including 1 (the speed-up's base); got "
                 f"{args.workers}")
    if args.load_g and args.experiment != "exp2c":
        ap.error(f"--load-g is exp2c's load; --experiment is {args.experiment}")
    workers = sorted(set(args.workers))
    with tempfile.TemporaryDirectory(prefix="experiment-scaling-") as tmp:
        try:
            doc = measure(args.experiment, args.trials, workers, root=Path(tmp),
                          load_g=args.load_g)
        except UsageError as err:  # e.g. a malformed --load-g
            ap.error(str(err))
        except KeyboardInterrupt:
            print("interrupted: nothing written", file=sys.stderr)
            return 130
    write_json(args.out_json, doc)
    print(table(doc))
    return 0


if __name__ == "__main__":
    sys.exit(main())
