"""Does a twirling fork lift more noodle than a still, skewering one? (issue 9, the open
problem). Runs the fork acquisition (``articutool.sim.scenes.skewer``) with TWIRL_CW 2 turns
and with no twirl, same seeds, and writes the mass lifted per run as JSON.

    .venv/bin/python benchmarks/noodle_twirl.py --seeds 10 --out results/noodle_twirl.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from articutool.sim.scenes import skewer
from articutool.sim.world import FeedingWorld


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--turns", type=float, default=2.0)
    ap.add_argument("--out", default="results/noodle_twirl.json")
    args = ap.parse_args(argv)
    runs = []
    for seed in range(args.seeds):
        for turns in (args.turns, 0.0):
            t0 = time.perf_counter()
            w = FeedingWorld("noodles", seed=seed)
            skewer(w, level=True, twirl_turns=turns)
            runs.append({"seed": seed, "twirl_turns": turns,
                         "lifted_g": round(w.masses_g()["utensil"], 3),
                         "ft_mass_g": round(w.ft_mass_g(), 3),
                         "realtime_factor": round(w.realtime_factor, 3),
                         "wall_s": round(time.perf_counter() - t0, 1)})
            print(runs[-1], flush=True)
    twirl = [r["lifted_g"] for r in runs if r["twirl_turns"] > 0]
    still = [r["lifted_g"] for r in runs if r["twirl_turns"] == 0]
    out = {"twirl_mean_g": sum(twirl) / len(twirl), "still_mean_g": sum(still) / len(still),
           "twirl_more_in": sum(a > b for a, b in zip(twirl, still, strict=True)),
           "seeds": args.seeds, "runs": runs}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps({k: v for k, v in out.items() if k != "runs"}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
