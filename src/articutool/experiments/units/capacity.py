"""Our "maximum capacity" protocol (thesis §5.2.3; ``experiments.toml [capacity]``): the
mean maximal scoop is Exp. 2c's load."""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Annotated, Any

from pydantic import Field, model_validator

from articutool.datafile import StrictModel
from articutool.experiments.analysis import measured, ok_records, rate
from articutool.experiments.config import ExperimentsConfig, Names
from articutool.experiments.markdown import ci95, mean_sd, num, table
from articutool.experiments.protocols import rounded, thesis_bite
from articutool.experiments.records import ConditionBase, OutcomeBase, TrialRecord
from articutool.experiments.stats import describe
from articutool.experiments.unit import Experiment, Hook, Visitors, add_foods_argument

if TYPE_CHECKING:
    from articutool.sim.world import SettleCache

__all__ = [
    "EXPERIMENT",
    "CapacityCondition",
    "CapacityConfig",
    "CapacityOutcome",
    "capacity_strategy",
    "capacity_trial",
    "summarize_capacity",
]


class Scoop(StrictModel):
    """The maximal scoop's path: the food's Articutool sweep (strategies.toml) with these
    insertion values (see the data file)."""

    depth_m: Annotated[float, Field(ge=0, le=0.02)]
    drag_m: Annotated[float, Field(ge=0, le=0.2)]
    offset_m: Annotated[float, Field(ge=-0.1, le=0.1)]
    sweep_to_deg: Annotated[float, Field(ge=0, le=90)]


class CapacityConfig(StrictModel):
    """Our "maximum capacity" protocol (see the data file)."""

    foods: Names
    scoop: dict[str, Scoop]

    @model_validator(mode="after")
    def _every_food_scoops(self) -> CapacityConfig:
        missing = [f for f in self.foods if f not in self.scoop]
        if missing:
            raise ValueError(f"scoop: no scoop for {missing}")
        return self



class CapacityCondition(ConditionBase):
    """A maximal scoop of ``food``."""


class CapacityOutcome(OutcomeBase):
    """One maximal scoop (:func:`capacity_trial`); a
    liquid's also ``brim_poured_g`` and ``brim_g``."""

    utensil: str
    completed: bool
    failed_stage: str
    scoop_g: float
    items_g: float
    ft_mass_g: float | None
    tilt_deg: float
    spilled_g: float
    realtime_factor: float
    brim_poured_g: float | None = None
    brim_g: float | None = None

    def food_g(self) -> float:
        """The food the trial ends with: the scoop."""
        return float(self.scoop_g)


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
    from articutool.sim.world import FeedingWorld

    food = cond.food
    setup = make_bite_world(food, "articutool", seed, settle_cache=settled)
    setup.strategy = capacity_strategy(setup.strategy, cfg.capacity.scoop[food])
    w = setup.world
    if hook:
        hook(w)
    try:
        r = run_bite(setup, stages=("above", "acquire"), timeout_s=cfg.exp1.timeout_s,
                     settings=thesis_bite(cfg),
                     visitors=visitors)
    finally:
        setup.arm.close()
    w.run(cfg.settings.settle_s)
    g = w.ledger.masses_g()
    out: dict[str, Any] = {
        "utensil": w.utensil, "completed": r.completed, "failed_stage": r.failed_stage,
        "scoop_g": rounded(w.weighing.utensil_mass_g()), "items_g": rounded(g["utensil"]),
        "ft_mass_g": rounded(w.weighing.ft_mass_g()) if w.weighing.comparable() else None,
        "tilt_deg": rounded(w.tilt_deg()), "spilled_g": rounded(r.spilled_g),
        "realtime_factor": rounded(w.realtime_factor)}
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
        out.update(brim_poured_g=rounded(brim), brim_g=rounded(b.ledger.masses_g()["utensil"]))
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



