"""The README's picture of a wound noodle bite: the fork's acquisition (press, TWIRL_CW,
tines up, level, lift; ``articutool.sim.scenes.skewer``) for one study seed, photographed
close up after the lift (headless, EGL). Never overwrites a file.

    .venv/bin/python examples/noodle_bite.py --seed 5000 --out docs/sim_noodle_bite.png
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

from articutool.sim.render import save_png
from articutool.sim.scenes import skewer
from articutool.sim.world import FeedingWorld


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=5000)
    ap.add_argument("--turns", type=float, default=None, help="default: the cable budget")
    ap.add_argument("--out", default="docs/sim_noodle_bite.png")
    args = ap.parse_args()
    out = Path(args.out)
    if out.exists():
        ap.error(f"--out: {out} exists; choose a new file (nothing is overwritten)")
    w = FeedingWorld.make("noodles", seed=args.seed)
    skewer(w, level=True, twirl_turns=args.turns)
    save_png(w, out, "utensil_close")
    print(f"{out}: {w.ledger.masses_g()['utensil']:.2f} g on the fork")
    return 0


if __name__ == "__main__":
    sys.exit(main())
