"""Exp. 2b's slosh-free Articutool condition alone, on the same seeds and goals as a full run.

Runs the experiment's own trial (:func:`articutool.experiments.units.exp2b.exp2b_trial`)
for the ``articutool_slosh_free`` variant, repeats 0..N-1 (seed ``1000·S + r``, goal ``r``
mod the staging set's goals), and sets each trial beside the same repeat's record in a
committed run (``--against``): to measure a change that touches only this condition without
re-running the other three.

    PYTHONPATH=src .venv/bin/python studies/exp2b_slosh_free.py \\
        --against results/liquid/exp2b/trials.jsonl \\
        --out studies/results/exp2b_slosh_free.json

The JSON is rewritten after every trial; CPU time is the process's.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

SYSTEM = "articutool_slosh_free"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--against", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args(argv)
    if a.out.exists():
        print(f"--out: {a.out} exists; not overwriting", file=sys.stderr)
        return 2
    from articutool.arm.scene import Scene
    from articutool.datafile import replace_own
    from articutool.experiments.config import ExperimentsConfig
    from articutool.experiments.design import trial_seed
    from articutool.experiments.runner import source_version
    from articutool.experiments.units.exp2b import Exp2bCondition, exp2b_trial

    before = {(r["repeat"], r["goal"]): r for r in map(json.loads, a.against.open())
              if r.get("system") == SYSTEM and r.get("food") == "water"}
    goals = [g.name for g in Scene.load().staging_set.goals]
    cfg = ExperimentsConfig.load()
    doc = {"system": SYSTEM, "food": "water", "base_seed": a.seed, "against": str(a.against),
           "source": source_version(), "command": " ".join(["studies/exp2b_slosh_free.py",
                                                            *(argv or sys.argv[1:])]),
           "trials": []}
    a.out.parent.mkdir(parents=True, exist_ok=True)
    for r in range(a.trials):
        goal = goals[r % len(goals)]
        c0 = time.process_time()
        out = exp2b_trial(Exp2bCondition(food="water", system=SYSTEM, goal=goal),
                          trial_seed(a.seed, r), cfg)
        old = before.get((r, goal), {})
        row = {"repeat": r, "goal": goal, "spilled_g": out.spilled_g,
               "spilled_by_place": out.spilled_by_place, "completed": out.completed,
               "motion_time_s": out.motion_time_s, "before_spilled_g": old.get("spilled_g"),
               "before_motion_time_s": old.get("motion_time_s"),
               "before_source": old.get("source"), "cpu_s": round(time.process_time() - c0, 1)}
        print(json.dumps(row), flush=True)
        doc["trials"].append(row)
        replace_own(a.out, json.dumps(doc, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
