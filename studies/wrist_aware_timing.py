"""How many verifier rejections and replans wrist-aware timing removes.

The decoupled planner times its path with toppra under the Jaco's limits; with
``wrist_aware_timing`` it also bounds the path speed so the wrist's required velocity (linear
in the path speed, Eq. 4.7) stays within the wrist's limit. The verifier stays an independent
check. This script plans the benchmark tasks both ways, for the spec's wrist speed and for
slower wrists (a heavier utensil or a sagging supply), and counts rejections and attempts.

    .venv/bin/python studies/wrist_aware_timing.py --out studies/results/wrist_aware_timing.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
import tomllib
from pathlib import Path

from articutool.bench.taskfile import load_task_set
from articutool.planning.api import plan
from articutool.planning.types import PlanRequest
from articutool.spec import default_spec_path, parse_spec


def spec_with_wrist_speed(vmax: float | None):
    """The packaged spec, optionally with both wrist joints limited to ``vmax`` rad/s."""
    raw = tomllib.loads(default_spec_path().read_text())
    if vmax is not None:
        raw["wrist"]["max_velocity"] = [vmax, vmax]
    return parse_spec(raw)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=int, default=40, help="first N benchmark tasks")
    ap.add_argument("--timeout", type=float, default=20.0)
    ap.add_argument("--speeds", default="spec,0.5,0.25",
                    help="wrist speed limits (rad/s) to test; 'spec' = the spec's value")
    ap.add_argument("--out", type=Path, default=None, help="write the JSON here too")
    args = ap.parse_args()
    tasks = load_task_set().tasks[: args.limit]
    summary: dict[str, dict] = {}
    for speed in args.speeds.split(","):
        vmax = None if speed == "spec" else float(speed)
        spec = spec_with_wrist_speed(vmax)
        label = f"{spec.wrist.max_velocity[0]:g} rad/s"
        for aware in (False, True):
            rows = []
            for task in tasks:
                t0 = time.perf_counter()
                r = plan(PlanRequest(planner="decoupled", task=task, timeout_s=args.timeout,
                                     wrist_aware_timing=aware), spec)
                rows.append((r.success, r.attempts, r.verification_rejections,
                             time.perf_counter() - t0,
                             r.trajectory.duration if r.trajectory is not None else None))
            solved = [r for r in rows if r[0]]
            key = f"{label}, {'wrist-aware' if aware else 'plain'} timing"
            summary[key] = {
                "tasks": len(rows),
                "solved": len(solved),
                "verification_rejections": sum(r[2] for r in rows),
                "replans": sum(max(0, r[1] - 1) for r in rows),
                "trials_with_rejection": sum(1 for r in rows if r[2] > 0),
                "median_time_s": statistics.median(r[3] for r in solved) if solved else None,
                "median_duration_s": (statistics.median(r[4] for r in solved)
                                      if solved else None),
            }
            print(f"{key:38s} " + json.dumps(summary[key]), file=sys.stderr)
    out = {"timeout_s": args.timeout, "tasks": len(tasks), "results": summary}
    text = json.dumps(out, indent=1)
    print(text)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
