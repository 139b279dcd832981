"""``articutool meal``: bad input refused before anything moves; the tree rendered."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import run_cli

pytest.importorskip("mujoco")


def _main(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    from articutool.cli import main

    rc = main(["meal", *args])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.mark.parametrize(("args", "field"), [
    (["--bites", "0"], "--bites"),
    (["--seed", "-1"], "--seed"),
    (["--threshold", "nan"], "--threshold"),
    (["--food", "soup"], "--food"),
    (["--strategies", "/nonexistent.toml"], "--strategies"),
    (["--video", "x.avi"], "--video"),
    (["--record", "x.json"], "--record"),
])
def test_bad_input_exits_2_naming_the_field(args: list[str], field: str,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    rc, _, err = _main(capsys, *args)
    assert rc == 2, err
    assert field in err and "Traceback" not in err


def test_a_strategy_file_with_an_unknown_primitive_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from articutool.feeding.strategies import default_strategies_path

    bad = tmp_path / "s.toml"
    bad.write_text(default_strategies_path().read_text().replace('"VIBRATE_ROLL"', '"SHAKE"'))
    rc, _, err = _main(capsys, "--food", "pecans", "--strategies", str(bad))
    assert rc == 2
    assert "stages.post_acquisition" in err and "SHAKE" in err


def test_a_sweep_that_does_not_move_is_refused_naming_the_field(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from articutool.feeding.strategies import default_strategies_path

    text = default_strategies_path().read_text()
    bad = tmp_path / "s.toml"
    bad.write_text(text.replace('motion = "sweep", depth_m = 0.002, pitch_down_deg = 35.0, '
                                'drag_m = 0.03', 'motion = "sweep", depth_m = 0.002, '
                                'pitch_down_deg = 35.0, drag_m = 0.0'))
    assert bad.read_text() != text
    rc, _, err = _main(capsys, "--food", "water", "--strategies", str(bad))
    assert rc == 2
    assert "water_tilted_dip.insertion" in err and "drag_m" in err and "Traceback" not in err


def test_show_tree_prints_every_stage_and_writes_dot_without_overwriting(
        tmp_path: Path) -> None:
    out = tmp_path / "tree.dot"
    r = run_cli("meal", "--food", "noodles", "--show-tree", str(out))
    assert r.returncode == 0, r.stderr
    for name in ("above", "acquire", "shed", "transport to Staging", "pre-move-into: TWIRL_CW",
                 "post-acquisition: NOODLE_SHED", "retreat (the bite failed)", "Unsafe?"):
        assert name in r.stdout
    assert "digraph" in out.read_text() and "NOODLE_SHED" in out.read_text()
    again = run_cli("meal", "--food", "noodles", "--show-tree", str(out))
    assert again.returncode == 2 and "exists" in again.stderr


@pytest.mark.skipif(shutil.which("dot") is None, reason="Graphviz `dot` is not installed")
def test_show_tree_renders_a_png(tmp_path: Path) -> None:
    out = tmp_path / "tree.png"
    r = run_cli("meal", "--food", "water", "--system", "baseline", "--show-tree", str(out))
    assert r.returncode == 0, r.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _run_on_a_terminal(*args: str, timeout_s: float = 600.0) -> tuple[int, str]:
    """Run ``articutool meal`` with stdout and stderr on a real pseudo-terminal; return its
    exit code and everything it wrote, ANSI escapes removed."""
    import os
    import re
    import select
    import time

    master, slave = os.openpty()
    env = {**os.environ, "TERM": "xterm-256color", "COLUMNS": "160", "LINES": "60"}
    env.pop("NO_COLOR", None)
    proc = subprocess.Popen([sys.executable, "-m", "articutool", "meal", *args],
                            stdin=subprocess.DEVNULL, stdout=slave, stderr=slave, env=env)
    os.close(slave)
    chunks: list[bytes] = []
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            if select.select([master], [], [], 1.0)[0]:
                try:
                    data = os.read(master, 65536)
                except OSError:  # EIO: the child closed the terminal
                    break
                if not data:
                    break
                chunks.append(data)
            elif proc.poll() is not None:
                break
        rc = proc.wait(timeout=max(1.0, deadline - time.monotonic()))
    finally:
        proc.kill()
        os.close(master)
    text = b"".join(chunks).decode("utf-8", "replace")
    return rc, re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", text)


@pytest.mark.slow
def test_a_meal_on_a_terminal_shows_the_live_tree_verbatim() -> None:
    # The live tree is py_trees' text, whose "[o]" (a selector) looks like rich markup; it
    # must reach the terminal as written, and the bite's record after it. The root guard is
    # py_trees' EternalGuard, a decorator ("-^-").
    rc, out = _run_on_a_terminal("--food", "pecans")
    assert rc == 0, out[-2000:]
    assert "[o] bite" in out and "-^- Unsafe?" in out
    assert "move to AbovePlate" in out
    assert "bite 1: " in out and "planning attempts: " in out
