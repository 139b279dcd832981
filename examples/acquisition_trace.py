"""Trace one acquisition in the physics world: per tree tick, the running behaviour, the
utensil tip's height above the container's floor, the utensil's tilt, the mass the world
counts on the utensil, the wrist's angles and its motors' torques.

    .venv/bin/python examples/acquisition_trace.py --food water --system baseline
    .venv/bin/python examples/acquisition_trace.py --food water --strategies my.toml

It runs Exp. 1's stages (above, acquire, resting) with the seed's strategy and prints a line
whenever the behaviour changes and every 0.2 s while the tip is within 5 cm of the floor.
This is how the report's "why we believe ours differ" notes on acquisition were measured.
"""

from __future__ import annotations

import argparse

import numpy as np
import py_trees

from articutool.meal.bites import container_floor, make_bite_world, run_bite


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--food", default="water", choices=["pecans", "water", "noodles"])
    ap.add_argument("--system", default="articutool", choices=["articutool", "baseline"])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--strategies", default=None, help="an action library (default: shipped)")
    ap.add_argument("--near-m", type=float, default=0.05, help="trace densely below this")
    args = ap.parse_args()

    setup = make_bite_world(args.food, args.system, args.seed, strategies=args.strategies)
    w = setup.world
    m = w.model
    floor = container_floor(w.scene, w.layout.container or "bowl")
    acts = [m.actuator(f"{n}/motor").id for n in w.layout.wrist_joints]

    class Trace(py_trees.visitors.VisitorBase):
        """After each tick, a line if the running behaviour changed or the tip is low."""

        def __init__(self) -> None:
            super().__init__(full=False)
            self.root, self.last, self.next_t = None, None, 0.0

        def run(self, behaviour: py_trees.behaviour.Behaviour) -> None:
            if behaviour.parent is None:
                self.root = behaviour

        def finalise(self) -> None:
            tip = self.root.tip() if self.root is not None else None
            name = tip.name if tip is not None else "-"
            h = float(w.tip_pose()[2, 3] - floor[2])
            if name != self.last or (h < args.near_m and w.time >= self.next_t):
                tau = np.round(w.data.actuator_force[acts], 2)
                print(f"{w.time:7.2f} s  {name:28.28s} tip {100 * h:5.1f} cm  "
                      f"tilt {w.tilt_deg():5.1f}°  "
                      f"utensil {w.ledger.masses_g()['utensil']:5.1f} g  "
                      f"wrist {np.round(w.wrist_q, 2)} rad  torque {tau} N·m", flush=True)
                self.last, self.next_t = name, w.time + 0.2

    print(f"{args.food} / {args.system}: strategy {setup.strategy_name}")
    r = run_bite(setup, stages=("above", "acquire", "resting"), visitors=[Trace()])
    print(f"acquired {r.acquired_g:.2f} g, at Resting {r.delivered_g:.2f} g, "
          f"failed stage {r.failed_stage or 'none'}")


if __name__ == "__main__":
    main()
