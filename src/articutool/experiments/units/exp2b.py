"""Exp. 2b (thesis §5.2.2, H2): a placed load carried from the common start to one Staging
goal of the scene's ``[staging_set]`` by the Articutool (decoupled + LEVELING) or the baseline
(strict ±20°, wrist locked), and this stack's variants beside them."""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal

from pydantic import Field, model_validator

from articutool.datafile import Positive, StrictModel
from articutool.experiments.analysis import (
    by_place,
    food_system,
    measured,
    ok_records,
    rate,
    summarize_mass,
    where,
)
from articutool.experiments.config import ExperimentsConfig, Names
from articutool.experiments.figures import mass_bars
from articutool.experiments.markdown import mass_rows, mean_sd, num, p_value, places, table
from articutool.experiments.protocols import (
    masses,
    rounded,
    transport,
    transport_outcome,
)
from articutool.experiments.records import ConditionBase, FoodCheck, OutcomeBase, TrialRecord
from articutool.experiments.stats import describe, fisher, welch
from articutool.experiments.unit import (
    Experiment,
    Hook,
    Visitors,
    add_foods_argument,
    usage,
)
from articutool.experiments.verdicts import Verdict, judge, mean_sd_g

if TYPE_CHECKING:
    from articutool.planning.pc_arm import PCArm
    from articutool.sim.world import FeedingWorld, SettleCache

__all__ = [
    "EXPERIMENT",
    "Exp2bCondition",
    "Exp2bConfig",
    "Exp2bOutcome",
    "carried_wrists",
    "exp2b_arm",
    "exp2b_trial",
    "summarize_exp2b",
]


class Exp2bVariant(StrictModel):
    """A system of this stack beside the thesis' two: ``system`` (whose planner and tool
    mode it keeps) with the food-aware check before the transport (retimed until predicted
    spill-free, or re-planned) and the wrist leveling against ``leveling`` (``apparent``:
    slosh-free), on ``foods``."""

    system: Literal["articutool", "baseline"]
    food_check: bool = True
    leveling: Literal["gravity", "apparent"] = "gravity"
    foods: Names

    @model_validator(mode="after")
    def _decoupled(self) -> Exp2bVariant:
        if self.leveling == "apparent" and self.system != "articutool":
            raise ValueError("leveling = 'apparent' needs the articutool system (the "
                             "decoupled wrist)")
        return self


class Exp2bConfig(StrictModel):
    """Exp. 2b (§5.2.2): the thesis' ``systems`` and this stack's ``variants`` beside them
    (each named; the name is the trial's ``system``)."""

    foods: Names
    systems: Names
    load_g: dict[str, Positive]
    variants: dict[str, Exp2bVariant] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _names(self) -> Exp2bConfig:
        for name, v in self.variants.items():
            if name in self.systems:
                raise ValueError(f"variants.{name}: the name of a thesis system")
            unknown = [f for f in v.foods if f not in self.foods]
            if unknown:
                raise ValueError(f"variants.{name}.foods: {unknown} not among foods "
                                 f"{self.foods}")
        return self



class Exp2bCondition(ConditionBase):
    """Exp. 2b: a placed load of ``food`` carried by ``system`` (a thesis system or a variant)
    to the staging-set ``goal`` (each trial's; a run's condition list has none)."""

    system: str
    goal: str | None = None

    def group(self) -> tuple[str, ...]:
        """The food and the system (a thesis system or a variant)."""
        return (self.food, self.system)


class Exp2bOutcome(OutcomeBase):
    """A placed load carried to a goal (:func:`exp2b_trial`); ``food_checks`` with the
    food-aware check only."""

    load_g: float
    held_g: float
    planner: str
    tolerance_deg: float | None
    completed: bool
    planning_attempts: int
    planning_wall_s: float
    planning_wait_sim_s: float
    motion_time_s: float
    failed_stage: str
    max_tilt_deg: float | None
    food_checks: list[FoodCheck] | None = None
    spilled_by_place: dict[str, float]
    spilled_g: float
    delivered_g: float
    airborne_g: float
    weighed_g: float
    masses_after_g: dict[str, float]
    realtime_factor: float


