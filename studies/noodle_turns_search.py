"""The noodle search's second stage: how many turns the Articutool's fork twirls inside the
nest, and, with the same budget, where else the still fork could go in.

The first stage (``acquisition_study.py search --foods noodles``) chose each system's skewer
place and depth from the same four candidates. The twirl's turns are the Articutool's alone:
the still fork has no counterpart, so its equal share of this stage's runs searches the one
thing it can vary, its insertion, at three places the first stage's grid did not hold (12.5 mm
along the heading, between its two offsets, at its two depths and between them). Each
candidate is one acquisition through the feeding tree up to Resting
(:func:`acquisition_study.one`) on each tuning seed 7 000 000 + k (the experiments use
0–999); every other field is the system's shipped strategy. The choice per system: the
highest mean acquired mass; a tie goes to the higher mean at Resting, then to the shipped
value, then to the first candidate.

The turns are the post-insertion ``TWIRL_CCW``'s rotations at its shipped speed: 1, 2 and 3
(the 2 shipped before this search and one either side); the turn before insertion (in the
air, winding the F/T cable) stays, so every candidate keeps the roll within the spec's turn
budget and ends at whole turns.

Run (niced, from the repository root): ``PYTHONPATH=src nice .venv/bin/python
studies/noodle_turns_search.py --seeds 3 --workers 2 --out
studies/results/noodle_turns_search.json``; ``--resume`` keeps the runs in ``--out``.
"""

from __future__ import annotations

import argparse
import functools
import itertools
import json
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from acquisition_study import (
    SYSTEMS,
    TUNING_SEED0,
    _write,
    choose,
    one,
    score,
    shipped_insertions,
)
from articutool.experiments.runner import source_version

FOOD = "noodles"
TURNS = (1.0, 2.0, 3.0)
BASELINE_OFFSET_M, BASELINE_DEPTHS_M = 0.0125, (0.002, 0.004, 0.006)


@functools.cache
def _twirl_inside():  # type: ignore[no-untyped-def]
    """The Articutool's shipped noodle strategy's stage inside the nest (read once)."""
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.spec import load_spec

    lib = StrategyLibrary.load(load_spec())
    return next(iter(lib.for_food(FOOD, "articutool").values())).stages.post_move_into


def candidates() -> dict[str, list[dict[str, Any]]]:
    """Each system's candidates: the Articutool's turns inside the nest (its
    ``post_move_into`` stage), the still fork's insertion; as many for each."""
    twirl = _twirl_inside()
    return {"articutool": [{"stages": {"post_move_into": {
                "primitive": twirl.primitive, "params": [t, twirl.params[1]]}}} for t in TURNS],
            "baseline": [{"insertion": {"offset_m": BASELINE_OFFSET_M, "depth_m": d}}
                         for d in BASELINE_DEPTHS_M]}


def shipped_values() -> dict[str, dict[str, Any]]:
    """What each system ships in the fields its candidates set."""
    return {"articutool": {"stages": {"post_move_into": _twirl_inside().model_dump()}},
            "baseline": {"insertion": shipped_insertions([FOOD])[FOOD, "baseline"]}}


def _is_shipped(cand: dict[str, Any], shipped: dict[str, Any]) -> bool:
    if "stages" in cand:
        return all(shipped["stages"][n] == v for n, v in cand["stages"].items())
    return all(shipped["insertion"][k] == v for k, v in cand["insertion"].items())


def best(runs: list[dict[str, Any]], cands: dict[str, list[dict[str, Any]]],
         shipped: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Per system, the choice among the candidates run so far (:func:`acquisition_study.choose`),
    with every candidate's scores and CPU."""
    out: dict[str, Any] = {}
    for system in SYSTEMS:
        scores: dict[int, dict[str, Any]] = {}
        for i, cand in enumerate(cands[system]):
            rs = [r for r in runs if r["system"] == system and r["candidate"] == i]
            if rs:
                scores[i] = {**score(rs, _is_shipped(cand, shipped[system])),
                             "cpu_s_process": sum(r["cpu_s_process"] for r in rs)}
        if scores:
            i = choose(scores)
            out[system] = {"candidate": i, **cands[system][i],
                           "mean_acquired_g": scores[i]["acquired_g"]["mean"],
                           "scores": {str(j): v for j, v in scores.items()}}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--resume", action="store_true")
    args = ap.parse_args(argv)
    if not 1 <= args.seeds <= 1000:
        print("--seeds must be in 1..1000", file=sys.stderr)
        return 2
    if not 1 <= args.workers <= 64:
        print("--workers must be in 1..64", file=sys.stderr)
        return 2
    cands, shipped = candidates(), shipped_values()
    doc: dict[str, Any] = {
        "command": "PYTHONPATH=src nice python studies/noodle_turns_search.py " + " ".join(
            sys.argv[1:] if argv is None else argv),
        "source": source_version(), "food": FOOD,
        "seeds": [TUNING_SEED0 + k for k in range(args.seeds)],
        "candidates": cands, "shipped": shipped, "runs": []}
    if args.resume and args.out.exists():
        old = json.loads(args.out.read_text())
        if old.get("candidates") != cands:
            print(f"--resume: {args.out} holds other candidates", file=sys.stderr)
            return 2
        doc["runs"] = old["runs"]
    done = {(r["system"], r["seed"], r["candidate"]) for r in doc["runs"]}
    # seed by seed, the cheaper still fork first
    todo = [(system, TUNING_SEED0 + k, c, cand)
            for k, system in itertools.product(range(args.seeds), SYSTEMS[::-1])
            for c, cand in enumerate(cands[system])
            if (system, TUNING_SEED0 + k, c) not in done]
    with ProcessPoolExecutor(args.workers) as pool:
        futures = {pool.submit(one, FOOD, system, seed, cand.get("insertion"),
                               cand.get("stages")): (c, system)
                   for system, seed, c, cand in todo}
        for f in as_completed(futures):
            run = f.result()
            run["candidate"] = futures[f][0]
            doc["runs"].append(run)
            doc["best"] = best(doc["runs"], cands, shipped)
            _write(args.out, doc)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
