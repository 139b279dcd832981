"""Bites and meals in the physics world: the feeding tree driving the MuJoCo arm and the
tool's own runtime, with the food accounted by physics.

:func:`make_bite_world` builds the world for a food and a system (the strategy, drawn from
the action library with the seed, picks the utensil; its
:class:`~articutool.feeding.system.System` is decided once, here), puts the arm at Resting
(the rigid baseline: the configuration that holds its locked utensil level there), levels the
empty utensil and tares the F/T sensor. :func:`run_bite` runs the bite tree
(:mod:`articutool.feeding.bite`) with the feeding tree's runner
(:func:`~articutool.feeding.tree.run_tree`) at 10 Hz of simulated time while the world steps,
and returns a :class:`BiteResult`: masses from the world's accounting at the end of each stage
(a visitor, :class:`StageLedger`), spills by place, planning attempts and times (the tree's
:class:`~articutool.feeding.tree.BiteRecorder`), and the outcome class
(:func:`~articutool.feeding.outcomes.classify_bite`). At the end of ``present`` the simulated
user (:class:`SimUser`) takes the bite (:meth:`FoodLedger.eat_from_utensil
<articutool.sim.ledger.FoodLedger.eat_from_utensil>`).
:func:`run_meal` runs N bites with the same tree.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import py_trees
from numpy.typing import NDArray
from py_trees.common import Status

from articutool.arm.scene import SCOOP_HEADING, Scene, container_floor
from articutool.feeding.behaviours import BiteStage, CountedRetry, TakeBite
from articutool.feeding.bite import BITE_STAGES, BiteSettings, bite_tree
from articutool.feeding.insertion import acquisition_waypoints, dish_outline
from articutool.feeding.outcomes import classify_bite
from articutool.feeding.strategies import Strategy, StrategyLibrary
from articutool.feeding.system import System
from articutool.feeding.tree import attempts_used, run_tree
from articutool.planning.pc_arm import PCArm
from articutool.sim import accounting as acc
from articutool.sim.arm_driver import sim_arm, world_load
from articutool.sim.params import PhysicsParams
from articutool.sim.world import FeedingWorld, SettleCache
from articutool.spec import Spec, load_spec
from articutool.tool.api import Mode, ToolAPI

__all__ = ["BiteResult", "MealSetup", "SimUser", "StageLedger", "make_bite_world", "run_bite",
           "run_meal", "shed_configuration"]

DEFAULT_SETTINGS = BiteSettings()


@dataclass
class BiteResult:
    """One bite's record (``to_dict`` is the ``--json`` form)."""

    bite: int
    food: str
    system: str
    strategy: str
    seed: int
    outcome: str | None  # None when no threshold was given (classified later)
    completed: bool
    acquired_g: float  # on the utensil after acquisition (before shedding)
    shed_g: float  # shed back into the container by the post-acquisition primitive
    delivered_g: float  # on the utensil when presented (or at the last stage run)
    spilled_g: float  # table + user during the bite
    spilled_by_place: dict[str, float]
    ft_delivered_g: float | None  # the F/T sensor's reading of delivered_g, when comparable
    planning_attempts: int  # to Staging (the thesis' count), else to the last goal planned
    planning_attempts_by_goal: dict[str, int]
    acquisition_attempts: int  # 0 if the bite had no acquire stage
    planning_wall_s: float  # the planners' own wall time (the attempts' budget is on it)
    planning_wait_sim_s: float  # simulated time that passed while planning (a tick per plan)
    motion_time_s: float
    sim_time_s: float
    wall_time_s: float
    failed_stage: str
    stages: list[str]
    masses_after: dict[str, dict[str, float]] = field(default_factory=dict)
    transport_max_tilt_deg: float = float("nan")  # utensil tilt during resting + staging
    # How the tree ended: "completed"; "retreated" (a stage failed after its retries, the
    # retreat to Resting ran); "stopped" (the guard's safe stop: a tool fault, stale tool
    # state or a stop request; the arm stopped where it was, the tool DISABLED);
    # "timed_out" (the bite's own time limit).
    end_state: str = ""
    # The stage running (or the last one that ended) when the bite ended: where a fault hit.
    last_stage: str = ""
    # The food checks before each transport (what was done, the prediction) and the grams
    # they predicted, beside ``spilled_g`` that the world measured.
    food_checks: list[dict[str, Any]] = field(default_factory=list)
    predicted_spill_g: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready record."""
        return asdict(self)


# The bite's transport: from the first of these stages that runs to the end of the last;
# anything that leaves the utensil then is spilled wherever it lands (sim.accounting).
TRANSPORT_STAGES = ("resting", "staging", "present")


class SimUser:
    """The simulated user (:class:`~articutool.feeding.behaviours.User`): takes what is on
    the utensil (:meth:`FoodLedger.eat_from_utensil
    <articutool.sim.ledger.FoodLedger.eat_from_utensil>`)."""

    def __init__(self, world: FeedingWorld) -> None:
        self.world = world

    def take_bite(self) -> float:
        """The grams on the utensil, eaten."""
        return self.world.ledger.eat_from_utensil()


class StageLedger(py_trees.visitors.VisitorBase):
    """Visitor (telemetry only): the world's food masses when each stage
    (:class:`~articutool.feeding.behaviours.BiteStage`) ends — a stage that ends with the
    user's bite, when the bite is offered (the step before
    :class:`~articutool.feeding.behaviours.TakeBite` succeeded), with the F/T sensor's
    reading —, the utensil's tilt while transporting, and where every item was when the
    transport began and when it ended (:data:`TRANSPORT_STAGES`)."""

    def __init__(self, world: FeedingWorld) -> None:
        super().__init__(full=False)
        self.world = world
        self.after: dict[str, dict[str, float]] = {}
        self.tilts: list[float] = []
        self.presented = False  # the bite was offered to the user
        self.last_stage = ""  # the stage ticked last
        # (item classes, spill events so far, masses) when the transport began / ended
        self.transport_start: tuple[np.ndarray, int, dict[str, float]] | None = None
        self.transport_end: np.ndarray | None = None

    def transport_spill(self) -> dict[str, float]:
        """Grams that left the utensil in transport, by place (container included): up to
        the end of the last transport stage, or now if the bite ended inside one."""
        if self.transport_start is None:
            return dict.fromkeys(acc.TRANSPORT_PLACES, 0.0)
        start, n, _ = self.transport_start
        end = self.transport_end if self.transport_end is not None \
            else self.world.ledger.item_classes()
        return acc.transport_spill(start, end, self.world.ledger.item_g, self.world.ledger.spills,
                                   n)

    def run(self, behaviour: py_trees.behaviour.Behaviour) -> None:
        offered = _bite_offered(behaviour)
        if offered is not None and offered not in self.after:
            self._ended(offered)  # before the user takes the bite
            self.presented = True
            self.after[offered]["ft"] = (self.world.weighing.ft_mass_g(0.5)
                                         if self.world.weighing.comparable() else float("nan"))
            return
        if not isinstance(behaviour, BiteStage):
            return
        stage = behaviour.stage
        if behaviour.status != Status.INVALID:
            self.last_stage = stage
        if behaviour.status == Status.RUNNING and stage in TRANSPORT_STAGES:
            if self.transport_start is None:
                w = self.world
                led = w.ledger
                self.transport_start = (led.item_classes(), len(led.spills), led.masses_g())
            self.transport_end = None  # (a later transport stage runs: not ended yet)
            if stage in ("resting", "staging"):
                self.tilts.append(self.world.tilt_deg())
        if behaviour.status in (Status.SUCCESS, Status.FAILURE) and stage not in self.after:
            self._ended(stage)

    def _ended(self, stage: str) -> None:
        self.after[stage] = self.world.ledger.masses_g()
        # What a scale under the utensil reads (a hanging strand counts as borne).
        self.after[stage]["carried"] = self.world.weighing.carried_g()
        if stage in TRANSPORT_STAGES and self.transport_start is not None:
            # Before the user eats: what is eaten is delivered, not lost.
            self.transport_end = self.world.ledger.item_classes()


def _bite_offered(behaviour: py_trees.behaviour.Behaviour) -> str | None:
    """The stage whose bite ``behaviour`` offers — it is the step right before the user's
    bite (:class:`~articutool.feeding.behaviours.TakeBite`, which runs next, in the same tick)
    and it succeeded — else None."""
    stage = behaviour.parent
    if behaviour.status != Status.SUCCESS or not isinstance(stage, BiteStage):
        return None
    k = stage.children.index(behaviour) + 1
    offers = k < len(stage.children) and isinstance(stage.children[k], TakeBite)
    return stage.stage if offers else None


@dataclass
class MealSetup:
    """What :func:`make_bite_world` built."""

    world: FeedingWorld
    arm: PCArm
    strategy_name: str
    strategy: Strategy
    seed: int
    system: System


def make_bite_world(food: str, system: str, seed: int = 0, *,
                    strategies: str | Path | None = None, load_g: float | None = None,
                    physics: str | Path | None = None,
                    settle_cache: SettleCache | None = None) -> MealSetup:
    """The world, the arm and the strategy for ``food`` with ``system`` (see module doc).
    ``load_g`` builds a world with a load to place by hand (Exp. 2b/2c) instead of a full
    container; ``physics`` another physics parameter file (e.g. the thesis' 125 g of noodles);
    ``settle_cache`` restores an earlier world's settled food (:class:`~articutool.sim.world.
    SettleCache`).
    Raises ``StrategyError`` / ``ValueError`` naming the field for bad input."""
    spec = load_spec()
    lib = StrategyLibrary.load(spec, strategies)
    name, strat = lib.choose(food, system, np.random.default_rng(seed))
    chosen = System.from_strategy(strat)
    params = PhysicsParams.load(physics) if physics is not None else None
    world = FeedingWorld.make(food, strat.utensil, spec=spec, params=params, seed=seed,
                               load_g=load_g, settle_cache=settle_cache)
    arm = sim_arm(world, seed=seed, rigid=not chosen.wrist, load=lambda: world_load(world),
                  leveling=strat.transport.leveling)
    if chosen.wrist:
        world.tool.set_mode(Mode.LEVELING)
        world.run(1.0)
        world.tool.set_mode(Mode.DISABLED)
    else:
        world.move_arm(arm.goal_configuration("Resting"))
        world.run(0.5)
    world.weighing.tare(0.3)  # level and empty, as one would before a meal
    return MealSetup(world, arm, name, strat, seed, chosen)


def shed_configuration(spec: Spec, scene: Scene, utensil: str, container: str = "bowl",
                       height_m: float = DEFAULT_SETTINGS.lift_m) -> NDArray[np.float64]:
    """Arm joints (6) of the shedding pose over ``container``: the utensil, level with the
    wrist at zero, holds its dish (a fork: the middle of its tines) over the container's
    centre, ``height_m`` above its inner floor — the height at which the bite tree sheds
    after its lift. The thesis' Exp. 2c sheds "while over the bowl", transporting from "a
    fixed Resting configuration (over the bowl)" (§5.2.3), and §4.4's strategies shed
    "harmlessly back into the bowl"; the spec's Resting holds the utensil over the plate.

    Everything comes from the scene (the container's place and size) and the spec (the
    utensil); headings are tried from the arm base's direction to the container in 15°
    steps, IK from the spec's named configurations, and the first collision-free solution
    is taken (deterministic). Raises ``ValueError`` naming the container when none exists.
    """
    from articutool.arm.ik import solve_level_ik
    from articutool.arm.model import ArmModel
    from articutool.food.dish import spoon_dish

    u = spec.utensil(utensil)
    if u.physics.kind == "spoon":
        back = u.tip_z - spoon_dish(u)[0]
    else:
        assert u.physics.tine_length is not None
        back = u.physics.tine_length / 2
    centre = container_floor(scene, container) + np.array([0.0, 0.0, height_m])
    model = ArmModel(spec, utensil, 8, scene)
    h0 = math.atan2(centre[1], centre[0])
    seeds = [np.r_[spec.arm.configuration(n), 0.0, 0.0] for n in spec.arm.configurations]
    q = solve_level_ik(model, lambda z: centre + back * z, h0, seeds)
    if q is not None:
        return q[:6]
    raise ValueError(f"container: no collision-free level utensil pose over {container!r}")


def _tree(setup: MealSetup, stages: Sequence[str], settings: BiteSettings,
          tool: ToolAPI | None = None) -> py_trees.behaviour.Behaviour:
    w = setup.world
    wps = acquisition_waypoints(setup.strategy,
                                container_floor(w.scene, w.layout.container or "bowl"),
                                SCOOP_HEADING, dish_outline(w.spec, w.utensil))
    return bite_tree(setup.arm, tool or w.tool, setup.strategy, wps, lambda: w.time,
                     system=setup.system, user=SimUser(w), stages=stages, settings=settings)


def run_bite(setup: MealSetup, *, bite: int = 0, stages: Sequence[str] = BITE_STAGES,
             threshold_g: float | None = None, settings: BiteSettings = DEFAULT_SETTINGS,
             root: py_trees.behaviour.Behaviour | None = None, timeout_s: float = 240.0,
             visitors: Sequence[py_trees.visitors.VisitorBase] = (),
             tool: ToolAPI | None = None) -> BiteResult:
    """Run one bite (``stages`` of :data:`~articutool.feeding.bite.BITE_STAGES`) and return its
    record. ``timeout_s`` is simulated time not counting the waits for plans (those depend on
    the machine's speed; each plan ends within the planner's own budget). ``root``: a tree
    from an earlier bite of the same meal (the same tree runs again);
    ``visitors`` join the tree's own (e.g. a progress display or a trace). ``tool``: the
    ``ToolAPI`` the tree drives (default the world's runtime; a
    :class:`~articutool.link.remote_tool.RemoteTool` runs the bite's tool side over the
    link, the world still stepping the runtime behind the server)."""
    w = setup.world
    if root is None:
        root = _tree(setup, stages, settings, tool)
    ledger = StageLedger(w)
    for n in root.iterate():  # the same tree runs every bite of a meal: count this bite's only
        if isinstance(n, CountedRetry):
            n.count = 0
    t0, wall0, n_spills = w.time, time.perf_counter(), len(w.ledger.spills)
    before = w.ledger.masses_g()
    # simulated time, not counting the waits for plans
    run = run_tree(root, w.run, lambda: w.time, period_s=0.1, timeout_s=timeout_s,
                   visitors=[ledger, *visitors])
    rec = run.record
    # A bite tree that fails has retreated to Resting (bite_tree's retreat).
    end_state = "retreated" if run.end == "failed" else run.end
    # Spilled and delivered as everywhere (sim.accounting): each item once, at its worst place;
    # before the transport a spill is food on the table or the user, in transport anything
    # that left the utensil, wherever it landed (a container apart).
    n_transport = (ledger.transport_start[1] if ledger.transport_start is not None
                   else len(w.ledger.spills))
    spilled = acc.spilled_by_place(w.ledger.spills[:n_transport], n_spills)
    moved = ledger.transport_spill()
    spilled = {"table": spilled["table"] + moved["table"],
               "critical": spilled["critical"] + moved["critical"],
               "container": moved["container"], "airborne": moved["airborne"]}
    after = ledger.after
    acquired = after.get("acquire", before)["utensil"]
    # Shed: what fell from the utensil back into the container during the shed stage.
    shed = (max(0.0, after["shed"]["container"] - after.get("acquire", before)["container"])
            if "shed" in after else 0.0)
    completed = end_state == "completed"
    # Delivered: on the utensil when presented (or after the last stage of a completed run
    # without ``present``), plus what reached the mouth region on the way (eaten by the
    # world's accounting). A bite stopped or failed before that delivered only what was
    # eaten: the food still on the utensil was never offered.
    if ledger.presented:
        end = after["present"]
    elif completed:
        end = after.get(stages[-1]) or w.ledger.masses_g()
    else:
        end = {**w.ledger.masses_g(), "utensil": 0.0}
    if w.strands and "carried" in end and end["utensil"] > 0:
        # A strand can hang from the fork onto a surface: its grams are what the fork bears,
        # as a scale under it reads (rigid pieces and particles are wholly on it or not).
        end = {**end, "utensil": end["carried"]}
    delivered = acc.delivered_g(before, end)
    # Attempts per goal, from this tree's own counters (zeroed before the bite; in tree
    # order, a retreat's last), also of a stage that failed and was stopped (INVALID since).
    counted = attempts_used(root)
    attempts = {k.removeprefix("planning_attempts_"): v for k, v in counted.items()
                if k.startswith("planning_attempts_")}
    goal = "Staging" if "Staging" in attempts else (list(attempts)[-1] if attempts else "")
    ft = after.get("present", {}).get("ft")
    return BiteResult(
        bite=bite, food=w.food or "", system=setup.system.name,
        strategy=setup.strategy_name, seed=setup.seed,
        outcome=(None if threshold_g is None
                 else classify_bite(delivered, spilled, threshold_g, completed)),
        completed=completed, acquired_g=acquired, shed_g=shed, delivered_g=delivered,
        spilled_g=sum(spilled.values()), spilled_by_place=spilled,
        ft_delivered_g=None if ft is None or ft != ft else float(ft),
        planning_attempts=attempts.get(goal, 0), planning_attempts_by_goal=attempts,
        acquisition_attempts=counted.get("acquisition_attempts", 0),
        planning_wall_s=rec.planning_wall_s,
        planning_wait_sim_s=rec.planning_wait_sim_s,
        motion_time_s=rec.motion_time_s,
        sim_time_s=w.time - t0, wall_time_s=time.perf_counter() - wall0,
        failed_stage="" if completed else rec.failed_stage or "stopped",
        stages=list(stages), masses_after=after,
        transport_max_tilt_deg=max(ledger.tilts) if ledger.tilts else float("nan"),
        end_state=end_state, last_stage=ledger.last_stage,
        food_checks=rec.food_checks,
        predicted_spill_g=_predicted(rec.food_checks))


def _predicted(checks: list[dict[str, Any]]) -> float | None:
    """Grams the executed transports' food checks predicted (None if none was checked)."""
    done = [c["predicted_spill_g"] for c in checks
            if c.get("duration_s") is not None and c.get("predicted_spill_g") is not None]
    return round(sum(done), 4) if done else None


def run_meal(food: str, system: str, *, bites: int = 1, seed: int = 0,
             strategies: str | Path | None = None, threshold_g: float | None = None,
             settings: BiteSettings = DEFAULT_SETTINGS,
             visitors: Sequence[py_trees.visitors.VisitorBase] = (),
             on_bite: Callable[[BiteResult], None] | None = None,
             setup: MealSetup | None = None) -> list[BiteResult]:
    """N bites of ``food`` with ``system`` with the same tree (one strategy per meal, drawn
    with ``seed``); a failed bite retreats to Resting and the meal goes on."""
    setup = setup or make_bite_world(food, system, seed, strategies=strategies)
    root = _tree(setup, BITE_STAGES, settings)
    out = []
    try:
        for k in range(bites):
            r = run_bite(setup, bite=k, threshold_g=threshold_g, settings=settings, root=root,
                         visitors=visitors)
            out.append(r)
            if on_bite is not None:
                on_bite(r)
    finally:
        setup.arm.close()
    return out
