"""The experiment runner: a killed run resumes without losing or repeating a trial; a torn
last line is cut off; a resume with other settings is refused; bad arguments exit 2 naming
the field, before any trial runs; the trial design is stable when trials are added."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

import articutool.cli as cli
from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.design import conditions, make_trials, trial_seed
from articutool.experiments.runner import (
    DataChecked,
    DataMismatchError,
    RunError,
    data_files,
    data_hash,
    log_path,
    pin_run,
    read_trial_log,
    run_experiment,
)
from conftest import wait_until

pytest.importorskip("mujoco")

ARTICUTOOL = [sys.executable, "-m", "articutool.cli"]


def _lines(p: Path) -> list[dict]:
    return [json.loads(x) for x in p.read_text().splitlines() if x.strip()]


def test_design_numbers_trials_trial_major_and_seeds_are_shared_by_conditions() -> None:
    cfg = ExperimentsConfig.load()
    conds = conditions("exp2b", cfg, goals=["a", "b", "c"])
    t4 = make_trials("exp2b", conds, 4, 2, goals=["a", "b", "c"])
    t6 = make_trials("exp2b", conds, 6, 2, goals=["a", "b", "c"])
    assert t6[: len(t4)] == t4  # more trials never renumber the ones run
    assert [t.trial for t in t4] == list(range(4 * len(conds)))
    assert {t.seed for t in t4 if t.repeat == 1} == {trial_seed(2, 1)} == {2001}
    assert [t.condition.goal for t in t6 if t.condition.system == "baseline"
            and t.condition.food == "water"] == ["a", "b", "c", "a", "b", "c"]
    with pytest.raises(ValueError, match="trials"):
        make_trials("exp2b", conds, 0, 0, goals=["a"])


RESULTS = Path(__file__).resolve().parents[1] / "results" / "experiments"


@pytest.mark.parametrize("experiment", ["capacity", "exp1", "exp2b", "exp2c"])
def test_every_committed_trial_reads_as_a_record_and_writes_back_its_own_line(
        experiment: str) -> None:
    from articutool.experiments.records import TrialRecord

    lines = (RESULTS / experiment / "trials.jsonl").read_text().splitlines()
    assert lines
    for line in lines:
        rec = TrialRecord.from_log(json.loads(line))
        assert json.dumps(rec.to_log()) == line  # same fields, values and order
        assert rec.experiment == experiment
        # a trial MuJoCo reset is kept as an error, with no outcome (docs/decisions.md)
        assert (rec.outcome is not None) != (rec.error is not None), rec.trial


def test_a_logged_record_not_as_the_protocols_write_it_is_refused_naming_the_field(
        tmp_path: Path) -> None:
    from articutool.datafile import ResultsError

    line = json.loads((RESULTS / "exp2b" / "trials.jsonl").read_text().splitlines()[0])
    log = log_path(tmp_path, "exp2b")
    log.parent.mkdir(parents=True)
    for bad, field in (({**line, "spilled_g": "a lot"}, f"trial {line['trial']}:\n  spilled_g: "),
                       ({k: v for k, v in line.items() if k != "held_g"}, "held_g: "),
                       ({**line, "spiled_g": 0.0}, "spiled_g: ")):
        log.write_text(json.dumps(bad) + "\n")
        with pytest.raises(ResultsError, match=field):
            read_trial_log(tmp_path, "exp2b")
    failed = {**line, "error": "RuntimeError: boom"}  # a trial that raised has no outcome
    log.write_text(json.dumps(failed) + "\n")
    with pytest.raises(ResultsError, match="no outcome"):
        read_trial_log(tmp_path, "exp2b")


def test_pin_run_refuses_other_settings(tmp_path: Path) -> None:
    pin_run(tmp_path / "run.json", {"seed": 0, "data_hash": "x"})
    pin_run(tmp_path / "run.json", {"seed": 0, "data_hash": "x"})  # same: a resume
    with pytest.raises(RunError, match="seed"):
        pin_run(tmp_path / "run.json", {"seed": 1, "data_hash": "x"})


class _Serial:
    """The executor protocol in this process (the runner under test is real)."""

    description = "serial"

    def run(self, fn, items, stop=None):
        for it in items:
            yield it, fn(it), None

    def close(self) -> None:
        pass


def test_a_torn_last_line_is_cut_off_and_its_trial_rerun(tmp_path: Path) -> None:
    cfg = ExperimentsConfig.load()
    goals = ["low_near"]
    trials = make_trials("exp2b", conditions("exp2b", cfg, goals=goals), 1, 0,
                         goals=goals)[:2]  # pecans: Articutool, baseline
    log = log_path(tmp_path, "exp2b")
    first = run_experiment(trials[:1], log, _Serial())
    assert first.ran == 1
    with open(log, "ab") as f:
        f.write(b'{"experiment": "exp2b", "trial": 1, "hel')  # a crash mid-write
    res = run_experiment(trials, log, _Serial())
    assert res.torn == 1 and res.skipped == 1 and res.ran == 1
    recs = _lines(log)
    assert [r["trial"] for r in recs] == [0, 1]
    assert recs[1]["system"] == "baseline" and recs[1]["held_g"] > 0


@pytest.mark.slow  # two real CLI runs with spawned workers: ~30 s on the shared 2 cores
def test_a_killed_run_resumes_and_loses_or_repeats_no_trial(tmp_path: Path) -> None:
    out = tmp_path / "res"
    cmd = [*ARTICUTOOL, "experiment", "exp2b", "--trials", "2", "--workers", "1",
           "--out", str(out)]
    env = {**os.environ, "MPLBACKEND": "Agg"}
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         start_new_session=True, env=env)
    log = log_path(out, "exp2b")
    wait_until(lambda: p.poll() is not None
               or (log.exists() and len(log.read_text().splitlines()) >= 2), 240, 0.1)
    assert p.poll() is None, "the run finished before it could be killed; use more trials"
    os.killpg(p.pid, signal.SIGKILL)  # the CLI and its worker processes, at once
    p.wait()
    before = log.read_bytes()
    done_before = {r["trial"] for r in _lines(log)} if before.endswith(b"\n") else {
        r["trial"] for r in _lines(log)[:-1]}
    # Two trials per condition; the conditions (the thesis' and the extra systems) are the run's.
    n = 2 * len(json.loads((out / "exp2b" / "run.json").read_text())["conditions"])
    assert 2 <= len(done_before) < n
    r = subprocess.run([*cmd, "--json"], capture_output=True, text=True, env=env,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    recs = _lines(log)
    trials = [x["trial"] for x in recs]
    assert sorted(trials) == list(range(n))  # none lost, none repeated
    assert log.read_bytes().startswith(before.rsplit(b"\n", 1)[0])  # old lines untouched
    assert f"{len(done_before)} already in" in r.stderr
    summary = json.loads(r.stdout)
    assert summary["run"]["trials"] == n
    assert summary["spilled_g"]["pecans"]["articutool"]["n"] == 2
    assert read_trial_log(out, "exp2b").records[0].trial == 0
    assert summary["run"]["ran_now"] == n - len(done_before)
    # Run again with nothing left: the summary is rewritten from the log and still says what
    # the last invocation that ran trials did.
    again = subprocess.run([*cmd, "--json"], capture_output=True, text=True, env=env,
                           timeout=600)
    assert again.returncode == 0, again.stderr
    kept = json.loads(again.stdout)["run"]
    for k in ("ran_now", "experiment_wall_time_s", "date", "command"):
        assert kept[k] == summary["run"][k], k


@pytest.mark.parametrize("argv, field", [
    (["capacity", "--trials", "0"], "--trials"),
    (["capacity", "--trials", "1001"], "--trials"),
    (["capacity", "--workers", "0"], "--workers"),
    (["capacity", "--seed", "-1"], "--seed"),
    (["capacity", "--trial", "99"], "--trial"),
    (["capacity", "--video", "x.mp4"], "--video needs --trial"),
    (["capacity", "--trial", "0", "--video", "x.avi"], "--video must end"),
    (["exp2c", "--trials", "1"], "capacity"),
    (["exp2c", "--load-g", "pecans=abc"], "--load-g"),
    (["exp2c", "--load-g", "pecans=7"], "--load-g: no load"),
    (["exp3", "--threshold-g", "-1"], "--threshold-g"),
    (["report"], "--out"),
])
def test_bad_arguments_exit_2_naming_the_field_and_run_nothing(tmp_path, capsys, argv,
                                                               field) -> None:
    out = tmp_path / ("missing" if argv == ["report"] else "res")
    code = cli.main(["experiment", *argv, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert field in err and "Traceback" not in err
    assert not any(out.rglob("trials.jsonl")) if out.exists() else True


def test_out_that_is_a_file_and_an_existing_video_are_refused(tmp_path, capsys) -> None:
    f = tmp_path / "file"
    f.write_text("keep")
    assert cli.main(["experiment", "capacity", "--out", str(f)]) == 2
    assert "--out" in capsys.readouterr().err and f.read_text() == "keep"
    v = tmp_path / "v.mp4"
    v.write_text("keep")
    assert cli.main(["experiment", "capacity", "--trial", "0", "--video", str(v),
                     "--out", str(tmp_path / "r")]) == 2
    assert "refusing to overwrite" in capsys.readouterr().err and v.read_text() == "keep"


def test_resume_with_another_seed_is_refused(tmp_path, capsys) -> None:
    out = tmp_path / "r"
    (out / "capacity").mkdir(parents=True)
    pin_run(out / "capacity" / "run.json", {"experiment": "capacity", "seed": 5})
    assert cli.main(["experiment", "capacity", "--trials", "1", "--out", str(out)]) == 2
    assert "seed" in capsys.readouterr().err
    assert not log_path(out, "capacity").exists()


def _trials_stopped_before_physics(monkeypatch: pytest.MonkeyPatch) -> list:
    """The trial specs the command hands to ``run_trial``, which stops each at once (an
    error, no physics)."""
    import articutool.experiments.runner as runner

    got: list = []

    def fake(spec, *_: object, **__: object):
        got.append(spec)
        return SimpleNamespace(error="stopped here")

    monkeypatch.setattr(runner, "run_trial", fake)
    return got


def test_a_replay_runs_the_logged_runs_conditions_when_todays_inputs_moved(
        tmp_path, capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    """Exp. 2c's loads and target come from capacity's and Exp. 1's results: after those ran
    again, ``--trial K`` still replays trial K with the load and target its run pinned (and
    says so), not today's, so it can reproduce the record."""
    out = tmp_path / "r"
    argv = ["experiment", "exp2c", "--out", str(out), "--load-g", "pecans=5,water=15",
            "--thresholds-g", "pecans=2,water=8"]
    cfg = ExperimentsConfig.load()
    today = [c.fields() for c in conditions("exp2c", cfg, load_g={"pecans": 5.0, "water": 15.0},
                                              target_g={"water": 8.5})]
    pinned = [{**c, "load_g": 16.0 if c["food"] == "water" else c["load_g"]} for c in today]
    (out / "exp2c").mkdir(parents=True)
    pin_run(out / "exp2c" / "run.json", {"experiment": "exp2c", "seed": 0, "conditions": pinned})
    got = _trials_stopped_before_physics(monkeypatch)
    water = next(i for i, c in enumerate(today) if c["food"] == "water")
    assert cli.main([*argv, "--trial", str(water)]) == 1
    err = capsys.readouterr().err
    assert got[0].condition.load_g == 16.0 and got[0].condition.food == "water"
    assert "logged run's conditions" in err and "load_g 15.0 → 16.0" in err
    got.clear()
    assert cli.main([*argv, "--trial", "0"]) == 1  # pecans: the same load either way
    assert got[0].condition.load_g == 5.0 and got[0].condition.food == "pecans"


