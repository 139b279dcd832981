"""Levers of the noodle acquisition, each twirl vs still on the same tuning seeds: does any
justified change to the noodle model or the fork's motion make a twirling fork lift more than
a still one? (The earlier adhesion levers are the shipped model's measured tack now;
``no_tack`` removes it.)

Every variant changes one thing from the shipped world (``data/physics.toml``, the fork's
acquisition ``sim/scenes.py: skewer``), with its source in ``LEVERS``. Tuning seeds are
5100-5102, disjoint from the confirmation seeds 5000-5009 of
``noodle_twirl.py``. Each variant's runs go to ``--out/<variant>.json`` (rewritten after every
run; rerunning keeps the runs already there), so two processes can run different variants;
every listed variant runs on a seed before any runs on the next.

    nice .venv/bin/python studies/noodle_levers.py --lever baseline no_tack
    .venv/bin/python studies/noodle_levers.py --table     # the docs' table from the JSON
    nice .venv/bin/python studies/noodle_levers.py --confirm no_tack --seeds 10
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from articutool.experiments.design import trial_seed
from articutool.sim.params import PhysicsParams
from articutool.sim.scenes import max_twirl_turns
from articutool.sim.world import FeedingWorld
from articutool.spec import load_spec
from noodle_twirl import one_run, summarise, write_study

CONFIRM_BASE_SEED = 5  # confirmation seeds 5000 + r, those of the first twirl study
TUNING_SEED0 = 5100  # 5100 + r: never a confirmation seed (5000-5009, noodle_twirl.py)


def _straight_rest(w: FeedingWorld) -> None:
    """Make every strand's rest shape straight (its ball joints' spring reference the identity
    relative pose) after it was laid as a spiral, and let the heap relax 1 s."""
    m = w.model
    for j in range(m.njnt):
        if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            q = m.body_quat[m.jnt_bodyid[j]]  # the laid turn relative to the parent segment
            m.qpos_spring[m.jnt_qposadr[j]:m.jnt_qposadr[j] + 4] = q * [1, -1, -1, -1]
    w.run(1.0, tick=False)


@dataclass(frozen=True)
class Lever:
    """One variant: what it changes and where its value comes from."""

    what: str
    source: str
    food: dict[str, Any] = field(default_factory=dict)  # overrides of foods.noodles
    world: dict[str, Any] = field(default_factory=dict)  # overrides of [world]
    prepare: Callable[[FeedingWorld], None] | None = None
    skewer: dict[str, Any] = field(default_factory=dict)
    turns: float | None = None  # twirl turns (default: the cable budget less 0.1 turn)
    still_from: str | None = None  # the still fork is identical to this variant's

    def params(self) -> PhysicsParams:
        d = PhysicsParams.load().model_dump()
        d["foods"]["noodles"].update(self.food)
        d["world"].update(self.world)
        return PhysicsParams.from_dict(d)


LEVERS: dict[str, Lever] = {
    "baseline": Lever("shipped model and motion", "data/physics.toml"),
    "no_tack": Lever(
        "no starch tack: friction only",
        "the shipped strands without their measured stickiness (physics.toml stickiness_pa)",
        food={"stickiness_pa": 0.0}),
    "straight_rest": Lever(
        "strands' rest shape straight (laid as spirals, then relaxed 1 s)",
        "a fresh strand's rest shape; the shipped one is its laid shape (fully relaxed)",
        prepare=_straight_rest),
    "solver": Lever(
        "solver iterations 30 → 100, no-slip passes 10 → 30",
        "numerical: more passes remove more of the soft contacts' creep",
        food={"noslip_iterations": 30}, world={"iterations": 100}),
    "deep_pile": Lever(
        "40 g (38 strands) in the same 3 cm radius: twice as deep",
        "a cooked serving is ~125-140 g (56 g dry × 2.2-2.5 water uptake; the thesis used "
        "125 g): 40 g is still under a third of one",
        food={"fill_g": 40.0}),
    "more_turns": Lever(
        "TWIRL_CCW 2 turns in the air first, then 4.9 turns inside (the roll budget's ±3)",
        "thesis §4.4: a twirl before insertion, then one inside; whole turns keep the tines' "
        "orientation at entry",
        skewer={"prewind_turns": 2.0}, turns=4.9, still_from="baseline"),
}


def seeds(n: int) -> list[int]:
    """The tuning seeds."""
    return [TUNING_SEED0 + r for r in range(n)]


def run_lever(name: str, seed: int, out_dir: Path) -> dict[str, Any]:
    """Twirl and still on one tuning seed (skipping runs already in the file)."""
    lever = LEVERS[name]
    path = out_dir / f"{name}.json"

    def runs() -> list[dict[str, Any]]:  # as on disk now: another process may add seeds
        return json.loads(path.read_text())["runs"] if path.exists() else []

    turns = lever.turns if lever.turns is not None else max_twirl_turns(load_spec())
    params = lever.params()
    for t in (turns, 0.0) if lever.still_from is None else (turns,):
        if any(r["seed"] == seed and r["twirl_turns"] == t for r in runs()):
            continue
        run = one_run(seed, t, params=params, prepare=lever.prepare,
                      **(lever.skewer if t else {}))
        print(name, json.dumps(run), flush=True)
        _write(path, name, lever, [*runs(), run], turns)
    return _write(path, name, lever, runs(), turns)


def confirm(name: str, n_seeds: int, out_dir: Path) -> dict[str, Any]:
    """A lever's confirmation study on noodle_twirl.py's seeds (5000 + r, never tuning seeds):
    twirl and still interleaved, resumable, the same summary and one-sided tests."""
    lever = LEVERS[name]
    path = out_dir / f"confirm_{name}.json"
    turns = lever.turns if lever.turns is not None else max_twirl_turns(load_spec())
    params = lever.params()
    runs = json.loads(path.read_text())["runs"] if path.exists() else []
    for r in range(n_seeds):
        seed = trial_seed(CONFIRM_BASE_SEED, r)
        for t in (turns, 0.0):
            if not any(x["seed"] == seed and x["twirl_turns"] == t for x in runs):
                runs.append(one_run(seed, t, params=params, prepare=lever.prepare,
                                    **(lever.skewer if t else {})))
                print(name, json.dumps(runs[-1]), flush=True)
                write_study(path, runs, turns, ["--confirm", name, "--seeds", str(n_seeds)],
                            "studies/noodle_levers.py")
    write_study(path, runs, turns, ["--confirm", name, "--seeds", str(n_seeds)],
                "studies/noodle_levers.py")
    return summarise(runs, turns)


def _write(path: Path, name: str, lever: Lever, runs: list[dict[str, Any]],
           turns: float) -> dict[str, Any]:
    doc = {"issue": 26, "lever": name, "what": lever.what, "source": lever.source,
           "food_overrides": lever.food, "world_overrides": lever.world,
           "skewer": lever.skewer, "twirl_turns": turns, "still_from": lever.still_from,
           "mujoco": mujoco.__version__, "runs": runs}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(doc, indent=2) + "\n")
    return doc


def _runs_with_still(doc: dict[str, Any], out_dir: Path) -> list[dict[str, Any]]:
    runs = list(doc["runs"])
    if doc.get("still_from"):
        base = json.loads((out_dir / f"{doc['still_from']}.json").read_text())["runs"]
        runs += [r for r in base if r["twirl_turns"] == 0.0]
    return runs


def table(out_dir: Path) -> str:
    """The docs' table from the JSON in ``out_dir``: a row per variant and tuning seed (twirl
    and still on the same pile), then the variant's mean difference over its paired seeds."""
    rows = ["| variant | seed | twirl: g lifted (strands on the fork: in / twirled / lifted) "
            "| still: g lifted (in / lifted) | twirl − still (g) | MuJoCo resets (warnings) "
            "| real-time factor twirl / still |", "|---|---|---|---|---|---|---|"]

    def g(r: dict[str, Any] | None, phases: tuple[str, ...]) -> str:
        if r is None:
            return "not run"
        n = " / ".join(str(r.get("strands_touching", {}).get(p, "?")) for p in phases)
        return f"{r['lifted_g']:.2f}{' (reset: not counted)' if r['reset'] else ''} ({n})"

    for name in LEVERS:
        path = out_dir / f"{name}.json"
        if not path.exists():
            continue
        doc = json.loads(path.read_text())
        runs = _runs_with_still(doc, out_dir)
        diffs = []
        for k, seed in enumerate(sorted({r["seed"] for r in doc["runs"]})):
            tw = next((r for r in runs if r["seed"] == seed and r["twirl_turns"] > 0), None)
            st = next((r for r in runs if r["seed"] == seed and r["twirl_turns"] == 0), None)
            ok = tw is not None and st is not None and not (tw["reset"] or st["reset"])
            if ok:
                diffs.append(tw["lifted_g"] - st["lifted_g"])
            pair = [r for r in (tw, st) if r is not None]
            warned = sorted({w.removeprefix("mjWARN_") for r in pair for w in r["warnings"]})
            rtf = " / ".join(f"{r['realtime_factor']:.2f}×" if r else "–" for r in (tw, st))
            rows.append(
                f"| {name + ': ' + doc['what'] if k == 0 else ''} | {seed} "
                f"| {g(tw, ('in', 'twirled', 'lifted'))} "
                f"| {g(st, ('in', 'lifted'))}{' (baseline)' if doc['still_from'] else ''} "
                f"| {f'{diffs[-1]:+.2f}' if ok else '–'} "
                f"| {sum(r['reset'] for r in pair)}"
                f"{' (' + ', '.join(warned) + ')' if warned else ''} | {rtf} |")
        if len(diffs) > 1:
            rows.append(f"| | mean | | | {np.mean(diffs):+.2f} ({sum(d > 0 for d in diffs)} of "
                        f"{len(diffs)} seeds more) | | |")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lever", nargs="+", choices=sorted(LEVERS), default=[])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--only-seed", type=int, default=None,
                    help="run the levers on this tuning seed only")
    ap.add_argument("--out", default="studies/results/noodle_levers")
    ap.add_argument("--table", action="store_true", help="print the docs' table; run nothing")
    ap.add_argument("--confirm", choices=sorted(LEVERS), default=None,
                    help="run this lever's confirmation study on seeds 5000 + r (--seeds of "
                         "them) into --out/confirm_<lever>.json")
    args = ap.parse_args(argv)
    out = Path(args.out)
    if args.table:
        print(table(out))
        return 0
    if args.confirm:
        print(json.dumps(confirm(args.confirm, args.seeds, out), indent=2))
        return 0
    todo = seeds(args.seeds) if args.only_seed is None else [args.only_seed]
    for seed in todo:  # every lever on a seed before the next seed
        for name in args.lever:
            run_lever(name, seed, out)
    print(table(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
