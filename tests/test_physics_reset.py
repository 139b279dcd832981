"""A run that MuJoCo reset after a numerical instability is detected and never counted:
MuJoCo's reset puts the arm, the wrist and the noodles back at the model's defaults
mid-transport (the fork "tilted" 146–156°, the noodles "returned" to the bowl), and a bite
that went on would count as one."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pytest

from articutool.experiments.analysis import summarize
from articutool.experiments.cli import trials_for
from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.runner import run_trial
from articutool.sim.world import FeedingWorld, PhysicsResetError


@pytest.fixture(autouse=True)
def _mujoco_log_in_tmp(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # MuJoCo appends its warnings to ./MUJOCO_LOG.TXT


def test_a_mujoco_reset_stops_the_run_and_says_where() -> None:
    w = FeedingWorld.make(None, "fork", seed=0, settle=False)
    w.run(0.1)  # a healthy world runs
    w.data.qvel[0] = np.nan  # what a blown-up contact solve leaves behind
    with pytest.raises(PhysicsResetError, match=r"mjWARN_BADQ\w+ ×1 .*DOF 0"):
        w.run(0.1)


def test_a_reset_trial_is_recorded_as_such_and_left_out_of_the_statistics(tmp_path) -> None:
    cfg = ExperimentsConfig.load()
    args = argparse.Namespace(trials=1, seed=0, load_g=None)
    trials, _ = trials_for("exp2b", args, Path(tmp_path), cfg)
    good = run_trial(trials[0])

    def blow_up(world: FeedingWorld) -> None:
        world.data.qvel[0] = np.nan

    bad = run_trial(trials[1], hook=blow_up)
    assert good.error is None
    assert bad.error is not None
    assert bad.error.startswith("PhysicsResetError: MuJoCo reset the simulation")
    s = summarize("exp2b", [good, bad], cfg)
    assert s["run"]["errors"] == 1 and s["run"]["physics_resets"] == 1
    spilled = s["spilled_g"][bad.condition.food]
    assert spilled[bad.condition.system]["n"] == 0 and spilled[good.condition.system]["n"] == 1
