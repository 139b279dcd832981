"""One fork acquisition in the noodles with the levers of issue 26 exposed, printing how many
strands touch the fork after each phase (in, during and after the twirl, risen, levelled,
lifted) as one JSON line: the diagnostic behind the README's table of what was tried.

It runs the steps of ``articutool.sim.scenes.skewer`` (the same waypoints, the tool's own
TWIRL_CW and LEVELING) with: ``--rise steep`` (rise with the tines still 60° down, the earlier
script) or ``tines-up`` (the shipped skewer); ``--fork-offset`` to move the tines onto the roll
axis (the spec's fork is ``utensils.fork.tip_x`` = 7 mm off it; 0 is *not* the Articutool's
geometry, a what-if).

    nice .venv/bin/python benchmarks/noodle_variant.py --seed 5000 --turns 2.9 --rise tines-up
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np

from articutool.arm.model import ArmModel
from articutool.sim import scenes
from articutool.sim.accounting import UTENSIL
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
    w = FeedingWorld("noodles", seed=args.seed, spec=spec)

    def on_fork() -> int:
        return int(np.sum(w.item_classes() == UTENSIL))

    log: dict[str, object] = dict(vars(args))
    box = w.scene.get("bowl")
    model = ArmModel(w.spec, w.utensil, 8, w.scene)
    w.tool.set_mode(Mode.LEVELING)
    w.run(1.0)
    w.tool.set_mode(Mode.DISABLED)
    w.tare_ft(0.2)
    c = np.array([box.xyz[0], box.xyz[1], box.xyz[2] - box.length / 2 + box.container_wall])
    a, z = math.radians(60.0), scenes._Z
    pts = [(c + z * 0.12, a, 0.1), (c + z * 0.03, a, 0.05), (c + z * 0.002, a, 0.02)]
    q0 = scenes.first_ik(model, np.concatenate([w.arm_q, scenes._wrist(w)]), pts[0][0], a)
    w.move_arm(q0[:6])
    w.follow_arm(scenes.cartesian_path(model, q0, pts), settle_s=0.2)
    log["in"] = on_fork()
    if args.turns > 0:
        ok, msg = w.tool.start_primitive("TWIRL_CW", [args.turns, 3.0])
        if not ok:
            raise SystemExit(f"the tool refused TWIRL_CW: {msg}")
        during: list[int] = []

        def done() -> bool:
            during.append(on_fork())
            return w.tool.mode != Mode.PRIMITIVE

        w.run_until(done, 30.0)
        log["during_twirl"] = during[::25]  # every 0.5 s
    log["twirled"] = on_fork()
    q = np.concatenate([w.arm_q, scenes._wrist(w)])
    rise = ([(pts[-1][0], a, 0.02), (c + z * 0.012, math.radians(30.0), 0.02),
             (c + z * 0.04, 0.0, 0.02)] if args.rise == "tines-up"
            else [(pts[-1][0], a, 0.02), (c + z * 0.04, a, 0.02)])
    w.follow_arm(scenes.cartesian_path(model, q, rise), settle_s=0.2)
    log["risen"] = on_fork()
    w.tool.set_mode(Mode.LEVELING)
    w.run(1.0)
    log["levelled"] = on_fork()
    scenes._lift(w, model)
    w.run(1.0)
    log.update(lifted=on_fork(), lifted_g=round(w.masses_g()["utensil"], 3),
               warnings=warnings_of(w.data),
               realtime_factor=round(w.realtime_factor, 3),
               wall_s=round(time.perf_counter() - t0))
    print(json.dumps(log), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
