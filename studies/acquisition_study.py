"""Acquisition that uses the wrist: one acquisition through the real feeding tree in
the physics world (the meal path up to Resting: above, acquire, shed, resting), per food ×
system × seed, and the parameter search that chose the strategies' sweep values.

Seeds: the committed experiments use base seed 0 (seeds 0–999, ``experiments/design.py``);
the search uses tuning seeds 7 000 000 + k, the measurement 8 000 000 + k — disjoint from
both and from each other.

``measure``: acquired mass (on the utensil after ``acquire``), mass at Resting, end state,
the wrist's largest tracking error in a wrist-made path (from the tool's measured joints vs
its reference), the arm's (ground truth vs its servo reference), real-time factor; summary
per food × system (mean ± SD, 95 % CI) and Welch's p between the systems.

``search``: the same candidates for both systems, applied to each system's own strategy's
insertion (water, pecans: sweep_to_deg × offset_m; noodles: offset_m × depth_m of the skewer),
on the same tuning seeds; per food and system the candidate with the highest mean acquired
mass; a tie goes to the higher mean at Resting, then to the system's shipped insertion, then to
the first in the grid. Runs go seed by seed (every candidate and system on one seed before the
next; the baseline's, the cheaper, first; the grid from its end, so a noodle search reaches the
nest's centre, where a twirl wakes every strand, last), and the JSON is rewritten after every
run, so an interrupted search keeps what finished; ``--resume`` keeps the runs already in
``--out`` and runs the rest. ``--workers N`` runs N at once, each in its own process, in that
order of starting; each run is its own seeded world, so the runs do not depend on it.

Run (one process, niced): ``PYTHONPATH=src nice python studies/acquisition_study.py
measure --foods water --seeds 10 --out studies/results/acquisition_study_water.json``
(pecans: ``--foods pecans --out studies/results/acquisition_study_pecans.json``) and
``... search --foods water --seeds 3 --out studies/results/strategy_search.json`` (pecans:
``studies/results/strategy_search_pecans.json``; noodles: ``--foods noodles --seeds 3
--workers 2 --out studies/results/strategy_search_noodles.json``).
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from articutool.experiments.stats import describe, welch
from articutool.feeding.behaviours import Execute
from articutool.feeding.strategies import Strategy
from articutool.meal.bites import DEFAULT_SETTINGS, _tree, make_bite_world, run_bite

STAGES_TO_RESTING = ("above", "acquire", "shed", "resting")
SYSTEMS = ("articutool", "baseline")
TUNING_SEED0, MEASURE_SEED0 = 7_000_000, 8_000_000
# The search's candidates per food, the same for both systems. Sweeps (water, pecans): where
# the turn in the food ends (the handle must clear the bowl's rim behind) × where along the
# heading the sweep is centred. The noodle skewer: where along the heading the fork goes in
# (the nest's centre, or towards the bowl's front) × how high above the floor its tip stops.
_SWEEP = [{"sweep_to_deg": a, "offset_m": o} for a, o in itertools.product(
    (15.0, 25.0), (0.01, 0.03))]
CANDIDATES: dict[str, list[dict[str, float]]] = {
    "water": _SWEEP, "pecans": _SWEEP,
    "noodles": [{"offset_m": o, "depth_m": d} for o, d in itertools.product(
        (0.0, 0.025), (0.002, 0.006))]}


def one(food: str, system: str, seed: int, insertion: dict[str, float] | None = None,
        stages: dict[str, dict[str, Any]] | None = None) -> dict[str, Any]:
    """One acquisition through the tree up to Resting; its record. ``insertion`` and
    ``stages`` (a stage's name to its ``primitive`` and ``params``) replace those fields of
    the system's own strategy."""
    setup = make_bite_world(food, system, seed)
    s: Strategy = setup.strategy
    if insertion:
        s = s.model_copy(update={"insertion": s.insertion.model_copy(update=insertion)})
    if stages:
        s = s.model_copy(update={"stages": s.stages.model_copy(update={
            n: type(getattr(s.stages, n)).model_validate(v) for n, v in stages.items()})})
    setup.strategy = s
    root = _tree(setup, STAGES_TO_RESTING, DEFAULT_SETTINGS)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    try:
        r = run_bite(setup, stages=STAGES_TO_RESTING, root=root)
    finally:
        setup.arm.close()
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    werr = max((n.wrist_tracking_error for n in root.iterate() if isinstance(n, Execute)),
               default=0.0)
    w = setup.world
    return {"food": food, "system": system, "seed": seed, "strategy": setup.strategy_name,
            "insertion": setup.strategy.insertion.model_dump(),
            "stages": setup.strategy.stages.model_dump(),
            "acquired_g": r.acquired_g,
            "at_resting_g": r.masses_after.get("resting", {}).get("utensil", 0.0),
            "end_state": r.end_state, "failed_stage": r.failed_stage,
            "wrist_tracking_error_deg": math.degrees(werr),
            "arm_tracking_error_deg": math.degrees(w.arm_tracking_error),
            "sim_time_s": r.sim_time_s, "wall_time_s": wall, "cpu_s_process": cpu,
            "realtime_factor_physics": w.realtime_factor}


def summarise(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Per food × system: describe() of acquired and at-Resting mass, tracking errors, RTF;
    per food: Welch's test of acquired mass between the systems."""
    out: dict[str, Any] = {}
    for food in sorted({r["food"] for r in runs}):
        per: dict[str, Any] = {}
        for system in SYSTEMS:
            rs = [r for r in runs if r["food"] == food and r["system"] == system]
            if not rs:
                continue
            per[system] = {
                "n": len(rs),
                "acquired_g": describe([r["acquired_g"] for r in rs]).to_dict(),
                "at_resting_g": describe([r["at_resting_g"] for r in rs]).to_dict(),
                "completed": sum(r["end_state"] == "completed" for r in rs),
                "wrist_tracking_error_deg_max": max(r["wrist_tracking_error_deg"] for r in rs),
                "arm_tracking_error_deg_max": max(r["arm_tracking_error_deg"] for r in rs),
                "realtime_factor_mean": sum(r["sim_time_s"] / r["wall_time_s"] for r in rs)
                / len(rs)}
        if len(per) == 2:
            a = [r["acquired_g"] for r in runs if r["food"] == food
                 and r["system"] == "articutool"]
            b = [r["acquired_g"] for r in runs if r["food"] == food
                 and r["system"] == "baseline"]
            per["welch_acquired"] = welch(a, b).to_dict()
        out[food] = per
    return out


def turn(food: str) -> dict[str, Any]:
    """The shipped sweep's turn in the food, planned for both systems from the same start
    (kinematics, no physics): its duration and each joint's travel (degrees)."""
    import numpy as np

    from articutool.arm.model import ArmModel
    from articutool.arm.scene import SCOOP_HEADING, Scene, container_floor
    from articutool.feeding.insertion import acquisition_waypoints, dish_outline
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.planning.tip_paths import cartesian_path, first_ik, wrist_sweep
    from articutool.spec import load_spec

    spec, scene = load_spec(), Scene.load()
    lib = StrategyLibrary.load(spec)
    s = next(v for v in lib.for_food(food, "articutool").values())
    model = ArmModel(spec, s.utensil, 8, scene)
    wps = acquisition_waypoints(s, container_floor(scene, "bowl"), SCOOP_HEADING,
                                dish_outline(spec, s.utensil))["into"]
    pts = [(np.array(w.position), w.pitch_down, w.speed) for w in wps]
    i0 = next(k for k, w in enumerate(wps) if w.wrist) - 1
    q0 = first_ik(model, np.r_[spec.arm.configuration("AbovePlate"), 0.0, 0.0],
                  pts[i0][0], pts[i0][1])
    arm = cartesian_path(model, q0, pts[i0:])
    q, dur, travel = q0, 0.0, np.zeros(8)
    for i in range(i0 + 1, len(pts)):
        seg = wrist_sweep(model, q, *pts[i - 1][:2], *pts[i])
        dur += seg.duration
        travel += np.abs(np.diff(seg.positions, axis=0)).sum(axis=0)
        q = seg.positions[-1].copy()
    base = np.abs(np.diff(arm.positions, axis=0)).sum(axis=0)
    return {"food": food, "baseline_turn_s": arm.duration, "articutool_turn_s": dur,
            "baseline_arm_travel_deg": np.degrees(base).round(1).tolist(),
            "articutool_arm_travel_deg": np.degrees(travel[:6]).round(1).tolist(),
            "articutool_wrist_pitch_travel_deg": round(float(np.degrees(travel[6])), 1)}


# The thesis' Fig. 6.1 (§6.1), for comparison only: mean acquired mass, g.
THESIS = {"water": ("5.02 ± 1.62", "0.68 ± 0.18", "0.0 as printed"),
          "pecans": ("1.83", "1.32", "0.0062")}


def table(doc: dict[str, Any]) -> str:
    """Markdown rows: food, system, n, acquired mean ± SD [95 % CI], at Resting, completed,
    tracking errors, RTF, Welch p; the thesis' numbers beside them."""
    rows = ["| food | system | n | acquired, g (mean ± SD) [95 % CI] | at Resting, g | "
            "completed | wrist / arm tracking error, max ° | RTF | Welch p | thesis Fig. 6.1 |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for food, per in doc["summary"].items():
        p = per.get("welch_acquired", {}).get("p")
        for i, system in enumerate(SYSTEMS):
            if system not in per:
                continue
            x = per[system]
            a, r = x["acquired_g"], x["at_resting_g"]
            sd = "–" if a["sd"] is None else f"{a['sd']:.2f}"
            ci = ("" if a["ci_low"] is None else f" [{a['ci_low']:.2f}, {a['ci_high']:.2f}]")
            th = THESIS.get(food, ("", "", ""))
            rows.append(
                f"| {food} | {system} | {x['n']} | {a['mean']:.2f} ± {sd}{ci} | "
                f"{r['mean']:.2f} | {x['completed']}/{x['n']} | "
                f"{x['wrist_tracking_error_deg_max']:.2f} / {x['arm_tracking_error_deg_max']:.2f}"
                f" | {x['realtime_factor_mean']:.2f} | "
                f"{'' if p is None or i else f'{p:.3g}'} | {th[i]}"
                f"{f' (p {th[2]})' if i == 0 and th[2] else ''} |")
    return "\n".join(rows)


def shipped_insertions(foods: list[str]) -> dict[tuple[str, str], dict[str, Any]]:
    """Each food's and system's insertion as the packaged strategies ship it."""
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.spec import load_spec

    lib = StrategyLibrary.load(load_spec())
    return {(f, s): next(iter(lib.for_food(f, s).values())).insertion.model_dump()
            for f, s in itertools.product(foods, SYSTEMS)}


def score(runs: list[dict[str, Any]], shipped: bool) -> dict[str, Any]:
    """One candidate's runs, as the search ranks them; ``shipped``: it is the system's shipped
    value."""
    return {"n": len(runs),
            "acquired_g": describe([r["acquired_g"] for r in runs]).to_dict(),
            "at_resting_g": describe([r["at_resting_g"] for r in runs]).to_dict(),
            "completed": sum(r["end_state"] == "completed" for r in runs),
            "shipped": shipped}


def choose(scores: dict[int, dict[str, Any]]) -> int:
    """The search's rule over candidates' :func:`score`: the highest mean acquired mass; a tie
    goes to the higher mean at Resting, then to the shipped value, then to the first."""
    return max(scores, key=lambda j: (scores[j]["acquired_g"]["mean"],
                                      scores[j]["at_resting_g"]["mean"],
                                      scores[j]["shipped"], -j))


def best(runs: list[dict[str, Any]], foods: list[str],
         shipped_by: dict[tuple[str, str], dict[str, Any]]) -> dict[str, Any]:
    """Per food/system, the search's choice (:func:`choose`) among the candidates run so far;
    the shipped insertion is ``shipped_by``'s (:func:`shipped_insertions`)."""
    out: dict[str, Any] = {}
    for food, system in itertools.product(foods, SYSTEMS):
        shipped = shipped_by[food, system]
        scores: dict[int, dict[str, Any]] = {}
        for i, cand in enumerate(CANDIDATES[food]):
            rs = [r for r in runs if r["food"] == food and r["system"] == system
                  and r["candidate"] == i]
            if rs:
                scores[i] = score(rs, all(shipped[k] == v for k, v in cand.items()))
        if scores:
            i = choose(scores)
            out[f"{food}/{system}"] = {"candidate": i, **CANDIDATES[food][i],
                                       "mean_acquired_g": scores[i]["acquired_g"]["mean"],
                                       "scores": {str(j): v for j, v in scores.items()}}
    return out


def _write(path: Path, doc: dict[str, Any]) -> None:
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(doc, indent=1))
    tmp.replace(path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mode", choices=("measure", "search", "table", "turn"))
    ap.add_argument("--foods", nargs="+", default=["water", "pecans"],
                    choices=sorted(CANDIDATES))
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--workers", type=int, default=1,
                    help="search: runs at once, each in its own process")
    ap.add_argument("--resume", action="store_true",
                    help="search: keep the runs already in --out and run the rest")
    args = ap.parse_args(argv)
    if args.seeds < 1 or args.seeds > 1000:
        print("--seeds must be in 1..1000", file=sys.stderr)
        return 2
    if args.workers < 1 or args.workers > 64:
        print("--workers must be in 1..64", file=sys.stderr)
        return 2
    if args.mode == "turn":  # kinematics only: who makes the turn, how long it takes
        for food in args.foods:
            print(json.dumps(turn(food)))
        return 0
    if args.mode == "table":  # the README's table from a measure JSON
        print(table(json.loads(args.out.read_text())))
        return 0
    cmd = "PYTHONPATH=src nice python studies/acquisition_study.py " + " ".join(
        sys.argv[1:] if argv is None else argv)
    doc: dict[str, Any] = {"command": cmd, "stages": list(STAGES_TO_RESTING), "runs": []}
    if args.mode == "measure":
        for food, k, system in itertools.product(args.foods, range(args.seeds), SYSTEMS):
            doc["runs"].append(one(food, system, MEASURE_SEED0 + k))
            doc["summary"] = summarise(doc["runs"])
            _write(args.out, doc)
    else:
        doc["candidates"] = {f: CANDIDATES[f] for f in args.foods}
        if args.resume and args.out.exists():
            old = json.loads(args.out.read_text())
            if old.get("candidates") != doc["candidates"]:
                print(f"--resume: {args.out} holds other candidates than this search's "
                      f"{doc['candidates']}", file=sys.stderr)
                return 2
            doc["runs"] = old["runs"]
        done = {(r["food"], r["system"], r["seed"], r["candidate"]) for r in doc["runs"]}
        shipped = shipped_insertions(args.foods)
        todo = [(food, system, TUNING_SEED0 + k, c, cand) for food in args.foods
                for k, system, (c, cand) in itertools.product(
                    range(args.seeds), SYSTEMS[::-1], list(enumerate(CANDIDATES[food]))[::-1])
                if (food, system, TUNING_SEED0 + k, c) not in done]

        def keep(run: dict[str, Any], c: int) -> None:
            run["candidate"] = c
            doc["runs"].append(run)
            doc["best"] = best(doc["runs"], args.foods, shipped)
            _write(args.out, doc)

        # each run is its own seeded world: the order they finish in changes nothing
        with ProcessPoolExecutor(args.workers) as pool:
            futures = {pool.submit(one, food, system, seed, cand): c
                       for food, system, seed, c, cand in todo}
            for f in as_completed(futures):
                keep(f.result(), futures[f])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