def exp2b_trial(cond: Exp2bCondition, seed: int, cfg: ExperimentsConfig,
                hook: Hook = None, visitors: Visitors = (),
                settled: SettleCache | None = None) -> Exp2bOutcome:
    """Exp. 2b: load placed at the common start, carried to ``cond.goal``."""
    from articutool.arm.scene import Scene
    from articutool.feeding.system import System
    from articutool.sim.world import FeedingWorld
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
        tr = transport(w, arm, goal, system, attempts=plan_attempts(food, base), cfg=cfg,
                       visitors=visitors, food=checked)
    finally:
        arm.close()
    return Exp2bOutcome.model_validate({
        "load_g": load, "held_g": rounded(held), "planner": system.transport.name,
        "tolerance_deg": tol, **tr,
        **transport_outcome(w, start, n_spills, before),
        "weighed_g": rounded(w.weighing.carried_g()),
        "masses_after_g": masses(w), "realtime_factor": rounded(w.realtime_factor)})


def exp2b_arm(world: FeedingWorld, name: str, cfg: ExperimentsConfig,
              goals: dict[str, Any], seed: int) -> PCArm:
    """The arm of Exp. 2b's system ``name`` (a thesis system or a variant): its wrist as the
    system carries the load (locked for the baseline, so a food check models the locked
    spoon), the variant's food check of the world's load and its leveling, and the staging
    set's ``goals``."""
    from articutool.feeding.system import System
    from articutool.sim.arm_driver import sim_arm, world_load

    variant = cfg.exp2b.variants.get(name)
    system = System.of(variant.system if variant is not None else name)
    checked = variant is not None and variant.food_check
    return sim_arm(world, seed=seed, rigid=not system.wrist,
                   load=(lambda: world_load(world)) if checked else None,
                   leveling=variant.leveling if variant is not None else "gravity",
                   goals=goals)


def plan_attempts(food: str, system: str) -> int:
    """The strategy library's plan-attempt limit for the food and system (the same for both
    systems in the shipped file)."""
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.spec import load_spec

    lib = StrategyLibrary.load(load_spec())
    found = lib.for_food(food, system)
    return max(s.attempts.plan for s in found.values()) if found else 3



def summarize_exp2b(records: Sequence[TrialRecord], cfg: Any) -> dict[str, Any]:
    """Spilled mass per food and system (Welch), spill frequency (Fisher), per goal, and the
    planning and completion figures."""
    ok = ok_records(records)
    systems = list(cfg.exp2b.systems)
    out: dict[str, Any] = {"spilled_g": summarize_mass(ok, cfg.exp2b.foods, systems,
                                                       lambda o: o.spilled_g)}
    freq: dict[str, Any] = {}
    per_goal: dict[str, Any] = {}
    plan: dict[str, Any] = {}
    for f in cfg.exp2b.foods:
        rs = {s: where(ok, food_system(f, s)) for s in systems}
        spill = {s: _spills(v) for s, v in rs.items()}
        if len(systems) == 2:
            a, b = systems
            freq[f] = fisher(spill[a], len(rs[a]), spill[b], len(rs[b])).to_dict()
            out["spilled_g"][f]["compare"]["p"]["fisher"] = freq[f]["p"]  # spill frequency
        per_goal[f] = {s: {g: describe([measured(r).spilled_g for r in v
                                        if r.condition.goal == g]).to_dict()
                           for g in dict.fromkeys(r.condition.goal for r in v)}
                       for s, v in rs.items()}
        outs = {s: [measured(r) for r in v] for s, v in rs.items()}
        plan[f] = {s: {"completed": rate(sum(1 for o in v if o.completed), len(v)),
                       "planning_attempts": describe([o.planning_attempts for o in v]
                                                     ).to_dict(),
                       "max_tilt_deg": describe([o.max_tilt_deg for o in v
                                                 if o.max_tilt_deg is not None]).to_dict(),
                       "held_g": describe([o.held_g for o in v]).to_dict()}
                   for s, v in outs.items()}
    out.update(spill_frequency_fisher=freq, per_goal=per_goal, transport=plan,
               spilled_by_place={f: {sys_: by_place(where(ok, food_system(f, sys_)))
                                     for sys_ in systems} for f in cfg.exp2b.foods},
               variants=summarize_exp2b_variants(ok, cfg))
    return out


def _spills(records: Sequence[TrialRecord]) -> int:
    """How many of ``records`` spilled anything in transport."""
    return sum(1 for r in records if measured(r).spilled_g > 1e-9)


