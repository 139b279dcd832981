"""Regenerates ``tests/module_costs.json``: each test module's summed test time, read from the
``--durations=0`` report of a default run (``make test PYTEST_ARGS=--durations=0 > log``;
``python tests/module_costs.py log``). The scheduler (``conftest.py``) sends the costliest
modules first so that no long module starts last while the other workers idle; the costs
order the work, they assert nothing."""

from __future__ import annotations

import json
import re
import sys
from collections import defaultdict
from pathlib import Path

LINE = re.compile(r"^([0-9.]+)s (?:call|setup|teardown)\s+(tests/[^:]+\.py)::")


def costs(report: str) -> dict[str, float]:
    """Seconds per module path, summed over the report's lines, largest first."""
    out: dict[str, float] = defaultdict(float)
    for line in report.splitlines():
        m = LINE.match(line.strip())
        if m:
            out[m.group(2)] += float(m.group(1))
    return {k: round(v, 1) for k, v in sorted(out.items(), key=lambda kv: -kv[1])}


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python tests/module_costs.py DURATIONS_LOG")
    table = costs(Path(sys.argv[1]).read_text(encoding="utf-8"))
    dest = Path(__file__).with_name("module_costs.json")
    dest.write_text(json.dumps(table, indent=1) + "\n", encoding="utf-8")
    print(f"{len(table)} modules -> {dest}")
