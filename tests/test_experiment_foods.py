"""``articutool experiment … --foods``: one food's conditions alone, on a full run's seeds."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest

from articutool.cli_support import UsageError
from articutool.experiments.cli import trials_for
from articutool.experiments.config import ExperimentsConfig


def _trials(tmp_path: Path, foods: str | None) -> list:
    args = argparse.Namespace(trials=3, seed=0, load_g=None, foods=foods)
    return trials_for("exp1", args, tmp_path, ExperimentsConfig.load())[0]


def test_foods_keeps_only_that_foods_conditions_with_the_full_runs_seeds(tmp_path) -> None:
    full = _trials(tmp_path, None)
    only = _trials(tmp_path, "noodles")
    assert {t.condition.food for t in only} == {"noodles"}
    assert len(only) == 3 * len(ExperimentsConfig.load().exp1.systems)
    seeds = {(t.condition.system, t.repeat): t.seed for t in full if t.condition.food == "noodles"}
    assert all(seeds[(t.condition.system, t.repeat)] == t.seed for t in only)


@pytest.mark.parametrize("foods", ["soup", "noodles,soup", ",", ""])
def test_foods_outside_the_experiment_is_refused_naming_the_field(tmp_path, foods) -> None:
    if foods == "":
        assert len(_trials(tmp_path, foods)) == len(_trials(tmp_path, None))  # not given
        return
    with pytest.raises(UsageError, match="--foods"):
        _trials(tmp_path, foods)


def test_the_cli_exits_2_on_a_bad_food_and_writes_nothing(tmp_path) -> None:
    out = tmp_path / "res"
    r = subprocess.run([sys.executable, "-m", "articutool", "experiment", "exp1", "--foods",
                        "soup", "--out", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--foods" in r.stderr and "Traceback" not in r.stderr
    assert not (out / "exp1").exists()


def test_physics_file_is_carried_by_every_condition(tmp_path) -> None:
    from articutool.sim.params import default_physics_path

    f = tmp_path / "noodles125.toml"
    f.write_text(default_physics_path().read_text().replace("fill_g = 20.0", "fill_g = 125.0"))
    args = argparse.Namespace(trials=1, seed=0, load_g=None, foods="noodles", physics=str(f))
    trials = trials_for("exp1", args, tmp_path, ExperimentsConfig.load())[0]
    assert trials and all(t.condition.physics == str(f.resolve()) for t in trials)


def test_a_bad_physics_file_exits_2_naming_the_field(tmp_path) -> None:
    f = tmp_path / "bad.toml"
    f.write_text("version = 1\n")
    r = subprocess.run([sys.executable, "-m", "articutool", "experiment", "exp1", "--foods",
                        "noodles", "--physics", str(f), "--out", str(tmp_path / "res")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "--physics" in r.stderr and "Traceback" not in r.stderr
