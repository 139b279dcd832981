"""Acquisition that uses the wrist (issue 25), in physics through the real feeding tree."""

from __future__ import annotations

import py_trees
import pytest

pytest.importorskip("mujoco")

from articutool.feeding.behaviours import Execute
from articutool.feeding.meal import DEFAULT_SETTINGS, _tree, make_bite_world, run_bite


@pytest.mark.slow
def test_the_wrist_made_scoop_level_brings_water_up_through_the_tree() -> None:
    # ~1 min of physics: dip tilted, the wrist levels in the water while the arm moves the
    # spoon along its heading, rise, shed over the bowl, transport to Resting.
    py_trees.blackboard.Blackboard.clear()
    setup = make_bite_world("water", "articutool", seed=777001)  # not an experiment seed
    assert setup.strategy.insertion.motion == "sweep"
    stages = ("above", "acquire", "shed", "resting")
    root = _tree(setup, stages, DEFAULT_SETTINGS)
    try:
        r = run_bite(setup, stages=stages, root=root)
    finally:
        setup.arm.close()
    assert r.end_state == "completed", r.failed_stage
    assert r.acquired_g > 0.0
    assert r.masses_after["resting"]["utensil"] > 0.0  # water carried to Resting
    # The wrist followed its part of the sweep (the tool's measured joints vs reference).
    errs = [n.wrist_tracking_error for n in root.iterate() if isinstance(n, Execute)]
    assert 0.0 < max(errs) < 0.2
