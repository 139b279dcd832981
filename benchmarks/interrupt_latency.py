"""How fast an interrupted experiment stops, and what it leaves, as JSON.

Runs ``articutool experiment capacity --trials N --workers W`` into a fresh folder, sends
SIGINT (or SIGTERM) to its main process alone once ``--after`` trials are logged (as
``kill -INT`` does), and reports per repeat: the exit code, the seconds from the signal to
the exit, the trials logged at the signal and at the exit, and the processes it started that
were still running 2 s after it ended::

    PYTHONPATH=src python benchmarks/interrupt_latency.py --repeats 3 \\
        --out results/interrupt_latency.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import psutil


def _children(pid: int) -> list[int]:
    return [c.pid for c in psutil.Process(pid).children()]


def _alive(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def _lines(log: Path) -> int:
    return log.read_text().count("\n") if log.exists() else 0


def run_once(a: argparse.Namespace) -> dict[str, Any]:
    out = Path(tempfile.mkdtemp(prefix="interrupt-"))
    log = out / "capacity" / "trials.jsonl"
    try:
        proc = subprocess.Popen([sys.executable, "-m", "articutool", "experiment", "capacity",
                                 "--trials", str(a.trials), "--workers", str(a.workers),
                                 "--out", str(out)], stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        while _lines(log) < a.after and proc.poll() is None:
            time.sleep(0.05)
        kids = _children(proc.pid)
        at_signal = _lines(log)
        t0 = time.monotonic()
        os.kill(proc.pid, getattr(signal, a.signal))
        try:
            rc: int | None = proc.wait(timeout=a.hang_s)
        except subprocess.TimeoutExpired:
            rc = None
            proc.kill()
            proc.wait()
        exit_s = time.monotonic() - t0
        time.sleep(2.0)
        left = [k for k in kids if _alive(k)]
        for k in left:
            os.kill(k, signal.SIGKILL)
        return {"exit_code": rc, "hung": rc is None, "exit_s": round(exit_s, 3),
                "logged_at_signal": at_signal, "logged_at_exit": _lines(log),
                "processes_started": len(kids), "processes_left_after_2_s": len(left)}
    finally:
        shutil.rmtree(out, ignore_errors=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=20, help="per condition (2 foods)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--after", type=int, default=2, help="signal once this many are logged")
    p.add_argument("--signal", choices=("SIGINT", "SIGTERM"), default="SIGINT")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--hang-s", type=float, default=120.0, help="give up waiting after this")
    p.add_argument("--out", default=None, help="write the JSON here too")
    a = p.parse_args()
    runs = [run_once(a) for _ in range(a.repeats)]
    result = {"command": f"articutool experiment capacity --trials {a.trials} --workers "
                         f"{a.workers}; {a.signal} to the main process after {a.after} "
                         "trials logged",
              "machine": {"cpus": os.cpu_count(), "load_avg": list(os.getloadavg()),
                          "python": platform.python_version()},
              "runs": runs}
    text = json.dumps(result, indent=1)
    print(text)
    if a.out:
        Path(a.out).write_text(text + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