def test_source_version_is_the_last_source_commit_and_flags_modified_sources() -> None:
    from articutool.experiments.runner import source_version

    root = Path(__file__).resolve().parents[1]
    head = subprocess.run(["git", "-C", str(root), "log", "-1", "--first-parent", "--format=%h",
                           "--abbrev=12", "--", "src"], capture_output=True, text=True)
    if head.returncode != 0:
        pytest.skip("not a git checkout")
    modified = subprocess.run(["git", "-C", str(root), "diff", "--quiet", "HEAD", "--",
                               "src"]).returncode != 0
    assert source_version() == head.stdout.strip() + ("+modified" if modified else "")



def test_source_version_after_a_merge_is_the_merge_not_a_later_dated_branch_commit(
        tmp_path: Path) -> None:
    """A branch commit dated after the line's own change has a tree without it: the code that
    runs after the merge is the merge's."""
    from articutool.experiments.runner import source_version

    def git(*args: str, date: str = "2026-01-01T00:00:00") -> str:
        env = {**os.environ, "GIT_AUTHOR_DATE": date, "GIT_COMMITTER_DATE": date,
               "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t",
               "GIT_COMMITTER_EMAIL": "t@t"}
        return subprocess.run(["git", "-C", str(tmp_path), *args], env=env, check=True,
                              capture_output=True, text=True).stdout.strip()

    git("init", "-q", "-b", "main")
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "a.py").write_text("a = 1\n")
    git("add", "-A")
    git("commit", "-qm", "base")
    git("checkout", "-q", "-b", "branch")
    (tmp_path / "src" / "b.py").write_text("b = 1\n")
    git("add", "-A")
    git("commit", "-qm", "branch", date="2026-01-03T00:00:00")
    git("checkout", "-q", "main")
    (tmp_path / "src" / "a.py").write_text("a = 2\n")
    git("commit", "-qam", "main", date="2026-01-02T00:00:00")
    git("merge", "-q", "--no-ff", "branch", "-m", "merge", date="2026-01-04T00:00:00")
    merge = git("rev-parse", "--short=12", "HEAD")
    assert source_version(tmp_path) == merge


