"""The physics world's arm as an :class:`~articutool.planning.pc_arm.ArmDriver`: the PC's
arm (:class:`~articutool.planning.pc_arm.PCArm`) plans, verifies and checks the food; this
driver only reads the world's joints and runs trajectories through its arm servos while the
caller steps the world.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from articutool.planning.pc_arm import PCArm
from articutool.sim.world import FeedingWorld
from articutool.trajectory import JointTrajectory

__all__ = ["MujocoArm", "sim_arm", "world_load"]


class MujocoArm:
    """The world's arm servos behind the driver protocol; the wrist's joints are the world's
    ground truth (a real driver reports the tool's)."""

    def __init__(self, world: FeedingWorld) -> None:
        self.world = world

    def joint_positions(self) -> NDArray[np.float64]:
        return self.world.q

    def follow(self, trajectory: JointTrajectory) -> None:
        self.world.follow_arm(trajectory, wait=False)

    def stop(self) -> None:
        self.world.stop_arm()

    @property
    def busy(self) -> bool:
        return self.world.arm_busy


def sim_arm(world: FeedingWorld, **kw: Any) -> PCArm:
    """The PC's arm driving ``world``'s arm (``kw``: :class:`PCArm`'s options)."""
    return PCArm(MujocoArm(world), world.spec, world.utensil, world.scene, **kw)


def world_load(world: FeedingWorld) -> Any:
    """The load on the world's utensil as the food check models it: its food and the grams
    on the utensil (the physics world's count stands for the weighing the F/T sensor gives
    a real tool), or None for a food whose spill is not modelled (strands) or nothing."""
    from articutool.food.loads import LoadError, food_load

    if not world.food:
        return None
    grams = world.ledger.masses_g()["utensil"]
    try:
        return food_load(world.params.definition(world.food), round(grams, 3))
    except LoadError:
        return None