def summarize_exp2b_variants(records: Sequence[TrialRecord], cfg: Any
                             ) -> dict[str, dict[str, Any]]:
    """Per variant (this stack's systems beside the thesis') and food: its spills and
    spilled mass against the thesis system it extends (same seeds and goals: Fisher and
    Welch), its motion time beside that system's, and what its food checks did (retimed,
    slosh-free, the speed scale kept)."""
    out: dict[str, dict[str, Any]] = {}
    for name, v in cfg.exp2b.variants.items():
        per: dict[str, Any] = {}
        for f in v.foods:
            rs = where(records, food_system(f, name))
            base = where(records, food_system(f, v.system))
            if not rs:
                continue
            checks = [c for r in rs for c in (measured(r).food_checks or [])]
            kept = [c for c in checks if c.executed is not False]
            carried = carried_wrists(v.system)
            per[f] = {
                "base": v.system,
                "spilled_g": describe([measured(r).spilled_g for r in rs]).to_dict(),
                "spills": rate(_spills(rs), len(rs)),
                "base_spills": rate(_spills(base), len(base)),
                "fisher_vs_base": (fisher(_spills(rs), len(rs), _spills(base), len(base))
                                   .to_dict() if base else None),
                "welch_vs_base": (welch([measured(r).spilled_g for r in rs],
                                        [measured(r).spilled_g for r in base]).to_dict()
                                  if base else None),
                "completed": rate(sum(1 for r in rs if measured(r).completed), len(rs)),
                "motion_time_s": describe([measured(r).motion_time_s for r in rs]).to_dict(),
                "base_motion_time_s": describe([measured(r).motion_time_s for r in base]
                                               ).to_dict(),
                "checks": len(checks),
                # checks that modelled the wrist the transport carries (locked for the
                # baseline): a check of another wrist predicts another transport
                "checks_of_carried_wrist": sum(1 for c in checks if c.wrist in carried),
                "retimed": sum(1 for c in kept if c.scale is not None and c.scale < 1.0),
                "slosh_free": sum(1 for c in kept if c.wrist == "slosh_free"),
                "scale": describe([float(c.scale) for c in kept if c.scale is not None]
                                  ).to_dict(),
                "predicted_spill_g": describe([float(c.predicted_spill_g) for c in kept
                                               if c.predicted_spill_g is not None]
                                              ).to_dict(),
                "spilled_by_place": by_place(rs),
            }
        out[name] = per
    return out


def carried_wrists(system: str) -> frozenset[str]:
    """The wrists a food check of ``system``'s transport may model: the locked spoon for the
    baseline, leveling (or slosh-free) for the Articutool."""
    from articutool.feeding.system import System

    return (frozenset({"leveling", "slosh_free"}) if System.of(system).wrist
            else frozenset({"locked"}))



def section_exp2b(s: Mapping[str, Any], cfg: Any) -> str:
    """Spilled mass, transport figures, places and goals beside the thesis'."""
    th = cfg.thesis["exp2b"]

    def cell(f: str, sys_: str, d: Mapping[str, Any]) -> list[str]:
        t = th.get(f, {})
        return [f"{d['nonzero']['k']}/{d['nonzero']['n']}",
                num(t.get(sys_)) if sys_ in t else "not in text"]

    rows = mass_rows(s["spilled_g"], cfg.exp2b.foods, cfg.exp2b.systems, th, cell)
    out = table(["food", "system", "n", "spilled (g), mean ± SD", "95 % CI",
                  "trials with spill", "thesis mean (g)", "Welch p (ours)", "p (thesis)"],
                 rows)
    rows = []
    for f in cfg.exp2b.foods:
        for sys_ in cfg.exp2b.systems:
            t = s["transport"][f][sys_]
            rows.append([f, sys_, mean_sd(t["held_g"]),
                         f"{t['completed']['k']}/{t['completed']['n']}",
                         mean_sd(t["planning_attempts"]), mean_sd(t["max_tilt_deg"], 1),
                         p_value(s["spill_frequency_fisher"].get(f, {}).get("p"))
                         if sys_ == cfg.exp2b.systems[0] else ""])
    out += "\n\n" + table(["food", "system", "load held after placing (g)", "completed",
                            "planning attempts", "max utensil tilt (°)",
                            "Fisher p, spill frequency"], rows)
    if s.get("spilled_by_place"):
        rows = [[f, sys_, places(s["spilled_by_place"][f][sys_])]
                for f in cfg.exp2b.foods for sys_ in cfg.exp2b.systems]
        out += ("\n\nWhere the spilled food went (g over all trials, trials with any): in "
                "transport anything that left the spoon is spilled, a container apart:\n\n"
                + table(["food", "system", "by place"], rows))
    rows = []
    for f in cfg.exp2b.foods:
        for sys_ in cfg.exp2b.systems:
            pg = s["per_goal"][f][sys_]
            rows.append([f, sys_] + [f"{mean_sd(v)} (n={v['n']})" for v in pg.values()])
    goals = list(next(iter(s["per_goal"][cfg.exp2b.foods[0]].values())).keys()) if rows else []
    out += "\n\nSpilled per goal (g):\n\n" + table(["food", "system", *goals], rows)
    return out + _sec_exp2b_variants(s, cfg)