class _TreeReachedError(Exception):
    """Raised by the stand-ins for the tree runners: the trial got as far as its tree."""


def _stub_trial_physics(monkeypatch: pytest.MonkeyPatch, runner: object
                        ) -> tuple[object, list[dict[str, object]]]:
    """Every protocol's physics stubbed out: ``runner`` stands for the feeding tree's run
    (transport: Exp. 2b, 2c) and the bite's (capacity, Exp. 1, Exp. 3). Returns the stub
    ``FeedingWorld`` (its ``make`` calls record the worlds a trial asked for) and the keyword
    arguments of every bite world made."""
    from types import SimpleNamespace
    from unittest import mock

    import articutool.feeding.tree as tree
    import articutool.meal.bites as meal
    import articutool.sim.arm_driver as arm_driver
    import articutool.sim.world as world
    from articutool.experiments.units import capacity

    bite_worlds: list[dict[str, object]] = []
    monkeypatch.setattr(tree, "run_tree", runner)
    monkeypatch.setattr(meal, "run_bite", runner)
    monkeypatch.setattr(tree, "transport_tree", mock.MagicMock())
    monkeypatch.setattr(meal, "make_bite_world", lambda *a, **k: bite_worlds.append(k) or
                        SimpleNamespace(world=mock.MagicMock(), arm=mock.MagicMock(),
                                        strategy=mock.MagicMock()))
    monkeypatch.setattr(capacity, "capacity_strategy", lambda s, _: s)
    monkeypatch.setattr(meal, "shed_configuration", lambda *a, **k: None)
    made = mock.MagicMock()
    monkeypatch.setattr(world, "FeedingWorld", made)
    monkeypatch.setattr(arm_driver, "sim_arm", mock.MagicMock())
    return made, bite_worlds


