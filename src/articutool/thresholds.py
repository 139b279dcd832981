"""Outcome thresholds derived from our own data (thesis §5.3: the thesis took its Exp. 2c and
Exp. 3 thresholds from its own Exp. 1 means; we take ours from ours, never borrow its numbers).

A neutral module below ``feeding`` (``articutool meal``) and ``experiments`` (Exp. 2c, Exp. 3),
which both read it; it only reads the summary Exp. 1 wrote.
"""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["DEFAULT_OUT", "exp1_means"]

DEFAULT_OUT = Path("results/experiments")  # the experiments' results root


def exp1_means(out: Path = DEFAULT_OUT) -> dict[str, float]:
    """Our Exp. 1 Articutool mean acquisition per food (g), from ``out/exp1/summary.json``
    (empty if it has not run). The outcome thresholds of Exp. 2c, Exp. 3 and ``articutool
    meal`` come from here, as the thesis took its thresholds from its own data."""
    p = Path(out) / "exp1" / "summary.json"
    if not p.exists():
        return {}
    acq = json.loads(p.read_text(encoding="utf-8")).get("acquired_g", {})
    return {f: float(v["articutool"]["mean"]) for f, v in acq.items()
            if v.get("articutool", {}).get("mean") is not None}
