"""Decoupled transports are collision-checked as executed: arm + leveling wrist.

The leveling wrist swings the utensil by up to ~90° during a transport, so a check with the
wrist locked at zero misses collisions: on the packaged task set such a check passes 5 of 87
plans that hit the user's head or torso, or the arm base, with the spoon (tasks 44, 49, 53,
55 and 89 with seed 0).
"""

from __future__ import annotations

import numpy as np
import pytest

from articutool.arm.model import ArmModel
from articutool.bench.taskfile import load_task_set
from articutool.planning.api import plan
from articutool.planning.queries import dense_times
from articutool.planning.types import PlanRequest, PlanResult

TASKS = {t.task_id: t for t in load_task_set().tasks}


@pytest.fixture(scope="module")
def executed(spec):
    """The 8-DOF arm + tool, as the tool executes a decoupled plan."""
    return ArmModel(spec, utensil="spoon", dof=8)


def _executed_collisions(executed: ArmModel, r: PlanResult
                         ) -> list[tuple[float, list[tuple[str, str]]]]:
    """Collisions of the 8-DOF tool along the arm trajectory with the verifier's wrist."""
    assert r.trajectory is not None and r.wrist_trajectory is not None
    t = dense_times(r.trajectory, 0.025)
    q = np.hstack([r.trajectory.sample(t)[0], r.wrist_trajectory.sample(t)[0]])
    return [(float(t[k]), executed.colliding_pairs(q[k]))
            for k in range(len(t)) if executed.in_collision(q[k])]


@pytest.mark.parametrize("task_id", [44, 53])
def test_decoupled_plan_is_collision_free_with_its_leveling_wrist(
        spec, executed, task_id: int) -> None:
    r = plan(PlanRequest("decoupled", TASKS[task_id], timeout_s=30.0, seed=0), spec)
    assert r.success, r.message
    assert _executed_collisions(executed, r) == []


@pytest.mark.slow
def test_every_decoupled_plan_of_the_packaged_set_is_collision_free_as_executed(
        spec, executed) -> None:
    hits = {}
    for task_id, task in TASKS.items():
        r = plan(PlanRequest("decoupled", task, timeout_s=20.0, seed=0), spec)
        if r.success:
            c = _executed_collisions(executed, r)
            if c:
                hits[task_id] = c[0]
    assert hits == {}