@pytest.mark.parametrize("experiment", ["capacity", "exp1", "exp2b", "exp2c", "exp3"])
def test_every_trial_that_runs_a_tree_gives_it_the_callers_visitors(
        monkeypatch: pytest.MonkeyPatch, experiment: str) -> None:
    """``run_trial(…, visitors=…)`` reaches the feeding tree of every protocol that runs one
    (what ``--record`` relies on for ``/feeding/tree``). The physics is stubbed out here; a
    real recording is in test_mcap_recording.py."""
    from articutool.experiments.runner import run_trial

    got: list[object] = []

    def runner(*_: object, **kw: object) -> None:
        got.append(kw.get("visitors"))
        raise _TreeReachedError

    _stub_trial_physics(monkeypatch, runner)
    goals = ["centre"]
    conds = conditions(experiment, ExperimentsConfig.load(), goals=goals,
                       load_g={"pecans": 5.0, "water": 5.0})
    mine = [object()]
    rec = run_trial(make_trials(experiment, conds, 1, 0, goals=goals)[0], visitors=mine)
    assert rec.error is not None and "_TreeReachedError" in rec.error, rec
    assert rec.outcome is None and rec.traceback
    assert got == [mine] and got[0] is mine


@pytest.mark.parametrize("experiment", ["capacity", "exp1", "exp2b", "exp2c", "exp3"])
def test_an_experiment_declares_it_places_its_load_exactly_when_its_worlds_get_one(
        monkeypatch: pytest.MonkeyPatch, experiment: str) -> None:
    """``places_load`` (which leaves the container fill's settings out of a run's pin) is
    what the trial does: its world is made with a placed load, so it never fills the
    container. The physics is stubbed out, as above."""
    from articutool.experiments.runner import run_trial
    from articutool.experiments.unit import registry

    def runner(*_: object, **__: object) -> None:
        raise _TreeReachedError

    made, bite_worlds = _stub_trial_physics(monkeypatch, runner)
    goals = ["centre"]
    conds = conditions(experiment, ExperimentsConfig.load(), goals=goals,
                       load_g={"pecans": 5.0, "water": 5.0})
    for spec in make_trials(experiment, conds, 1, 0, goals=goals):
        assert run_trial(spec).error is not None  # stopped once its world was made
    loads = [c.kwargs.get("load_g") for c in made.make.call_args_list]
    placed = bool(loads) and all(g is not None and g > 0 for g in loads)
    assert registry()[experiment].places_load == placed, (loads, bite_worlds)
    assert placed or bite_worlds  # an experiment that places no load acquires its bites


