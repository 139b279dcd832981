"""Fold a run of some of an experiment's foods (its own ``--out``) into the full run's trial log.

When one food's model changes (water: the 250 g bowl became the SPH liquid), only that food's
trials need running again: ``articutool experiment EXP --foods F --out PART`` runs them on the
same seeds. This folds them into the full run ``FULL``: each of PART's records replaces FULL's
record of the same condition and repeat (same seed), re-indexed to FULL's trial order; every
other line of FULL's log is kept byte for byte, and the log is written in trial order, as a run
appends it. It refuses unless

- PART's conditions are FULL's for PART's foods, in FULL's order, but for the values other
  runs measured (``MEASURED``: Exp. 2c's load and target, which follow capacity and Exp. 1;
  the part's replace FULL's in its ``run.json``), its seeds are FULL's, and PART holds every
  repeat FULL does;
- PART's trials ran on today's data for its foods (its pinned data hash is today's), and the
  data of each of FULL's other foods is the same today as at each commit its trials ran on
  (the hash of that commit's data files, read from git, against today's).

When only one system's strategy of a food changed (a search moved the baseline's), ``--drop
FOOD/SYSTEM`` instead removes that condition's records from FULL's log and pins today's data,
so that resuming FULL runs exactly them again on their seeds. It refuses unless every kept
record's data is today's at its commit: its food's model and, for FOOD's other conditions,
their own system's strategies (``data_hash(..., systems=)``).

FULL's ``run.json`` then pins today's data hash (its trials are each on the data they ran on,
and the data of every food is today's), so `articutool experiment EXP --out FULL` resumes it:
with nothing to run it writes the summary from the folded log, keeping when and how the run
was made. Each record keeps the commit it ran on (``source``): the report shows the mix.

    PYTHONPATH=src .venv/bin/python studies/fold_run.py exp1 \\
        --part results/experiments_water_bowl --full results/experiments
    .venv/bin/articutool experiment exp1 --out results/experiments --workers 1
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from articutool.experiments.config import ExperimentsConfig

REPO = Path(__file__).resolve().parents[1]
# A condition's values measured by other runs (Exp. 2c's load: capacity's mean; its closed
# loop's target: Exp. 1's): the part's, run on today's results, replace the full run's.
MEASURED = ("load_g", "target_g")
DATA = "src/articutool/data"


def _data_at(commit: str, into: Path) -> Path:
    """The data directory as it was at ``commit`` (from git), written under ``into``."""
    names = subprocess.run(["git", "-C", str(REPO), "ls-tree", "--name-only", commit, DATA + "/"],
                           check=True, capture_output=True, text=True).stdout.split()
    for name in names:
        blob = subprocess.run(["git", "-C", str(REPO), "show", f"{commit}:{name}"], check=True,
                              capture_output=True).stdout
        (into / Path(name).name).write_bytes(blob)
    return into


def _check_unchanged(exp: str, cfg: ExperimentsConfig, food: str, commit: str,
                     system: str | None = None) -> None:
    """Refuse unless the data a trial of ``exp`` on ``food`` (of ``system`` only, if given)
    reads is the same today as at ``commit``; ``cfg`` is today's experiments config."""
    from articutool.experiments.runner import data_hash

    only = None if system is None else {system}
    with tempfile.TemporaryDirectory() as tmp:
        then = data_hash(exp, cfg, {food}, _data_at(commit, Path(tmp)), systems=only)
    if then != data_hash(exp, cfg, {food}, systems=only):
        what = food if system is None else f"{food}/{system}"
        raise SystemExit(f"{exp}: the data of {what} changed since {commit}; run it again")


