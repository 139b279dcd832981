"""A run interrupted by SIGINT or SIGTERM sent to its main process alone (as
``kill -INT`` and ``timeout -s INT`` do) stops although trials are still running, keeps every
finished trial in its log, and leaves no process behind. Real processes, real signals.

Hang guards (the subprocess timeouts) are far above what the run needs; no test measures time.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from conftest import wait_until

HERE = Path(__file__).parent
SRC = HERE.parent / "src"
HANG = 120  # s: an interrupted run that has not ended by then has hung


def _env() -> dict[str, str]:
    return {"PATH": "/usr/bin:/bin", "PYTHONPATH": str(SRC), "MPLBACKEND": "Agg",
            "HOME": os.environ.get("HOME", "/tmp")}


def _descendants(pid: int) -> set[int]:
    """Every process below ``pid``."""
    try:
        return {c.pid for c in psutil.Process(pid).children(recursive=True)}
    except psutil.NoSuchProcess:
        return set()


def _running(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def _lines(log: Path) -> list[str]:
    return log.read_text().splitlines() if log.exists() else []


def _interrupt_when_logged(proc: subprocess.Popen[str], log: Path, n: int,
                           sig: signal.Signals) -> tuple[set[int], str, str]:
    """Wait until ``log`` holds ``n`` lines, send ``sig`` to the main process only, wait for
    it to end; its processes before the signal, and its output."""
    assert wait_until(lambda: len(_lines(log)) >= n or proc.poll() is not None, HANG, 0.1), \
        "no trial finished"
    assert proc.poll() is None, proc.communicate()
    time.sleep(0.5)  # let the workers settle into the trials that never end
    children = _descendants(proc.pid)
    os.kill(proc.pid, sig)
    try:
        out, err = proc.communicate(timeout=HANG)
    except subprocess.TimeoutExpired:
        left = _descendants(proc.pid)
        proc.kill()
        for c in left:
            os.kill(c, signal.SIGKILL)
        pytest.fail(f"the run did not end after {sig.name}: it hung")
    # The processes it started are gone (a stopped resource tracker may take a moment).
    wait_until(lambda: not any(_running(c) for c in children), 30, 0.2)
    left = [c for c in children if _running(c)]
    for c in left:
        os.kill(c, signal.SIGKILL)
    assert not left, f"processes left behind: {left}"
    return children, out, err


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_local_run_with_trials_that_never_end_stops_and_keeps_the_finished(
        sig, tmp_path):
    log = tmp_path / "log.jsonl"
    proc = subprocess.Popen([sys.executable, str(HERE / "interrupt_worker.py"), str(log), "6"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=_env())
    children, out, err = _interrupt_when_logged(proc, log, 2, sig)
    assert proc.returncode == 0, err
    assert len(children) >= 2  # the two workers were there, and were stopped
    res = json.loads(out)
    assert res == {"ran": 2, "interrupted": True, "lost": 0, "keys": [0, 1]}
    assert sorted(json.loads(x)["k"] for x in _lines(log)) == [0, 1]


def test_an_interrupted_dask_run_stops_and_keeps_the_finished(tmp_path):
    pytest.importorskip("distributed")
    log = tmp_path / "log.jsonl"
    proc = subprocess.Popen([sys.executable, str(HERE / "interrupt_worker.py"), str(log), "6",
                             "--dask"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=_env())
    _, out, err = _interrupt_when_logged(proc, log, 2, signal.SIGINT)
    assert proc.returncode == 0, err
    res = json.loads(out.strip().splitlines()[-1])
    assert res == {"ran": 2, "interrupted": True, "lost": 0, "keys": [0, 1]}


@pytest.mark.slow
def test_experiment_interrupted_by_sigint_keeps_its_trials_and_resumes(tmp_path):
    """The real command on Exp. 2b (80 trials; its water trials run the SPH liquid, minutes
    each: four minutes in all, so slow; the runner's interrupts are also tested above)."""
    cmd = [sys.executable, "-m", "articutool", "experiment", "exp2b", "--trials", "20",
           "--workers", "2", "--out", str(tmp_path)]
    log = tmp_path / "exp2b" / "trials.jsonl"
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=_env())
    _, _, err = _interrupt_when_logged(proc, log, 2, signal.SIGINT)
    assert proc.returncode == 130, err
    assert "interrupted:" in err and "run the same command again to resume" in err
    assert "Traceback" not in err
    recs = [json.loads(x) for x in _lines(log)]  # every line whole
    kept = [r["trial"] for r in recs]
    assert len(kept) == len(set(kept)) >= 2
    assert len(kept) < 80  # it stopped: the rest was not run
    assert not (tmp_path / "exp2b" / "summary.json").exists()
    # The resume starts from what was kept, running only the others.
    again = subprocess.run([*cmd[:-4], "--trials", "1", "--workers", "1", "--out",
                            str(tmp_path)], capture_output=True, text=True, env=_env(),
                           timeout=HANG * 5)
    assert again.returncode == 0, again.stderr
    first_two = {0, 1, 2, 3}  # --trials 1: trial 0 of each food and system
    done_before = len(first_two & set(kept))
    assert f"{done_before} already in" in " ".join(again.stderr.split())
