"""Bad input to the PC-side commands (verify, demo, bench, info) through the real CLI.

Every refusal: exit 2, a message naming the field, no traceback, and no work done first.
"""

import json
import subprocess
import sys
from pathlib import Path

from articutool.bench.taskfile import default_tasks_path

EXE = Path(sys.executable).with_name("articutool")
EXAMPLE = Path(__file__).parents[1] / "examples" / "transport_feasible.json"


def _cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(EXE), *args], capture_output=True, text=True, timeout=300,
                          cwd=cwd, env={"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"})


def _refused(proc: subprocess.CompletedProcess[str], *words: str) -> None:
    out = proc.stdout + proc.stderr
    assert proc.returncode == 2, out
    assert "Traceback" not in out, out
    for w in words:
        assert w in proc.stderr, proc.stderr


def test_verify_wrist_out_into_a_missing_directory_is_refused_before_verifying(tmp_path):
    target = tmp_path / "missing" / "wrist.json"
    r = _cli("verify", str(EXAMPLE), "--wrist-out", str(target))
    _refused(r, "--wrist-out", str(target.parent))
    assert r.stdout == ""  # refused before verifying: no report printed


def test_verify_non_utf8_trajectory_is_refused(tmp_path):
    f = tmp_path / "traj.json"
    f.write_bytes(b'{"joint_names": ["\xff\xfe"], "points": []}')
    _refused(_cli("verify", str(f)), str(f), "UTF-8")


def test_demo_negative_seed_is_refused():
    _refused(_cli("demo", "--seed", "-1", "--no-plot"), "--seed", ">= 0")


def test_demo_plot_with_an_unknown_format_is_refused_before_planning(tmp_path):
    r = _cli("demo", "--plot", str(tmp_path / "tilt.xyz"), "--json")
    _refused(r, "--plot", "png")
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
    _refused(r, "tasks[1].start[1]", "j2n6s200_joint_2", "5.46")
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
        _refused(proc, "--seed")
