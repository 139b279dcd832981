"""How many strands of the settled nest lie where each acquisition puts the fork's tip?
For each seed the default noodle bowl is built and settled (``FeedingWorld.make``); within
the fork's half-width (horizontally) of the insertion point the strands are counted, and of
them those with a segment whose centre lies above the tip's height over the floor (a strand
the tines can pass beside rather than press down). The points: the bowl's centre with the tip
2 mm above the floor (the scripted ``sim/scenes.py: skewer`` of ``studies/noodle_twirl.py``)
and ``offset_m`` along the scoop heading with the tip ``depth_m`` above the floor (the feeding
tree's noodle strategies, ``data/strategies.toml``). Geometry of the settled pile only: no
fork moves.

    PYTHONPATH=src nice .venv/bin/python studies/noodle_footprint.py --seeds 0-19 7000-7009 \\
        --out studies/results/noodle_footprint.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from articutool.arm.scene import SCOOP_HEADING, Cylinder
from articutool.feeding.strategies import StrategyLibrary
from articutool.sim.scenes import SKEWER_TIP_ABOVE_FLOOR_M
from articutool.sim.strand_laws import fork_half_width
from articutool.sim.world import FeedingWorld
from articutool.spec import load_spec


def footprint(seed: int, offset_m: float, depth_m: float, radius_m: float) -> dict[str, Any]:
    """Strands of the settled nest under the scripted and the tree's insertion points."""
    w = FeedingWorld.make("noodles", "fork", seed=seed)
    box = w.scene.get(w.layout.container or "bowl")
    assert isinstance(box, Cylinder) and box.container_wall is not None
    floor = float(box.inner_floor()[2])
    centre = np.asarray(box.xyz[:2], dtype=float)
    points = {"scripted": (centre, SKEWER_TIP_ABOVE_FLOOR_M),
              "tree": (centre + offset_m * SCOOP_HEADING[:2], depth_m)}
    out: dict[str, Any] = {"seed": seed, "strands": len(w.layout.food_strands)}
    top = 0.0
    for name, (p, depth) in points.items():
        under = above = 0
        for s in w.layout.food_strands:
            pos = np.array([w.data.xpos[w.model.body(f"{s}/{i}").id]
                            for i in range(w.layout.strand_segments)])
            near = np.linalg.norm(pos[:, :2] - p, axis=1) <= radius_m
            under += bool(near.any())
            above += bool((near & (pos[:, 2] - floor > depth)).any())
            top = max(top, float(np.max(pos[:, 2] - floor)))
        out[f"{name}_under"] = under
        out[f"{name}_above_tip"] = above
    out["nest_top_mm"] = round(top * 1e3, 1)
    return out


def _seeds(specs: list[str]) -> list[int]:
    out: list[int] = []
    for s in specs:
        a, _, b = s.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", nargs="+", default=["0-19"], help="seeds or ranges A-B")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    spec = load_spec()
    lib = StrategyLibrary.load(spec)
    places = {(s.insertion.offset_m, s.insertion.depth_m) for s in lib.strategies.values()
              if s.food == "noodles"}
    if len(places) != 1:
        ap.error(f"the noodle strategies insert at different places: {sorted(places)}")
    offset, depth = places.pop()
    radius = fork_half_width(spec, "fork")
    rows = [footprint(s, offset, depth, radius) for s in _seeds(args.seeds)]
    doc = {"command": "studies/noodle_footprint.py " + " ".join(
               sys.argv[1:] if argv is None else argv),
           "tree_offset_m": offset, "tree_depth_m": depth,
           "scripted_depth_m": SKEWER_TIP_ABOVE_FLOOR_M,
           "fork_half_width_m": radius,
           "mean": {k: round(float(np.mean([r[k] for r in rows])), 2) for k in (
               "scripted_under", "scripted_above_tip", "tree_under", "tree_above_tip",
               "nest_top_mm")},
           "rows": rows}
    if args.out:
        Path(args.out).write_text(json.dumps(doc, indent=1) + "\n")
    print(json.dumps({k: v for k, v in doc.items() if k != "rows"}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
