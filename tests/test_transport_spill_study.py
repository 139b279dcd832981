"""studies/transport_spill.py keeps one code's trials per file: its ``source`` names the code
every trial in it ran, so resuming a file written by other code is refused (exit 2, the file
untouched) instead of mixing commits under one name."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from conftest import assert_refused

STUDY = Path(__file__).resolve().parents[1] / "studies" / "transport_spill.py"


def test_resuming_another_codes_file_is_refused_and_leaves_it_untouched(tmp_path) -> None:
    out = tmp_path / "spill.json"
    out.write_text(json.dumps({"source": "0123456789ab", "trials": [
        {"goal": "centre", "condition": "locked", "scale": 0.5, "lost_g": 0.0}]}))
    before = out.read_bytes()
    proc = subprocess.run([sys.executable, str(STUDY), "--out", str(out), "--goals", "centre",
                           "--conditions", "locked", "--scales", "0.5,0.75"],
                          capture_output=True, text=True, timeout=300)
    assert_refused(proc, "--out", "0123456789ab")
    assert out.read_bytes() == before
