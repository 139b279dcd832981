"""studies/fold_run.py --drop: one condition's records leave a run's log so that resuming runs
them again on today's data; a kept record whose own data changed since its commit refuses it,
and nothing is written."""

from __future__ import annotations

import importlib
import json
import subprocess
from pathlib import Path

import pytest

from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.runner import data_hash

REPO = Path(__file__).resolve().parents[1]
STUDIES = REPO / "studies"
# the last commit before the strands' tack became the film's law at each crossing angle:
# the noodles' model, and so their data, differ from today's
OLD = "a1c6e5f^"


@pytest.fixture
def fold_run(monkeypatch):  # type: ignore[no-untyped-def]
    monkeypatch.syspath_prepend(str(STUDIES))
    return importlib.import_module("fold_run")


def _head() -> str:
    return subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"], check=True,
                          capture_output=True, text=True).stdout.strip()


def _run(tmp_path: Path, articutool_source: str) -> Path:
    """A two-condition noodle run of exp3, two repeats, pinned to some other data."""
    d = tmp_path / "full" / "exp3"
    d.mkdir(parents=True)
    conds = [{"food": "noodles", "system": "articutool"}, {"food": "noodles", "system": "baseline"}]
    (d / "run.json").write_text(json.dumps({"experiment": "exp3", "seed": 0,
                                            "data_hash": "0" * 16, "conditions": conds}))
    lines = [json.dumps({"trial": 2 * r + c, "repeat": r, "seed": r, "food": "noodles",
                         "system": cond["system"],
                         "source": articutool_source if c == 0 else OLD})
             for r in range(2) for c, cond in enumerate(conds)]
    (d / "trials.jsonl").write_text("\n".join(lines) + "\n")
    return tmp_path / "full"


def test_drop_removes_one_condition_and_pins_todays_data(fold_run, tmp_path: Path) -> None:
    full = _run(tmp_path, _head())
    done = fold_run.drop("exp3", full, "noodles", "baseline")
    assert done == {"kept": 2, "dropped": 2}
    recs = [json.loads(x) for x in (full / "exp3" / "trials.jsonl").read_text().splitlines()]
    assert [(r["trial"], r["system"]) for r in recs] == [(0, "articutool"), (2, "articutool")]
    run = json.loads((full / "exp3" / "run.json").read_text())
    assert run["data_hash"] == data_hash("exp3", ExperimentsConfig.load(), {"noodles"})


def test_drop_refuses_a_kept_record_on_other_data(fold_run, tmp_path: Path) -> None:
    full = _run(tmp_path, OLD)
    before = {p.name: p.read_bytes() for p in (full / "exp3").iterdir()}
    with pytest.raises(SystemExit, match="noodles/articutool changed since"):
        fold_run.drop("exp3", full, "noodles", "baseline")
    assert {p.name: p.read_bytes() for p in (full / "exp3").iterdir()} == before
