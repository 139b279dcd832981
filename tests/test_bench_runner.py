"""Exp. 2a runner: resumable JSONL log, executors (process pool, Dask), reports, CLI refusals.

Most tests inject ``fake_plan`` (a stand-in for the OMPL planners, defined at module level so
worker processes can unpickle it); ``test_cli_json_with_the_real_planner`` runs the real
``planning.api.plan`` on one task.
"""

from __future__ import annotations

import json
import math
import os
import re

import pytest

from articutool.bench import report
from articutool.bench.executors import DaskExecutor, ExecutorError, LocalExecutor
from articutool.bench.runner import (
    RunConfig,
    RunConfigError,
    make_trials,
    parse_planners,
    read_log,
    record_key,
    run_trial,
    run_trials,
)
from articutool.bench.taskfile import load_task_set, save_task_set
from articutool.cli import main
from articutool.planning.types import PLANNERS, PlanRequest, PlanResult, TransportTask

# ------------------------------------------------------------- stand-ins --


def _solvable(req: PlanRequest) -> bool:
    if req.tolerance_deg is not None:  # sweep: looser tolerance solves more tasks
        return req.task.task_id % 4 < req.tolerance_deg / 10
    return (req.task.task_id + len(req.planner)) % 3 != 0


def fake_plan(req: PlanRequest, spec) -> PlanResult:
    """Deterministic stand-in: success and time depend on the task and the planner."""
    ok = _solvable(req)
    return PlanResult(
        planner=req.planner, task_id=req.task.task_id, success=ok,
        planning_time_s=0.01 * (req.task.task_id + 1) * (1 + PLANNERS.index(req.planner)),
        attempts=1, verification_rejections=0, path_length=1.5 if ok else math.nan,
        max_tilt_deg=3.0 if ok else math.nan,
        verified=ok if req.planner == "decoupled" else None,
        message="fake", trajectory=None, wrist_trajectory=None)


def crashing_plan(req: PlanRequest, spec) -> PlanResult:
    """Kills its worker process on task 2 (a segfaulting planner), else like fake_plan."""
    if req.task.task_id == 2:
        os._exit(3)
    return fake_plan(req, spec)


def raising_plan(req: PlanRequest, spec) -> PlanResult:
    raise RuntimeError("planner bug")


def _tasks(n: int) -> list[TransportTask]:
    return [TransportTask(k, tuple([0.1 * k] * 6), tuple([0.2 + 0.1 * k] * 6)) for k in range(n)]


@pytest.fixture(scope="module")
def pool():
    ex = LocalExecutor(2)
    yield ex
    ex.close()


# ------------------------------------------------------------------- log --


def test_resume_runs_only_the_missing_trials_and_ignores_a_torn_line(tmp_path, pool):
    trials = make_trials(_tasks(3), ["decoupled", "strict6"], timeout_s=5.0, seed=7)
    log = tmp_path / "results.jsonl"
    # A previous run finished two trials, then died while writing the third.
    done = [run_trial(trials[0], fake_plan), run_trial(trials[3], fake_plan)]
    torn = json.dumps(run_trial(trials[1], fake_plan))[:40]
    log.write_text("".join(json.dumps(r) + "\n" for r in done) + torn)
    state = read_log(log)
    assert (len(state.records), state.torn, state.corrupt) == (2, 1, 0)

    res = run_trials(trials, log, pool, plan_fn=fake_plan)
    assert (res.ran, res.skipped, res.torn, res.lost) == (4, 2, 1, [])
    state = read_log(log)
    assert (state.torn, state.corrupt) == (0, 0)
    keys = [record_key(r) for r in state.records]
    assert sorted(keys, key=str) == sorted((t.key for t in trials), key=str)
    assert len(set(keys)) == len(keys) == 6
    assert keys[:2] == [trials[0].key, trials[3].key]  # the old lines are untouched

    again = run_trials(trials, log, pool, plan_fn=fake_plan)
    assert (again.ran, again.skipped) == (0, 6)
    assert len(read_log(log).records) == 6


def test_a_worker_crash_loses_no_finished_trial(tmp_path):
    trials = make_trials(_tasks(4), ["strict6"], timeout_s=5.0)
    log = tmp_path / "results.jsonl"
    ex = LocalExecutor(1)
    try:
        res = run_trials(trials, log, ex, plan_fn=crashing_plan)
    finally:
        ex.close()
    logged = {record_key(r)[1] for r in read_log(log).records}
    assert 2 in {t.task.task_id for t, _ in res.lost}
    assert 2 not in logged
    assert logged | {t.task.task_id for t, _ in res.lost} == {0, 1, 2, 3}
    assert {0, 1} <= logged  # finished before the crash, durable
    ex = LocalExecutor(1)
    try:
        res2 = run_trials(trials, log, ex, plan_fn=fake_plan)
    finally:
        ex.close()
    assert res2.ran == 4 - len(logged) and not res2.lost
    assert {record_key(r)[1] for r in read_log(log).records} == {0, 1, 2, 3}