def _sec_exp2b_variants(s: Mapping[str, Any], cfg: Any) -> str:
    """This stack's systems beside the thesis' two (same seeds and goals as the system each
    extends)."""
    rows = []
    for name, per in (s.get("variants") or {}).items():
        v = cfg.exp2b.variants[name]
        what = ("food-aware check" if v.food_check else "no food check") + (
            ", slosh-free leveling" if v.leveling == "apparent" else "")
        for f, e in per.items():
            rows.append([f, f"{name} ({v.system} + {what})",
                         f"{e['spills']['k']}/{e['spills']['n']}",
                         f"{e['base_spills']['k']}/{e['base_spills']['n']}",
                         mean_sd(e["spilled_g"]),
                         p_value((e.get("fisher_vs_base") or {}).get("p")),
                         f"{mean_sd(e['motion_time_s'], 1)} vs "
                         f"{mean_sd(e['base_motion_time_s'], 1)}",
                         f"{e['retimed']}/{e['checks']}", f"{e['slosh_free']}/{e['checks']}",
                         f"{e.get('checks_of_carried_wrist', '–')}/{e['checks']}",
                         places(e["spilled_by_place"])])
    if not rows:
        return ""
    return ("\n\n**This stack's systems beside the thesis' two** (extra conditions on the same "
            "seeds and goals as the thesis system each extends; the thesis' comparison above "
            "is unchanged by them):\n\n"
            + table(["food", "system", "trials with spill", "same, its thesis system",
                      "spilled (g), mean ± SD", "Fisher p vs its thesis system",
                      "motion time (s), it vs its thesis system", "checks retimed",
                      "checks slosh-free", "checks of the wrist carried", "spilled by place"],
                     rows)
            + "\n\nA check of the wrist carried predicts the transport the trial makes (the "
              "locked spoon for the baseline); a check of another wrist tests nothing about "
              "this transport.")



def claims_exp2b(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float,
               tests: Mapping[str, Any]) -> list[Verdict]:
    """Our summary ``s`` against the thesis' ``th`` on each claim it tests, judged by the
    pre-registered ``tests`` at ``alpha`` (:func:`~articutool.experiments.verdicts.judge`)."""
    out = []
    for food, d in s["spilled_g"].items():
        a, b = d.get("articutool"), d.get("baseline")
        if not a or not b:
            continue
        t = th.get(food, {})
        given = isinstance(t.get("articutool"), float | int) and isinstance(
            t.get("baseline"), float | int)
        thesis = (f"{t['articutool']:.2f} vs {t['baseline']:.2f} g spilled, p {t.get('p')}"
                  if given else t.get("note", "not given"))
        nz = (a.get("nonzero", {}).get("k"), b.get("nonzero", {}).get("k"))
        test, size, others, verdict = judge(
            d.get("compare"), tests["exp2b"],
            t["articutool"] - t["baseline"] if given else None, -1, alpha,
            not a.get("sd") and not b.get("sd"), "g",
            labels={"fisher": "Fisher (spill frequency)"})
        spills = (f"; spilled in {nz[0]}/{a['n']} vs {nz[1]}/{b['n']}"
                  if None not in nz else "")
        out.append(Verdict(
            "H2", "Fig. 6.3", f"{food}: the Articutool spills less in transport than the "
            "locked baseline", thesis, f"{mean_sd_g(a)} vs {mean_sd_g(b)} spilled{spills}", test,
            size, others, verdict))
    return out



