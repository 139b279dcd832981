"""One trial of each experiment in the physics world (imperative shell).

Each protocol takes a trial's condition, its seed and the settings, runs the world and the
project's own code (the feeding tree's transport subtree, the tool's primitives, the planners
and verifier), and returns every measured quantity as the experiment's outcome
(:mod:`articutool.experiments.records`). Trials differ only by
their seed (food placement, sensor noise and gyro bias, planner seed). A ``hook`` may be
given the world before anything moves (video recording for ``--trial K --video``), and
``visitors`` (py_trees visitors) join every feeding tree a trial ticks, as ``articutool meal``
passes them to :func:`~articutool.meal.bites.run_bite`: the list is read when the tree is
built, after the hook, so a hook may add to it (``--record``: the recording's
:attr:`~articutool.sim.mcap_record.WorldMcapRecorder.tree_visitor`, which only reads the
tree's state, so a recorded replay has the logged outcome). The capacity protocol runs no tree.

- :func:`capacity_trial` — our "maximum capacity" protocol (§5.2.3; see ``experiments.toml``);
- :func:`exp2b_trial` — a placed load carried from the common start to one Staging goal of
  the scene's ``[staging_set]`` (§5.2.2): the Articutool (decoupled + LEVELING) or the
  baseline (strict ±20°, wrist locked);
- :func:`exp2c_trial` — the capacity load placed over the bowl (the thesis' "fixed Resting
  configuration (over the bowl)", :func:`~articutool.meal.bites.shed_configuration`), the
  shedding primitive there (or not: control), then carried to Staging by the Articutool
  (§5.2.3).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.records import (
    BiteCondition,
    BiteOutcome,
    CapacityCondition,
    CapacityOutcome,
    Exp2bCondition,
    Exp2bOutcome,
    Exp2cCondition,
    Exp2cOutcome,
)
from articutool.planning.pc_arm import PCArm
from articutool.sim import accounting as acc
from articutool.sim.arm_driver import sim_arm, world_load
from articutool.sim.world import FeedingWorld, SettleCache

if TYPE_CHECKING:
    import py_trees

    from articutool.feeding.bite import BiteSettings
    from articutool.feeding.system import System

__all__ = ["BITE_PROTOCOLS", "Hook", "capacity_strategy", "capacity_trial", "closed_loop_params",
           "closed_loop_target_g", "exp1_trial", "exp2b_arm", "exp2b_trial", "exp2c_trial",
           "exp3_trial", "json_safe", "transport", "transport_outcome"]

Hook = Callable[[FeedingWorld], None] | None
Visitors = Sequence["py_trees.visitors.VisitorBase"]


def _thesis_bite(cfg: ExperimentsConfig) -> BiteSettings:
    """The bite as the thesis' systems make it: the shared planning budget and no food check
    before a transport (the food-aware check is this stack's, run beside them in Exp. 2b's
    variants)."""
    from articutool.feeding.bite import BiteSettings

    return BiteSettings(budget_s=cfg.settings.plan_budget_s, food_check=False)


def _r(x: float) -> float:
    return round(float(x), 4)


def _masses(world: FeedingWorld) -> dict[str, float]:
    return {k: _r(v) for k, v in world.ledger.masses_g().items()}


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
        "planning_wall_s": _r(rec.planning_wall_s),
        "planning_wait_sim_s": _r(rec.planning_wait_sim_s),
        "motion_time_s": _r(rec.motion_time_s),
        "failed_stage": rec.failed_stage,
        "max_tilt_deg": _r(max(tilts)) if tilts else None,
        **({"food_checks": [_food_check_summary(c) for c in rec.food_checks]} if food else {}),
    }


def _food_check_summary(check: Mapping[str, Any]) -> dict[str, Any]:
    """What a food check decided, for the trial's record: the wrist it modelled (for a plan
    it refused, the wrist of its last try), the speed scale it kept and the spill it
    predicted (its full record stays in the bite's log)."""
    keep = ("wrist", "scale", "predicted_spill_g", "planned_duration_s", "duration_s",
            "min_margin_deg", "executed", "slosh_free_fallback")
    out = {k: check[k] for k in keep if k in check}
    modelled = [t["wrist"] for t in check.get("tried", ()) if "wrist" in t]
    if "wrist" not in out and modelled:  # a refused plan: the wrist its last try modelled
        out["wrist"] = modelled[-1]
    return out


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
    spilled = {k: _r(v) for k, v in acc.transport_spill(
        start, world.ledger.item_classes(), world.ledger.item_g, events, n_spills).items()}
    return {
        "spilled_by_place": spilled,
        "spilled_g": _r(sum(spilled.values())),
        "delivered_g": _r(acc.delivered_g(before, after)),
        "airborne_g": after["airborne"],
    }


def capacity_trial(cond: CapacityCondition, seed: int, cfg: ExperimentsConfig,
                   hook: Hook = None, visitors: Visitors = (),
                   settled: SettleCache | None = None) -> CapacityOutcome:
    """One maximal scoop (thesis §5.2.3: an experimenter's repeated maximal manual scoops,
    their mean): the Articutool scoops through the full bowl along the capacity scoop's path
    (``[capacity.scoop]``: the food's own sweep made as deep and long as the bowl allows,
    no shedding), lifts the utensil level out of the food, holds it ``settle_s``; what it
    holds then is one maximal load (``scoop_g``; weighed as a scale under the utensil would,
    and by the F/T sensor). For a liquid, ``brim_g``: what the leveled spoon keeps of a pour
    filling its dish to the rim — the most any scoop can leave in it without surface
    tension."""
    from articutool.meal.bites import make_bite_world, run_bite
    from articutool.sim.loading import dish_volume_m3
    from articutool.sim.params import Liquid

    food = cond.food
    setup = make_bite_world(food, "articutool", seed, settle_cache=settled)
    setup.strategy = capacity_strategy(setup.strategy, cfg.capacity.scoop[food])
    w = setup.world
    if hook:
        hook(w)
    try:
        r = run_bite(setup, stages=("above", "acquire"), timeout_s=cfg.exp1.timeout_s,
                     settings=_thesis_bite(cfg),
                     visitors=visitors)
    finally:
        setup.arm.close()
    w.run(cfg.settings.settle_s)
    g = w.ledger.masses_g()
    out: dict[str, Any] = {
        "utensil": w.utensil, "completed": r.completed, "failed_stage": r.failed_stage,
        "scoop_g": _r(w.weighing.utensil_mass_g()), "items_g": _r(g["utensil"]),
        "ft_mass_g": _r(w.weighing.ft_mass_g()) if w.weighing.comparable() else None,
        "tilt_deg": _r(w.tilt_deg()), "spilled_g": _r(r.spilled_g),
        "realtime_factor": _r(w.realtime_factor)}
    fp = w.params.food(food)
    if isinstance(fp, Liquid):
        from articutool.tool.api import Mode

        u = w.spec.utensil(w.utensil)
        # The dish's level volume, less one of a load's particles: the pour's last must fit.
        brim = (dish_volume_m3(u) * fp.density * 1000.0
                - fp.load_item_mass * 1000.0)
        b = FeedingWorld.make(food, w.utensil, spec=w.spec, scene=w.scene, seed=seed,
                               load_g=brim, mouth=False, settle_cache=settled)
        if b.placement.max_load_g() < brim:  # the pour's lattice holds less than the level volume
            brim = b.placement.max_load_g() - 1e-6
            b = FeedingWorld.make(food, w.utensil, spec=w.spec, scene=w.scene, seed=seed,
                                   load_g=brim, mouth=False, settle_cache=settled)
        b.tool.set_mode(Mode.LEVELING)
        b.run(1.0)
        b.placement.place(settle_s=cfg.settings.settle_s)
        out.update(brim_poured_g=_r(brim), brim_g=_r(b.ledger.masses_g()["utensil"]))
    return CapacityOutcome.model_validate(out)


def capacity_strategy(strategy: Any, scoop: Any) -> Any:
    """The food's Articutool strategy with the capacity scoop's path (``scoop``: depth, drag,
    offset, the pitch it levels to in the food) and no primitive: the scoop lifts what it
    gathered and sheds nothing on purpose."""
    from articutool.feeding.strategies import AcquisitionStages, PrimitiveStage

    none = PrimitiveStage(primitive="NONE", params=[])
    ins = strategy.insertion.model_copy(update={
        "motion": "sweep", "depth_m": scoop.depth_m, "drag_m": scoop.drag_m,
        "offset_m": scoop.offset_m, "sweep_to_deg": scoop.sweep_to_deg})
    return strategy.model_copy(update={
        "insertion": ins,
        "stages": AcquisitionStages(pre_move_into=none, post_move_into=none,
                                    post_acquisition=none)})


def exp2b_trial(cond: Exp2bCondition, seed: int, cfg: ExperimentsConfig,
                hook: Hook = None, visitors: Visitors = (),
                settled: SettleCache | None = None) -> Exp2bOutcome:
    """Exp. 2b: load placed at the common start, carried to ``cond.goal``."""
    from articutool.arm.scene import Scene
    from articutool.feeding.system import System
    from articutool.tool.api import Mode

    food, name, goal = cond.food, cond.system, cond.goal
    if goal is None:
        raise ValueError("an Exp. 2b trial needs its goal")
    variant = cfg.exp2b.variants.get(name)
    base = variant.system if variant is not None else name
    # The thesis' systems: the Articutool's own planner, the baseline's strict6 at the
    # experiments' tolerance.
    system = System.of(base, tolerance_deg=cfg.settings.arm_tolerance_deg)
    checked = variant is not None and variant.food_check
    sset = Scene.load().staging_set
    if sset is None:
        raise ValueError("the scene has no [staging_set]")
    load = cfg.exp2b.load_g[food]
    w = FeedingWorld.make(food, seed=seed, load_g=load, q_arm=sset.start, mouth=False,
                           settle_cache=settled)
    if hook:
        hook(w)
    tol = system.transport.tolerance_deg
    arm = exp2b_arm(w, name, cfg, {g.name: g.q for g in sset.goals}, seed)
    try:
        if system.wrist:
            w.tool.set_mode(Mode.LEVELING)
        w.run(1.0)
        w.weighing.tare(0.3)
        held = w.placement.place(settle_s=cfg.settings.settle_s)
        before, n_spills, start = w.ledger.masses_g(), len(w.ledger.spills), w.ledger.item_classes()
        tr = transport(w, arm, goal, system, attempts=_plan_attempts(food, base), cfg=cfg,
                       visitors=visitors, food=checked)
    finally:
        arm.close()
    return Exp2bOutcome.model_validate({
        "load_g": load, "held_g": _r(held), "planner": system.transport.name,
        "tolerance_deg": tol, **tr,
        **transport_outcome(w, start, n_spills, before), "weighed_g": _r(w.weighing.carried_g()),
        "masses_after_g": _masses(w), "realtime_factor": _r(w.realtime_factor)})


def exp2b_arm(world: FeedingWorld, name: str, cfg: ExperimentsConfig,
              goals: dict[str, Any], seed: int) -> PCArm:
    """The arm of Exp. 2b's system ``name`` (a thesis system or a variant): its wrist as the
    system carries the load (locked for the baseline, so a food check models the locked
    spoon), the variant's food check of the world's load and its leveling, and the staging
    set's ``goals``."""
    from articutool.feeding.system import System

    variant = cfg.exp2b.variants.get(name)
    system = System.of(variant.system if variant is not None else name)
    checked = variant is not None and variant.food_check
    return sim_arm(world, seed=seed, rigid=not system.wrist,
                   load=(lambda: world_load(world)) if checked else None,
                   leveling=variant.leveling if variant is not None else "gravity",
                   goals=goals)


def _plan_attempts(food: str, system: str) -> int:
    """The strategy library's plan-attempt limit for the food and system (the same for both
    systems in the shipped file)."""
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.spec import load_spec

    lib = StrategyLibrary.load(load_spec())
    found = lib.for_food(food, system)
    return max(s.attempts.plan for s in found.values()) if found else 3


def exp2c_trial(cond: Exp2cCondition, seed: int, cfg: ExperimentsConfig,
                hook: Hook = None, visitors: Visitors = (),
                settled: SettleCache | None = None) -> Exp2cOutcome:
    """Exp. 2c: ``cond.load_g`` placed at the shedding pose over the bowl, the shedding
    primitive there (``primitive``: the strategy's open-loop one; ``closed_loop``: the
    F/T-driven one of ``[exp2c.closed_loop]``) or not (``control``), then transport to
    Staging with the Articutool."""
    from articutool.arm.scene import Scene
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.feeding.system import System
    from articutool.meal.bites import shed_configuration
    from articutool.spec import load_spec
    from articutool.tool.api import Mode

    food, arm_cond, load = cond.food, cond.condition, float(cond.load_g)
    spec = load_spec()
    strat = StrategyLibrary.load(spec).strategies[cfg.exp2c.strategy[food]]
    stage = strat.stages.post_acquisition
    scene = Scene.load()
    q_shed = shed_configuration(spec, scene, strat.utensil)
    w = FeedingWorld.make(food, strat.utensil, spec=spec, scene=scene, seed=seed, load_g=load,
                           q_arm=q_shed, mouth=False, settle_cache=settled)
    if hook:
        hook(w)
    arm = sim_arm(w, seed=seed)
    prim: dict[str, Any] = {"primitive": None}
    try:
        w.tool.set_mode(Mode.LEVELING)
        w.run(1.0)
        w.weighing.tare(0.3)
        held = w.placement.place(settle_s=cfg.settings.settle_s)
        loaded, n_loaded = w.ledger.masses_g(), len(w.ledger.spills)
        if arm_cond in ("primitive", "closed_loop"):
            shed = cfg.exp2c.closed_loop[food] if arm_cond == "closed_loop" else stage
            params = list(shed.params)
            if arm_cond == "closed_loop" and cond.target_g is not None:
                params = closed_loop_params(shed.primitive, params, float(cond.target_g))
            w.tool.set_mode(Mode.DISABLED)  # primitives are refused while leveling
            ok, msg = w.tool.start_primitive(shed.primitive, params)
            done = ok and w.run_until(lambda: w.tool.mode != Mode.PRIMITIVE, 60.0)
            st = w.tool.primitive_status()
            w.run(cfg.settings.settle_s)
            prim = {"primitive": shed.primitive, "primitive_params": params,
                    "primitive_ok": bool(done and st is not None and st.success),
                    "primitive_message": msg if not ok else (st.message if st else "")}
        before, n_before, start = w.ledger.masses_g(), len(w.ledger.spills), w.ledger.item_classes()
        spills_primitive = acc.spilled_by_place(w.ledger.spills, n_loaded)
        tr = transport(w, arm, "Staging", System.from_strategy(strat),
                       attempts=strat.attempts.plan, cfg=cfg, visitors=visitors)
    finally:
        arm.close()
    # Over the bowl, before transport, what the primitive moves into the container is shed
    # (thesis §5: not a failure); onto the table or the user it is spilled. In transport
    # anything that leaves the spoon is spilled, wherever it lands.
    shed_g = _r(max(0.0, before["container"] - loaded["container"]))
    by_primitive = {"container": shed_g, **{k: _r(v) for k, v in spills_primitive.items()}}
    out = transport_outcome(w, start, n_before, before)
    for place, g in spills_primitive.items():  # a primitive's spill is a spill of the trial
        out["spilled_by_place"][place] = _r(out["spilled_by_place"][place] + g)
    out["spilled_g"] = _r(sum(out["spilled_by_place"].values()))
    return Exp2cOutcome.model_validate({
        "load_g": load, "held_g": _r(held), **prim, "primitive_moved_g": by_primitive,
        "after_primitive_g": _r(before["utensil"]), "shed_g": shed_g, **tr, **out,
        "weighed_g": _r(w.weighing.carried_g()), "masses_after_g": _masses(w),
        "realtime_factor": _r(w.realtime_factor)})


def closed_loop_target_g(threshold_g: float, item_g: float, noise_g: float) -> float:
    """The closed-loop shedding target for a meaningful-success threshold: the primitive
    stops at the first weighing at most this; for the load left to stay *above* the
    threshold, the target stands one item (the smallest step a load changes by) plus three
    standard deviations of one weighing above it."""
    if not (threshold_g >= 0 and item_g > 0 and noise_g >= 0):
        raise ValueError("threshold_g >= 0, item_g > 0 and noise_g >= 0 are required")
    return threshold_g + item_g + 3.0 * noise_g


def closed_loop_params(primitive: str, params: list[float], target_g: float) -> list[float]:
    """``params`` of a closed-loop shedding primitive with its load target set to
    ``target_g`` (primitives without a load target are returned unchanged)."""
    from articutool.tool.primitives import get_primitive

    names = get_primitive(primitive).parameter_names
    if "target_load_g" not in names:
        return list(params)
    out = list(params)
    out[names.index("target_load_g")] = float(target_g)
    return out


def json_safe(x: Any) -> Any:
    """``x`` with every non-finite float replaced by ``None`` (the log is strict JSON)."""
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, dict):
        return {k: json_safe(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [json_safe(v) for v in x]
    return x


def _bite(cond: BiteCondition, seed: int, cfg: ExperimentsConfig, hook: Hook,
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
                     settings=_thesis_bite(cfg),
                     visitors=visitors)
    finally:
        setup.arm.close()
    w = setup.world
    w.run(cfg.settings.settle_s)
    rec = r.to_dict()
    rec["bite_wall_time_s"] = rec.pop("wall_time_s")
    for k in ("bite", "food", "system", "seed"):
        rec.pop(k)
    return json_safe({**rec, "utensil": w.utensil, "masses_end_g": _masses(w),
                      "weighed_end_g": _r(w.weighing.utensil_mass_g()),
                      "realtime_factor": _r(w.realtime_factor)})


def exp1_trial(cond: BiteCondition, seed: int, cfg: ExperimentsConfig,
               hook: Hook = None, visitors: Visitors = (),
               settled: SettleCache | None = None) -> BiteOutcome:
    """Exp. 1 (§5.1): from AbovePlate, acquire with the system's strategy, move
    level-constrained to Resting; the mass on the utensil there (``mass_g``, ground truth;
    ``ft_mass_g`` as the F/T sensor weighs it when comparable)."""
    rec = _bite(cond, seed, cfg, hook, ("above", "acquire", "resting"), cfg.exp1.timeout_s,
                visitors, settled)
    rec["mass_g"] = rec["weighed_end_g"]  # as the experimenter weighs it (strands: borne)
    return BiteOutcome.model_validate(rec)


def exp3_trial(cond: BiteCondition, seed: int, cfg: ExperimentsConfig,
               hook: Hook = None, visitors: Visitors = (),
               settled: SettleCache | None = None) -> BiteOutcome:
    """Exp. 3 (§5.3): the whole bite — above the food, acquire, shed, Resting, Staging,
    present (the simulated user takes it). The outcome class is derived at analysis time,
    at the report's threshold (``outcome`` here is ``None``)."""
    return BiteOutcome.model_validate(_bite(
        cond, seed, cfg, hook, ("above", "acquire", "shed", "resting", "staging", "present"),
        cfg.exp3.timeout_s, visitors, settled))


BITE_PROTOCOLS = {"exp1": exp1_trial, "exp3": exp3_trial}
