"""A load on the utensil goes where the utensil goes: no piece of it falls asleep there.

MuJoCo's sleeping freezes a resting tree until an awake one touches it. A piece resting in a
still spoon can lose its contact for a few steps and fall asleep; when the spoon then moves
away nothing touches it again, and it hangs in the air where the spoon was (and the ledger,
seeing a sleeping item with nothing below it, files it on the floor). Exp. 2b, pecans,
seed 0 at the staging start showed it: two of four placed pieces stayed behind.
"""

from __future__ import annotations

import numpy as np

from articutool.arm.scene import Scene
from articutool.sim import accounting as acc
from articutool.sim.world import FeedingWorld
from articutool.tool.api import Mode


def test_a_placed_load_moves_with_the_spoon_and_never_hangs_where_it_was() -> None:
    sset = Scene.load().staging_set
    assert sset is not None
    w = FeedingWorld.make("pecans", seed=0, load_g=2.5, q_arm=sset.start, mouth=False)
    w.tool.set_mode(Mode.LEVELING)
    w.run(1.0)
    w.weighing.tare(0.3)
    w.placement.place(settle_s=1.0)
    w.run(1.0)  # the spoon held still: a resting piece could fall asleep now
    masses = w.ledger.masses_g()
    assert masses["critical"] == 0.0, masses  # nothing reached the floor from a still spoon
    on = np.flatnonzero(w.ledger.item_classes() == acc.UTENSIL)
    assert on.size >= 2
    bodies = w.ledger.item_body[on]
    before = w.data.xpos[bodies].copy()
    tip0 = np.array(w.data.xpos[w.model.body("utensil").id])
    goal = next(g for g in sset.goals if g.name == "centre")
    w.move_arm(goal.q, duration=6.0)
    w.run(0.5)
    moved_utensil = float(np.linalg.norm(w.data.xpos[w.model.body("utensil").id] - tip0))
    assert moved_utensil > 0.2
    moved = np.linalg.norm(w.data.xpos[bodies] - before, axis=1)
    # Every piece that rested on the spoon moved with it or fell: none stayed in the air.
    assert (moved > 0.01).all(), dict(zip(on.tolist(), moved.round(4).tolist(), strict=True))
