"""The Exp. 2b staging set in the scene: every configuration in the joint limits, the locked
utensil level, collision-free, the goals spread out, and each goal reached from the common
start by both the decoupled planner and the baseline's strict ±20° planner."""

from __future__ import annotations

import numpy as np
import pytest

from articutool.arm.model import ArmModel
from articutool.arm.scene import Scene, SceneError
from articutool.experiments.config import ExperimentsConfig
from articutool.planning.api import plan
from articutool.planning.types import PlanRequest, TransportTask

SSET = Scene.load().staging_set


def test_the_scene_defines_a_start_and_five_goals() -> None:
    assert SSET is not None and len(SSET.goals) == 5
    with pytest.raises(KeyError, match="known"):
        SSET.goal("nowhere")


def test_a_malformed_staging_set_is_refused_naming_the_field() -> None:
    with pytest.raises(SceneError, match="staging_set"):
        Scene.from_dict({"staging_set": {"start": [0.0] * 5, "goals": []}})


@pytest.mark.parametrize("utensil", ["spoon", "soup_spoon"])
def test_every_configuration_is_level_collision_free_and_in_limits(spec, utensil: str) -> None:
    model = ArmModel(spec, utensil=utensil)
    tips = []
    for q in [SSET.start, *(g.q for g in SSET.goals)]:
        q = np.asarray(q)
        assert np.all(q >= spec.arm.lower) and np.all(q <= spec.arm.upper)
        q8 = np.r_[q, 0.0, 0.0]
        T = model.tip_pose(q8)
        assert np.degrees(np.arccos(min(1.0, T[2, 1]))) < 1.0  # tip y axis ("up") vertical
        assert not model.in_collision(q8)
        tips.append(T[:3, 3])
    goals = np.array(tips[1:])
    d = np.linalg.norm(goals[:, None] - goals[None], axis=-1)
    assert d[np.triu_indices(5, 1)].min() > 0.05  # spread: no two goals within 5 cm


@pytest.mark.parametrize("planner", ["decoupled", "strict6"])
def test_every_goal_is_reached_from_the_start_by_both_planners(spec, planner: str) -> None:
    cfg = ExperimentsConfig.load()
    tol = None if planner == "decoupled" else cfg.settings.arm_tolerance_deg
    for utensil in ("spoon", "soup_spoon"):
        for g in SSET.goals:
            task = TransportTask(0, tuple(SSET.start), tuple(g.q))
            r = plan(PlanRequest(planner=planner, task=task, timeout_s=cfg.settings.plan_budget_s,
                                 seed=0, tolerance_deg=tol, utensil=utensil), spec)
            assert r.success, f"{g.name} {utensil}: {r.message}"
