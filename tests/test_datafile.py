"""Data files given on the command line (--spec, --tasks, scenes): unreadable or malformed
input exits 2 with a message naming the file, never a traceback."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from articutool.bench.taskfile import TaskFileError, load_task_set
from articutool.spec import SpecError, default_spec_path, load_spec

EXE = Path(sys.executable).with_name("articutool")
LATIN1 = "version = 1\n# café, crème brûlée\n".encode("latin-1")  # not UTF-8


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(EXE), *args], capture_output=True, text=True, timeout=120)


def _assert_clean_refusal(proc: subprocess.CompletedProcess[str], *words: str) -> None:
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and "internal error" not in proc.stderr
    for w in words:
        assert w in proc.stderr


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_a_non_utf8_spec_exits_2_naming_the_file(tmp_path, suffix):
    bad = tmp_path / f"latin1{suffix}"
    bad.write_bytes(LATIN1)
    with pytest.raises(SpecError, match="not UTF-8") as e:
        load_spec(bad)
    assert str(bad) in str(e.value) and "byte 0xe9" in str(e.value)
    _assert_clean_refusal(_cli("info", "--spec", str(bad)), str(bad), "not UTF-8")


def test_a_non_utf8_task_file_exits_2_naming_the_file(tmp_path):
    bad = tmp_path / "tasks.json"
    bad.write_bytes(b'{"name": "caf\xe9"}')
    with pytest.raises(TaskFileError, match="not UTF-8"):
        load_task_set(bad)
    proc = _cli("bench", "transport", "--tasks", str(bad), "--out", str(tmp_path / "out"),
                "--workers", "1")
    _assert_clean_refusal(proc, str(bad), "not UTF-8")


def test_duplicate_wrist_joint_names_are_refused_naming_the_field(tmp_path):
    text = default_spec_path().read_text(encoding="utf-8")
    old = 'joint_names = ["atool_pitch", "atool_roll"]'
    assert old in text
    for names in ('["atool_roll", "atool_roll"]', '["atool_pitch", "j2n6s200_joint_6"]'):
        bad = tmp_path / "dup.toml"
        bad.write_text(text.replace(old, f"joint_names = {names}"), encoding="utf-8")
        with pytest.raises(SpecError, match=r"wrist\.joint_names"):
            load_spec(bad)
        _assert_clean_refusal(_cli("info", "--spec", str(bad)), "wrist.joint_names")
