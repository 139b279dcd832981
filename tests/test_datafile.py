"""Data files given on the command line (--spec, --tasks, scenes): unreadable or malformed
input exits 2 with a message naming the file, never a traceback."""

from __future__ import annotations

import pytest

from articutool.bench.taskfile import TaskFileError, load_task_set
from articutool.spec import SpecError, default_spec_path, load_spec
from conftest import assert_refused, run_cli

LATIN1 = "version = 1\n# café, crème brûlée\n".encode("latin-1")  # not UTF-8


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_a_non_utf8_spec_exits_2_naming_the_file(tmp_path, suffix):
    bad = tmp_path / f"latin1{suffix}"
    bad.write_bytes(LATIN1)
    with pytest.raises(SpecError, match="not UTF-8") as e:
        load_spec(bad)
    assert str(bad) in str(e.value) and "byte 0xe9" in str(e.value)
    assert_refused(run_cli("info", "--spec", str(bad)), str(bad), "not UTF-8")


def test_a_non_utf8_task_file_exits_2_naming_the_file(tmp_path):
    bad = tmp_path / "tasks.json"
    bad.write_bytes(b'{"name": "caf\xe9"}')
    with pytest.raises(TaskFileError, match="not UTF-8"):
        load_task_set(bad)
    proc = run_cli("bench", "transport", "--tasks", str(bad), "--out", str(tmp_path / "out"),
                   "--workers", "1")
    assert_refused(proc, str(bad), "not UTF-8")


def test_duplicate_wrist_joint_names_are_refused_naming_the_field(tmp_path):
    text = default_spec_path().read_text(encoding="utf-8")
    old = 'joint_names = ["atool_pitch", "atool_roll"]'
    assert old in text
    for names in ('["atool_roll", "atool_roll"]', '["atool_pitch", "j2n6s200_joint_6"]'):
        bad = tmp_path / "dup.toml"
        bad.write_text(text.replace(old, f"joint_names = {names}"), encoding="utf-8")
        with pytest.raises(SpecError, match=r"wrist\.joint_names"):
            load_spec(bad)
        assert_refused(run_cli("info", "--spec", str(bad)), "wrist.joint_names")
