"""benchmarks/plan_profile.py: the profile names every part of a plan as a share of the
profiled CPU time, and bad input exits 2 naming the option."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "plan_profile.py"


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True,
                          text=True, timeout=300)


def test_profile_accounts_for_the_parts_of_a_plan(tmp_path) -> None:
    out = tmp_path / "p.json"
    p = _run("--limit", "2", "--out", str(out))
    assert p.returncode == 0, p.stderr
    d = json.loads(p.stdout)
    assert d == json.loads(out.read_text())
    assert d["tasks"] == 2 and d["plain_cpu_median_ms"] > 0
    for part in d["parts"].values():
        assert 0.0 <= part["share"] <= 1.0
    # Every plan times its path and verifies it (decoupled).
    assert d["parts"]["timing: toppra + wrist-rate constraint"]["cpu_s"] > 0
    assert d["parts"]["verify: verify_trajectory"]["cpu_s"] > 0
    assert all(v > 0 for v in d["collision_check_cpu"].values())
    pieces = d["pieces_about_median"]
    assert pieces["tasks"] and set(pieces["median_ms"]) == {
        "plan", "setup", "search", "timing", "recheck", "recheck_collisions", "verify"}
    assert all(v > 0 for v in pieces["median_ms"].values())


def test_bad_options_exit_2_naming_them() -> None:
    for args, name in ((["--system", "strict7"], "--system"), (["--limit", "0"], "--limit"),
                       (["--timeout", "0"], "--timeout")):
        p = _run(*args)
        assert p.returncode == 2 and name in p.stderr, (args, p.stderr)
