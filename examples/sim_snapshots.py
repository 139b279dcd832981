"""The README's simulation pictures: one snapshot per food (headless, EGL).

    .venv/bin/python examples/sim_snapshots.py --out docs
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

from articutool.sim.render import save_png
from articutool.sim.scenes import scoop
from articutool.sim.world import FeedingWorld
from articutool.tool.api import Mode


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs")
    out = Path(ap.parse_args().out)
    out.mkdir(parents=True, exist_ok=True)
    # Pecans: the scripted scoop, leveled, above the bowl.
    w = FeedingWorld.make("pecans", seed=0)
    scoop(w, level=True)
    save_png(w, out / "sim_pecans.png", "utensil")
    # Water: 8 g poured into the leveled, tared soup spoon (the Exp. 2b load).
    w = FeedingWorld.make("water", seed=0, load_g=8.0)
    w.tool.set_mode(Mode.LEVELING)
    w.run(1.0)
    w.placement.place(settle_s=1.0)
    save_png(w, out / "sim_water.png", "utensil")
    # Noodles: the strands settled in the bowl, the fork above.
    w = FeedingWorld.make("noodles", seed=0)
    save_png(w, out / "sim_noodles.png", "bowl")


if __name__ == "__main__":
    main()