def test_a_planner_exception_is_a_failed_record_not_a_crash():
    (trial,) = make_trials(_tasks(1), ["strict8"], timeout_s=1.0)
    rec = run_trial(trial, raising_plan)
    assert rec["success"] is False
    assert "RuntimeError: planner bug" in rec["error"]
    assert record_key(rec) == trial.key


def test_corrupt_middle_line_is_skipped_and_counted(tmp_path):
    (t0, t1) = make_trials(_tasks(2), ["strict6"], timeout_s=1.0)
    log = tmp_path / "r.jsonl"
    log.write_text(json.dumps(run_trial(t0, fake_plan)) + "\n{not json\n"
                   + json.dumps(run_trial(t1, fake_plan)) + "\n")
    state = read_log(log)
    assert (len(state.records), state.corrupt, state.torn) == (2, 1, 0)


def test_resume_with_other_settings_is_refused(tmp_path):
    cfg = RunConfig("abc", 30.0, "rrtconnect", "spoon", "h")
    cfg.check_or_write(tmp_path / "run.json")
    cfg.check_or_write(tmp_path / "run.json")  # same settings: fine
    with pytest.raises(RunConfigError, match=re.escape("timeout_s 30.0 → 10.0")):
        RunConfig("abc", 10.0, "rrtconnect", "spoon", "h").check_or_write(tmp_path / "run.json")


@pytest.mark.parametrize(
    ("kwargs", "msg"),
    [
        ({"planners": ["decoupled", "strict7"]}, "unknown system 'strict7'"),
        ({"planners": []}, "at least one"),
        ({"timeout_s": 0.0}, "--timeout"),
        ({"timeout_s": -1.0}, "--timeout"),
        ({"timeout_s": math.nan}, "--timeout"),
        ({"algorithm": "prm"}, "--planner"),
        ({"seed": -1}, "--seed"),
    ],
)
def test_make_trials_validates(kwargs, msg):
    args = {"planners": ["decoupled"], "timeout_s": 1.0} | kwargs
    with pytest.raises(RunConfigError, match=msg):
        make_trials(_tasks(1), **args)


def test_parse_planners_keeps_order_and_drops_duplicates():
    assert parse_planners("strict8, decoupled,strict8") == ("strict8", "decoupled")


# ---------------------------------------------------------------- reports --


