"""Bad input to the PC-side commands (verify, demo, bench, info) through the real CLI.

Every refusal: exit 2, a message naming the field, no traceback, and no work done first.
"""

import functools
import json
import subprocess
import sys
from pathlib import Path

import pytest

from articutool.bench.taskfile import default_tasks_path
from conftest import assert_refused, minimal_env, run_cli

EXAMPLE = Path(__file__).parents[1] / "examples" / "transport_feasible.json"
_cli = functools.partial(run_cli, env=minimal_env())


def test_verify_wrist_out_into_a_missing_directory_is_refused_before_verifying(tmp_path):
    target = tmp_path / "missing" / "wrist.json"
    r = _cli("verify", str(EXAMPLE), "--wrist-out", str(target))
    assert_refused(r, "--wrist-out", str(target.parent))
    assert r.stdout == ""  # refused before verifying: no report printed


def test_verify_non_utf8_trajectory_is_refused(tmp_path):
    f = tmp_path / "traj.json"
    f.write_bytes(b'{"joint_names": ["\xff\xfe"], "points": []}')
    assert_refused(_cli("verify", str(f)), str(f), "UTF-8")


def test_demo_negative_seed_is_refused():
    assert_refused(_cli("demo", "--seed", "-1", "--no-plot"), "--seed", ">= 0")


def test_demo_plot_with_an_unknown_format_is_refused_before_planning(tmp_path):
    r = _cli("demo", "--plot", str(tmp_path / "tilt.xyz"), "--json")
    assert_refused(r, "--plot", "png")
    assert r.stdout == "" and not any(tmp_path.iterdir())


def test_demo_plot_into_a_directory_writes_a_file_inside_it(tmp_path):
    r = _cli("demo", "--plot", str(tmp_path), "--json", "--seed", "1", "--timeout", "20")
    assert r.returncode == 0, r.stdout + r.stderr
    written = Path(json.loads(r.stdout)["plot"])
    assert written.parent == tmp_path and written.suffix == ".png"
    assert written.stat().st_size > 10_000


def test_bench_task_outside_the_joint_limits_is_bad_input_not_a_failed_trial(tmp_path):
    doc = json.loads(default_tasks_path().read_text())
    doc["tasks"] = doc["tasks"][:2]
    doc["tasks"][1]["start"][1] = 7.0  # joint 2: limits [0.82, 5.46] rad
    tasks = tmp_path / "tasks.json"
    tasks.write_text(json.dumps(doc))
    out = tmp_path / "out"
    r = _cli("bench", "transport", "--tasks", str(tasks), "--systems", "decoupled",
             "--timeout", "2", "--workers", "1", "--out", str(out))
    assert_refused(r, "tasks[1].start[1]", "j2n6s200_joint_2", "5.46")
    assert not (out / "results.jsonl").exists()  # no trial ran, none was recorded


def test_info_prints_the_wrist_joint_order():
    r = _cli("info")
    assert r.returncode == 0, r.stderr
    assert "Wrist (joint order [pitch, roll])" in r.stdout


def test_bad_input_exits_2_also_when_run_as_a_module():
    # `python -m articutool.cli` must not run a second copy of the CLI module, whose
    # UsageError the handlers would not catch (exit 3 with a traceback).
    for module in ("articutool.cli", "articutool"):
        proc = subprocess.run([sys.executable, "-m", module, "demo", "--seed", "-1"],
                              capture_output=True, text=True, timeout=120)
        assert_refused(proc, "--seed")


# Every command that writes a new file the user names refuses, before any work, a path that
# is a link (even one to nothing: the file would be created at its target) or that cannot be
# created (in /proc); rendering commands used to render first and fail, or run until killed.
_OUTPUTS = {
    "verify --wrist-out": (("verify", str(EXAMPLE), "--wrist-out", "{out}"), ".json"),
    "view --export": (("view", "--recording", "missing.npz", "--export", "{out}"), ".mp4"),
    "sim --video": (("sim", "--video", "{out}"), ".mp4"),
    "sim --snapshot": (("sim", "--snapshot", "{out}"), ".png"),
    "sim --record": (("sim", "--record", "{out}"), ".npz"),
    "meal --video": (("meal", "--threshold", "1", "--video", "{out}"), ".gif"),
    "experiment --video": (("experiment", "exp1", "--trial", "0", "--video", "{out}"), ".mp4"),
}


@pytest.mark.parametrize("where", ["dangling", "proc"])
@pytest.mark.parametrize("command", sorted(_OUTPUTS))
def test_an_output_that_is_a_link_or_cannot_be_created_is_refused_first(command, where,
                                                                         tmp_path):
    args, suffix = _OUTPUTS[command]
    target = tmp_path / f"target{suffix}"
    if where == "dangling":
        out = tmp_path / f"out{suffix}"
        out.symlink_to(target)
    else:
        out = Path(f"/proc/articutool-out{suffix}")
    r = _cli(*(a.format(out=out) for a in args), cwd=tmp_path)
    assert_refused(r, command.split()[1], str(out))
    assert r.stdout == ""
    assert not target.exists() and not out.exists()
