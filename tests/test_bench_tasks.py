"""Exp. 2a task generation: determinism, validity for all three systems, file validation."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.arm.ik import IKSettings, solve_pose_ik
from articutool.arm.model import ArmModel
from articutool.arm.scene import Scene
from articutool.bench.taskfile import FILE_VERSION, TaskFileError, load_task_set, save_task_set
from articutool.bench.tasks import generate_tasks, tip_tilt_deg
from articutool.cli import main
from articutool.tool.kinematics import nearest_leveling_solution

LEVEL_TOL_DEG = 0.1  # IK converges to 1e-3 rad ≈ 0.057°


@pytest.fixture(scope="module")
def models(spec):
    scene = Scene.load()
    return ArmModel(spec, "spoon", 6, scene), ArmModel(spec, "spoon", 8, scene)


@pytest.fixture(scope="module")
def small_set(spec):
    return generate_tasks(spec, 6, seed=11)


def _assert_valid(task_set, spec, models):
    m6, m8 = models
    assert task_set.tasks, "the filter kept no task"
    for t, extra in zip(task_set.tasks, task_set.extras, strict=True):
        for q, w, tip in ((t.start, t.start_wrist, extra["start_tip"]),
                          (t.goal, t.goal_wrist, extra["goal_tip"])):
            q = np.array(q)
            assert np.all(q >= spec.arm.lower) and np.all(q <= spec.arm.upper)
            # strict6: the rigid tool is level and collision-free, the tip on its target.
            assert not m6.in_collision(q)
            assert tip_tilt_deg(m6, q) < LEVEL_TOL_DEG
            assert np.linalg.norm(m6.tip_pose(q)[:3, 3] - tip[:3]) < 1e-3
            # strict8: arm + stored wrist angles, level and collision-free.
            q8 = np.concatenate([q, w])
            assert np.all(np.abs(w) <= [spec.wrist.pitch_limits[1], spec.wrist.roll_limits[1]])
            assert not m8.in_collision(q8)
            assert tip_tilt_deg(m8, q8) < LEVEL_TOL_DEG
            # decoupled: a leveling wrist solution exists inside the limits for this arm pose.
            R = m6.tool_base_rotations(q)
            wl, found = nearest_leveling_solution(R.T @ [0.0, 0.0, 1.0], spec.wrist.limits,
                                                  [0.0, 0.0])
            assert found
            assert tip_tilt_deg(m8, np.concatenate([q, wl])) < 1e-5
        assert not np.allclose(t.start, t.goal)


def test_generation_is_deterministic_given_the_seed(spec, small_set):
    # The candidates come one after another from the seed's stream: seed 11's first three
    # drawn again are the small set's first three (half the IK of drawing all six again).
    again = generate_tasks(spec, 3, seed=11)
    first = [i for i, t in enumerate(small_set.tasks) if t.task_id < 3]
    assert again.tasks == tuple(small_set.tasks[i] for i in first)
    assert again.extras == tuple(small_set.extras[i] for i in first)
    other = generate_tasks(spec, 3, seed=12)
    assert other.tasks
    assert other.to_dict()["tasks"] != small_set.to_dict()["tasks"][: len(other.tasks)]


def test_generated_tasks_are_level_and_collision_free_for_all_systems(spec, models, small_set):
    _assert_valid(small_set, spec, models)
    assert small_set.candidates == 6
    kept = {t.task_id for t in small_set.tasks}
    assert kept <= set(range(6))
    # Each rejected candidate is charged to at least one and at most every system.
    r = small_set.ik_rejections.values()
    assert max(r) <= 6 - len(kept) <= sum(r)


def test_start_over_the_food_and_goal_in_front_of_the_user(small_set):
    scene = Scene.load()
    head = scene.get("user_head")
    for extra in small_set.extras:
        food = scene.get(extra["source"])
        s = np.array(extra["start_tip"][:3])
        assert np.hypot(*(s[:2] - food.xyz[:2])) < food.radius
        assert s[2] > food.xyz[2]
        g = np.array(extra["goal_tip"][:3])
        assert g[1] < head.xyz[1] - head.radius  # in front of the face
        assert abs(g[0] - head.xyz[0]) < 0.1


def test_packaged_task_set_is_valid(spec, models):
    ts = load_task_set()
    assert ts.seed == 2025 and ts.candidates == 100
    assert 0 < len(ts.tasks) <= 100
    assert len(ts.tasks) == ts.candidates - sum(
        1 for k in range(ts.candidates) if k not in {t.task_id for t in ts.tasks})
    _assert_valid(ts, spec, models)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6), st.integers(0, 2**31 - 1))
def test_pose_ik_recovers_a_reachable_pose(models, offsets, seed):
    m6, _ = models
    lo, hi = m6.lower, m6.upper
    home = np.array([-1.47568, 2.92779, 1.00845, -2.0847, 1.43588, 1.32575])
    q_true = np.clip(home + 0.4 * np.array(offsets), lo, hi)
    target = m6.tip_pose(q_true)
    q0 = np.clip(q_true + np.random.default_rng(seed).normal(0, 0.1, 6), lo, hi)
    q = solve_pose_ik(m6, "tip", target, q0, IKSettings())
    assert q is not None
    T = m6.tip_pose(q)
    assert np.linalg.norm(T[:3, 3] - target[:3, 3]) < 2e-4
    assert np.linalg.norm(T[:3, :3] - target[:3, :3]) < 5e-3


def test_save_load_roundtrip_and_refuse_overwrite(tmp_path, small_set):
    p = tmp_path / "tasks.json"
    save_task_set(small_set, p)
    back = load_task_set(p)
    assert back.tasks == small_set.tasks
    assert back.sha256 == small_set.sha256
    assert (back.seed, back.spec_hash, back.generator_version) == (
        small_set.seed, small_set.spec_hash, small_set.generator_version)
    before = p.read_bytes()
    with pytest.raises(TaskFileError, match="refusing to overwrite"):
        save_task_set(small_set, p)
    assert p.read_bytes() == before


def _doc(small_set):
    return json.loads(json.dumps(small_set.to_dict()))


@pytest.mark.parametrize(
    ("mutate", "field"),
    [
        (lambda d: d["tasks"][0].pop("goal"), "tasks[0].goal"),
        (lambda d: d["tasks"][1].__setitem__("start", d["tasks"][1]["start"][:5]),
         "tasks[1].start"),
        (lambda d: d["tasks"][0].__setitem__("start_wrist", [0.0, 0.0, 0.0]),
         "tasks[0].start_wrist"),
        (lambda d: d["tasks"][0]["goal"].__setitem__(2, math.nan), "tasks[0].goal[2]"),
        (lambda d: d["tasks"][0]["start"].__setitem__(0, "x"), "tasks[0].start[0]"),
        (lambda d: d.__setitem__("version", FILE_VERSION + 1), "version"),
        (lambda d: d.pop("seed"), "seed"),
        (lambda d: d["tasks"][1].__setitem__("task_id", d["tasks"][0]["task_id"]),
         "duplicate task_id"),
        (lambda d: d["tasks"][0].__setitem__("task_id", -1), "tasks[0].task_id"),
        (lambda d: d.__setitem__("format", "something else"), "format"),
        (lambda d: d["tasks"][0].__setitem__("bogus", 1), "tasks[0].bogus"),
    ],
)
def test_malformed_task_file_is_refused_naming_the_field(tmp_path, small_set, mutate, field):
    d = _doc(small_set)
    mutate(d)
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(d))  # NaN is written as the JSON extension literal NaN
    with pytest.raises(TaskFileError) as err:
        load_task_set(p)
    assert field in str(err.value)


def test_unreadable_and_non_json_files_are_refused(tmp_path):
    with pytest.raises(TaskFileError, match="cannot read"):
        load_task_set(tmp_path / "missing.json")
    p = tmp_path / "bad.json"
    p.write_text('{"version": 1, "tasks": [')
    with pytest.raises(TaskFileError, match="not valid JSON"):
        load_task_set(p)


def test_cli_tasks_writes_a_valid_file_and_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "t.json"
    assert main(["bench", "tasks", "--count", "3", "--seed", "5", "--out", str(out)]) == 0
    ts = load_task_set(out)
    assert ts.seed == 5 and ts.candidates == 3
    assert f"kept {len(ts.tasks)} of 3" in capsys.readouterr().out
    before = out.read_bytes()
    assert main(["bench", "tasks", "--count", "3", "--seed", "6", "--out", str(out)]) == 2
    assert "refusing to overwrite" in capsys.readouterr().err
    assert out.read_bytes() == before
    assert main(["bench", "tasks", "--count", "0", "--seed", "6",
                    "--out", str(tmp_path / "u.json")]) == 2
    assert not (tmp_path / "u.json").exists()
