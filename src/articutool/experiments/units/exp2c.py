"""Exp. 2c (thesis §5.2.3, H2): the capacity load placed over the bowl (the thesis' "fixed
Resting configuration (over the bowl)", :func:`~articutool.meal.bites.shed_configuration`), the
shedding primitive there (or not: control), then carried to Staging by the Articutool; the
outcome classes at a meaningful-success threshold per food."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, ClassVar, Literal, get_args

from pydantic import Field, model_validator

from articutool.datafile import StrictModel
from articutool.experiments.analysis import (
    by_place,
    class_counts,
    classify,
    compare_counts,
    measured,
    ok_records,
    rate,
    where,
)
from articutool.experiments.config import ExperimentsConfig, Names
from articutool.experiments.figures import outcome_bars
from articutool.experiments.markdown import mean_sd, p_value, places, table
from articutool.experiments.protocols import masses, rounded, transport, transport_outcome
from articutool.experiments.records import ConditionBase, OutcomeBase, TrialRecord
from articutool.experiments.stats import describe, fisher
from articutool.experiments.unit import (
    MAX_LOAD_G,
    Experiment,
    Hook,
    Visitors,
    add_foods_argument,
    foods_asked,
    parse_food_grams,
    usage,
)
from articutool.experiments.verdicts import Verdict, judge
from articutool.sim import accounting as acc

if TYPE_CHECKING:
    from articutool.sim.world import SettleCache

__all__ = [
    "EXP2C_CLASSES",
    "EXP2C_CONDITIONS",
    "EXPERIMENT",
    "Exp2cArm",
    "Exp2cCondition",
    "Exp2cConfig",
    "Exp2cOutcome",
    "classify_exp2c",
    "closed_loop_params",
    "closed_loop_target_g",
    "exp2c_trial",
    "summarize_exp2c",
]

# Exp. 2c's conditions: no primitive, the strategy's open-loop primitive, the closed-loop
# (F/T) one.
Exp2cArm = Literal["control", "primitive", "closed_loop"]
EXP2C_CONDITIONS: tuple[Exp2cArm, ...] = get_args(Exp2cArm)
EXP2C_CLASSES = ("meaningful_success", "trivial_success", "transport_failure", "failed")


class ShedPrimitive(StrictModel):
    """A shedding primitive and its parameters (checked against the tool's registry)."""

    primitive: Annotated[str, Field(min_length=1)]
    params: list[float]

    @model_validator(mode="after")
    def _known(self) -> ShedPrimitive:
        import numpy as np

        from articutool.spec import load_spec
        from articutool.tool.primitives import make_primitive

        make_primitive(self.primitive, self.params, load_spec(), np.zeros(2))  # names the field
        return self


class Exp2cConfig(StrictModel):
    """Exp. 2c (§5.2.3): the strategy whose post-acquisition primitive is the open-loop test,
    and the closed-loop (F/T) primitive of the third condition (thesis §7.1.2)."""

    foods: Names
    strategy: dict[str, str]
    closed_loop: dict[str, ShedPrimitive]



class Exp2cCondition(ConditionBase):
    """Exp. 2c: ``load_g`` of ``food`` over the bowl, then ``condition``; ``target_g``: the
    closed-loop primitive's load target; ``strategies``: another action-library file (the
    shedding sweep's candidates)."""

    condition: Exp2cArm
    load_g: float
    target_g: float | None = None
    strategies: str | None = None

    def group(self) -> tuple[str, ...]:
        """The food and the condition."""
        return (self.food, self.condition)


class Exp2cOutcome(OutcomeBase):
    """A load shed over the bowl (or not), then carried to Staging (:func:`exp2c_trial`);
    the primitive's parameters, success and message when one ran."""

    load_g: float
    held_g: float
    primitive: str | None
    primitive_params: list[float] | None = None
    primitive_ok: bool | None = None
    primitive_message: str | None = None
    primitive_moved_g: dict[str, float]
    after_primitive_g: float
    shed_g: float
    completed: bool
    planning_attempts: int
    planning_wall_s: float
    planning_wait_sim_s: float
    motion_time_s: float
    failed_stage: str
    max_tilt_deg: float | None
    spilled_by_place: dict[str, float]
    spilled_g: float
    delivered_g: float
    airborne_g: float
    weighed_g: float
    masses_after_g: dict[str, float]
    realtime_factor: float


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
    from articutool.sim.arm_driver import sim_arm
    from articutool.sim.world import FeedingWorld
    from articutool.spec import load_spec
    from articutool.tool.api import Mode

    food, arm_cond, load = cond.food, cond.condition, float(cond.load_g)
    spec = load_spec()
    strat = StrategyLibrary.load(spec, cond.strategies).strategies[cfg.exp2c.strategy[food]]
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
    shed_g = rounded(max(0.0, before["container"] - loaded["container"]))
    by_primitive = {"container": shed_g, **{k: rounded(v) for k, v in spills_primitive.items()}}
    out = transport_outcome(w, start, n_before, before)
    for place, g in spills_primitive.items():  # a primitive's spill is a spill of the trial
        out["spilled_by_place"][place] = rounded(out["spilled_by_place"][place] + g)
    out["spilled_g"] = rounded(sum(out["spilled_by_place"].values()))
    return Exp2cOutcome.model_validate({
        "load_g": load, "held_g": rounded(held), **prim, "primitive_moved_g": by_primitive,
        "after_primitive_g": rounded(before["utensil"]), "shed_g": shed_g, **tr, **out,
        "weighed_g": rounded(w.weighing.carried_g()), "masses_after_g": masses(w),
        "realtime_factor": rounded(w.realtime_factor)})


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



def classify_exp2c(rec: TrialRecord, threshold_g: float) -> str:
    """Exp. 2c's class (§5.2.3): a table or user spill is a transport failure."""
    c = classify(rec, threshold_g)
    return "transport_failure" if c in ("table_spill", "user_spill") else c


def summarize_exp2c(records: Sequence[TrialRecord], cfg: Any,
                    thresholds_g: Mapping[str, float] | None) -> dict[str, Any]:
    """Outcome classes per food and condition at ``thresholds_g`` (per food); Fisher's exact
    test of meaningful success, each primitive condition against control and closed loop
    against open loop (``fisher_meaningful``, ``…_closed_loop``, ``…_closed_vs_open``).
    Without thresholds only the spill/no-spill split is given."""
    ok = ok_records(records)
    out: dict[str, Any] = {"thresholds_g": dict(thresholds_g) if thresholds_g else None,
                           "foods": {}}
    for f in cfg.exp2c.foods:
        entry: dict[str, Any] = {}
        for c in EXP2C_CONDITIONS:
            rs = where(ok, _in(f, c))
            outs = [measured(r) for r in rs]
            e: dict[str, Any] = {
                "spill": rate(sum(1 for o in outs if o.spilled_g > 1e-9), len(rs)),
                "delivered_g": describe([o.delivered_g for o in outs]).to_dict(),
                "held_g": describe([o.held_g for o in outs]).to_dict(),
                "shed_g": describe([o.shed_g for o in outs]).to_dict(),
                "spilled_by_place": by_place(rs)}
            if thresholds_g and f in thresholds_g:
                e.update(class_counts([classify_exp2c(r, thresholds_g[f]) for r in rs],
                                 EXP2C_CLASSES))
            entry[c] = e
        # Each primitive condition against control, and closed loop against open loop.
        for suffix, (a, b) in {"": ("primitive", "control"),
                               "_closed_loop": ("closed_loop", "control"),
                               "_closed_vs_open": ("closed_loop", "primitive")}.items():
            ta, tb = entry[a], entry[b]
            if thresholds_g and f in thresholds_g:
                counts = (ta["counts"]["meaningful_success"], ta["n"],
                          tb["counts"]["meaningful_success"], tb["n"])
                entry["fisher_meaningful" + suffix] = fisher(*counts).to_dict()
                entry["compare_meaningful" + suffix] = compare_counts(*counts)
            a_rs, b_rs = (where(ok, _in(f, k)) for k in (a, b))
            entry["fisher_no_spill" + suffix] = fisher(
                sum(1 for r in a_rs if measured(r).spilled_g <= 1e-9), len(a_rs),
                sum(1 for r in b_rs if measured(r).spilled_g <= 1e-9), len(b_rs)).to_dict()
        out["foods"][f] = entry
    return out


def _in(food: str, condition: str) -> Callable[[ConditionBase], bool]:
    """Whether a condition is Exp. 2c's ``condition`` with ``food``."""
    return lambda c: c.food == food and c.condition == condition



def section_exp2c(s: Mapping[str, Any], cfg: Any) -> str:
    """Loads, thresholds, outcome classes and tests beside the thesis'."""
    th = cfg.thesis["exp2c"]
    ths = s.get("thresholds_g")
    out = (f"Loads: {', '.join(f'{f} {g:.2f} g' for f, g in s.get('load_g', {}).items())} "
           f"({s.get('load_source', '?')}); thesis: "
           + " / ".join(f"{g:g} g" for g in th["capacity_g"].values()) + ". Thresholds: "
           + (", ".join(f"{f} {g:.2f} g" for f, g in ths.items()) if ths else "none")
           + f" ({s.get('thresholds_source', '?')}); thesis: "
           + " / ".join(f"> {cfg.thesis['exp1'][f]['articutool'][0]:g} g"
                        for f in cfg.exp2c.foods)
           + " (its Exp. 1 means)."
           + (" Closed-loop load targets, from the thresholds (threshold + one item + 3 σ of one "
              "weighing): " + ", ".join(f"{f} {g:.2f} g" for f, g in
                                        s["closed_loop_target_g"].items()) + "."
              if s.get("closed_loop_target_g") else "") + "\n\n")
    rows = []
    for f in cfg.exp2c.foods:
        e = s["foods"][f]
        for c in EXP2C_CONDITIONS:
            if c not in e:  # a summary written before the closed-loop condition
                continue
            d = e[c]
            t = th.get(f"{f}_{c}", {})
            pct = d.get("percent", {})
            cls = [f"{d['counts'][k]} ({pct[k]:.0f} %)" if "counts" in d and d["n"] else "–"
                   for k in EXP2C_CLASSES]
            rows.append([f, c, d["spill"]["n"], mean_sd(d["held_g"]), mean_sd(d["shed_g"]),
                         mean_sd(d["delivered_g"]), *cls,
                         ", ".join(f"{k.replace('_', ' ')} {v:g} %" for k, v in t.items()),
                         "" if c == "control" else
                         p_value(e.get("fisher_meaningful" + ("" if c == "primitive" else
                                                         "_closed_loop"), {}).get("p"))])
    out += table(["food", "condition", "n", "held (g)", "shed into container (g)",
                   "delivered (g)", "meaningful", "trivial", "transport failure",
                   "tree failed", "thesis", "Fisher p (meaningful, vs control)"], rows)
    rows = [[f, c, places(s["foods"][f][c].get("spilled_by_place"))]
            for f in cfg.exp2c.foods for c in EXP2C_CONDITIONS if c in s["foods"][f]]
    out += ("\n\nWhere the spilled food went (g over all trials, trials with any):\n\n"
            + table(["food", "condition", "by place"], rows))
    out += ("\n\nSpill frequency alone (Fisher, no-spill trials, primitive vs control): "
            + ", ".join(f"{f} p = {p_value(s['foods'][f]['fisher_no_spill'].get('p'))}"
                        for f in cfg.exp2c.foods) + ".")
    closed = [f for f in cfg.exp2c.foods if "fisher_no_spill_closed_vs_open" in s["foods"][f]]
    if closed:
        cvo = {f: s["foods"][f].get("fisher_meaningful_closed_vs_open", {}) for f in closed}
        out += (" Closed loop vs open loop (meaningful success): "
                + ", ".join(f"{f} p = {p_value(cvo[f].get('p'))}" for f in closed) + ".")
    return out



def _thresholds(args: argparse.Namespace, out: Path, cfg: Any) -> tuple[dict[str, float] | None,
                                                                         str]:
    """Exp. 2c's thresholds: ``--thresholds-g``, else OUR Exp. 1 Articutool means (the thesis
    took its own Exp. 1 means), else none (only spill / no spill is reported)."""
    from articutool.thresholds import exp1_means

    if getattr(args, "thresholds_g", None):
        th = parse_food_grams(args.thresholds_g, "--thresholds-g", MAX_LOAD_G)
        other = sorted(set(th) - set(cfg.exp2c.foods))
        if other or not th:
            raise usage(f"--thresholds-g must give grams for foods of Exp. 2c "
                         f"({', '.join(cfg.exp2c.foods)}); got {args.thresholds_g!r}")
        return th, "--thresholds-g"
    means = exp1_means(out)
    th = {f: means[f] for f in cfg.exp2c.foods if f in means}
    if th:
        return th, f"our Exp. 1 Articutool means ({out / 'exp1' / 'summary.json'})"
    return None, "none: run exp1 first or pass --thresholds-g"


def _run_foods(args: argparse.Namespace, cfg: Any) -> list[str]:
    """The foods of Exp. 2c this run runs: those ``--foods`` names (all without it; a name
    that is not Exp. 2c's is the command's to refuse)."""
    wanted = foods_asked(args) or []
    return [f for f in cfg.exp2c.foods if f in wanted] or list(cfg.exp2c.foods)


def _exp2c_loads(args: argparse.Namespace, out: Path, cfg: Any) -> tuple[dict[str, float], str]:
    from articutool.thresholds import capacity_means

    if args.load_g:
        loads = parse_food_grams(args.load_g, "--load-g", MAX_LOAD_G)
        src = "--load-g"
    else:
        loads = capacity_means(out)
        p = out / "capacity" / "summary.json"
        if loads is None:
            raise usage(f"exp2c needs the capacity load: run `articutool experiment capacity "
                         f"--out {out}` first, or pass --load-g pecans=G,water=G")
        src = f"our capacity means ({p})"
    missing = [f for f in _run_foods(args, cfg) if f not in loads or loads[f] <= 0]
    if missing:
        raise usage(f"--load-g: no load > 0 g for {missing}")
    unknown = sorted(set(loads) - set(cfg.exp2c.foods))
    if unknown:
        raise usage(f"--load-g: unknown foods {unknown}; Exp. 2c's foods: "
                     f"{', '.join(cfg.exp2c.foods)}")
    _check_loads(loads, cfg, "--load-g" if args.load_g else f"the capacity summary {src}")
    return loads, src


def _check_loads(loads: dict[str, float], cfg: Any, field: str) -> None:
    """Every load within what its food's Exp. 2c utensil can hold (exit 2 naming the range)."""
    from articutool.feeding.strategies import StrategyLibrary
    from articutool.sim.params import PhysicsParams
    from articutool.sim.placement import capacity_bound_reason, utensil_capacity_bound_g
    from articutool.spec import load_spec

    spec, params = load_spec(), PhysicsParams.load()
    lib = StrategyLibrary.load(spec)
    for food, g in loads.items():
        utensil = lib.strategies[cfg.exp2c.strategy[food]].utensil
        most = utensil_capacity_bound_g(spec, params, food, utensil)
        if not g <= most:
            raise usage(f"{field}: {food} must be in (0, {most:.2f}] g, the most the "
                         f"{utensil} can hold ({capacity_bound_reason(params.food(food))}); "
                         f"got {g:g}")


def _closed_loop_targets(thresholds: dict[str, float], cfg: Any) -> dict[str, float]:
    """Per food with a load-targeting closed-loop primitive, its target from the food's
    meaningful-success threshold (:func:`closed_loop_target_g`): one item's mass (the
    physics' food model) and the noise of one weighing (the F/T sensor's per-sample noise
    over the primitive's window)."""
    from articutool.sim.params import Liquid, PhysicsParams
    from articutool.spec import load_spec
    from articutool.tool.primitives import get_primitive

    spec, params = load_spec(), PhysicsParams.load()
    out = {}
    for food, shed in cfg.exp2c.closed_loop.items():
        names = get_primitive(shed.primitive).parameter_names
        if "target_load_g" not in names or food not in thresholds:
            continue
        window = shed.params[names.index("window_s")] if "window_s" in names else 0.0
        n = max(1, round(window * spec.ft.rate_hz))
        noise_g = spec.ft.force_noise_n / spec.imu.gravity * 1000.0 / math.sqrt(n)
        fp = params.food(food)
        # One item of a placed load: a load particle of a liquid, a piece otherwise.
        item = fp.load_item_mass if isinstance(fp, Liquid) else fp.piece_mass
        out[food] = round(closed_loop_target_g(thresholds[food], item * 1000.0, noise_g), 3)
    return out



_EXP2C = {"primitive": ("", "the open-loop primitive"),
          "closed_loop": ("_closed_loop", "the closed-loop primitive")}


def claims_exp2c(s: Mapping[str, Any], th: Mapping[str, Any], alpha: float,
               tests: Mapping[str, Any]) -> list[Verdict]:
    """Our summary ``s`` against the thesis' ``th`` on each claim it tests, judged by the
    pre-registered ``tests`` at ``alpha`` (:func:`~articutool.experiments.verdicts.judge`)."""
    if not s.get("thresholds_g"):
        return []
    out = []
    for food, d in s["foods"].items():
        ctrl = d.get("control")
        if not ctrl:
            continue
        for cond, (suffix, name) in _EXP2C.items():
            c = d.get(cond)
            comp = d.get("compare_meaningful" + suffix)
            if not c or comp is None:
                continue
            ms_c = ctrl["percent"].get("meaningful_success", 0.0)
            ms_p = c["percent"].get("meaningful_success", 0.0)
            tc = th.get(f"{food}_control", {}).get("meaningful_success", 0.0)
            tp = th.get(f"{food}_primitive", {}).get("meaningful_success")
            thesis = (f"meaningful success {tp:g} % with the primitive vs {tc:g} % control"
                      if tp is not None else "not given")
            constant = ms_c == ms_p and ms_c in (0.0, 100.0)
            test, size, others, verdict = judge(
                comp, tests["exp2c"], (tp - tc) / 100 if tp is not None else None, +1,
                alpha, constant, "points")
            out.append(Verdict(
                "H2", "Fig. 6.4", f"{food}: {name} raises meaningful success over control",
                thesis + (" (open loop; the thesis had no closed loop)"
                          if cond == "closed_loop" else ""),
                f"{ms_p:.0f} % vs {ms_c:.0f} % (n {c['n']} / {ctrl['n']})", test, size,
                others, verdict))
    return out



class Exp2cExperiment(Experiment):
    """Exp. 2c."""

    name = "exp2c"
    help = "shedding primitives vs control, H2 (§5.2.3)"
    title = "Exp. 2c — shedding primitives (H2, §5.2.3; cf. Fig. 6.4)"
    hypothesis = "H2"
    thesis_figure = "Fig. 6.4"
    order = 30
    condition = Exp2cCondition
    config_model = Exp2cConfig
    places_load = True
    claims: ClassVar[dict[str, str]] = {"exp2c": "Exp. 2c meaningful success (H2)"}
    outcome = Exp2cOutcome
    noted_inputs = ("load_g", "load_source", "closed_loop_target_g")
    noted_settings = ("thresholds_source",)
    unjudged = "Exp. 2c needs outcome thresholds: Exp. 1's means or --thresholds-g"

    run_trial = staticmethod(exp2c_trial)
    verdicts = staticmethod(claims_exp2c)
    section = staticmethod(section_exp2c)

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        add_foods_argument(parser)
        parser.add_argument("--load-g", default=None, metavar="FOOD=G,…",
                            help="the load per food (default: our capacity means)")
        parser.add_argument("--thresholds-g", default=None, metavar="FOOD=G,…",
                            help="meaningful-success thresholds (default: our Exp. 1 "
                                 "Articutool means)")

    def add_report_arguments(self, parser: argparse.ArgumentParser) -> None:
        parser.add_argument("--thresholds-g", default=None, metavar="FOOD=G,…",
                            help="Exp. 2c thresholds (default: our Exp. 1 Articutool means)")

    def inputs(self, args: argparse.Namespace, out: Path, cfg: ExperimentsConfig
               ) -> tuple[dict[str, Any], dict[str, Any]]:
        """The load per food and the closed-loop targets (from the thresholds)."""
        foods = _run_foods(args, cfg)
        loads, src = _exp2c_loads(args, out, cfg)
        loads = {f: g for f, g in loads.items() if f in foods}
        th, _ = _thresholds(args, out, cfg)
        if th is None or any(f not in th for f in foods):
            raise usage("exp2c needs each food's meaningful-success threshold (its "
                        "closed-loop target is derived from it): run `articutool experiment "
                        f"exp1 --out {out}` first, or pass --thresholds-g "
                        + ",".join(f"{f}=G" for f in foods))
        targets = _closed_loop_targets({f: th[f] for f in foods}, cfg)
        return ({"load_g": loads, "target_g": targets},
                {"load_g": loads, "load_source": src, "closed_loop_target_g": targets})

    def analysis(self, args: argparse.Namespace, out: Path, cfg: ExperimentsConfig, *,
                 required: bool = True) -> dict[str, Any]:
        th, src = _thresholds(args, out, cfg)
        return {"thresholds_g": th, "thresholds_source": src}

    def conditions(self, cfg: ExperimentsConfig, *, load_g: Mapping[str, float] | None = None,
                   target_g: Mapping[str, float] | None = None, **inputs: Any) -> list[Any]:
        """Per food of ``load_g`` (the capacity), the three conditions at its load; the
        closed loop's load target ``target_g``, derived from the food's meaningful-success
        threshold (:func:`closed_loop_target_g`)."""
        if load_g is None:
            raise ValueError("exp2c needs the load per food (the capacity)")
        return [Exp2cCondition(food=f, condition=c, load_g=round(float(load_g[f]), 2),
                               target_g=round(float(target_g[f]), 3)
                               if c == "closed_loop" and target_g is not None
                               and f in target_g else None)
                for f in cfg.exp2c.foods if f in load_g for c in EXP2C_CONDITIONS]

    def summarize(self, records: Sequence[TrialRecord], cfg: ExperimentsConfig,
                  thresholds_g: Mapping[str, float] | None = None, **settings: Any
                  ) -> dict[str, Any]:
        return summarize_exp2c(records, cfg, thresholds_g)

    def differences(self, summary: Mapping[str, Any], cfg: ExperimentsConfig) -> list[str]:
        s, th, out = summary, cfg.thesis, []
        if not s.get("thresholds_g"):
            return out
        for f in cfg.exp2c.foods:
            for c in ("control", "primitive"):  # the thesis has no closed-loop condition
                d, t = s["foods"][f][c], th["exp2c"].get(f"{f}_{c}", {})
                for k, v in t.items():
                    ours = d.get("percent", {}).get(k)
                    if ours is not None:
                        out.append(f"{f} {c}: {k.replace('_', ' ')} {ours:.0f} % vs the "
                                   f"thesis' {v:g} % ({ours - v:+.0f} points)")
        return out

    def figure(self, records: Sequence[TrialRecord], summary: Mapping[str, Any],
               cfg: ExperimentsConfig, directory: Path) -> Path | None:
        if not summary.get("thresholds_g"):
            return None
        groups = {f"{f}\n{c}": summary["foods"][f][c]["counts"]
                  for f in cfg.exp2c.foods for c in EXP2C_CONDITIONS
                  if c in summary["foods"][f] and "counts" in summary["foods"][f][c]}
        return outcome_bars(groups, EXP2C_CLASSES, "Exp. 2c: shedding primitives vs control "
                            "(cf. thesis Fig. 6.4)", directory / "exp2c.png")

    def facts(self, summary: Mapping[str, Any] | None, records: Sequence[TrialRecord],
              cfg: ExperimentsConfig) -> dict[str, str]:
        """The loads, what was held, the thresholds, the primitives and what they shed."""
        f: dict[str, str] = {}
        c = summary
        if not c:
            return f
        if c.get("load_g"):
            f["exp2c_loads"] = ", ".join(f"{k} {g:.2f} g" for k, g in c["load_g"].items())
        f["exp2c_held"] = ", ".join(f"{k} {mean_sd(v['control']['held_g'])} g"
                                    for k, v in c["foods"].items() if "control" in v)
        if c.get("thresholds_g"):
            f["exp2c_thresholds"] = ", ".join(f"{k} {g:.2f} g"
                                              for k, g in c["thresholds_g"].items())
        for food, key in (("pecans", "vibrate"), ("water", "tilt")):
            prim = c["foods"].get(food, {}).get("primitive")
            if prim:
                f[f"exp2c_{key}_shed"] = f"{mean_sd(prim['shed_g'])} g"
        for r in records:
            o = r.outcome
            params = getattr(o, "primitive_params", None)
            if (o is None or r.condition.condition != "primitive"  # type: ignore[attr-defined]
                    or not params):
                continue
            key = {"pecans": "exp2c_vibrate", "water": "exp2c_tilt"}.get(r.condition.food)
            if key:
                f.setdefault(key, "(" + ", ".join(f"{x:g}" for x in params) + ")")
        return f


EXPERIMENT = Exp2cExperiment()