def test_a_placed_load_experiments_pin_does_not_read_the_container_fill(tmp_path) -> None:
    """A container-fill setting moves the pin of an experiment that fills the container, not
    that of one whose loads are placed; a placed load's own setting moves both."""
    from articutool.sim.params import Liquid

    data = _data_copy(tmp_path)
    physics = data / "physics.toml"
    text = physics.read_text()
    cfg = ExperimentsConfig.load()
    assert "\nsph_bowl_settle_s = 0.5\n" in text and Liquid.BOWL_FIELDS
    physics.write_text(text.replace("\nsph_bowl_settle_s = 0.5\n", "\nsph_bowl_settle_s = 0.4\n"))
    for exp, moves in (("exp1", True), ("capacity", True), ("exp2b", False), ("exp2c", False)):
        assert (data_hash(exp, cfg, {"water"}, data) != data_hash(exp, cfg, {"water"})) == moves
    physics.write_text(text.replace("\nsph_particle_radius = 0.001\n",
                                    "\nsph_particle_radius = 0.0009\n"))
    for exp in ("exp1", "capacity", "exp2b", "exp2c"):
        assert data_hash(exp, cfg, {"water"}, data) != data_hash(exp, cfg, {"water"})
    # the pecans' passes while the spoon is in the bowl: a filled container's setting too
    assert "\nnoslip_iterations_digging = 0\n" in text
    physics.write_text(text.replace("\nnoslip_iterations_digging = 0\n",
                                    "\nnoslip_iterations_digging = 1\n"))
    for exp, moves in (("exp1", True), ("capacity", True), ("exp2c", False)):
        assert (data_hash(exp, cfg, {"pecans"}, data) != data_hash(exp, cfg, {"pecans"})) == moves


def test_the_data_hash_reads_only_the_runs_foods(tmp_path) -> None:
    """Another food's model does not change a run's pin; its own does."""
    import shutil
    from importlib import resources

    data = tmp_path / "data"
    shutil.copytree(Path(str(resources.files("articutool") / "data")), data)
    physics = data / "physics.toml"
    text = physics.read_text()
    assert "\nfill_g = 10.0\n" in text  # the noodles' nest
    physics.write_text(text.replace("\nfill_g = 10.0\n", "\nfill_g = 125.0\n"))
    cfg = ExperimentsConfig.load()
    for foods in ({"pecans", "water"}, {"pecans"}):
        assert data_hash("exp1", cfg, foods, data) == data_hash("exp1", cfg, foods)
    assert data_hash("exp1", cfg, {"noodles"}, data) != data_hash("exp1", cfg, {"noodles"})
    assert data_hash("exp1", cfg, {"pecans"}) != data_hash("exp1", cfg, {"water"})


