"""studies/shedding_sweep.py: the control gets as many candidates as the shedding primitive
(the same budget), each candidate is the shipped action library with exactly the one part of
Exp. 2c's strategy changed and loadable by the real library, and Exp. 2c's trial reads the
library it is given; bad input exits 2. The sweeps themselves (minutes to an hour) are the
study, not a test."""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import pytest

from articutool.datafile import read_document
from articutool.experiments.config import ExperimentsConfig
from articutool.feeding.strategies import StrategyError, StrategyLibrary, default_strategies_path
from articutool.spec import load_spec

STUDIES = Path(__file__).resolve().parents[1] / "studies"


@pytest.fixture
def sweep(monkeypatch):
    monkeypatch.syspath_prepend(str(STUDIES))
    return importlib.import_module("shedding_sweep")


@pytest.mark.parametrize("food", ["pecans", "water"])
def test_the_control_gets_the_primitives_budget_starting_from_the_shipped_transport(
        sweep, food) -> None:
    prims = sweep.candidates(food, "primitive")
    ctrl = sweep.candidates(food, "control")
    assert len(ctrl) == len(prims) and len({sweep.label(c) for c in ctrl}) == len(ctrl)
    name = ExperimentsConfig.load().exp2c.strategy[food]
    shipped = StrategyLibrary.load(load_spec()).strategies[name]
    assert ctrl[0]["transport"] == shipped.transport.model_dump(exclude_none=True,
                                                                exclude_defaults=True)


@pytest.mark.parametrize(("food", "condition"), [("pecans", "primitive"),
                                                 ("water", "primitive"),
                                                 ("water", "control")])
def test_each_candidate_changes_only_its_part_of_the_strategy(sweep, food, condition) -> None:
    spec = load_spec()
    name = ExperimentsConfig.load().exp2c.strategy[food]
    raw = read_document(default_strategies_path(), "strategy file", StrategyError)
    shipped = StrategyLibrary.from_dict(raw, spec).strategies
    for change in sweep.candidates(food, condition):
        lib = StrategyLibrary.from_dict(sweep.candidate_library(raw, name, change), spec)
        got = lib.strategies
        assert {k: v for k, v in got.items() if k != name} == {
            k: v for k, v in shipped.items() if k != name}
        if condition == "primitive":
            stage = got[name].stages.post_acquisition
            want = change["post_acquisition"]
            assert (stage.primitive, list(stage.params)) == (want["primitive"], want["params"])
            assert got[name].model_copy(update={"stages": shipped[name].stages}) == shipped[name]
        else:
            assert got[name].transport.planner == change["transport"]["planner"]
            assert got[name].model_copy(update={"transport": shipped[name].transport}) == \
                shipped[name]


def test_exp2c_reads_the_action_library_it_is_given(tmp_path) -> None:
    from articutool.experiments.units.exp2c import Exp2cCondition, exp2c_trial

    missing = tmp_path / "none.json"
    cond = Exp2cCondition(food="pecans", condition="control", load_g=2.0,
                          strategies=str(missing))
    with pytest.raises(StrategyError, match=r"none\.json"):
        exp2c_trial(cond, 0, ExperimentsConfig.load())
    assert "strategies" not in Exp2cCondition(food="pecans", condition="control",
                                              load_g=2.0).fields()


def test_bad_input_exits_2_before_any_trial(sweep, tmp_path, capsys) -> None:
    out = tmp_path / "s.json"
    out.write_text("{}")
    assert sweep.main(["--food", "pecans", "--out", str(out)]) == 2
    assert json.loads(out.read_text()) == {}
    assert sweep.main(["--food", "pecans", "--seeds", "0", "--out",
                       str(tmp_path / "a.json")]) == 2
    assert sweep.main(["--food", "water", "--results", str(tmp_path / "none"), "--out",
                       str(tmp_path / "b.json")]) == 2
    err = capsys.readouterr().err
    assert "exists" in err and "--seeds" in err and "--load-g" in err
    assert not (tmp_path / "a.json").exists() and not (tmp_path / "b.json").exists()
