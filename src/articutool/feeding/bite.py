"""One bite as a py_trees tree, from subtrees that each run alone (thesis §3.2.1, §4.3, §4.4).

Stages, in order (:data:`STAGES`; a bite may run any ordered subset, e.g. Exp. 1 runs
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
- ``present``: hold the bite still at Staging for the user;
- ``return``:  move back to Resting.

Shape::

    Selector "bite"                      (no memory: the guard is checked every tick)
      EternalGuard "Unsafe?"             -> Safe stop (arm stopped, tool DISABLED)
      Selector "bite or retreat"         (memory)
        ToolModeScope <carry mode> (then DISABLED)
          Sequence "bite steps"          one subtree per stage
        SuccessIsFailure "retreat"       a failed bite moves to Resting and still fails
          ToolModeScope ... move to Resting

The carry mode is LEVELING for the Articutool and DISABLED (wrist locked) for the rigid
6-DOF baseline; a primitive runs with the tool DISABLED first (the runtime refuses primitives
while leveling) and the carry mode is restored after it, whatever happened.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import py_trees

from articutool.feeding.behaviours import (
    ArmInterface,
    Attempts,
    Execute,
    PlanLift,
    PlanPath,
    RunPrimitive,
    Settle,
    ToolModeScope,
)
from articutool.feeding.insertion import TipWaypoint
from articutool.feeding.strategies import Stage, Strategy
from articutool.feeding.tree import guarded, motion
from articutool.tool.api import Mode, ToolAPI

__all__ = ["STAGES", "BiteSettings", "bite_tree", "stage_tree"]

STAGES = ("above", "acquire", "shed", "resting", "staging", "present", "return")


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


def _path(arm: ArmInterface, what: str, waypoints: Sequence[TipWaypoint],
          tool: ToolAPI | None = None, clock: Callable[[], float] | None = None
          ) -> py_trees.behaviour.Behaviour:
    # With the tool: a path whose segments the wrist makes sends it the wrist's part.
    return py_trees.composites.Sequence(
        what, memory=True, children=[PlanPath(arm, what, list(waypoints)),
                                     Execute(arm, what, tool, clock)])


def _primitive(tool: ToolAPI, stage: Stage, name: str, carry: Mode
               ) -> py_trees.behaviour.Behaviour:
    run = RunPrimitive(tool, stage.primitive, stage.params, name)
    if stage.is_none:
        return run
    return ToolModeScope(run, tool, Mode.DISABLED, carry)


def stage_tree(name: str, arm: ArmInterface, tool: ToolAPI, strategy: Strategy,
               waypoints: dict[str, list[TipWaypoint]], clock: Callable[[], float],
               settings: BiteSettings = BiteSettings()) -> py_trees.behaviour.Behaviour:
    """The subtree of one stage (see the module doc); ``waypoints`` from
    :func:`articutool.feeding.insertion.acquisition_waypoints`."""
    wrist = strategy.system == "articutool"
    carry = Mode.LEVELING if wrist else Mode.DISABLED
    planner = strategy.transport.planner
    plan_kw = {"attempts": strategy.attempts.plan, "budget_s": settings.budget_s}
    seq = py_trees.composites.Sequence
    st = strategy.stages
    if name == "above":
        # Empty utensil: the loose planner, no verification, the wrist holding (§4.3.1).
        return seq("above", memory=True, children=[
            motion(arm, "AbovePlate", "decoupled", verify=False, **plan_kw),
            _path(arm, "to above the food", waypoints["above"])])
    if name == "acquire":
        steps = [_primitive(tool, st.pre_move_into, "pre-move-into", Mode.DISABLED),
                 _path(arm, "into the food", waypoints["into"],
                       *((tool, clock) if wrist else (None, None))),
                 _primitive(tool, st.post_move_into, "post-move-into", Mode.DISABLED),
                 _path(arm, "out of the food", waypoints["out"],
                       *((tool, clock) if wrist else (None, None)))]
        if wrist:
            steps.append(Settle(tool, Mode.LEVELING, settings.level_s, clock))
        steps.append(seq(f"lift {settings.lift_m * 100:g} cm", memory=True, children=[
            PlanLift(arm, settings.lift_m), Execute(arm, "lift")]))
        # Bounded retries of the whole acquisition (each from the above-food pose).
        n = strategy.attempts.acquire
        return Attempts(seq("acquire steps", memory=True, children=steps), n,
                        "acquisition_attempts", name=f"acquire (up to {n} attempts)")
    if name == "shed":
        steps = [_primitive(tool, st.post_acquisition, "post-acquisition", carry)]
        if wrist:
            steps.append(Settle(tool, Mode.LEVELING, settings.level_s / 2, clock))
        return seq("shed", memory=True, children=steps)
    if name in ("resting", "staging"):
        goal = name.capitalize()
        return motion(arm, goal, planner, name=f"transport to {goal}",
                      food=settings.food_check, tool=tool,
                      clock=clock, then=carry if wrist else None, **plan_kw)
    if name == "present":
        return Settle(tool, carry, settings.present_s, clock,
                      name=f"present at Staging {settings.present_s:g} s ({carry.name})")
    if name == "return":
        return motion(arm, "Resting", "decoupled" if wrist else planner,
                      name="return to Resting", **plan_kw)
    raise ValueError(f"stage: unknown stage {name!r}; known: {', '.join(STAGES)}")


def bite_tree(arm: ArmInterface, tool: ToolAPI, strategy: Strategy,
              waypoints: dict[str, list[TipWaypoint]], clock: Callable[[], float], *,
              stages: Sequence[str] = STAGES, settings: BiteSettings = BiteSettings()
              ) -> py_trees.behaviour.Behaviour:
    """One bite (see the module doc): ``stages`` in :data:`STAGES` order."""
    unknown = [s for s in stages if s not in STAGES]
    if unknown or not stages:
        raise ValueError(f"stages: unknown or empty {unknown}; known: {', '.join(STAGES)}")
    if list(stages) != sorted(stages, key=STAGES.index):
        raise ValueError(f"stages must be in the order {', '.join(STAGES)}")
    carry = Mode.LEVELING if strategy.system == "articutool" else Mode.DISABLED
    # Before acquisition the utensil is empty: the wrist holds (DISABLED); the carry mode
    # starts with the tool-only leveling inside ``acquire``.
    first_mode = Mode.DISABLED if stages[0] in ("above", "acquire") else carry
    subtrees = []
    for s in stages:
        sub = stage_tree(s, arm, tool, strategy, waypoints, clock, settings)
        sub.bite_stage = s  # type: ignore[attr-defined]  # for visitors (telemetry, ledger)
        subtrees.append(sub)
    steps = py_trees.composites.Sequence("bite steps", memory=True, children=subtrees)
    # A failed bite retreats: up out of the container (if the lift fails, from where it is),
    # then to Resting; the bite still fails.
    lift = py_trees.decorators.FailureIsSuccess(
        name="up if possible", child=py_trees.composites.Sequence(
            "retreat lift", memory=True,
            children=[PlanLift(arm, settings.lift_m), Execute(arm, "retreat lift")]))
    home = motion(arm, "Resting", strategy.transport.planner if carry is Mode.DISABLED
                  else "decoupled", attempts=strategy.attempts.plan,
                  budget_s=settings.budget_s)
    retreat = py_trees.decorators.SuccessIsFailure(
        name="retreat (the bite failed)",
        child=ToolModeScope(py_trees.composites.Sequence("retreat", memory=True,
                                                         children=[lift, home]),
                            tool, carry, Mode.DISABLED))
    retreat.is_retreat = True  # type: ignore[attr-defined]  # the recorder keeps the cause
    body = py_trees.composites.Selector("bite or retreat", memory=True, children=[
        ToolModeScope(steps, tool, first_mode, Mode.DISABLED), retreat])
    return guarded(body, arm, tool, clock, settings.stale_s)
