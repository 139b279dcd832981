"""Where planning time goes: per-phase wall time of each transport planner over a task set.

Plans every (planner, task) of the packaged Exp. 2a task set (or ``--tasks FILE``) in this one
process, one after the other, and prints JSON: per planner the success count, the median and
p90 of the whole ``plan()`` call over solved tasks (wall time, and the process's CPU time),
and for each phase of
:data:`articutool.planning.api.PHASES` (setup, search, simplify, timing, recheck, verify) its
median, p90 and share of the summed planning time. The planners run interleaved task by task,
so their ratios are measured side by side under the same load.

    .venv/bin/python benchmarks/plan_breakdown.py --limit 20 --timeout 10 [--out FILE]

``--baseline`` also plans each (planner, task) right after with the baseline planner settings
(OMPL's automatic range in rejection mode, no direct motion, full smoothing, the pair
loop, models rebuilt per plan, toppra grid 0.01 rad) and reports paired median ratios (new /
baseline) of planning time and trajectory duration on the tasks both solved.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from articutool.planning.types import PHASES, PLANNERS, PlanRequest, TransportTask

if TYPE_CHECKING:
    from articutool.planning.ompl_planner import PlannerSettings

def baseline_settings() -> PlannerSettings:
    """The baseline planner settings, OMPL's and toppra's defaults (toppra's constraint objects
    and the decoupled check's buffer are reused regardless; they measured < 1 ms per plan)."""
    from articutool.planning.ompl_planner import PlannerSettings

    return PlannerSettings(range_everywhere=False, try_direct=False, simplify="full",
                           broadphase=False, cache_models=False, toppra_grid=0.01)


def _stats(x: list[float]) -> dict[str, float | None]:
    import numpy as np

    if not x:
        return {"median_ms": None, "p90_ms": None}
    a = np.asarray(x) * 1e3
    return {"median_ms": round(float(np.median(a)), 3),
            "p90_ms": round(float(np.percentile(a, 90)), 3)}


def emit(doc: dict, path: str | None) -> None:
    """Print ``doc`` as JSON and, with a ``path``, write it there too."""
    text = json.dumps(doc, indent=1)
    print(text)
    if path:
        Path(path).write_text(text + "\n")


def selected_tasks(path: str | None, limit: int | None, timeout: float, systems: list[str],
                   option: str) -> tuple[list[TransportTask], str | None]:
    """The tasks ``--tasks``/``--limit`` select, or the message naming the bad option (with
    ``--timeout``, which must be > 0, and the systems named by ``option``)."""
    for s in systems:
        if s not in PLANNERS:
            return [], f"{option}: unknown system {s!r}; allowed: {', '.join(PLANNERS)}"
    if limit is not None and limit < 1:
        return [], f"--limit must be >= 1; got {limit}"
    if not timeout > 0:
        return [], f"--timeout must be > 0 s; got {timeout}"
    from articutool.bench.taskfile import TaskFileError, load_task_set

    try:
        return list(load_task_set(path).tasks[:limit]), None
    except TaskFileError as err:
        return [], f"--tasks: {err}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tasks", metavar="FILE", default=None, help="task file (default: packaged)")
    ap.add_argument("--systems", default=",".join(PLANNERS))
    ap.add_argument("--limit", type=int, default=None, help="only the first N tasks")
    ap.add_argument("--timeout", type=float, default=10.0, help="per plan, s (default 10)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", metavar="FILE", default=None, help="also write the JSON here")
    ap.add_argument("--baseline", action="store_true",
                    help="also plan with the baseline settings, side by side")
    args = ap.parse_args(argv)
    planners = [s.strip() for s in args.systems.split(",") if s.strip()]
    tasks, bad = selected_tasks(args.tasks, args.limit, args.timeout, planners, "--systems")
    if bad:
        print(bad, file=sys.stderr)
        return 2
    import numpy as np  # the planner and the statistics: once the options are good

    from articutool.planning.ompl_planner import plan_transport
    from articutool.spec import load_spec

    spec = load_spec()
    baseline = baseline_settings()
    runs: dict[str, list[dict]] = {s: [] for s in planners}
    baseline_runs: dict[str, list[dict]] = {s: [] for s in planners}
    t_start = time.perf_counter()
    load_before = os.getloadavg()

    def record(req: PlanRequest, settings: PlannerSettings | None) -> dict:
        c0 = time.process_time()
        r = plan_transport(req, spec, settings=settings)
        cpu = time.process_time() - c0
        dur = float(r.trajectory.times[-1]) if r.trajectory is not None else None
        return {"task_id": req.task.task_id, "success": r.success, "time_s": r.planning_time_s,
                "cpu_s": cpu, "attempts": r.attempts, "duration_s": dur, "phases_s": dict(r.phases)}

    for task in tasks:
        for s in planners:
            req = PlanRequest(s, task, timeout_s=args.timeout, seed=args.seed)
            runs[s].append(record(req, None))
            if args.baseline:
                baseline_runs[s].append(record(req, baseline))
    out: dict = {"tasks": len(tasks), "timeout_s": args.timeout, "seed": args.seed,
                 "wall_s": round(time.perf_counter() - t_start, 2),
                 "load_avg_before_after": [round(load_before[0], 2),
                                           round(os.getloadavg()[0], 2)],
                 "systems": {}}
    for s, rs in runs.items():
        ok = [r for r in rs if r["success"]]
        total = sum(r["time_s"] for r in ok) or float("nan")
        phases = {}
        for p in PHASES:
            v = [r["phases_s"].get(p, 0.0) for r in ok]
            phases[p] = {**_stats(v), "share": round(sum(v) / total, 3)}
        glue = [r["time_s"] - sum(r["phases_s"].values()) for r in ok]
        phases["other"] = {**_stats(glue), "share": round(sum(glue) / total, 3)}
        cpu = _stats([r["cpu_s"] for r in ok])
        out["systems"][s] = {"solved": len(ok), "of": len(rs), **_stats([r["time_s"] for r in ok]),
                             "cpu_median_ms": cpu["median_ms"], "cpu_p90_ms": cpu["p90_ms"],
                             "mean_attempts": round(float(np.mean([r["attempts"] for r in rs])), 2),
                             "phases": phases,
                             "failed_tasks": [r["task_id"] for r in rs if not r["success"]]}
    base = out["systems"].get("decoupled", {}).get("median_ms")
    if base:
        out["median_ratio_to_decoupled"] = {
            s: round(v["median_ms"] / base, 2) for s, v in out["systems"].items()
            if v["median_ms"] is not None}
    if args.baseline:
        out["baseline"] = {}
        for s in planners:
            pairs = [(n, b) for n, b in zip(runs[s], baseline_runs[s], strict=True)
                     if n["success"] and b["success"]]
            ok = [b["time_s"] for b in baseline_runs[s] if b["success"]]

            def ratio(key: str, pairs: list = pairs) -> float | None:
                v = [n[key] / b[key] for n, b in pairs]
                return round(float(np.median(v)), 3) if v else None

            out["baseline"][s] = {"solved": len(ok), "of": len(baseline_runs[s]), **_stats(ok),
                                  "paired_time_ratio": ratio("time_s"),
                                  "paired_duration_ratio": ratio("duration_s")}
    emit(out, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