def test_another_foods_strategy_does_not_move_a_runs_pin(tmp_path) -> None:
    """A noodle strategy's twirl read only by noodle trials: changing it moves the pin of a
    run with noodles, not that of a run of pecans and water."""
    data = _data_copy(tmp_path)
    strategies = data / "strategies.toml"
    text = strategies.read_text()
    twirl = 'stages.post_move_into = { primitive = "TWIRL_CCW", params = [3.0, 3.0] }'
    assert text.count(twirl) == 1
    strategies.write_text(text.replace(twirl, twirl.replace("3.0, 3.0", "2.0, 3.0")))
    cfg = ExperimentsConfig.load()
    for exp in ("exp1", "exp2c", "capacity"):
        assert data_hash(exp, cfg, {"pecans", "water"}, data) == data_hash(
            exp, cfg, {"pecans", "water"})
    for exp in ("exp1", "exp3"):
        assert data_hash(exp, cfg, {"noodles"}, data) != data_hash(exp, cfg, {"noodles"})


def test_the_committed_runs_are_pinned_to_todays_data() -> None:
    """Every committed experiment's ``run.json`` pins the data it would read today, so its
    command resumes (and a change to a food's model that would change its trials is seen)."""
    root = Path(__file__).resolve().parents[1] / "results" / "experiments"
    cfg = ExperimentsConfig.load()
    runs = sorted(root.glob("*/run.json"))
    assert runs
    for p in runs:
        run = json.loads(p.read_text())
        foods = {c["food"] for c in run["conditions"]}
        assert data_hash(run["experiment"], cfg, foods) == run["data_hash"], p


class _Elsewhere:
    """A worker on another machine, its articutool data in ``data``: runs the checked trial
    function it is sent there, and reports what it raises as a worker failure."""

    description = "elsewhere"

    def __init__(self, data: Path) -> None:
        self.data = data

    def run(self, fn, items, stop=None):
        assert isinstance(fn, DataChecked)  # what every executor is sent
        for it in items:
            try:
                yield it, dataclasses.replace(fn, data=self.data)(it), None
            except Exception as err:
                yield it, None, err

    def close(self) -> None:
        pass


def _data_copy(tmp_path: Path) -> Path:
    import shutil
    from importlib import resources

    data = tmp_path / "data"
    shutil.copytree(Path(str(resources.files("articutool") / "data")), data)
    return data


def test_a_worker_whose_data_differs_refuses_the_trial_naming_the_file(tmp_path) -> None:
    data = _data_copy(tmp_path)
    assert data_files(data) == data_files()  # a copy of the same files: the same hash
    ran: list = []
    ok = DataChecked(lambda spec: ran.append(spec) or {"trial": spec.trial}, data_files(), data)
    spec = SimpleNamespace(trial=7)
    assert ok(spec) == {"trial": 7} and ran == [spec]
    physics = data / "physics.toml"
    physics.write_text(physics.read_text() + "\n# edited on this worker\n")
    (data / "strategies.toml").unlink()
    with pytest.raises(DataMismatchError) as err:
        dataclasses.replace(ok, data=data)(SimpleNamespace(trial=8))
    msg = str(err.value)
    assert "refused trial 8" in msg and "differ: physics.toml" in msg
    assert "missing on the worker: strategies.toml" in msg and "same commit" in msg
    assert ran == [spec]  # the refused trial did not run