class Exp2bExperiment(Experiment):
    """Exp. 2b."""

    name = "exp2b"
    help = "transport of placed loads to five Staging goals, H2 (§5.2.2)"
    title = "Exp. 2b — transport of placed loads (H2, §5.2.2; cf. Fig. 6.3)"
    hypothesis = "H2"
    thesis_figure = "Fig. 6.3"
    order = 20
    condition = Exp2bCondition
    config_model = Exp2bConfig
    places_load = True
    claims: ClassVar[dict[str, str]] = {"exp2b": "Exp. 2b spilled mass (H2)"}
    outcome = Exp2bOutcome
    noted_inputs = ("goals",)

    run_trial = staticmethod(exp2b_trial)
    verdicts = staticmethod(claims_exp2b)
    section = staticmethod(section_exp2b)

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        add_foods_argument(parser)

    def inputs(self, args: argparse.Namespace, out: Path, cfg: ExperimentsConfig
               ) -> tuple[dict[str, Any], dict[str, Any]]:
        """The staging set's goals."""
        from articutool.arm.scene import Scene

        sset = Scene.load().staging_set
        if sset is None:
            raise usage("the scene has no [staging_set] (Exp. 2b's start and goals)")
        goals = [g.name for g in sset.goals]
        return {"goals": goals}, {"goals": goals}

    def conditions(self, cfg: ExperimentsConfig, **inputs: Any) -> list[Any]:
        """The thesis' systems on every food, then the variants on theirs (no goal: each
        trial's is its repeat's, :meth:`trial_condition`)."""
        thesis = [Exp2bCondition(food=f, system=s) for f in cfg.exp2b.foods
                  for s in cfg.exp2b.systems]
        return thesis + [Exp2bCondition(food=f, system=name)
                         for name, v in cfg.exp2b.variants.items() for f in v.foods]

    def trial_condition(self, cond: Any, repeat: int, *, goals: Sequence[str] = (),
                        **inputs: Any) -> Any:
        """Repeats spread over the ``goals`` in turn (repeat ``r`` → goal ``r mod
        len(goals)``: 20 trials = 4 per goal)."""
        if not goals:
            raise ValueError("exp2b needs the staging set's goals")
        return cond.model_copy(update={"goal": goals[repeat % len(goals)]})

    def summarize(self, records: Sequence[TrialRecord], cfg: ExperimentsConfig,
                  **settings: Any) -> dict[str, Any]:
        return summarize_exp2b(records, cfg)

    def differences(self, summary: Mapping[str, Any], cfg: ExperimentsConfig) -> list[str]:
        s, out = summary, []
        for f, t in cfg.thesis["exp2b"].items():
            for sys_ in cfg.exp2b.systems:
                m = s["spilled_g"].get(f, {}).get(sys_, {}).get("mean")
                if m is not None and isinstance(t.get(sys_), float | int):
                    out.append(f"{f}, {sys_}: spilled {m:.2f} g vs the thesis' "
                               f"{t[sys_]:.2f} g ({m - t[sys_]:+.2f} g)")
            p = s["spilled_g"].get(f, {}).get("welch", {}).get("p")
            if "p" in t:
                out.append(f"{f}: Welch p {p_value(p)} vs the thesis' {t['p']}")
        return out

    def figure(self, records: Sequence[TrialRecord], summary: Mapping[str, Any],
               cfg: ExperimentsConfig, directory: Path) -> Path | None:
        return mass_bars(records, summary["spilled_g"], cfg.exp2b.foods, cfg.exp2b.systems,
                         lambda o: o.spilled_g, "spilled during transport (g), mean ± 95% CI",
                         "Exp. 2b: spill carrying placed loads to five Staging goals "
                         "(cf. thesis Fig. 6.3)", directory / "exp2b.png")

    def facts(self, summary: Mapping[str, Any] | None, records: Sequence[TrialRecord],
              cfg: ExperimentsConfig) -> dict[str, str]:
        """The loads and what was held after placing."""
        f: dict[str, str] = {}
        ok = [r for r in records if not r.error and r.outcome is not None]
        if ok:
            f["exp2b_loads"] = ", ".join(f"{k} {g:g} g" for k, g in cfg.exp2b.load_g.items())
            for food in cfg.exp2b.foods:
                held = [float(r.outcome.held_g) for r in ok  # type: ignore[union-attr]
                        if r.condition.food == food]
                if held:
                    d = describe(held)
                    f[f"exp2b_{food}_held"] = (f"{d.mean:.2f} ± {d.sd:.2f} g" if d.n > 1
                                               else f"{d.mean:.2f} g")
        return f


EXPERIMENT = Exp2bExperiment()
