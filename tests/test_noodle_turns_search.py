"""studies/noodle_turns_search.py: both systems get the same number of candidates, the
shipped values are among them, and the choice follows the declared rule (mean acquired, then
at Resting, then the shipped value)."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

STUDIES = Path(__file__).resolve().parents[1] / "studies"


@pytest.fixture
def search(monkeypatch):  # type: ignore[no-untyped-def]
    monkeypatch.syspath_prepend(str(STUDIES))
    return importlib.import_module("noodle_turns_search")


def _run(system: str, c: int, acquired: float, resting: float) -> dict:
    return {"system": system, "candidate": c, "acquired_g": acquired, "at_resting_g": resting,
            "end_state": "completed", "cpu_s_process": 1.0}


def test_the_same_budget_and_the_shipped_turns_among_the_candidates(search) -> None:
    cands, shipped = search.candidates(), search.shipped_values()
    assert len(cands["articutool"]) == len(cands["baseline"])
    assert sum(search._is_shipped(c, shipped["articutool"]) for c in cands["articutool"]) == 1
    # the still fork's candidates are places the first stage did not try
    first = importlib.import_module("acquisition_study").CANDIDATES["noodles"]
    assert not any(c["insertion"] == f for c in cands["baseline"] for f in first)


def test_the_choice_follows_the_rule(search) -> None:
    cands, shipped = search.candidates(), search.shipped_values()
    ship = next(i for i, c in enumerate(cands["articutool"])
                if search._is_shipped(c, shipped["articutool"]))
    other = (ship + 1) % len(cands["articutool"])
    tie = [_run("articutool", ship, 2.0, 2.0), _run("articutool", other, 2.0, 2.0)]
    assert search.best(tie, cands, shipped)["articutool"]["candidate"] == ship
    more_kept = [_run("articutool", ship, 2.0, 0.0), _run("articutool", other, 2.0, 2.0)]
    assert search.best(more_kept, cands, shipped)["articutool"]["candidate"] == other
    more = [_run("articutool", ship, 2.0, 2.0), _run("articutool", other, 4.0, 0.0)]
    assert search.best(more, cands, shipped)["articutool"]["candidate"] == other
