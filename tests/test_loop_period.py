"""The wrist's 50 Hz loop keeps its period whatever the link receives: the real tool
(``articutool tool``: its loop process and its link process) under two flooder processes of
2 000 unsigned requests/s each and a CPU hog, for 10 s (``benchmarks/bench_loop_period.py
--short``; the committed 10-minute figures are ``results/loop_period.json``). In one process
with the link, the loop's longest period under this load was 47 ms here (800 ms over
3 minutes)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def test_the_loop_keeps_its_period_under_link_floods_and_a_cpu_hog(tmp_path: Path) -> None:
    out = tmp_path / "loop.json"
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_loop_period.py"),
                        "--short", "--out", str(out)], capture_output=True, text=True,
                       timeout=300, env=dict(os.environ, PYTHONPATH=str(ROOT / "src")))
    assert r.returncode == 0, r.stderr[-3000:]
    (level,) = json.loads(out.read_text())["levels"]
    assert level["tool_exit_code"] == 0 and level["tool_stopped_cleanly"], level
    assert level["tool_tracebacks"] == 0
    sent = sum(level["sent_per_flooder"])
    refused = level["link_counters_delta"]["link_refused_unpaired"]
    assert sent > 10_000 and refused > 0.5 * sent, level  # the flood did reach the tool
    if level["loop_realtime"] == 0.0:  # the tool says so in its health telemetry
        pytest.skip("the loop could not have real-time priority here (no CAP_SYS_NICE or "
                    f"RLIMIT_RTPRIO): longest period {level['period_max_ms']:.1f} ms, not "
                    "asserted on a shared scheduler")
    assert level["period_max_ms"] <= 40.0, level
    assert level["periods_over_2x"] == 0 and level["overruns"] == 0, level