def fold(exp: str, part: Path, full: Path) -> dict[str, int]:
    """Fold ``part/exp``'s records into ``full/exp``'s log (module doc); returns counts."""
    from articutool.datafile import read_own_json, replace_own
    from articutool.experiments.config import ExperimentsConfig
    from articutool.experiments.runner import data_hash, log_path

    cfg = ExperimentsConfig.load()
    run_p, run_f = (read_own_json(d / exp / "run.json", "run") for d in (part, full))
    if run_p is None or run_f is None:
        raise SystemExit(f"{exp}: both runs need a run.json")
    keys = sorted(run_f["conditions"][0])

    def cond_key(c: dict[str, object]) -> tuple[object, ...]:
        return tuple(c[k] for k in keys)

    def same_but_measured(c: dict[str, object]) -> tuple[object, ...]:
        return tuple(c[k] for k in keys if k not in MEASURED)

    foods_p = {c["food"] for c in run_p["conditions"]}
    conds_p = run_p["conditions"]
    conds_f = [c for c in run_f["conditions"] if c["food"] in foods_p]
    if [same_but_measured(c) for c in conds_p] != [same_but_measured(c) for c in conds_f]:
        raise SystemExit(f"{exp}: {part}'s conditions are not {full}'s for "
                         f"{sorted(foods_p)}")
    # FULL's condition → PART's (the same but for the values measured by other runs)
    renamed = {cond_key(f): cond_key(c) for c, f in zip(conds_p, conds_f, strict=True)}
    if run_p["seed"] != run_f["seed"]:
        raise SystemExit(f"{exp}: the runs' base seeds differ")
    foods_all = {c["food"] for c in run_f["conditions"]}
    if run_p["data_hash"] != data_hash(exp, cfg, foods_p):
        raise SystemExit(f"{exp}: {part}'s trials did not run on today's data for "
                         f"{sorted(foods_p)}")
    lines_f = log_path(full, exp).read_text().splitlines()
    recs_f = [json.loads(x) for x in lines_f]
    for food in sorted(foods_all - foods_p):  # each kept food, at each commit it ran on
        commits = {r["source"].removesuffix("+modified") for r in recs_f if r["food"] == food}
        for c in sorted(commits):
            _check_unchanged(exp, cfg, food, c)
    index = {(renamed[cond_key(r)], r["repeat"]): (r["trial"], r["seed"]) for r in recs_f
             if cond_key(r) in renamed}
    recs_p = [json.loads(x) for x in log_path(part, exp).read_text().splitlines()]
    mine = {(cond_key(r), r["repeat"]): r for r in recs_p}
    if set(mine) != set(index):
        raise SystemExit(f"{exp}: {part} holds {len(mine)} trials of the folded conditions, "
                         f"{full} {len(index)}; finish the part's run first")
    out = [(r["trial"], x) for x, r in zip(lines_f, recs_f, strict=True)
           if cond_key(r) not in renamed]
    for k, r in mine.items():
        trial, seed = index[k]
        if r["seed"] != seed:
            raise SystemExit(f"{exp}: trial {trial}'s seed differs between the runs")
        out.append((trial, json.dumps({**r, "trial": trial})))
    # In trial order, as a run appends them (its conditions interleaved, repeat by repeat).
    replace_own(log_path(full, exp), "\n".join(x for _, x in sorted(out)) + "\n")
    mapped = iter(conds_p)
    conditions = [next(mapped) if c["food"] in foods_p else c for c in run_f["conditions"]]
    replace_own(full / exp / "run.json", json.dumps(
        {**run_f, "conditions": conditions, "data_hash": data_hash(exp, cfg, foods_all)},
        indent=1) + "\n")
    return {"kept": len(out) - len(mine), "folded": len(mine)}


def drop(exp: str, full: Path, food: str, system: str) -> dict[str, int]:
    """Drop the records of ``food``'s ``system`` condition from ``full/exp``'s log and pin
    today's data, so that resuming ``full`` runs them again on the same seeds (module doc).
    Refuses unless every kept record's data is today's at the commit it ran on: its food's
    model, and for ``food``'s other conditions their own system's strategies."""
    from articutool.datafile import read_own_json, replace_own
    from articutool.experiments.config import ExperimentsConfig
    from articutool.experiments.runner import data_hash, log_path

    cfg = ExperimentsConfig.load()
    run = read_own_json(full / exp / "run.json", "run")
    if run is None:
        raise SystemExit(f"{exp}: {full} holds no run.json")
    if not any(c["food"] == food and c.get("system") == system for c in run["conditions"]):
        raise SystemExit(f"{exp}: no condition {food}/{system} in {full}")
    lines = log_path(full, exp).read_text().splitlines()
    recs = [json.loads(x) for x in lines]

    def dropped(r: dict[str, object]) -> bool:
        return r["food"] == food and r.get("system") == system

    kept = {(str(r["food"]), r.get("system") if r["food"] == food else None,
             str(r["source"]).removesuffix("+modified")) for r in recs if not dropped(r)}
    for f, sysname, commit in sorted(kept, key=str):
        _check_unchanged(exp, cfg, f, commit, sysname)
    out = [x for x, r in zip(lines, recs, strict=True) if not dropped(r)]
    replace_own(log_path(full, exp), "\n".join(out) + "\n")
    foods_all = {c["food"] for c in run["conditions"]}
    replace_own(full / exp / "run.json", json.dumps(
        {**run, "data_hash": data_hash(exp, cfg, foods_all)}, indent=1) + "\n")
    return {"kept": len(out), "dropped": len(lines) - len(out)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("experiment")
    ap.add_argument("--full", type=Path, required=True)
    how = ap.add_mutually_exclusive_group(required=True)
    how.add_argument("--part", type=Path)
    how.add_argument("--drop", metavar="FOOD/SYSTEM",
                     help="drop one condition's records to run them again by resuming")
    a = ap.parse_args(argv)
    if a.drop is not None:
        food, _, system = a.drop.partition("/")
        done = drop(a.experiment, a.full, food, system)
    else:
        done = fold(a.experiment, a.part, a.full)
    print(json.dumps({"experiment": a.experiment, **done}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