def summarize_capacity(records: Sequence[TrialRecord]) -> dict[str, Any]:
    """Per food, the maximal scoops' mass (completed scoops; a scoop whose tree failed is no
    maximal scoop) and, for a liquid, the brim test's; the capacity — Exp. 2c's load — is the
    mean maximal scoop, unless a liquid's scoops do not fill the dish to the brim: then the
    scoop was bounded by the pool it dipped in, not the spoon, and the capacity is the brim."""
    ok = ok_records(records)
    foods = list(dict.fromkeys(r.condition.food for r in ok))
    out: dict[str, Any] = {"foods": {}}
    for f in foods:
        rs = [measured(r) for r in ok if r.condition.food == f]
        done = [o for o in rs if o.completed]
        scoop = describe([o.scoop_g for o in done]).to_dict()
        entry: dict[str, Any] = {"utensil": rs[0].utensil, "scoop_g": scoop,
                                 "completed": rate(len(done), len(rs))}
        brims = [o.brim_g for o in rs if o.brim_g is not None]
        cap, source = scoop, "mean maximal scoop"
        if brims:
            entry["brim_g"] = describe(brims).to_dict()
            if scoop.get("mean") is None or scoop["mean"] < entry["brim_g"]["mean"]:
                cap, source = entry["brim_g"], ("the dish filled to the brim: the scoops "
                                                "were bounded by the pool's depth")
        entry.update(capacity_g=cap, capacity_source=source)
        out["foods"][f] = entry
    return out



def section_capacity(s: Mapping[str, Any], cfg: Any) -> str:
    """Our capacity per food beside the thesis'."""
    th = cfg.thesis["exp2c"]["capacity_g"]
    rows = []
    for f, v in s["foods"].items():
        c = v["capacity_g"]
        diff = (f"{c['mean'] - th[f]:+.1f} g ({100 * (c['mean'] / th[f] - 1):+.0f} %)"
                if c.get("mean") is not None and f in th else "–")
        done = v.get("completed", {})
        rows.append([f, v["utensil"], f"{done.get('k', '?')}/{done.get('n', '?')}",
                     mean_sd(v.get("scoop_g")), ci95(v.get("scoop_g")), mean_sd(v.get("brim_g")),
                     f"**{num(c.get('mean'))}**", v.get("capacity_source", "–"),
                     f"{th.get(f, '–')}", diff])
    return (table(["food", "utensil", "scoops completed", "maximal scoop (g), mean ± SD",
                    "95 % CI", "dish filled to the brim (g)", "capacity (Exp. 2c's load, g)",
                    "from", "thesis (g)", "ours − thesis"], rows)
            + "\n\nProtocol (§5.2.3: an experimenter's repeated maximal manual scoops; their "
              "mean is Exp. 2c's load): the Articutool scoops through the full bowl along "
              "the food's own sweep made maximal (`experiments.toml [capacity.scoop]`: the "
              "dish's outline 1 mm above the bowl's floor, dragged through the food, levelled "
              "in it as far as the handle clears the rim; no shedding primitive), lifts the "
              "spoon level and holds it 1 s; what it holds then, pieces perched on others "
              "included, is one maximal load. A liquid's trial also fills the leveled dish to "
              "its brim: a particle liquid without surface tension holds at most the dish's "
              "level volume (the soup spoon: 16.79 mL, 16.8 g of water). The thesis' 20 g of "
              "water is 3.2 g (19 %) more than that level volume: spread over the rim's "
              "opening (π · 30 · 22.5 mm² = 21.2 cm²) it is a 1.5 mm layer above the rim — a "
              "meniscus pinned at a brim-full spoon's rim (water's capillary length is "
              "2.7 mm; such menisci bulge 1-2 mm), which a model without surface tension "
              "cannot hold.")



class CapacityExperiment(Experiment):
    """The maximal scoops."""

    name = "capacity"
    help = "maximum-capacity loads (Exp. 2c's load)"
    title = "Maximum capacity (Exp. 2c's load, §5.2.3)"
    order = 25
    condition = CapacityCondition
    config_model = CapacityConfig
    outcome = CapacityOutcome

    run_trial = staticmethod(capacity_trial)
    section = staticmethod(section_capacity)

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        add_foods_argument(parser)

    def conditions(self, cfg: ExperimentsConfig, **inputs: Any) -> list[Any]:
        return [CapacityCondition(food=f) for f in cfg.capacity.foods]

    def summarize(self, records: Sequence[TrialRecord], cfg: ExperimentsConfig,
                  **settings: Any) -> dict[str, Any]:
        return summarize_capacity(records)


EXPERIMENT = CapacityExperiment()
