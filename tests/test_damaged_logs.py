"""Damaged trial logs are never read silently: ``experiment report`` (a real subprocess)
counts and names every bad line, shows the counts on its page, and exits 2 naming the
condition, the trials promised and found when a log holds fewer than its run promised.

The results are a copy of the committed capacity run (40 trials: pecans and water, 20
each): its log, ``summary.json`` (20 per condition) and ``run.json`` (the conditions).
"""

from __future__ import annotations

import functools
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from articutool.bench.runner import read_log
from articutool.experiments.runner import trial_key
from conftest import assert_refused, minimal_env, run_cli

RESULTS = Path(__file__).parents[1] / "results" / "experiments" / "capacity"
_cli = functools.partial(run_cli, env=minimal_env(), timeout=300)


@pytest.fixture
def results(tmp_path: Path) -> Path:
    out = tmp_path / "results"
    (out / "capacity").mkdir(parents=True)
    for name in ("trials.jsonl", "summary.json", "run.json"):
        shutil.copyfile(RESULTS / name, out / "capacity" / name)
    return out


def _lines(out: Path) -> list[bytes]:
    return (out / "capacity" / "trials.jsonl").read_bytes().split(b"\n")[:-1]


def _write(out: Path, lines: list[bytes]) -> None:
    (out / "capacity" / "trials.jsonl").write_bytes(b"".join(x + b"\n" for x in lines))


def _report(out: Path):
    return _cli("experiment", "report", "--out", str(out))


def _page(out: Path) -> str:
    return (out / "report.md").read_text()


def test_the_committed_log_reads_clean_and_the_page_says_so(results):
    r = _report(results)
    assert r.returncode == 0, r.stderr
    assert "warning" not in r.stderr and "error" not in r.stderr
    assert "| capacity | 40 | 40 | none | 20 | pecans 20, water 20 | complete |" in _page(results)


def test_a_log_cut_in_half_mid_line_exits_2_naming_the_short_conditions(results):
    log = results / "capacity" / "trials.jsonl"
    data = log.read_bytes()
    log.write_bytes(data[:len(data) // 2])
    n = len(data[:len(data) // 2].split(b"\n")) - 1  # complete lines left
    r = _report(results)
    assert_refused(r, f"{n} record(s) accepted", f"line {n + 1}: no newline at its end",
                   "condition pecans has", "of the 20 trials its run promised",
                   "missing trial(s)")
    page = _page(results)  # written, with the damage at the top and in the table
    assert "**Warning: the trial logs of capacity" in page and "**short: pecans" in page


def test_garbage_lines_beside_every_trial_are_named_and_cost_no_trial(results):
    lines = _lines(results)
    lines[3:3] = [b"garbage {", b"", b"[1, 2]"]
    _write(results, lines)
    r = _report(results)
    assert r.returncode == 0, r.stderr  # every promised trial is there: a warning, not a refusal
    assert ("43 line(s) read, 40 record(s) accepted, 3 bad line(s) (line 4: not JSON "
            "(Expecting value); line 5: empty; line 6: not a record (a JSON list))") in r.stderr
    assert "line 4: not JSON" in _page(results) and "complete" in _page(results)


@pytest.mark.parametrize("value,why", [(b"NaN", b"NaN is not a JSON number"),
                                       (b"-Infinity", b"-Infinity is not a JSON number"),
                                       (b"1e999", b"1e999 is too large for a float")])
def test_a_record_holding_a_non_finite_number_is_a_bad_line(results, value, why):
    lines = _lines(results)
    k = json.loads(lines[7])["trial"]
    lines[7] = lines[7].replace(b'"scoop_g": ', b'"scoop_g": ' + value + b", \"was\": ", 1)
    _write(results, lines)
    r = _report(results)
    assert_refused(r, f"line 8: {why.decode()}", f"missing trial(s) {k})",
                   "has 19 of the 20 trials")


def test_a_trial_logged_twice_is_named(results):
    lines = _lines(results)
    _write(results, [*lines, lines[0]])
    r = _report(results)
    assert r.returncode == 0, r.stderr
    assert "line 41: the same trial as line 1" in r.stderr


@pytest.mark.parametrize("kind", ["random", "empty"])
def test_random_bytes_or_an_empty_log_exit_2_with_no_trial(results, kind):
    log = results / "capacity" / "trials.jsonl"
    log.write_bytes(np.random.default_rng(3).bytes(20_000) if kind == "random" else b"")
    state = read_log(log, key=trial_key)
    assert state.records == [] and len(state.bad) == state.lines
    r = _report(results)
    assert_refused(r, f"{state.lines} line(s) read, 0 record(s) accepted",
                   "condition pecans has 0 of the 20 trials", "missing trial(s) 0, 2, 4",
                   "condition water has 0 of the 20 trials")
    assert "Not run yet" in _page(results)


def test_without_run_json_the_summarised_conditions_are_still_counted(results):
    (results / "capacity" / "run.json").unlink()
    (results / "capacity" / "trials.jsonl").write_bytes(b"")
    assert_refused(_report(results), "condition pecans has 0 of the 20",
                   "condition water has 0 of the 20")


def test_a_log_that_is_a_link_is_refused_and_its_target_kept(results, tmp_path):
    # The log is a run's own file (a run appends to it and cuts a torn tail): the report
    # reads it only as such, never through a link to a file elsewhere.
    elsewhere = tmp_path / "mine.jsonl"
    log = results / "capacity" / "trials.jsonl"
    shutil.move(log, elsewhere)
    log.symlink_to(elsewhere)
    before = elsewhere.read_bytes()
    assert_refused(_report(results), "trials.jsonl", "symbolic link")
    assert elsewhere.read_bytes() == before and not (results / "report.md").exists()


def test_a_bench_log_names_its_bad_lines_by_number(tmp_path):
    log = tmp_path / "results.jsonl"
    rec = {"system": "decoupled", "task_id": 3, "seed": 0, "success": True}
    log.write_text(json.dumps(rec) + "\n{\"system\": \"strict6\"}\n" + json.dumps(rec)
                   + "\n" + '{"torn')
    state = read_log(log)
    assert state.lines == 4 and state.corrupt == 1 and state.torn == 1
    assert [n for n, _ in state.bad] == [2, 4] and state.duplicates == [(3, 1)]
    assert "line 2: no trial identity (KeyError: 'task_id')" in state.describe()
