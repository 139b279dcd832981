"""Planning speed comparisons, measured here because tests assert no timing: is the
decoupled planner the fastest on the same Exp. 2a tasks (thesis Fig. 6.2), and does RRT* end
within its budget? Wall time on this machine, so a measurement, not a pass/fail; the
behaviour (every task planned, every trial finished) stays in ``tests/test_slow_bench.py``
and ``tests/test_planning.py``.

    .venv/bin/python benchmarks/system_speed.py --out results/system_speed.json
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import platform
import sys
import tempfile
from pathlib import Path

from articutool.bench.taskfile import load_task_set
from articutool.cli import main as articutool
from articutool.planning.api import plan
from articutool.planning.types import PlanRequest


def planners(limit: int, timeout_s: float, workers: int) -> dict:
    """``articutool bench transport`` on the first ``limit`` tasks: each planner's summary,
    and whether decoupled's median planning time is below each strict planner's."""
    with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(io.StringIO()) as out:
        code = articutool(["bench", "transport", "--limit", str(limit), "--timeout",
                           str(timeout_s), "--workers", str(workers), "--out",
                           str(Path(tmp) / "run"), "--json"])
    summary = json.loads(out.getvalue())
    dec = summary["decoupled"]["median_time_s"]
    faster = {s: (None if summary[s]["median_time_s"] is None or dec is None
                  else dec < summary[s]["median_time_s"]) for s in ("strict6", "strict8")}
    return {"exit_code": code, "tasks": limit, "timeout_s": timeout_s, "workers": workers,
            "summary": summary, "decoupled_median_faster_than": faster}


def rrtstar_budget(limit: int, budget_s: float, seed: int) -> dict:
    """RRT* (bounded anytime refinement) on the first ``limit`` tasks: its planning time
    against its budget (tasks whose straight motion is valid need no search)."""
    rows = []
    for task in load_task_set().tasks[:limit]:
        r = plan(PlanRequest("decoupled", task, timeout_s=budget_s, algorithm="rrtstar",
                             seed=seed))
        rows.append({"task_id": task.task_id, "success": r.success,
                     "planning_time_s": r.planning_time_s,
                     "search_s": r.phases.get("search", 0.0)})
    worst = max(r["planning_time_s"] for r in rows)
    return {"budget_s": budget_s, "tasks": rows, "max_planning_time_s": worst,
            "within_budget_plus_1s": worst <= budget_s + 1.0}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=int, default=5, help="first N Exp. 2a tasks")
    ap.add_argument("--timeout", type=float, default=30.0, help="planning budget per task (s)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None, help="write the JSON here too")
    args = ap.parse_args()
    result = {
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "load_avg": os.getloadavg()},
        "systems": planners(args.limit, args.timeout, args.workers),
        "rrtstar": rrtstar_budget(args.limit, 10.0, 3),
    }
    text = json.dumps(result, indent=1)
    print(text)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + "\n")
    return 0 if result["systems"]["exit_code"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
