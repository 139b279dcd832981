"""The bite's food telemetry (``StageLedger``) and the simulated user (``SimUser``) on a
stand-in world: the user's bite is the tree's, and the ledger weighs the bite as offered."""

from __future__ import annotations

import numpy as np
import py_trees
from py_trees.common import Status

from articutool.feeding.behaviours import BiteStage, TakeBite
from articutool.meal.bites import SimUser, StageLedger


class World:
    """What the ledger and the user read and do, with a log of the calls in order; it
    stands in for the world, its food ledger and its weighing at once."""

    def __init__(self) -> None:
        self.on_utensil, self.eaten, self.spills = 2.5, 0.0, []
        self.calls: list[str] = []
        self.ledger = self.weighing = self

    def masses_g(self) -> dict[str, float]:
        self.calls.append("masses")
        return {"utensil": self.on_utensil, "eaten": self.eaten}

    def carried_g(self) -> float:
        return self.on_utensil

    def item_classes(self) -> np.ndarray:
        return np.zeros(1)

    def comparable(self) -> bool:
        return True

    def ft_mass_g(self, _: float) -> float:
        self.calls.append("ft")
        return self.on_utensil

    def tilt_deg(self) -> float:
        return 0.0

    def eat_from_utensil(self) -> float:
        self.calls.append("eat")
        g, self.on_utensil, self.eaten = self.on_utensil, 0.0, self.eaten + self.on_utensil
        return g


def _present(world: World, visitors: list) -> BiteStage:
    stage = BiteStage("present", [py_trees.behaviours.Success("hold"),
                                  TakeBite(SimUser(world))])
    tree = py_trees.trees.BehaviourTree(stage)
    tree.visitors += visitors
    tree.tick()
    return stage


def test_the_user_takes_the_bite_with_no_visitor_attached() -> None:
    world = World()
    stage = _present(world, [])
    assert stage.status == Status.SUCCESS
    assert world.calls == ["eat"] and world.eaten == 2.5
    assert stage.children[1].feedback_message == "2.50 g taken"


def test_the_ledger_weighs_the_bite_as_offered_before_the_user_takes_it() -> None:
    world = World()
    ledger = StageLedger(world)
    _present(world, [ledger])
    assert ledger.presented and ledger.last_stage == "present"
    assert ledger.after["present"]["utensil"] == 2.5 and ledger.after["present"]["ft"] == 2.5
    assert world.calls == ["masses", "ft", "eat"]  # weighed, then eaten, in the same tick
    assert world.eaten == 2.5
