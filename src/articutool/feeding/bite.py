"""One bite as a py_trees tree, from subtrees that each run alone (thesis §3.2.1, §4.3, §4.4).

Stages, in order (:data:`BITE_STAGES`; a bite may run any ordered subset, e.g. Exp. 1 runs
``above, acquire, resting``):

- ``above``:   move to AbovePlate (a preparatory motion, empty utensil: no verification),
  then to the strategy's above-food pose (a free joint motion);
- ``acquire``: Pre-Move-Into primitive, into the food (Cartesian path), Post-Move-Into
  primitive, out of the food, tool-only leveling (Articutool), lift; up to the strategy's
  ``attempts.acquire`` times;
- ``shed``:    Post-Acquisition primitive over the container (shedding), then level again;
- ``resting``: transport to Resting (plan → verify → check the food → execute, bounded
  attempts; the food check retimes a transport predicted to spill, or re-plans);
- ``staging``: transport to Staging (the same; the thesis' planning attempts count here);
- ``present``: hold the bite still at Staging for the user, who then takes it
  (:class:`~articutool.feeding.behaviours.TakeBite`: the
  :class:`~articutool.feeding.behaviours.User` interface);
- ``return``:  move back to Resting.

Shape::

    Selector "bite"                      (no memory: the guard is checked every tick)
      EternalGuard "Unsafe?"             -> Safe stop (arm stopped, tool DISABLED)
      Selector "bite or retreat"         (memory)
        ToolModeScope <carry mode> (then DISABLED)
          Sequence "bite steps"          one BiteStage per stage
        Retreat                          a failed bite moves to Resting and still fails
          ToolModeScope ... move to Resting

What differs between the systems comes from their
:class:`~articutool.feeding.system.System`: the carry mode is LEVELING for the Articutool and
DISABLED (wrist locked) for the rigid 6-DOF baseline, and the planners are the system's. A
primitive runs with the tool DISABLED first (the runtime refuses primitives while leveling)
and the carry mode is restored after it, whatever happened.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import py_trees

from articutool.feeding.behaviours import (
    ArmInterface,
    BiteStage,
    Board,
    CountedRetry,
    Execute,
    PlanLift,
    PlanPath,
    Retreat,
    RunPrimitive,
    Settle,
    TakeBite,
    ToolModeScope,
    User,
)
from articutool.feeding.insertion import TipWaypoint
from articutool.feeding.strategies import PrimitiveStage, Strategy
from articutool.feeding.system import LOOSE, System
from articutool.feeding.tree import guarded, motion, motion_steps
from articutool.tool.api import Mode, ToolAPI

__all__ = ["BITE_STAGES", "BiteSettings", "bite_tree", "stage_tree"]

BITE_STAGES = ("above", "acquire", "shed", "resting", "staging", "present", "return")


@dataclass(frozen=True)
class BiteSettings:
    """Timing of a bite (our choices; the thesis gives none), and whether the load is checked
    before each transport (``food_check``: :class:`~articutool.feeding.behaviours.CheckFood`,
    retimed until predicted spill-free, else re-planned; the thesis' systems carry without
    it, so its experiments turn it off)."""

    budget_s: float = 10.0  # the planner's own budget per attempt (its wall time)
    level_s: float = 1.0  # tool-only leveling: the wrist settles well within 1 s (measured)
    lift_m: float = 0.10  # straight up out of the container after extraction
    present_s: float = 3.0  # the bite is held still at Staging for the user
    stale_s: float = 0.5  # the guard's limit on the tool state's age
    food_check: bool = True  # check the load before each transport


def _path(arm: ArmInterface, what: str, waypoints: Sequence[TipWaypoint], board: Board,
          tool: ToolAPI | None = None, clock: Callable[[], float] | None = None
          ) -> py_trees.behaviour.Behaviour:
    # With the tool: a path whose segments the wrist makes sends it the wrist's part.
    return py_trees.composites.Sequence(
        what, memory=True, children=[PlanPath(arm, what, list(waypoints), board=board),
                                     Execute(arm, what, tool, clock, board=board)])


def _primitive(tool: ToolAPI, stage: PrimitiveStage, name: str, carry: Mode, board: Board
               ) -> py_trees.behaviour.Behaviour:
    run = RunPrimitive(tool, stage.primitive, stage.params, name, board=board)
    if stage.is_none:
        return run
    return ToolModeScope(run, tool, Mode.DISABLED, carry, board=board)


def stage_tree(name: str, arm: ArmInterface, tool: ToolAPI, strategy: Strategy,
               waypoints: dict[str, list[TipWaypoint]], clock: Callable[[], float], *,
               system: System, user: User, board: Board,
               settings: BiteSettings = BiteSettings()) -> BiteStage:
    """The subtree of one stage (see the module doc) for ``system``, its behaviours sharing
    ``board`` (the tree's); ``waypoints`` from
    :func:`articutool.feeding.insertion.acquisition_waypoints`; ``user`` takes the bite at
    the end of ``present``."""
    wrist, carry = system.wrist, system.carry
    plan_kw = {"attempts": strategy.attempts.plan, "budget_s": settings.budget_s,
               "board": board}
    seq = py_trees.composites.Sequence
    st = strategy.stages
    if name == "above":
        # Empty utensil: the loose planner, no verification, the wrist holding (§4.3.1).
        return BiteStage("above", [motion(arm, "AbovePlate", LOOSE, **plan_kw),
                                   _path(arm, "to above the food", waypoints["above"],
                                         board)])
    if name == "acquire":
        steps = [_primitive(tool, st.pre_move_into, "pre-move-into", Mode.DISABLED, board),
                 _path(arm, "into the food", waypoints["into"], board,
                       *((tool, clock) if wrist else (None, None))),
                 _primitive(tool, st.post_move_into, "post-move-into", Mode.DISABLED, board),
                 _path(arm, "out of the food", waypoints["out"], board,
                       *((tool, clock) if wrist else (None, None)))]
        if wrist:
            steps.append(Settle(tool, Mode.LEVELING, settings.level_s, clock, board=board))
        steps.append(seq(f"lift {settings.lift_m * 100:g} cm", memory=True, children=[
            PlanLift(arm, settings.lift_m, board=board), Execute(arm, "lift", board=board)]))
        # Bounded retries of the whole acquisition (each from the above-food pose).
        n = strategy.attempts.acquire
        return BiteStage("acquire", [CountedRetry(seq("acquire steps", memory=True, children=steps),
                                              n, "acquisition_attempts")])
    if name == "shed":
        steps = [_primitive(tool, st.post_acquisition, "post-acquisition", carry, board)]
        if wrist:
            steps.append(Settle(tool, Mode.LEVELING, settings.level_s / 2, clock, board=board))
        return BiteStage("shed", steps)
    if name in ("resting", "staging"):
        goal = name.capitalize()
        return BiteStage(name, motion_steps(arm, goal, system.transport,
                                            food=settings.food_check, tool=tool, clock=clock,
                                            then=carry if wrist else None, **plan_kw),
                         name=f"transport to {goal}")
    if name == "present":
        hold = Settle(tool, carry, settings.present_s, clock,
                      name=f"hold {settings.present_s:g} s ({carry.name})", board=board)
        return BiteStage("present", [hold, TakeBite(user)], name="present at Staging")
    if name == "return":
        return BiteStage("return", motion_steps(arm, "Resting", system.home, **plan_kw),
                         name="return to Resting")
    raise ValueError(f"stage: unknown stage {name!r}; known: {', '.join(BITE_STAGES)}")


def bite_tree(arm: ArmInterface, tool: ToolAPI, strategy: Strategy,
              waypoints: dict[str, list[TipWaypoint]], clock: Callable[[], float], *,
              system: System, user: User, stages: Sequence[str] = BITE_STAGES,
              settings: BiteSettings = BiteSettings()) -> py_trees.behaviour.Behaviour:
    """One bite of ``strategy`` with ``system`` (see the module doc): ``stages`` in
    :data:`BITE_STAGES` order; ``user`` takes the bite at the end of ``present``. The tree's
    behaviours share a :class:`~articutool.feeding.behaviours.Board` of its own
    (:func:`~articutool.feeding.tree.board_of`)."""
    unknown = [s for s in stages if s not in BITE_STAGES]
    if unknown or not stages:
        raise ValueError(f"stages: unknown or empty {unknown}; known: {', '.join(BITE_STAGES)}")
    if list(stages) != sorted(stages, key=BITE_STAGES.index):
        raise ValueError(f"stages must be in the order {', '.join(BITE_STAGES)}")
    carry, board = system.carry, Board()
    # Before acquisition the utensil is empty: the wrist holds (DISABLED); the carry mode
    # starts with the tool-only leveling inside ``acquire``.
    first_mode = Mode.DISABLED if stages[0] in ("above", "acquire") else carry
    subtrees: list[py_trees.behaviour.Behaviour] = [
        stage_tree(s, arm, tool, strategy, waypoints, clock, system=system, user=user,
                   board=board, settings=settings) for s in stages]
    steps = py_trees.composites.Sequence("bite steps", memory=True, children=subtrees)
    # A failed bite retreats: up out of the container (if the lift fails, from where it is),
    # then to Resting; the bite still fails.
    lift = py_trees.decorators.FailureIsSuccess(
        name="up if possible", child=py_trees.composites.Sequence(
            "retreat lift", memory=True,
            children=[PlanLift(arm, settings.lift_m, board=board),
                      Execute(arm, "retreat lift", board=board)]))
    home = motion(arm, "Resting", system.home, attempts=strategy.attempts.plan,
                  budget_s=settings.budget_s, board=board)
    retreat = Retreat(ToolModeScope(py_trees.composites.Sequence("retreat", memory=True,
                                                                 children=[lift, home]),
                                    tool, carry, Mode.DISABLED, board=board))
    body = py_trees.composites.Selector("bite or retreat", memory=True, children=[
        ToolModeScope(steps, tool, first_mode, Mode.DISABLED, board=board), retreat])
    return guarded(body, arm, tool, clock, settings.stale_s, board=board)
