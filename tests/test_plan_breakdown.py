"""benchmarks/plan_breakdown.py: the per-phase breakdown is JSON that accounts for the
planning time, and bad input exits 2 naming the option."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from articutool.planning.types import PHASES

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "plan_breakdown.py"


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True,
                          text=True, timeout=300)


def test_breakdown_prints_every_phase_per_system(tmp_path) -> None:
    out = tmp_path / "b.json"
    p = _run("--limit", "2", "--systems", "decoupled,strict6", "--baseline", "--out", str(out))
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    assert d == json.loads(out.read_text())
    assert d["tasks"] == 2 and set(d["systems"]) == {"decoupled", "strict6"}
    for s in d["systems"].values():
        assert s["solved"] == 2 and s["median_ms"] > 0 and s["cpu_median_ms"] > 0
        assert set(s["phases"]) == {*PHASES, "other"}
        assert abs(sum(p["share"] for p in s["phases"].values()) - 1.0) < 0.01
    assert d["median_ratio_to_decoupled"]["decoupled"] == 1.0
    for s in d["baseline"].values():  # the baseline settings, paired with the defaults
        assert s["solved"] == 2 and s["paired_time_ratio"] > 0
        assert s["paired_duration_ratio"] > 0


def test_bad_options_exit_2_naming_them() -> None:
    for args, name in ((["--systems", "strict7"], "--systems"), (["--limit", "0"], "--limit"),
                       (["--timeout", "-1"], "--timeout"),
                       (["--tasks", "/nonexistent.json"], "--tasks")):
        p = _run(*args)
        assert p.returncode == 2 and name in p.stderr, (args, p.stderr)
