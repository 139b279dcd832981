"""What the experiments' protocols share (imperative shell): the thesis' bite settings, the
feeding tree's transport subtree run to a goal and what it did to the load, and one bite
through the feeding tree; each experiment's protocol is in its module
(:mod:`articutool.experiments.units`).

A protocol takes a trial's condition, its seed and the settings, runs the world and the
project's own code (the feeding tree's transport subtree, the tool's primitives, the planners
and verifier), and returns every measured quantity as the experiment's outcome. Trials differ
only by their seed (food placement, sensor noise and gyro bias, planner seed). A ``hook`` may
be given the world before anything moves (video recording for ``--trial K --video``), and
``visitors`` (py_trees visitors) join every feeding tree a trial ticks, as ``articutool meal``
passes them to :func:`~articutool.meal.bites.run_bite`: the list is read when the tree is
built, after the hook, so a hook may add to it (``--record``: the recording's
:attr:`~articutool.sim.mcap_record.WorldMcapRecorder.tree_visitor`, which only reads the
tree's state, so a recorded replay has the logged outcome).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.records import BiteCondition, FoodCheck
from articutool.experiments.unit import Hook, Visitors
from articutool.sim import accounting as acc

if TYPE_CHECKING:
    from articutool.feeding.bite import BiteSettings
    from articutool.feeding.system import System
    from articutool.planning.pc_arm import PCArm
    from articutool.sim.world import FeedingWorld, SettleCache

__all__ = ["bite", "json_safe", "masses", "rounded", "thesis_bite", "transport",
           "transport_outcome"]


def thesis_bite(cfg: ExperimentsConfig) -> BiteSettings:
    """The bite as the thesis' systems make it: the shared planning budget and no food check
    before a transport (the food-aware check is this stack's, run beside them in Exp. 2b's
    variants)."""
    from articutool.feeding.bite import BiteSettings

    return BiteSettings(budget_s=cfg.settings.plan_budget_s, food_check=False)


def rounded(x: float) -> float:
    """``x`` as a record keeps it (4 decimals)."""
    return round(float(x), 4)


def masses(world: FeedingWorld) -> dict[str, float]:
    """The world's masses by place (g), as a record keeps them."""
    return {k: rounded(v) for k, v in world.ledger.masses_g().items()}


def transport(world: FeedingWorld, arm: PCArm, goal: str, system: System, *, attempts: int,
              cfg: ExperimentsConfig, visitors: Visitors = (), food: bool = False
              ) -> dict[str, Any]:
    """Run ``system``'s transport subtree of the feeding tree (plan → verify → execute,
    bounded attempts, the tool's mode scoped; ``food``: the food-aware check of ``arm``'s
    load before executing) to ``goal``, with ``visitors`` on the tree; then hold still
    ``settle_s``. Returns what the tree recorded and the tilt the utensil reached on the
    way."""
    from py_trees.common import Status

    from articutool.feeding.tree import attempts_used, run_tree, transport_tree

    s = cfg.settings
    tilts: list[float] = []

    def watch(w: FeedingWorld) -> None:
        tilts.append(w.tilt_deg())

    world.on_tick.append(watch)
    try:
        root = transport_tree(arm, world.tool, goal, system, attempts=attempts,
                              budget_s=s.plan_budget_s, clock=lambda: world.time, food=food)
        run = run_tree(root, world.run, lambda: world.time, timeout_s=s.tree_timeout_s,
                       visitors=visitors)
    finally:
        world.on_tick.remove(watch)
    used = attempts_used(root).get(f"planning_attempts_{goal}", 0)
    world.run(s.settle_s)
    rec = run.record
    return {
        "completed": run.status == Status.SUCCESS,
        "planning_attempts": used,
        "planning_wall_s": rounded(rec.planning_wall_s),
        "planning_wait_sim_s": rounded(rec.planning_wait_sim_s),
        "motion_time_s": rounded(rec.motion_time_s),
        "failed_stage": rec.failed_stage,
        "max_tilt_deg": rounded(max(tilts)) if tilts else None,
        **({"food_checks": [FoodCheck.of(c) for c in rec.food_checks]} if food else {}),
    }

def transport_outcome(world: FeedingWorld, start: np.ndarray, n_spills: int,
                      before: dict[str, float]) -> dict[str, Any]:
    """What a transport did to the load, by the one definition of both
    (:mod:`articutool.sim.accounting`): everything that left the utensil since the transport
    began (item classes ``start``, the world's spill events from index ``n_spills``, masses
    ``before``) is spilled, by place — a container included (``spilled_by_place``); what is
    on the utensil now (plus anything eaten) is delivered. Only the load counts, as the
    experimenter weighs the utensil: food that missed it while the load was placed (a
    particle sliding off the plate meanwhile) is not the transport's."""
    after = world.ledger.masses_g()
    carried = {int(k) for k in np.flatnonzero(np.asarray(start) == acc.UTENSIL)}
    spills = world.ledger.spills
    events = spills[:n_spills] + [e for e in spills[n_spills:] if e.item in carried]
    spilled = {k: rounded(v) for k, v in acc.transport_spill(
        start, world.ledger.item_classes(), world.ledger.item_g, events, n_spills).items()}
    return {
        "spilled_by_place": spilled,
        "spilled_g": rounded(sum(spilled.values())),
        "delivered_g": rounded(acc.delivered_g(before, after)),
        "airborne_g": after["airborne"],
    }



def json_safe(x: Any) -> Any:
    """``x`` with every non-finite float replaced by ``None`` (the log is strict JSON)."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_safe(v) for v in x]
    return x


def bite(cond: BiteCondition, seed: int, cfg: ExperimentsConfig, hook: Hook,
          stages: tuple[str, ...], timeout_s: float, visitors: Visitors,
          settled: SettleCache | None) -> dict[str, Any]:
    """One bite through the feeding tree (:func:`articutool.meal.bites.run_bite`): the
    world, arm and strategy from :func:`~articutool.meal.bites.make_bite_world` (the
    strategy drawn from the action library with the seed; ``cond.strategies``, when
    given, is another action-library file), the given stages."""
    from articutool.meal.bites import make_bite_world, run_bite

    setup = make_bite_world(cond.food, cond.system, seed, strategies=cond.strategies,
                            physics=cond.physics, settle_cache=settled)
    if hook:
        hook(setup.world)
    try:
        r = run_bite(setup, stages=stages, timeout_s=timeout_s,
                     settings=thesis_bite(cfg),
                     visitors=visitors)
    finally:
        setup.arm.close()
    w = setup.world
    w.run(cfg.settings.settle_s)
    rec = r.to_dict()
    rec["bite_wall_time_s"] = rec.pop("wall_time_s")
    for k in ("bite", "food", "system", "seed"):
        rec.pop(k)
    return json_safe({**rec, "utensil": w.utensil, "masses_end_g": masses(w),
                      "weighed_end_g": rounded(w.weighing.utensil_mass_g()),
                      "realtime_factor": rounded(w.realtime_factor)})
