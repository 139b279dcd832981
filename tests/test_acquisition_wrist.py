"""Acquisition that uses the wrist, in physics through the real feeding tree."""

from __future__ import annotations

import numpy as np
import pytest
from py_trees.common import Status

from articutool.api_types import JobResult
from articutool.feeding.behaviours import Board, Execute
from articutool.tool.api import ToolState
from articutool.trajectory import JointTrajectory

ARM = tuple(f"a{i}" for i in range(6))


class _Arm:
    def __init__(self) -> None:
        self.started: list[JointTrajectory] = []
        self.busy = True

    def start_execute(self, traj: JointTrajectory) -> object:
        self.started.append(traj)
        arm = self

        class Job:
            def done(self) -> bool:
                return not arm.busy

            def result(self) -> JobResult:
                return JobResult(True, "arrived")

            def cancel(self) -> None:
                arm.busy = False

        return Job()

    def stop(self) -> None:
        self.busy = False


class _Tool:
    def __init__(self, accept: bool) -> None:
        self.accept, self.followed, self.position = accept, [], (0.0, 0.0)

    def follow_trajectory(self, traj: JointTrajectory, start_delay: float = 0.0):
        if not self.accept:
            return False, "trajectory refused: test"
        self.followed.append(traj)
        return True, "following"

    def state(self) -> ToolState:
        return ToolState(0.0, 0, ("p", "r"), self.position, (0.0, 0.0), (1.0, 0.0, 0.0, 0.0),
                         (0.0, 0.0, 0.0), (0.0, 0.0, 9.81))


def _execute(tool: _Tool, wrist_moves: bool = True) -> tuple[Execute, _Arm, list[float]]:
    t = [0.0]
    arm = _Arm()
    board = Board()
    ex = Execute(arm, "sweep", tool, lambda: t[0], board=board)  # type: ignore[arg-type]
    pitch = np.linspace(0.0, -0.5 if wrist_moves else 0.0, 11)
    pos = np.column_stack([np.zeros((11, 6)), pitch, np.zeros(11)])
    board.trajectory = JointTrajectory(
        (*ARM, "p", "r"), np.linspace(0.0, 1.0, 11), pos, np.zeros((11, 8)))
    return ex, arm, t


def test_a_wrist_made_path_sends_the_wrist_its_part_as_the_arm_starts() -> None:
    tool = _Tool(accept=True)
    ex, arm, t = _execute(tool)
    ex.tick_once()
    assert len(arm.started) == 1 and len(tool.followed) == 1
    assert tool.followed[0].joint_names == ("p", "r")
    np.testing.assert_allclose(tool.followed[0].positions[-1], [-0.5, 0.0])
    t[0] = 0.5  # the reference is at −0.25 rad; the wrist reads 0.05 rad behind it
    tool.position = (-0.2, 0.0)
    ex.tick_once()
    assert ex.status == Status.RUNNING
    assert ex.wrist_tracking_error == pytest.approx(0.05, abs=1e-6)
    arm.busy = False
    ex.tick_once()
    assert ex.status == Status.SUCCESS and "wrist tracking error" in ex.feedback_message


def test_a_refused_wrist_part_fails_before_the_arm_moves() -> None:
    tool = _Tool(accept=False)
    ex, arm, _ = _execute(tool)
    ex.tick_once()
    assert ex.status == Status.FAILURE and "refused" in ex.feedback_message
    assert arm.started == []


def test_a_path_whose_wrist_does_not_move_leaves_the_tool_alone() -> None:
    tool = _Tool(accept=True)
    ex, arm, _ = _execute(tool, wrist_moves=False)
    ex.tick_once()
    assert len(arm.started) == 1 and tool.followed == []


@pytest.mark.slow
def test_the_wrist_made_scoop_level_brings_water_up_through_the_tree() -> None:
    pytest.importorskip("mujoco")
    from articutool.meal.bites import DEFAULT_SETTINGS, _tree, make_bite_world, run_bite

    # ~1 min of physics: dip tilted, the wrist levels in the water while the arm moves the
    # spoon along its heading, rise, shed over the bowl, transport to Resting.
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
