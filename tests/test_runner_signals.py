"""The test runner itself: a runner told to stop takes the processes its tests started with it."""

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

from conftest import ROOT, descendants, wait_until


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


def test_a_terminated_runner_takes_the_processes_its_tests_started(tmp_path: Path) -> None:
    """SIGTERM to pytest (a CI timeout, ``kill``) while a test waits on a process it started —
    here in a new session, as the Ctrl-C tests start theirs — leaves no such process running."""
    test = tmp_path / "test_starts_a_process.py"
    test.write_text(textwrap.dedent(f"""
        import subprocess, time
        from pathlib import Path

        def test_waits():
            p = subprocess.Popen(["sleep", "300"], start_new_session=True)
            # written whole, then renamed: the waiting test never reads a file half written
            Path({str(tmp_path / "pid.part")!r}).write_text(str(p.pid))
            Path({str(tmp_path / "pid.part")!r}).replace({str(tmp_path / "pid")!r})
            time.sleep(300)
    """))
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "tests"),
                                                        os.environ.get("PYTHONPATH", "")])}
    runner = subprocess.Popen([sys.executable, "-m", "pytest", "-q", "-p", "conftest",
                               "-p", "no:cacheprovider", "--rootdir", str(tmp_path), str(test)],
                              cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    try:
        assert wait_until(lambda: (tmp_path / "pid").exists(), 120)
        child = int((tmp_path / "pid").read_text())
        assert child in descendants(runner.pid)
        runner.send_signal(signal.SIGTERM)
        assert runner.wait(60) == -signal.SIGTERM
        assert wait_until(lambda: not _alive(child), 10)
    finally:
        runner.kill()
        if (tmp_path / "pid").exists():
            with contextlib.suppress(ProcessLookupError):
                os.kill(int((tmp_path / "pid").read_text()), signal.SIGKILL)
