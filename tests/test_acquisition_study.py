"""studies/acquisition_study.py's search: the same candidates for both systems, each a valid
insertion of the system's own strategy; the choice and its tie rule; tuning seeds disjoint
from the experiments'; bad input exits 2. The runs themselves (minutes each) are not a test."""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import pytest

from articutool.feeding.strategies import Insertion, StrategyLibrary
from articutool.spec import load_spec

STUDIES = Path(__file__).resolve().parents[1] / "studies"


@pytest.fixture
def study(monkeypatch):
    monkeypatch.syspath_prepend(str(STUDIES))
    return importlib.import_module("acquisition_study")


def _shipped(food: str, system: str):
    lib = StrategyLibrary.load(load_spec())
    return next(iter(lib.for_food(food, system).values())).insertion


def test_every_candidate_is_a_valid_insertion_for_both_systems(study) -> None:
    assert study.TUNING_SEED0 > 999  # the experiments use seeds 0-999
    for food, cands in study.CANDIDATES.items():
        for system in study.SYSTEMS:
            ins = _shipped(food, system)
            for cand in cands:
                Insertion.model_validate({**ins.model_dump(), **cand})


def _runs(system: str, scores: dict[int, tuple[float, float]]) -> list[dict]:
    return [{"food": "noodles", "system": system, "candidate": c, "acquired_g": a,
             "at_resting_g": r, "end_state": "completed"} for c, (a, r) in scores.items()]


SHIPPED = 1  # the candidate the rule's tests treat as the shipped insertion


def test_the_choice_is_the_most_acquired_then_at_resting_then_shipped_then_first(
        study) -> None:
    n = len(study.CANDIDATES["noodles"])
    shipped_by = {("noodles", s): {**_shipped("noodles", s).model_dump(),
                                   **study.CANDIDATES["noodles"][SHIPPED]}
                  for s in study.SYSTEMS}
    for system in study.SYSTEMS:
        shipped = SHIPPED
        other = (shipped + 1) % n

        def choice(scores: dict[int, tuple[float, float]], s: str = system) -> int:
            return study.best(_runs(s, scores), ["noodles"],
                              shipped_by)[f"noodles/{s}"]["candidate"]

        assert choice({shipped: (1.0, 1.0), other: (2.0, 0.0)}) == other
        assert choice({shipped: (1.0, 0.5), other: (1.0, 0.9)}) == other
        assert choice({i: (0.0, 0.0) for i in range(n)}) == shipped
        rest = [i for i in range(n) if i != shipped]
        assert choice({i: (0.0, 0.0) for i in rest}) == rest[0]


def test_bad_input_exits_2(study, tmp_path, capsys) -> None:
    with pytest.raises(SystemExit) as e:
        study.main(["search", "--foods", "soup", "--out", str(tmp_path / "x.json")])
    assert e.value.code == 2
    out = tmp_path / "old.json"
    out.write_text(json.dumps({"candidates": {"noodles": []}, "runs": []}))
    assert study.main(["search", "--foods", "noodles", "--resume", "--out", str(out)]) == 2
    assert "other candidates" in capsys.readouterr().err
