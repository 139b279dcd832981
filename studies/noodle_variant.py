"""One fork acquisition in the noodles with the model's levers exposed, printing how many
strands touch the fork after each phase (in, during and after the twirl, risen, levelled,
lifted) as one JSON line: the diagnostic behind the lever study (studies/noodle_levers.py).

It runs ``articutool.sim.scenes.skewer`` (the tool's own TWIRL_CW and LEVELING) with:
``--rise steep`` (rise with the tines still 60° down, the earlier script) or ``tines-up``
(the shipped skewer); ``--fork-offset`` to move the tines onto the roll axis (the spec's fork
is ``utensils.fork.tip_x`` = 7 mm off it; 0 is *not* the Articutool's geometry, a what-if).

    nice .venv/bin/python studies/noodle_variant.py --seed 5000 --turns 2.9 --rise tines-up
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from articutool.sim.accounting import UTENSIL
from articutool.sim.scenes import skewer
from articutool.sim.world import FeedingWorld
from articutool.spec import Spec, load_spec
from articutool.tool.api import Mode
from noodle_twirl import warnings_of


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=5000)
    ap.add_argument("--turns", type=float, default=2.9)
    ap.add_argument("--rise", choices=("tines-up", "steep"), default="tines-up")
    ap.add_argument("--fork-offset", type=float, default=None, metavar="M",
                    help="the tines' distance from the roll axis (m; default: the spec's)")
    args = ap.parse_args(argv)
    spec = load_spec()
    if args.fork_offset is not None:
        d = spec.model_dump()
        d["utensils"]["fork"]["tip_x"] = args.fork_offset
        spec = Spec.model_validate(d)
    t0 = time.perf_counter()
    w = FeedingWorld.make("noodles", seed=args.seed, spec=spec)
    log: dict[str, object] = dict(vars(args))
    during: list[int] = []

    def on_fork() -> int:
        return int(np.sum(w.ledger.item_classes() == UTENSIL))

    def every_half_second(world: FeedingWorld) -> None:
        if world.tool.mode == Mode.PRIMITIVE and round(world.time / world.dt) % 250 == 0:
            during.append(on_fork())

    w.on_tick.append(every_half_second)
    skewer(w, level=True, twirl_turns=args.turns, tines_up=args.rise == "tines-up",
           on_phase=lambda name: log.__setitem__(name, on_fork()))
    log["during_twirl"] = during
    log.update(lifted_g=round(w.ledger.masses_g()["utensil"], 3),
               warnings=warnings_of(w.data),
               realtime_factor=round(w.realtime_factor, 3),
               wall_s=round(time.perf_counter() - t0))
    print(json.dumps(log), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
