"""Two copies of the source side by side on the feeding tree's costs: a pecan bite of the
Articutool (``meal.bites.make_bite_world`` + ``run_bite``, seed by seed, each in a fresh
process, the copies interleaved so the machine's load falls on both alike).

Per bite: the tree's tick (thread CPU of ``BehaviourTree.tick`` up to its post-tick handler,
which steps the world: the behaviours, the guard and the visitors), the plans (the planning
jobs' own wall time, ``planning_wall_s``), the world's real-time factor (simulated s ÷ thread
CPU s of its stepping) and the whole bite's process CPU; and the bite's outcome, which must be
the same for both copies (a restructuring changes no physics).

    git archive <rev> src | tar -x -C /tmp/old
    .venv/bin/python benchmarks/code_speed.py --code before=/tmp/old/src --code after=src \\
        --seeds 3 --out results/code_speed.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

from bench_io import machine, write_json

OUTCOME = ("acquired_g", "delivered_g", "spilled_g", "sim_time_s", "motion_time_s",
           "transport_max_tilt_deg", "end_state")


def one(seed: int) -> dict:
    """One bite in this process (see module doc)."""
    import py_trees

    from articutool.meal.bites import make_bite_world, run_bite

    ticks: list[float] = []
    plain = py_trees.trees.BehaviourTree.tick

    def timed(self, pre_tick_handler=None, post_tick_handler=None):
        t0 = time.thread_time()

        def post(tree):
            ticks.append(time.thread_time() - t0)
            if post_tick_handler is not None:
                post_tick_handler(tree)

        return plain(self, pre_tick_handler, post)

    py_trees.trees.BehaviourTree.tick = timed
    c0 = time.process_time()
    setup = make_bite_world("pecans", "articutool", seed)
    r = run_bite(setup, threshold_g=0.5)
    cpu = time.process_time() - c0
    rec = r.to_dict() if hasattr(r, "to_dict") else dict(vars(r))
    return {"seed": seed, "ticks": len(ticks),
            "tick_ms_median": round(1e3 * statistics.median(ticks), 4),
            "tick_ms_mean": round(1e3 * statistics.fmean(ticks), 4),
            "planning_wall_s": round(rec["planning_wall_s"], 4),
            "realtime_factor": round(setup.world.realtime_factor, 4),
            "bite_cpu_s": round(cpu, 2),
            "outcome": {k: rec[k] for k in OUTCOME}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--code", action="append", required=True, metavar="NAME=SRC")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--out", default="results/code_speed.json")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one is not None:
        print(json.dumps(one(args.one)))
        return 0
    codes = dict(c.split("=", 1) for c in args.code)
    info = machine()
    rows: dict[str, list[dict]] = {n: [] for n in codes}
    here = Path(__file__).resolve()
    for seed in range(args.seeds):
        for name, src in codes.items():
            env = {"PYTHONPATH": f"{Path(src).resolve()}:{here.parent}", "MUJOCO_GL": "egl",
                   "PATH": "/usr/bin:/bin"}
            p = subprocess.run([sys.executable, str(here), "--code", "x=y", "--one", str(seed)],
                               capture_output=True, text=True, env=env, timeout=1800,
                               cwd=here.parents[1])
            if p.returncode != 0:
                raise SystemExit(f"{name} seed {seed}: {p.stderr[-2000:]}")
            rows[name].append(json.loads(p.stdout.strip().splitlines()[-1]))
            print(name, rows[name][-1], flush=True)
    names = list(codes)
    summary = {n: {k: round(statistics.median(r[k] for r in rows[n]), 4)
                   for k in ("tick_ms_median", "planning_wall_s", "realtime_factor",
                             "bite_cpu_s")} for n in names}
    if len(names) == 2:
        a, b = names
        summary["ratio_" + b + "_over_" + a] = {
            k: round(summary[b][k] / summary[a][k], 3) for k in summary[a]}
        summary["same_outcomes"] = all(x["outcome"] == y["outcome"]
                                       for x, y in zip(rows[a], rows[b], strict=True))
    write_json(args.out, {"machine": info, "codes": codes, "bites": rows,
                          "summary": summary})
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