def test_a_run_on_a_worker_with_other_data_logs_nothing_and_says_why(tmp_path) -> None:
    cfg = ExperimentsConfig.load()
    goals = ["low_near"]
    trials = make_trials("exp2b", conditions("exp2b", cfg, goals=goals), 1, 0,
                         goals=goals)[:1]
    data = _data_copy(tmp_path)
    scene = data / "scene.toml"
    scene.write_text(scene.read_text() + "\n# another commit\n")
    log = log_path(tmp_path / "out", "exp2b")
    res = run_experiment(trials, log, _Elsewhere(data))
    assert res.ran == 0 and res.records == []
    assert not log.exists() or _lines(log) == []
    [(_, why)] = res.lost
    assert why.startswith("DataMismatchError") and "differ: scene.toml" in why


@pytest.mark.slow  # four exp2b trials (two in this process, two in a Dask worker): ~2 min
def test_two_trials_in_the_threads_of_one_dask_worker_give_their_outcomes_alone(
        tmp_path, monkeypatch) -> None:
    """A ``dask worker`` runs several tasks at once in its threads by default: two trials in
    the two threads of one worker process give the records they give one after the other
    in one process (every field but the timing and bookkeeping ones the replay check
    ignores)."""
    pytest.importorskip("distributed")
    from distributed import Client, LocalCluster

    from articutool.bench.executors import DaskExecutor
    from articutool.experiments.cli import BOOKKEEPING_FIELDS, TIMING_FIELDS
    from articutool.experiments.runner import log_trial

    monkeypatch.chdir(tmp_path)  # MuJoCo writes MUJOCO_LOG.TXT on a warning
    cfg = ExperimentsConfig.load()
    goals = ["low_near"]
    trials = make_trials("exp2b", conditions("exp2b", cfg, goals=goals), 1, 0,
                         goals=goals)[:2]  # pecans: Articutool, baseline (one seed)
    ignored = TIMING_FIELDS | BOOKKEEPING_FIELDS

    def outcomes(lines):
        return {r["trial"]: {k: v for k, v in r.items() if k not in ignored} for r in lines}

    alone = outcomes(log_trial(t) for t in trials)
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster, Client(cluster) as client:
        res = run_experiment(trials, log_path(tmp_path, "exp2b"), DaskExecutor(client=client))
        assert res.lost == [] and res.ran == 2
        pids = {r.pid for r in res.records}
    assert len(pids) == 1  # one worker process ran both
    assert all(r.error is None for r in res.records), [r.error for r in res.records]
    assert outcomes(r.to_log() for r in res.records) == alone


def test_exp2c_trials_carry_the_closed_loop_target_derived_from_the_threshold(
        tmp_path: Path) -> None:
    """``experiment exp2c`` builds its conditions from the loads and thresholds given: the
    closed loop's load target stands above the food's threshold (one item and three σ of a
    weighing), and the run notes the loads and targets it used."""
    from argparse import Namespace

    from articutool.experiments.cli import trials_for

    args = Namespace(trials=1, seed=0, load_g="pecans=5,water=10",
                     thresholds_g="pecans=2,water=5", foods=None)
    trials, extra = trials_for("exp2c", args, tmp_path, ExperimentsConfig.load())
    targets = extra["closed_loop_target_g"]
    assert targets and all(g > {"pecans": 2.0, "water": 5.0}[f] for f, g in targets.items())
    assert extra["load_g"] == {"pecans": 5.0, "water": 10.0}
    for t in trials:
        c = t.condition
        assert c.target_g == (targets.get(c.food) if c.condition == "closed_loop" else None)


def test_exp2c_of_one_food_needs_only_that_food_s_load_and_threshold(
        tmp_path, capsys, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--foods pecans`` runs pecans' three conditions from pecans' load and threshold alone
    (re-running one food after its capacity and Exp. 1 moved); without ``--foods`` every
    food's load is still needed."""
    got = _trials_stopped_before_physics(monkeypatch)
    out = tmp_path / "r"
    argv = ["experiment", "exp2c", "--out", str(out), "--load-g", "pecans=5",
            "--thresholds-g", "pecans=2"]
    assert cli.main([*argv, "--foods", "pecans", "--trial", "2"]) == 1
    assert got[0].condition.food == "pecans" and got[0].condition.load_g == 5.0
    capsys.readouterr()
    assert cli.main(argv) == 2
    assert "--load-g: no load > 0 g for ['water']" in capsys.readouterr().err
    assert len(got) == 1