def test_summary_json_shape_plots_and_csv(tmp_path, pool):
    planners = ("decoupled", "strict6", "strict8")
    trials = make_trials(_tasks(6), planners, timeout_s=5.0)
    res = run_trials(trials, tmp_path / "results.jsonl", pool, plan_fn=fake_plan)
    s = report.summarize(res.records, planners)
    assert set(s) == set(planners)
    for name, v in s.items():
        expected = [t for t in trials if t.planner == name]
        solved = [t for t in expected if _solvable(PlanRequest(name, t.task))]
        assert v["trials"] == 6 and v["successes"] == len(solved)
        assert v["success_rate"] == pytest.approx(len(solved) / 6)
        times = sorted(0.01 * (t.task.task_id + 1) * (1 + PLANNERS.index(name)) for t in solved)
        assert v["median_time_s"] == pytest.approx(times[len(times) // 2] if len(times) % 2
                                                   else sum(times[len(times) // 2 - 1:
                                                                  len(times) // 2 + 1]) / 2)
        assert v["mean_time_s"] == pytest.approx(sum(times) / len(times))
        assert v["median_time_s"] <= v["p90_time_s"] <= max(times)
        assert v["thesis_success_rate"] == report.THESIS[name]["success_rate"]
    assert s["decoupled"]["verified"] == s["decoupled"]["successes"]
    assert s["strict6"]["verified"] is None
    json.dumps(s, allow_nan=False)  # strict JSON

    csv_path = report.write_results_csv(res.records, tmp_path / "results.csv")
    lines = csv_path.read_text().splitlines()
    assert lines[0].split(",") == list(report.CSV_FIELDS)
    assert len(lines) == 1 + len(trials)
    png = report.cactus_plot(res.records, planners, tmp_path / "cactus.png", timeout_s=5.0)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_tolerance_sweep_summary_and_plot(tmp_path, pool):
    tols = (5.0, 10.0, 20.0, 45.0)
    trials = make_trials(_tasks(8), ["strict6"], timeout_s=5.0, tolerances_deg=tols)
    res = run_trials(trials, tmp_path / "sweep.jsonl", pool, plan_fn=fake_plan)
    sweep = report.summarize_sweep(res.records)
    assert list(sweep) == list(tols)
    rates = [sweep[t]["success_rate"] for t in tols]
    assert rates == [pytest.approx(sum(k % 4 < t / 10 for k in range(8)) / 8) for t in tols]
    csv_path = report.write_sweep_csv(sweep, tmp_path / "tolerance_sweep.csv")
    assert len(csv_path.read_text().splitlines()) == 1 + len(tols)
    png = report.tolerance_sweep_plot(sweep, tmp_path / "tolerance_sweep.png")
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_render_table_lists_every_planner_beside_the_thesis():
    from rich.console import Console

    recs = [run_trial(t, fake_plan) for t in make_trials(_tasks(3), PLANNERS, timeout_s=1.0)]
    console = Console(record=True, width=200)
    console.print(report.render_table(report.summarize(recs, PLANNERS)))
    text = console.export_text()
    for name in PLANNERS:
        assert name in text
    assert "96.0 %" in text and "75.70 s" in text


# ------------------------------------------------------------------- Dask --


def test_dask_executor_on_a_local_cluster(tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        ex = DaskExecutor(cluster.scheduler_address)
        try:
            assert "127.0.0.1" in ex.description
            trials = make_trials(_tasks(4), ["decoupled", "strict8"], timeout_s=5.0)
            log = tmp_path / "results.jsonl"
            res = run_trials(trials, log, ex, plan_fn=fake_plan)
            assert (res.ran, res.lost) == (8, [])
            state = read_log(log)
            assert {record_key(r) for r in state.records} == {t.key for t in trials}
            local = [run_trial(t, fake_plan) for t in trials]
            by_key = {record_key(r): r for r in state.records}
            assert all(by_key[record_key(r)] == r for r in local)
        finally:
            ex.close()


def test_dask_executor_refuses_an_unreachable_scheduler():
    with pytest.raises(ExecutorError, match="cannot connect"):
        DaskExecutor("tcp://127.0.0.1:9", timeout_s=1.0)


# -------------------------------------------------------------------- CLI --


@pytest.fixture
def tiny_tasks(tmp_path):
    ts = load_task_set()
    from dataclasses import replace

    small = replace(ts, tasks=ts.tasks[:1], extras=ts.extras[:1])
    p = tmp_path / "tasks.json"
    save_task_set(small, p)
    return p


@pytest.mark.parametrize(
    ("args", "msg"),
    [
        (["--systems", "decoupled,bogus"], "unknown system 'bogus'"),
        (["--timeout", "0"], "--timeout"),
        (["--timeout", "-3"], "--timeout"),
        (["--timeout", "nan"], "--timeout"),
        (["--workers", "0"], "--workers"),
        (["--tasks", "MALFORMED"], "tasks[0].start"),
        (["--tasks", "MISSING"], "cannot read"),
        (["--seed", "-1"], "--seed"),
    ],
)
def test_cli_refuses_bad_input_before_any_work(tmp_path, capsys, tiny_tasks, args, msg):
    bad = tmp_path / "bad.json"
    doc = json.loads(tiny_tasks.read_text())
    doc["tasks"][0]["start"] = doc["tasks"][0]["start"][:4]
    bad.write_text(json.dumps(doc))
    args = [{"MALFORMED": str(bad), "MISSING": str(tmp_path / "nope.json")}.get(a, a)
            for a in args]
    if "--tasks" not in args:
        args += ["--tasks", str(tiny_tasks)]
    out = tmp_path / "out"
    code = main(["bench", "transport", "--out", str(out), *args])
    assert code == 2
    assert msg in capsys.readouterr().err
    assert not (out / "results.jsonl").exists()


def test_cli_json_with_the_real_planner(tmp_path, capsys, tiny_tasks):
    out = tmp_path / "out"
    argv = ["bench", "transport", "--tasks", str(tiny_tasks), "--systems", "decoupled",
            "--timeout", "10", "--workers", "1", "--out", str(out), "--json"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert list(summary) == ["decoupled"]
    d = summary["decoupled"]
    for key in ("success_rate", "median_time_s", "mean_time_s", "p90_time_s"):
        assert key in d
    assert d["trials"] == 1
    (rec,) = read_log(out / "results.jsonl").records
    assert rec["success"] == (d["successes"] == 1)
    if rec["success"]:
        assert 0 < d["median_time_s"] == rec["planning_time_s"]
        assert rec["verified"] is True
    assert (out / "results.csv").exists() and (out / "cactus.png").exists()
    # Rerunning resumes: nothing left to do, same summary.
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out) == summary
    # Other settings in the same directory are refused before any work.
    assert main([*argv[:-1], "--planner", "rrtstar", "--json"]) == 2
    assert "other settings" in capsys.readouterr().err
