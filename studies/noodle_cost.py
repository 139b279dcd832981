"""What the noodle world costs, and where: the scripted twirl (``sim/scenes.py: skewer``) in a
bowl of ``--fill-g`` grams, with the CPU time (of this process) and MuJoCo's sleeping state
recorded every half simulated second: how many strands are awake, the awake degrees of
freedom, contacts. The real-time factor is simulated s ÷ CPU s.

MuJoCo puts islands to sleep (trees joined by contacts or constraints), not single trees: a
nest whose strands touch is one island, so it sleeps whole while nothing touches it and wakes
whole when the fork does. The record shows how much of each phase the nest is awake.

    nice .venv/bin/python studies/noodle_cost.py --fill-g 20 \
        --out studies/results/noodle_cost_20g.json

``--settle-s S --cpu-budget-s B`` instead runs the freshly laid bowl (no settle, the tool off)
for S simulated seconds or B CPU seconds of this thread, whichever ends first, recording every
0.02 simulated s the thread's CPU, contacts, constraint rows, awake degrees of freedom and
MuJoCo's arena high-water mark, the JSON rewritten each time: the cost of a nest as it falls
and heaps, the whole nest awake, measurable at the thesis' 125 g within a budget.

    PYTHONPATH=src nice .venv/bin/python studies/noodle_cost.py --fill-g 125 --settle-s 0.6 \
        --cpu-budget-s 900 --out studies/results/noodle_settle_125g.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from articutool.sim.accounting import UTENSIL
from articutool.sim.build import WorldConfig, build_parts
from articutool.sim.params import PhysicsParams
from articutool.sim.scenes import skewer
from articutool.sim.world import FeedingWorld
from noodle_twirl import warnings_of


def nest_params(fill_g: float) -> PhysicsParams:
    """The packaged physics with a noodle bowl of ``fill_g`` grams."""
    d = PhysicsParams.load().model_dump()
    d["foods"]["noodles"]["fill_g"] = fill_g
    return PhysicsParams.from_dict(d)


def measure(fill_g: float, seed: int, turns: float | None) -> dict[str, Any]:
    """One scripted acquisition in a bowl of ``fill_g``; its cost, phase by phase."""
    params = nest_params(fill_g)
    c0 = time.process_time()
    w = FeedingWorld.make("noodles", seed=seed, params=params)
    built = time.process_time() - c0
    m = w.model
    trees = np.array([m.body_treeid[m.body(f"{s}/0").id] for s in w.layout.food_strands])
    samples: list[dict[str, Any]] = []
    phases: dict[str, dict[str, Any]] = {}

    def sample(world: FeedingWorld) -> None:
        if round(world.time / world.dt) % 25:
            return
        dd = world.data
        samples.append({"t": round(world.time, 2), "cpu_s": round(time.process_time() - c0, 2),
                        "strands_awake": int(np.sum(dd.tree_asleep[trees] < 0)),
                        "dofs_awake": int(dd.nv_awake), "contacts": int(dd.ncon)})

    def phase(name: str) -> None:
        phases[name] = {"t": round(w.time, 2), "cpu_s": round(time.process_time() - c0, 1),
                        "strands_on_fork": int(np.sum(w.ledger.item_classes() == UTENSIL))}

    w.on_tick.append(sample)
    t_start, c_start = w.time, time.process_time()
    skewer(w, level=True, twirl_turns=turns, on_phase=phase)
    cpu = time.process_time() - c_start
    awake = [s for s in samples if s["strands_awake"]]
    return {"fill_g": fill_g, "seed": seed, "strands": len(w.layout.food_strands),
            "segments": w.layout.strand_segments, "bodies": int(m.nbody), "dofs": int(m.nv),
            "build_and_settle_cpu_s": round(built, 1),
            "script_sim_s": round(w.time - t_start, 2), "script_cpu_s": round(cpu, 1),
            "realtime_factor": round((w.time - t_start) / cpu, 4),
            "awake_share_of_time": round(len(awake) / max(len(samples), 1), 3),
            "lifted_g": round(w.ledger.masses_g()["utensil"], 2), "phases": phases,
            "warnings": {n: int(w.data.warning[int(x)].number)
                         for n, x in mujoco.mjtWarning.__members__.items()
                         if w.data.warning[int(x)].number},
            "loadavg": os.getloadavg(), "samples": samples}


def awake_cost(fill_g: float, seed: int, seconds: float) -> dict[str, Any]:
    """The bowl of ``fill_g`` built and settled, then ``seconds`` with sleeping off (the whole
    nest awake, as while the fork stirs it): CPU per simulated second."""
    c0 = time.process_time()
    w = FeedingWorld.make("noodles", seed=seed, params=nest_params(fill_g))
    built = time.process_time() - c0
    w.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)
    c1 = time.process_time()
    w.run(seconds)
    cpu = time.process_time() - c1
    return {"fill_g": fill_g, "seed": seed, "strands": len(w.layout.food_strands),
            "bodies": int(w.model.nbody), "dofs": int(w.model.nv),
            "build_and_settle_cpu_s": round(built, 1), "awake_sim_s": seconds,
            "awake_cpu_s": round(cpu, 1), "awake_realtime_factor": round(seconds / cpu, 4),
            "contacts": int(w.data.ncon), "loadavg": os.getloadavg()}


def settle_trace(fill_g: float, seed: int, seconds: float, cpu_budget_s: float,
                 write: Callable[[dict[str, Any]], None]) -> dict[str, Any]:
    """The bowl of ``fill_g`` laid and left to fall for ``seconds`` (tool off) or until
    ``cpu_budget_s`` of this thread's CPU; ``write`` gets the record after each 0.02 s."""
    c0 = time.thread_time()
    w = FeedingWorld(build_parts(WorldConfig("noodles", seed=seed,
                                                 params=nest_params(fill_g))))
    m = w.model
    rec: dict[str, Any] = {
        "fill_g": fill_g, "seed": seed, "strands": len(w.layout.food_strands),
        "segments": w.layout.strand_segments, "bodies": int(m.nbody), "dofs": int(m.nv),
        "arena_mb": round(m.narena / 2**20), "build_cpu_s": round(time.thread_time() - c0, 1),
        "samples": []}
    t0, c1 = w.time, time.thread_time()
    while w.time - t0 < seconds - 1e-9 and time.thread_time() - c1 < cpu_budget_s:
        w.run(0.02, tick=False)
        dd, cpu = w.data, time.thread_time() - c1
        rec["samples"].append({"t": round(w.time - t0, 3), "cpu_s": round(cpu, 1),
                               "contacts": int(dd.ncon), "rows": int(dd.nefc),
                               "dofs_awake": int(dd.nv_awake),
                               "arena_used_mb": round(dd.maxuse_arena / 2**20, 1)})
        rec.update(sim_s=round(w.time - t0, 3), cpu_s=round(cpu, 1),
                   realtime_factor=round((w.time - t0) / cpu, 5),
                   arena_max_used_mb=round(dd.maxuse_arena / 2**20, 1),
                   warnings=warnings_of(dd),
                   loadavg=os.getloadavg())
        write(rec)
    return rec


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fill-g", type=float, default=20.0)
    ap.add_argument("--seed", type=int, default=6000)
    ap.add_argument("--turns", type=float, default=None)
    ap.add_argument("--out", default=None)
    ap.add_argument("--awake-s", type=float, default=None,
                    help="instead of the script: this many seconds with the nest kept awake")
    ap.add_argument("--settle-s", type=float, default=None,
                    help="instead of the script: the laid bowl falling for this many seconds")
    ap.add_argument("--cpu-budget-s", type=float, default=600.0,
                    help="with --settle-s: stop after this much CPU (default 600 s)")
    args = ap.parse_args(argv)
    if not 0 < args.fill_g <= 250:
        ap.error(f"--fill-g must be in (0, 250] g; got {args.fill_g}")
    if args.settle_s is not None and not (0 < args.settle_s <= 10 and args.cpu_budget_s > 0):
        ap.error("--settle-s must be in (0, 10] s and --cpu-budget-s > 0")

    def write(rec: dict[str, Any]) -> None:
        if args.out:
            text = json.dumps({"command": "studies/noodle_cost.py " + " ".join(
                sys.argv[1:] if argv is None else argv), "mujoco": mujoco.__version__, **rec},
                indent=1)
            Path(args.out).parent.mkdir(parents=True, exist_ok=True)
            Path(args.out).write_text(text + "\n")

    if args.settle_s is not None:
        rec = settle_trace(args.fill_g, args.seed, args.settle_s, args.cpu_budget_s, write)
    elif args.awake_s is None:
        rec = measure(args.fill_g, args.seed, args.turns)
    else:
        rec = awake_cost(args.fill_g, args.seed, args.awake_s)
    write(rec)
    print(json.dumps({k: v for k, v in rec.items() if k != "samples"}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
