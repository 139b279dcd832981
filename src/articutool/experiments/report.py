"""Our numbers beside the thesis': one Markdown section per experiment, the figures, and the
whole report (Markdown + HTML) — the shell that turns summaries into pages and files.

The report re-summarises every experiment from its trial log, so thresholds (Exp. 2c from our
Exp. 1, Exp. 3's likewise) are applied when the report is written; commands, machine, date and
wall times come from each experiment's ``summary.json``.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

from pydantic import BaseModel, ConfigDict, Field

from articutool.experiments.analysis import (
    EXP2C_CLASSES,
    completeness,
    meaningful_at,
    representative_trials,
    summarize,
)
from articutool.experiments.design import EXP2C_CONDITIONS
from articutool.experiments.figures import mass_bars, outcome_bars
from articutool.experiments.records import TrialRecord
from articutool.experiments.stats import FisherResult, fisher
from articutool.experiments.verdicts import TEST_NAMES, code_versions, thesis_trials, verdicts
from articutool.feeding.outcomes import OUTCOMES
from articutool.thresholds import Grams

if TYPE_CHECKING:
    from articutool.experiments.runner import TrialLog

__all__ = ["CROSS_CHECKS", "HONESTY", "LogCheck", "check_log", "cross_checks",
           "deviation_facts", "deviations_section", "differences", "figure",
           "hypotheses_section", "read_exp2a", "read_summary", "section",
           "thesis_exp3_no_spill", "write_report"]

ORDER = ("exp1", "exp2b", "capacity", "exp2c", "exp3")
TITLES = {
    "capacity": "Maximum capacity (Exp. 2c's load, §5.2.3)",
    "exp1": "Exp. 1 — acquisition (H1, §5.1; cf. Fig. 6.1)",
    "exp2b": "Exp. 2b — transport of placed loads (H2, §5.2.2; cf. Fig. 6.3)",
    "exp2c": "Exp. 2c — shedding primitives (H2, §5.2.3; cf. Fig. 6.4)",
    "exp3": "Exp. 3 — noodles end to end (H3, §5.3; cf. Fig. 6.5)",
}
HONESTY = """\
- **Trials differ only by seed.** Repeat *r* of every condition has seed 1000·S + r: the food's
  placement, the sensors' noise and gyro bias, and the planner's seed. The systems face the
  same seeds (common random numbers). Every trial's record holds its seed;
  `articutool experiment EXP --trial K` replays it alone.
- **Nothing is tuned to match the thesis.** Food models, utensils, primitives' parameters,
  planners, budgets and tolerances are the project's data files (`data/physics.toml`,
  `hardware.toml`, `strategies.toml`, `experiments.toml`, `scene.toml`) as they were; the
  thesis' numbers appear only beside ours. Where ours differ, the section says by how much
  and what physical reason we believe explains it.
- **The baseline gets the same care.** Its strategy is its best one in the action library
  (wrist locked, strict ±20° transport as in the thesis' physical trials), with the same
  planners (OMPL RRT-Connect), the same per-attempt budget and attempt limit, the same
  feeding-tree transport subtree, and the same world.
- **Outcomes come from physics and the tool's own code**: masses are the world's accounting
  of every piece or particle (on the utensil, shed into a container, on the table, on the
  user/wheelchair/floor, eaten at the mouth); the classes are
  `articutool.feeding.outcomes.classify_bite`. Only a shedding primitive over the bowl,
  before the transport, sheds; in transport anything that leaves the utensil is spilled
  wherever it lands, a container included (reported apart, by place; docs/accounting.md).
- **One meaning of spilled and eaten in every experiment** (`articutool.sim.accounting`):
  spilled grams count each piece or particle once, at the worst place it reached (before the
  transport once it stayed 0.1 s on the table or the user; a piece that lands on the table
  and rolls to the floor is one critical spill); eaten is each item once (pieces, particles,
  noodle strands); delivered is what is on the utensil plus what was eaten; noodle grams are
  what the fork bears, as a scale under it would read. Exp. 2b and 2c have no mouth: the
  experimenter weighs the utensil at the goal.
"""


def _f(x: Any, nd: int = 2) -> str:
    if x is None:
        return "–"
    if isinstance(x, float):
        return f"{x:.{nd}f}"
    return str(x)


def _p(x: Any) -> str:
    if x is None:
        return "n/a"
    return f"{x:.2g}" if x >= 1e-3 else f"{x:.1e}"


def _msd(d: Mapping[str, Any] | None, nd: int = 2) -> str:
    if not d or d.get("mean") is None:
        return "–"
    s = f"{d['mean']:.{nd}f}"
    if d.get("sd") is not None:
        s += f" ± {d['sd']:.{nd}f}"
    return s


def _ci(d: Mapping[str, Any] | None, nd: int = 2) -> str:
    if not d or d.get("ci_low") is None:
        return "–"
    return f"[{d['ci_low']:.{nd}f}, {d['ci_high']:.{nd}f}]"


def _table(head: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


# ---------------------------------------------------------------------- summaries --
class _Open(BaseModel):
    model_config = ConfigDict(extra="allow", frozen=True)


class _Run(_Open):
    machine: dict[str, Any] | None = None
    date: str | None = None
    command: str | None = None
    executor: str | None = None
    experiment_wall_time_s: Annotated[float, Field(strict=True, allow_inf_nan=False,
                                                   ge=0)] | None = None


class _SummaryFile(_Open):
    run: _Run = Field(default_factory=_Run)
    load_g: dict[str, Grams] | None = None
    load_source: str | None = None
    goals: list[str] | None = None


class _BenchRun(_Open):
    timeout_s: Annotated[float, Field(strict=True, allow_inf_nan=False, gt=0)]
    planner: str | None = None


def read_summary(path: Path) -> dict[str, Any] | None:
    """An experiment's ``summary.json`` as this package writes it (``None`` if absent), for
    what a rerun and the report take from it (the run's machine, date, command, loads,
    goals): a file that is not as written (garbage, another shape, NaN, a link, a FIFO, a
    folder) raises :class:`~articutool.datafile.ResultsError` naming it and the field."""
    from articutool.datafile import read_own_json

    s = read_own_json(path, "experiment summary", _SummaryFile)
    if s is None:
        return None
    out = s.model_dump(exclude_unset=True)
    out["run"] = s.run.model_dump(exclude_unset=True)
    return out


# ------------------------------------------------------------------- trial logs --
@dataclass(frozen=True)
class LogCheck:
    """An experiment's trial log checked against what its run promised: ``log`` as read
    (lines, records, bad lines), ``per_condition`` the trials per condition its last
    finished run was asked for (``summary.json``; ``None`` when no run finished or it was
    not recorded), and per condition the trials found and missing
    (:func:`~articutool.experiments.analysis.completeness`)."""

    experiment: str
    log: TrialLog
    per_condition: int | None
    conditions: Mapping[str, Mapping[str, Any]]

    @property
    def short(self) -> dict[str, Mapping[str, Any]]:
        """The conditions with fewer trials than promised."""
        n = self.per_condition
        return {k: v for k, v in self.conditions.items() if n is not None and v["found"] < n}

    def shortfalls(self) -> list[str]:
        """One sentence per condition short of its promised trials (empty when none)."""
        out = []
        for cond, v in self.short.items():
            missing = v["missing"]
            named = (f" (missing trial(s) {', '.join(map(str, missing[:10]))}"
                     + (f" and {len(missing) - 10} more" if len(missing) > 10 else "") + ")"
                     ) if missing else ""
            out.append(f"{self.log.state.path}: condition {cond} has {v['found']} of the "
                       f"{self.per_condition} trials its run promised{named}")
        return out


def check_log(out: Path, experiment: str, log: TrialLog,
              summary: Mapping[str, Any] | None) -> LogCheck:
    """``log`` checked against its run: the trials per condition its last finished run asked
    for (``summary``'s ``run.trials_per_condition``), over the conditions ``run.json``
    pinned, in its order, so a missing trial is named by index (without ``run.json``: the
    conditions the records hold). A ``run.json`` not as a run writes it raises
    :class:`~articutool.datafile.ResultsError` naming it."""
    from pydantic import ValidationError

    from articutool.datafile import ResultsError, format_validation_error, read_own_json
    from articutool.experiments.records import CONDITIONS

    n = (summary or {}).get("run", {}).get("trials_per_condition")
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        return LogCheck(experiment, log, None, {})
    path = out / experiment / "run.json"
    pinned = read_own_json(path, "the run's settings")
    conds = None
    if pinned is not None:
        try:
            conds = [CONDITIONS[experiment].model_validate(c) for c in pinned["conditions"]]
        except ValidationError as err:
            raise ResultsError(format_validation_error(
                err, f"the run's settings {path}: conditions:")) from None
        except (KeyError, TypeError):
            raise ResultsError(f"the run's settings {path} hold no list of conditions; it is "
                               "not as a run writes it") from None
    found = completeness(log.records, n, conds)
    if conds is None:  # the conditions the last run summarised, also when no record is left
        for cond in (summary or {}).get("per_condition_n") or {}:
            found.setdefault(str(cond), {"found": 0, "missing": []})
    return LogCheck(experiment, log, n, found)


def _logs_section(checks: Sequence[LogCheck]) -> str:
    """The page's account of every trial log read: lines, records, bad lines, and the
    trials per condition promised and found."""
    rows = []
    for c in checks:
        st = c.log.state
        if not st.lines and st.path is not None and not st.path.exists():
            continue
        found = (", ".join(f"{k} {v['found']}" for k, v in c.conditions.items())
                 if c.conditions else "–")
        status = ("**short: " + "; ".join(f"{k} {v['found']} of {c.per_condition}"
                                          for k, v in c.short.items()) + "**" if c.short
                  else "no finished run" if c.per_condition is None else "complete")
        rows.append([c.experiment, st.lines, len(st.records),
                     "; ".join(st.problems()).replace("|", "\\|") or "none",
                     c.per_condition or "–", found, status])
    if not rows:
        return ""
    return ("## Trial logs\n\nWhat each `<exp>/trials.jsonl` held when this page was written: "
            "lines read, records accepted, every bad line by number and why (a line that is "
            "not a JSON record, holds NaN or an infinity, or is torn is not read), and the "
            "trials per condition its last finished run asked for beside those found. A "
            "condition short of its trials makes `articutool experiment report` exit 2.\n\n"
            + _table(["experiment", "lines read", "records accepted", "bad lines",
                      "trials per condition (promised)", "found per condition", "status"],
                     rows) + "\n")


# ------------------------------------------------------------------------ figures --
def figure(exp: str, records: Sequence[TrialRecord], summary: Mapping[str, Any], cfg: Any,
           directory: Path) -> Path | None:
    """Write the experiment's figure into ``directory``; None if there is nothing to draw."""
    ok = [r for r in records if not r.error]
    if not ok:
        return None
    if exp == "exp2b":
        return mass_bars(ok, summary["spilled_g"], cfg.exp2b.foods, cfg.exp2b.systems,
                         lambda o: o.spilled_g, "spilled during transport (g), mean ± 95% CI",
                         "Exp. 2b: spill carrying placed loads to five Staging goals "
                         "(cf. thesis Fig. 6.3)", directory / "exp2b.png")
    if exp == "exp1":
        return mass_bars(ok, summary["acquired_g"], cfg.exp1.foods, cfg.exp1.systems,
                         lambda o: o.mass_g, "mass on the utensil at Resting (g), mean ± 95% CI",
                         "Exp. 1: acquisition (cf. thesis Fig. 6.1)", directory / "exp1.png")
    if exp == "exp2c" and summary.get("thresholds_g"):
        groups = {f"{f}\n{c}": summary["foods"][f][c]["counts"]
                  for f in cfg.exp2c.foods for c in EXP2C_CONDITIONS
                  if c in summary["foods"][f] and "counts" in summary["foods"][f][c]}
        return outcome_bars(groups, EXP2C_CLASSES, "Exp. 2c: shedding primitives vs control "
                            "(cf. thesis Fig. 6.4)", directory / "exp2c.png")
    if exp == "exp3":
        groups = {s: v["counts"] for s, v in summary["systems"].items()}
        return outcome_bars(groups, OUTCOMES, f"Exp. 3: noodles end to end, threshold "
                            f"{summary['threshold_g']:g} g (cf. thesis Fig. 6.5)",
                            directory / "exp3.png")
    return None


# ----------------------------------------------------------------------- sections --
def _run_line(s: Mapping[str, Any]) -> str:
    r = s.get("run", {})
    w = r.get("wall_time_per_trial_s") or {}
    resets = r.get("physics_resets", 0)
    parts = [f"{r.get('trials', 0)} trials ({r.get('trials_per_condition', '?')} per "
             f"condition; {r.get('errors', 0)} errors"
             + (f", of them {resets} runs that MuJoCo reset after a numerical instability, "
                "not counted" if resets else "") + ")"]
    if w.get("mean") is not None:
        parts.append(f"wall time per trial {w['mean']:.1f} ± {_f(w.get('sd'), 1)} s, "
                     f"sum {r.get('wall_time_total_s')} s")
    if r.get("sources"):
        parts.append("code: " + ", ".join(f"{k} ({n} trials)" for k, n in r["sources"].items()))
    if r.get("experiment_wall_time_s") is not None:
        parts.append(f"last invocation {r['experiment_wall_time_s']} s on "
                     f"{r.get('executor', '?')}")
    ml = r.get("machine_load")
    if ml:
        parts.append("machine load (1/5/15-min averages) " + "/".join(
            f"{x:g}" for x in ml["before"]) + " at the start, " + "/".join(
            f"{x:g}" for x in ml["after"]) + " at the end")
    return "; ".join(parts)


def _sec_capacity(s: Mapping[str, Any], cfg: Any) -> str:
    th = cfg.thesis["exp2c"]["capacity_g"]
    rows = []
    for f, v in s["foods"].items():
        c = v["capacity_g"]
        diff = (f"{c['mean'] - th[f]:+.1f} g ({100 * (c['mean'] / th[f] - 1):+.0f} %)"
                if c.get("mean") is not None and f in th else "–")
        done = v.get("completed", {})
        rows.append([f, v["utensil"], f"{done.get('k', '?')}/{done.get('n', '?')}",
                     _msd(v.get("scoop_g")), _ci(v.get("scoop_g")), _msd(v.get("brim_g")),
                     f"**{_f(c.get('mean'))}**", v.get("capacity_source", "–"),
                     f"{th.get(f, '–')}", diff])
    return (_table(["food", "utensil", "scoops completed", "maximal scoop (g), mean ± SD",
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


def _sec_static_tilt(d: Mapping[str, Any]) -> str:
    """The liquid's static-tilt test beside hydrostatics (``sim-calibrate --food water
    --json``'s ``static_tilt``)."""
    st = d.get("static_tilt", d)
    out = (f"Load {st.get('load_g', '?')} g on the {st.get('utensil', '?')}, the wrist "
           f"turned at {st.get('rate_rad_s', '?')} rad/s to each tilt and held "
           f"{st.get('hold_s', '?')} s; grams that left the spoon in the particle world beside "
           "what an ideal liquid of the load's volume spills at the tilt the spoon really has "
           "(`articutool.food.hydrostatics`).\n\n")
    for direction in ("tip", "side"):
        v = st.get(direction)
        if not v:
            continue
        rows = [[f"{r['tilt_deg']:.1f}", f"{r['spilled_g']:.2f}", f"{r['hydrostatic_g']:.2f}"]
                for r in v.get("rows", [])]
        out += (f"**{'Over the tip' if direction == 'tip' else 'Sideways'}** (load kept "
                f"{_f(v.get('kept_g'))} g): spill onset {_f(v.get('onset_deg'), 1)}° in the "
                f"world, {_f(v.get('hydrostatic_onset_deg'), 1)}° by hydrostatics.\n\n"
                + _table(["tilt (°)", "spilled, particles (g)", "spilled, hydrostatics (g)"],
                         rows) + "\n\n")
    return out


def _sec_slosh(d: Mapping[str, Any]) -> str:
    """The slosh model's predicted spill beside the particle world's, per trial, on the
    Exp. 2b paths (``studies/transport_spill.py``'s JSON)."""
    rows = []
    trials = d.get("trials", [])
    for t in trials:
        rows.append([t.get("goal", "–"), t.get("condition", t.get("wrist_used", "–")),
                     _f(t.get("scale")), t.get("seed", "–"), _f(t.get("max_tilt_deg"), 1),
                     _f(t.get("predicted_spill_g")), _f(t.get("lost_g"))])
    head = (f"{d.get('water', '')}\n\nLoad {d.get('load_g', '?')} g; command: "
            f"`{d.get('command', '?')}`. Simulated is what left the spoon during the "
            "transport (the study's `lost_g`), not what ran off while the load was placed.\n\n")
    tail = ""
    cut = (d.get("summary", {}).get("prediction") or {}).get("spill_threshold_g")
    both = [t for t in trials if t.get("predicted_spill_g") is not None
            and t.get("lost_g") is not None]
    if cut is not None and both:
        agree = sum((t["predicted_spill_g"] > cut) == (t["lost_g"] > cut) for t in both)
        tail = (f"\nThe model and the particles agree on whether a transport spills (more "
                f"than {cut:g} g) in {agree} of {len(both)} transports "
                f"({100 * agree / len(both):.0f} %).\n")
    return head + _table(["goal", "wrist", "speed scale", "seed", "max tilt (°)",
                          "predicted by the slosh model (g)",
                          "simulated, spilled in transport (g)"], rows) + "\n" + tail


def _sec_strands(d: Mapping[str, Any]) -> str:
    """The noodle strand's mechanisms, each alone beside its law (``sim-calibrate --food
    noodles --json``): the capstan hold on a bar and on a tine, frictionless controls,
    bending against the elastica, tack against the cited stickiness, and the strand."""
    def verdict(v: Mapping[str, Any]) -> str:
        return {True: "pass", False: "**fail**"}.get(v.get("pass"), "reported")

    rows = []
    for key, what in (("capstan_bar", "capstan, fork-wide bar"),
                      ("capstan_bar_frictionless", "capstan, frictionless bar"),
                      ("capstan_tine", "capstan, one tine"),
                      ("capstan_tine_frictionless", "capstan, frictionless tine")):
        v = d.get(key)
        if v:
            rows.append([what, f"{_f(v.get('bar_radius_mm'), 2)} mm",
                         f"hold ratio {_f(v.get('hold_ratio'))}",
                         f"e^(μπ) = {_f(v.get('law_e_mu_pi'))}", verdict(v)])
    for o in d.get("cantilever", {}).get("overhangs", []):
        rows.append(["bending, cantilever", f"{_f(o.get('overhang_mm'), 1)} mm overhang",
                     f"tip falls {_f(o.get('tip_fall_mm'))} mm",
                     f"elastica {_f(o.get('law_elastica_mm'))} mm",
                     verdict(d.get("cantilever", {}))])
    for t in d.get("tack", {}).get("tests", []):
        rows.append([f"tack, on the {t.get('on', '?')}", f"{t.get('contacts_at_rest', '?')} "
                     "contacts", f"pull-off {_f(t.get('pull_off_N_per_m'))} N/m",
                     f"{_f(t.get('law_N_per_m'))} N/m (cited "
                     f"{'–'.join(_f(x) for x in t.get('law_range_N_per_m', []))})", verdict(t)])
    st = d.get("strand", {})
    if st:
        rows.append(["strand", f"{st.get('segments', '?')} segments of "
                     f"{_f(st.get('segment_mm'))} mm", f"{_f(st.get('mass_g'))} g, "
                     f"{_f(st.get('diameter_mm'), 1)} mm",
                     f"cooked: {_f(st.get('cited_mass_g'))} g, "
                     f"{'–'.join(_f(x, 1) for x in st.get('cited_diameter_mm', []))} mm",
                     verdict(st)])
    bend = _f(d.get("capstan_tine", {}).get("bending_over_tension"), 1)
    head = ("Each mechanism of the noodle strand alone, beside the law it should follow "
            "(tolerances: capstan on the bar within 20 % of e^(μπ), a frictionless bar "
            f"≤ 1.1; on a tine bending is {bend}× the tension, so no rope law applies and "
            f"it is reported). All pass: **{d.get('all_pass', '?')}**.\n\n")
    return head + _table(["mechanism", "set-up", "simulated", "law", "verdict"], rows) + "\n"


# The cross-checks the report shows when their JSON files are in the results directory.
CROSS_CHECKS = {
    "static_tilt_water.json": (
        "Static-tilt test of the water", _sec_static_tilt,
        "articutool sim-calibrate --food water --json > {out}/static_tilt_water.json"),
    "slosh_crosscheck.json": (
        "Slosh model vs particle world on the Exp. 2b paths", _sec_slosh,
        "python studies/transport_spill.py --out {out}/slosh_crosscheck.json"),
    "strand_laws_noodles.json": (
        "Noodle mechanisms against their laws (capstan, bending, tack)", _sec_strands,
        "articutool sim-calibrate --food noodles --json > {out}/strand_laws_noodles.json"),
}


def cross_checks(out: Path) -> str:
    """The static-tilt table, the slosh cross-check and the noodle mechanisms' table, read
    from their JSON files in ``out``; a clear "not yet measured" for a missing one."""
    from articutool.datafile import ResultsError, read_own_json

    md = ""
    for name, (title, render, cmd) in CROSS_CHECKS.items():
        md += f"## {title}\n\n"
        try:
            d = read_own_json(out / name, name)
            if d is None:
                md += (f"Not yet measured: `{name}` is not in this results directory. Make "
                       f"it with `{cmd.format(out=out)}`.\n\n")
                continue
            md += render(d) + (f"\n*Source:* `{name}`, measured by "
                               f"`{cmd.format(out=out)}`.\n\n")
        except (ResultsError, KeyError, TypeError, ValueError) as err:
            md += f"`{name}` could not be read ({type(err).__name__}: {err}).\n\n"
    return md


def _mass_rows(block: Mapping[str, Any], foods: Sequence[str], systems: Sequence[str],
               thesis: Mapping[str, Any], cell: Any) -> list[list[Any]]:
    """Rows food | system | n | mean ± SD | 95 % CI | thesis cell | Welch p | thesis p (the
    p-values on each food's first row)."""
    rows = []
    for f in foods:
        e = block[f]
        for sys_ in systems:
            d, first = e[sys_], sys_ == systems[0]
            rows.append([f, sys_, d["n"], _msd(d), _ci(d), *cell(f, sys_, d),
                         _p(e.get("welch", {}).get("p")) if first else "",
                         thesis.get(f, {}).get("p", "–") if first else ""])
    return rows


def _sec_exp2b(s: Mapping[str, Any], cfg: Any) -> str:
    th = cfg.thesis["exp2b"]

    def cell(f: str, sys_: str, d: Mapping[str, Any]) -> list[str]:
        t = th.get(f, {})
        return [f"{d['nonzero']['k']}/{d['nonzero']['n']}",
                _f(t.get(sys_)) if sys_ in t else "not in text"]

    rows = _mass_rows(s["spilled_g"], cfg.exp2b.foods, cfg.exp2b.systems, th, cell)
    out = _table(["food", "system", "n", "spilled (g), mean ± SD", "95 % CI",
                  "trials with spill", "thesis mean (g)", "Welch p (ours)", "p (thesis)"],
                 rows)
    rows = []
    for f in cfg.exp2b.foods:
        for sys_ in cfg.exp2b.systems:
            t = s["transport"][f][sys_]
            rows.append([f, sys_, _msd(t["held_g"]), f"{t['completed']['k']}/{t['completed']['n']}",
                         _msd(t["planning_attempts"]), _msd(t["max_tilt_deg"], 1),
                         _p(s["spill_frequency_fisher"].get(f, {}).get("p"))
                         if sys_ == cfg.exp2b.systems[0] else ""])
    out += "\n\n" + _table(["food", "system", "load held after placing (g)", "completed",
                            "planning attempts", "max utensil tilt (°)",
                            "Fisher p, spill frequency"], rows)
    if s.get("spilled_by_place"):
        rows = [[f, sys_, _places(s["spilled_by_place"][f][sys_])]
                for f in cfg.exp2b.foods for sys_ in cfg.exp2b.systems]
        out += ("\n\nWhere the spilled food went (g over all trials, trials with any): in "
                "transport anything that left the spoon is spilled, a container apart:\n\n"
                + _table(["food", "system", "by place"], rows))
    rows = []
    for f in cfg.exp2b.foods:
        for sys_ in cfg.exp2b.systems:
            pg = s["per_goal"][f][sys_]
            rows.append([f, sys_] + [f"{_msd(v)} (n={v['n']})" for v in pg.values()])
    goals = list(next(iter(s["per_goal"][cfg.exp2b.foods[0]].values())).keys()) if rows else []
    out += "\n\nSpilled per goal (g):\n\n" + _table(["food", "system", *goals], rows)
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
                         _msd(e["spilled_g"]), _p((e.get("fisher_vs_base") or {}).get("p")),
                         f"{_msd(e['motion_time_s'], 1)} vs {_msd(e['base_motion_time_s'], 1)}",
                         f"{e['retimed']}/{e['checks']}", f"{e['slosh_free']}/{e['checks']}",
                         f"{e.get('checks_of_carried_wrist', '–')}/{e['checks']}",
                         _places(e["spilled_by_place"])])
    if not rows:
        return ""
    return ("\n\n**This stack's systems beside the thesis' two** (extra conditions on the same "
            "seeds and goals as the thesis system each extends; the thesis' comparison above "
            "is unchanged by them):\n\n"
            + _table(["food", "system", "trials with spill", "same, its thesis system",
                      "spilled (g), mean ± SD", "Fisher p vs its thesis system",
                      "motion time (s), it vs its thesis system", "checks retimed",
                      "checks slosh-free", "checks of the wrist carried", "spilled by place"],
                     rows)
            + "\n\nA check of the wrist carried predicts the transport the trial makes (the "
              "locked spoon for the baseline); a check of another wrist tests nothing about "
              "this transport.")


def _places(d: Mapping[str, Any] | None) -> str:
    """``{"table": {"g", "trials"}, …}`` as "table 0.42 g (1), container …" (none: "none")."""
    parts = [f"{p} {v['g']:.2f} g ({v['trials']})" for p, v in (d or {}).items() if v["g"] > 0]
    return ", ".join(parts) or "none"


def _sec_exp2c(s: Mapping[str, Any], cfg: Any) -> str:
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
            rows.append([f, c, d["spill"]["n"], _msd(d["held_g"]), _msd(d["shed_g"]),
                         _msd(d["delivered_g"]), *cls,
                         ", ".join(f"{k.replace('_', ' ')} {v:g} %" for k, v in t.items()),
                         "" if c == "control" else
                         _p(e.get("fisher_meaningful" + ("" if c == "primitive" else
                                                         "_closed_loop"), {}).get("p"))])
    out += _table(["food", "condition", "n", "held (g)", "shed into container (g)",
                   "delivered (g)", "meaningful", "trivial", "transport failure",
                   "tree failed", "thesis", "Fisher p (meaningful, vs control)"], rows)
    rows = [[f, c, _places(s["foods"][f][c].get("spilled_by_place"))]
            for f in cfg.exp2c.foods for c in EXP2C_CONDITIONS if c in s["foods"][f]]
    out += ("\n\nWhere the spilled food went (g over all trials, trials with any):\n\n"
            + _table(["food", "condition", "by place"], rows))
    out += ("\n\nSpill frequency alone (Fisher, no-spill trials, primitive vs control): "
            + ", ".join(f"{f} p = {_p(s['foods'][f]['fisher_no_spill'].get('p'))}"
                        for f in cfg.exp2c.foods) + ".")
    closed = [f for f in cfg.exp2c.foods if "fisher_no_spill_closed_vs_open" in s["foods"][f]]
    if closed:
        cvo = {f: s["foods"][f].get("fisher_meaningful_closed_vs_open", {}) for f in closed}
        out += (" Closed loop vs open loop (meaningful success): "
                + ", ".join(f"{f} p = {_p(cvo[f].get('p'))}" for f in closed) + ".")
    return out


def _sec_exp1(s: Mapping[str, Any], cfg: Any) -> str:
    th = cfg.thesis["exp1"]

    def cell(f: str, sys_: str, d: Mapping[str, Any]) -> list[str]:
        t = th.get(f, {}).get(sys_)
        return [f"{t[0]:.2f} ± {t[1]:.2f}" if t else "–"]

    rows = _mass_rows(s["acquired_g"], cfg.exp1.foods, cfg.exp1.systems, th, cell)
    return _table(["food", "system", "n", "acquired (g), mean ± SD", "95 % CI",
                   "thesis (g)", "Welch p (ours)", "p (thesis)"], rows)


def thesis_exp3_no_spill(thesis_exp3: Mapping[str, Any]) -> FisherResult | None:
    """Fisher's exact test (two-sided) of trials without spill (meaningful + trivial
    success), Articutool against the baseline, recomputed from the thesis' own Exp. 3 counts
    (§6.3, Fig. 6.5; ``[thesis.exp3]`` of experiments.toml). From 14/20 against 7/20 it gives
    p ≈ 0.056, where the thesis prints p < 0.00012. None if a count is missing."""
    counts = []
    for sys_ in ("articutool", "baseline"):
        t = thesis_exp3.get(sys_, {})
        if not all(isinstance(t.get(k), int) for k in OUTCOMES[:4]):
            return None
        counts += [t["meaningful_success"] + t["trivial_success"],
                   sum(t[k] for k in OUTCOMES[:4])]
    return fisher(*counts)


def _sec_exp3(s: Mapping[str, Any], cfg: Any) -> str:
    th = cfg.thesis["exp3"]
    rows = []
    for sys_, d in s["systems"].items():
        t = th.get(sys_, {})
        rows.append([sys_, d["n"], *(d["counts"][k] for k in OUTCOMES),
                     " / ".join(str(t.get(k, "–")) for k in OUTCOMES[:4]),
                     _msd(d["planning_attempts"]), _f(t.get("planning_attempts")),
                     _msd(d["delivered_g"])])
    out = _table(["system", "n", *(k.replace("_", " ") for k in OUTCOMES),
                  "thesis (meaningful / trivial / table / user, of 20)",
                  "planning attempts to Staging", "thesis attempts", "delivered (g)"], rows)
    at = s.get("at_thesis_threshold")
    if at:
        sy = list(at["meaningful_success"])
        out += (f"\n\nAt the thesis' {at['threshold_g']:.1f} g (taken from the bimodal "
                "distribution of its Exp. 3 baseline's bites, §5.3), our meaningful successes "
                "are " + " vs ".join(f"{at['meaningful_success'][x]}/{at['n'][x]}" for x in sy)
                + f" ({' vs '.join(sy)}; Fisher p {_p(at.get('fisher', {}).get('p'))}). Ours "
                "below is the rule the thesis used for Exp. 2c (our Exp. 1 Articutool mean).")
    ours = (f"\n\nThreshold {s['threshold_g']:g} g. Ours: Fisher p, meaningful success: "
            f"{_p(s.get('fisher_meaningful', {}).get('p'))}; no spill: "
            f"{_p(s.get('fisher_no_spill', {}).get('p'))}; Welch p, planning attempts: "
            f"{_p(s.get('welch_planning_attempts', {}).get('p'))}.")
    printed = th.get("p_no_spill", "not given")
    r = thesis_exp3_no_spill(th)
    if r is None:
        return out + ours + f" The thesis' no-spill p, as printed: {printed}."
    (a, a_no), (b, b_no) = r.table
    return (out + ours + f" The thesis' no-spill p, as printed: {printed}; recomputed here "
            f"from the thesis' own counts ({a}/{a + a_no} vs {b}/{b + b_no} trials without "
            f"spill, Fisher's exact test, two-sided): p = {_p(r.p)}.")


def differences(exp: str, s: Mapping[str, Any], cfg: Any) -> list[str]:
    """Where our numbers differ from the thesis', by how much (one line each)."""
    th = cfg.thesis
    out: list[str] = []
    if exp == "exp2b":
        for f, t in th["exp2b"].items():
            for sys_ in cfg.exp2b.systems:
                m = s["spilled_g"].get(f, {}).get(sys_, {}).get("mean")
                if m is not None and isinstance(t.get(sys_), float | int):
                    out.append(f"{f}, {sys_}: spilled {m:.2f} g vs the thesis' "
                               f"{t[sys_]:.2f} g ({m - t[sys_]:+.2f} g)")
            p = s["spilled_g"].get(f, {}).get("welch", {}).get("p")
            if "p" in t:
                out.append(f"{f}: Welch p {_p(p)} vs the thesis' {t['p']}")
    elif exp == "exp2c" and s.get("thresholds_g"):
        for f in cfg.exp2c.foods:
            for c in ("control", "primitive"):  # the thesis has no closed-loop condition
                d, t = s["foods"][f][c], th["exp2c"].get(f"{f}_{c}", {})
                for k, v in t.items():
                    ours = d.get("percent", {}).get(k)
                    if ours is not None:
                        out.append(f"{f} {c}: {k.replace('_', ' ')} {ours:.0f} % vs the "
                                   f"thesis' {v:g} % ({ours - v:+.0f} points)")
    elif exp == "exp1":
        for f in cfg.exp1.foods:
            for sys_ in cfg.exp1.systems:
                m = s["acquired_g"][f][sys_].get("mean")
                t = th["exp1"].get(f, {}).get(sys_)
                if m is not None and t:
                    out.append(f"{f}, {sys_}: {m:.2f} g vs the thesis' {t[0]:.2f} g "
                               f"({m - t[0]:+.2f} g)")
    elif exp == "exp3":
        for sys_, d in s["systems"].items():
            t = th["exp3"].get(sys_, {})
            if d["n"]:
                ms = 100.0 * d["counts"]["meaningful_success"] / d["n"]
                tms = 100.0 * t.get("meaningful_success", 0) / max(thesis_trials(t), 1)
                out.append(f"{sys_}: meaningful success {ms:.0f} % vs the thesis' {tms:.0f} % "
                           f"({ms - tms:+.0f} points)")
            a = d["planning_attempts"].get("mean")
            if a is not None and "planning_attempts" in t:
                out.append(f"{sys_}: {a:.2f} planning attempts to Staging vs the thesis' "
                           f"{t['planning_attempts']:.2f}")
    return out


def section(exp: str, summary: Mapping[str, Any], cfg: Any, figure_name: str | None,
            notes: str = "") -> str:
    """One experiment's Markdown: title, our numbers beside the thesis', the differences,
    ``notes`` (why we believe they differ), the figure and the run line."""
    body = {"capacity": _sec_capacity, "exp1": _sec_exp1, "exp2b": _sec_exp2b,
            "exp2c": _sec_exp2c, "exp3": _sec_exp3}[exp](summary, cfg)
    md = f"## {TITLES[exp]}\n\n{body}\n"
    diff = differences(exp, summary, cfg)
    if diff:
        md += "\n**Beside the thesis:** " + "; ".join(diff) + ".\n"
    if notes:
        md += f"\n{notes.strip()}\n"
    if figure_name:
        md += f"\n![{exp}]({figure_name})\n"
    md += f"\n*Run:* {_run_line(summary)}.\n"
    cmd = summary.get("run", {}).get("command")
    if cmd:
        md += f"\n```sh\n{cmd}\n```\n"
    return md


_CLAIM_KINDS = {
    "exp1": "Exp. 1 acquired mass (H1)", "exp2a_success": "Exp. 2a tasks solved (H2)",
    "exp2a_time": "Exp. 2a planning time (H2)", "exp2b": "Exp. 2b spilled mass (H2)",
    "exp2c": "Exp. 2c meaningful success (H2)", "exp3_success": "Exp. 3 meaningful success (H3)",
    "exp3_no_spill": "Exp. 3 bites without spill (H3)",
    "exp3_attempts": "Exp. 3 planning attempts (H3)"}
_CI_METHODS = {"welch": "Welch's t interval of the difference of means",
               "bootstrap": "bias-corrected and accelerated bootstrap (9 999 resamples, fixed "
                            "seed)",
               "newcombe": "Newcombe's hybrid score interval of the difference of rates, "
                           "from the two Wilson intervals"}


def hypotheses_section(summaries: Mapping[str, Mapping[str, Any]], cfg: Any) -> str:
    """The per-hypothesis table (:func:`articutool.experiments.verdicts.verdicts`), the
    pre-registered tests it used (``experiments.toml [tests]``) and which code every trial
    ran (``run.sources`` of each experiment)."""
    alpha = cfg.settings.alpha
    rows = [[v.hypothesis, v.figure, v.claim, v.thesis, v.ours, v.test, v.size, v.others,
             f"**{v.verdict}**"]
            for v in verdicts(summaries, cfg.thesis, alpha, cfg.tests)]
    md = ("## What the simulation shows, per hypothesis\n\n"
          "Each claim is judged by the test pre-registered for its kind of measurement (the "
          "table after this one) and by the 95 % interval of our difference. A claim is "
          f"*reproduced* when our difference has the thesis' direction with p < {alpha:g} and "
          "the thesis' difference lies inside our interval; *reproduced in sign only* when it "
          "is significant in the thesis' direction but the interval excludes the thesis' "
          "difference (or the thesis gives no number); *contradicted* when it is significant "
          "the other way; *not reproduced* when the test does not separate the systems; "
          "*cannot test* when our measurement cannot carry the claim (no food moved in either "
          "condition, both at the same floor or ceiling, or not run). The thesis' numbers "
          "decide only between *reproduced* and *reproduced in sign only*. The other tests "
          "are printed beside the chosen one, never used to decide. Differences are the first "
          "system's minus the second's (rates in percentage points), planning times the "
          "strict system's median over the decoupled one's. Why ours differ is in each "
          "experiment's section below.\n\n"
          + _table(["H", "figure", "claim", "thesis", "ours", "pre-registered test (p)",
                    "difference [95 % CI] beside the thesis'", "other tests (p)", "verdict"],
                   rows) + "\n")
    pre = [[_CLAIM_KINDS.get(k, k), t.measure, TEST_NAMES[t.test], _CI_METHODS[t.ci], t.why]
           for k, t in cfg.tests.items()]
    md += ("\n**Pre-registered tests** (`experiments.toml [tests]`, chosen from the type of "
           "each measurement; chosen after the run at `68222c7` had been read, binding every "
           "run after it):\n\n"
           + _table(["claims", "measurement", "test (two-sided)", "interval of the difference",
                     "why"], pre) + "\n")
    versions = code_versions({k: v for k, v in summaries.items() if k != "exp2a"})
    every = {v for vs in versions.values() for v in vs}
    n = sum(sum(vs.values()) for vs in versions.values())
    if len(every) == 1:
        md += f"\n**Code.** All {n} trials ran on one code version: {next(iter(every))}.\n"
    elif every:
        md += ("\n**Code.** The trials ran on more than one code version: " + "; ".join(
            f"{exp}: " + ", ".join(f"{k} ({c})" for k, c in vs.items())
            for exp, vs in versions.items()) + ".\n")
    return md


def read_exp2a(directory: Path) -> tuple[dict[str, Any] | None, list[dict[str, Any]]]:
    """The transport benchmark's run settings (``run.json``) and records
    (``results.jsonl``, :func:`articutool.bench.runner.read_log`) in ``directory``;
    ``(None, [])`` when it holds none."""
    from articutool.bench.runner import read_log
    from articutool.datafile import read_own_json

    run = read_own_json(directory / "run.json", "Exp. 2a run settings", _BenchRun)
    if run is None:
        return None, []
    return run.model_dump(), read_log(directory / "results.jsonl").records


def _sec_exp2a(s: Mapping[str, Any], run: Mapping[str, Any], cfg: Any, where: str) -> str:
    """The planning benchmark beside the thesis' Fig. 6.2 (our records at ``where``)."""
    th = cfg.thesis.get("exp2a", {})
    rows = []
    for name, v in s["planners"].items():
        t = th.get(name, {})
        med = v.get("median_s")
        rows.append([name, f"{v['solved']}/{v['tasks']}",
                     "–" if med is None else f"{med * 1e3:.1f} ms",
                     f"{t['success']:g} %, median {t['median_s']:g} s" if t else "–"])
    return ("## Exp. 2a — transport planning benchmark (H2, §5.2.1; cf. Fig. 6.2)\n\n"
            + _table(["system", "solved", "median planning time (solved)",
                      f"thesis ({th.get('timeout_s', '?'):g} s timeout)"], rows)
            + f"\n\nOur records: `{where}` ({run.get('planner', '?')}, "
              f"{s['timeout_s']:g} s per task; `articutool bench transport --out {where}`; "
              "docs/planning.md). A failed plan counts as taking the whole timeout in the "
              "rank tests.\n")


def deviation_facts(summaries: Mapping[str, Mapping[str, Any]],
                    records: Mapping[str, Sequence[TrialRecord]], out: Path, cfg: Any
                    ) -> dict[str, str]:
    """The figures the deviations table quotes (``{name}`` in ``experiments.toml
    [[deviations]]``), computed from the records, the summaries, the cross-checks' JSON
    and the physics file; a figure that cannot be formed is absent (shown as "–")."""
    from articutool.experiments.stats import describe

    f: dict[str, str] = {"plan_budget_s": f"{cfg.settings.plan_budget_s:g}"}

    def msd(values: Sequence[float]) -> str:
        d = describe(values)
        return f"{d.mean:.2f} ± {d.sd:.2f} g" if d.n > 1 else f"{d.mean:.2f} g"

    a2 = summaries.get("exp2a")
    if a2:
        f["exp2a_timeout_s"] = f"{a2['timeout_s']:g}"
        f["exp2a_algorithm"] = str(a2.get("algorithm", "?"))
        f["exp2a_tasks"] = str(max((v["tasks"] for v in a2["planners"].values()), default=0))
        if a2.get("max_solved_s") is not None:
            f["exp2a_max_solved_s"] = f"{a2['max_solved_s']:.1f}"
        f["exp2a_unsolved"] = ", ".join(
            f"{k} {v['tasks'] - v['solved']} of {v['tasks']}"
            for k, v in a2["planners"].items()) or "–"
    ok2b = [r for r in records.get("exp2b", ()) if not r.error and r.outcome is not None]
    if ok2b:
        f["exp2b_loads"] = ", ".join(f"{k} {g:g} g" for k, g in cfg.exp2b.load_g.items())
        for food in cfg.exp2b.foods:
            held = [float(r.outcome.held_g) for r in ok2b  # type: ignore[union-attr]
                    if r.condition.food == food]
            if held:
                f[f"exp2b_{food}_held"] = msd(held)
    c = summaries.get("exp2c")
    if c:
        if c.get("load_g"):
            f["exp2c_loads"] = ", ".join(f"{k} {g:.2f} g" for k, g in c["load_g"].items())
        f["exp2c_held"] = ", ".join(f"{k} {_msd(v['control']['held_g'])} g"
                                    for k, v in c["foods"].items() if "control" in v)
        if c.get("thresholds_g"):
            f["exp2c_thresholds"] = ", ".join(f"{k} {g:.2f} g"
                                              for k, g in c["thresholds_g"].items())
        for food, key in (("pecans", "vibrate"), ("water", "tilt")):
            prim = c["foods"].get(food, {}).get("primitive")
            if prim:
                f[f"exp2c_{key}_shed"] = f"{_msd(prim['shed_g'])} g"
        for r in records.get("exp2c", ()):
            o = r.outcome
            params = getattr(o, "primitive_params", None)
            if (o is None or r.condition.condition != "primitive" or not params):
                continue
            key = {"pecans": "exp2c_vibrate", "water": "exp2c_tilt"}.get(r.condition.food)
            if key:
                f.setdefault(key, "(" + ", ".join(f"{x:g}" for x in params) + ")")
    e3 = summaries.get("exp3")
    if e3:
        f["exp3_threshold"] = f"{e3['threshold_g']:.2f} g"
        at = e3.get("at_thesis_threshold")
        if at:
            f["exp3_at_thesis_threshold"] = " vs ".join(
                f"{at['meaningful_success'][x]}/{at['n'][x]}" for x in at["meaningful_success"])
        base = e3["systems"].get("baseline", {}).get("delivered_g")
        if base and base.get("mean") is not None:
            f["exp3_baseline_delivered"] = (f"{_msd(base)} g in {base['n']} bites")
    r = thesis_exp3_no_spill(cfg.thesis.get("exp3", {}))
    if r is not None:
        f["thesis_exp3_no_spill_p"] = _p(r.p)
    f.update(_crosscheck_facts(out))
    f.update(_physics_facts())
    return f


def _crosscheck_facts(out: Path) -> dict[str, str]:
    """The slosh-free speed-up (as a ratio of speed settings and of durations) and the
    water's static-tilt onsets, from the cross-checks' JSON in ``out``."""
    from articutool.datafile import ResultsError, read_own_json

    f: dict[str, str] = {}
    try:
        sl = read_own_json(out / "slosh_crosscheck.json", "slosh cross-check")
        st = read_own_json(out / "static_tilt_water.json", "static-tilt test")
    except ResultsError:
        return f
    if isinstance(sl, dict):
        summ = sl.get("summary", {})
        fast = summ.get("fastest_spill_free_scale", {})
        lev, sf = fast.get("leveling"), fast.get("slosh_free")
        by = summ.get("by_condition_and_scale", {})
        if lev and sf:
            f["slosh_speedup_settings"] = f"{sf / lev:.2f}"
            d_lev = by.get("leveling", {}).get(f"{float(lev)}", {}).get("mean_duration_s")
            d_sf = by.get("slosh_free", {}).get(f"{float(sf)}", {}).get("mean_duration_s")
            if d_lev and d_sf:
                f["slosh_speedup_durations"] = f"{d_lev / d_sf:.2f}"
    tip = (st.get("static_tilt", st) if isinstance(st, dict) else {}).get("tip") or {}
    if tip.get("onset_deg") is not None:
        f["water_onset_deg"] = f"{tip['onset_deg']:.1f}°"
    if tip.get("hydrostatic_onset_deg") is not None:
        f["water_onset_hydro_deg"] = f"{tip['hydrostatic_onset_deg']:.1f}°"
    return f


def _physics_facts() -> dict[str, str]:
    """The noodle nest and the water model, from the physics file the world builds."""
    from articutool.sim.params import PhysicsParams

    f: dict[str, str] = {}
    p = PhysicsParams.load()
    try:
        n = p.food("noodles")
        f["noodle_fill_g"] = f"{n.fill_g:g} g"
        f["noodle_strands"] = f"{n.fill_g / (n.piece_mass * 1e3):.0f}"
    except (KeyError, AttributeError, TypeError, ValueError, ZeroDivisionError):
        pass
    try:
        w = p.food("water")
        spread = getattr(w, "load_radius_spread", 0.0)
        f["water_model"] = (
            f"frictionless particles, {w.particle_radius * 1e3:g} mm in radius "
            f"({w.particle_mass(w.particle_radius) * 1e3:.2f} g each) in the bowl and "
            f"{w.load_particle_radius * 1e3:g} mm"
            + (f" ± {100 * spread:.0f} %" if spread else "")
            + " in a load placed on a spoon; no surface tension and no meniscus")
    except (KeyError, AttributeError, TypeError, ValueError):
        pass
    return f


class _Facts(dict):  # type: ignore[type-arg]
    def __missing__(self, key: str) -> str:
        return "–"


def deviations_section(cfg: Any, facts: Mapping[str, str]) -> str:
    """The deviations table (``experiments.toml [[deviations]]``), its ``{name}`` figures
    filled from ``facts`` (:func:`deviation_facts`)."""
    known = _Facts(facts)
    rows = [[d.topic, d.thesis.format_map(known), d.ours.format_map(known),
             d.why.format_map(known)] for d in cfg.deviations]
    return ("## Where our protocol differs from the thesis'\n\n"
            "Every place the protocol differs, what the thesis did, what we do and why; the "
            "figures are computed from this run's records and cross-checks "
            "(`experiments.toml [[deviations]]`).\n\n"
            + _table(["what", "thesis", "ours", "why"], rows) + "\n")


def replays(exp: str, records: Sequence[TrialRecord], summary: Mapping[str, Any],
            out: Path) -> str:
    """Per condition, a typical and the worst trial (:func:`representative_trials`) with the
    command that replays it with a video; a video already at that path is linked."""
    run = summary.get("run", {})
    n, seed = run.get("trials_per_condition"), run.get("base_seed", 0)
    rows = []
    for cond, picks in representative_trials(records).items():
        cells = [cond]
        for kind in ("typical", "worst"):
            k = picks[kind]
            video = out / exp / "videos" / f"trial-{k}.mp4"
            cell = f"trial {k}" + (f" ([video]({exp}/videos/{video.name}))"
                                   if video.exists() else "")
            cells.append(cell)
        rows.append(cells)
    if not rows:
        return ""
    cmd = (f"articutool experiment {exp} --out {out}" + (f" --trials {n}" if n else "")
           + (f" --seed {seed}" if seed else "") + f" --trial K --video {out}/{exp}/videos/"
           "trial-K.mp4")
    return ("\n**Replays** (typical: food mass nearest the condition's median; worst: most "
            "spilled, then least food):\n\n" + _table(["condition", "typical", "worst"], rows)
            + f"\n\n```sh\n{cmd}\n```\n")


# ------------------------------------------------------------------------- report --
def write_report(out: Path, cfg: Any, *, thresholds_g: Mapping[str, float] | None,
                 thresholds_source: str, threshold_g: float | None,
                 on_kept: Callable[[Path, Path], None] | None = None,
                 exp2a: Path | None = None,
                 on_log: Callable[[LogCheck], None] | None = None) -> tuple[Path, Path]:
    """Write ``out/report.md`` and ``out/report.html`` (figures in each experiment's
    directory); experiments not yet run are listed as missing, with their ``notes.md`` (why
    not) if present. ``out/<exp>/notes.md``, if present, is included in the experiment's
    section: the physical reasons we believe explain
    where our numbers differ, written by whoever examined the run (trials, videos).
    A report there that is not as this command wrote it (edited) is kept beside it first
    (:func:`_write_generated`), and ``on_kept(report, copy)`` is told. ``exp2a`` is the
    transport planning benchmark's folder (``bench transport --out``), whose claims join
    the per-hypothesis table (absent or empty: listed as not run). Every trial log read
    is checked against its run (:func:`check_log`), shown in the page's "Trial logs" section
    and given to ``on_log``; a log with bad lines or a condition short of its promised
    trials is flagged at the top of the page."""
    from articutool.datafile import ResultsError, own_folder, read_text
    from articutool.experiments.runner import read_trial_log

    parts = ["# The thesis' physical experiments in simulation\n",
             f"Generated {_dt.datetime.now(_dt.UTC).isoformat(timespec='seconds')} by "
             f"`articutool experiment report --out {out}`. Thesis: J. J. Martinez, *Articutool* "
             "(MS thesis, UW 2025), Ch. 5 (protocols) and Ch. 6 (results).\n",
             "## Regenerate\n",
             "Every experiment resumes from its trial log (`<exp>/trials.jsonl`); each section "
             "below gives the exact command that made it, and each cross-check at the end the "
             "command that measured it. All five, the cross-checks and this page:\n\n"
             "```sh\nmake experiments                 # 20 trials per condition, as the thesis\n"
             "EXP_TRIALS=5 make experiments    # a shorter run\n"
             "articutool experiment exp2b --trial K --video trial.mp4   # replay one trial\n```\n",
             "## Honesty rules\n", HONESTY]
    from articutool.experiments.analysis import summarize_exp2a

    missing = []
    machines = {}
    summaries: dict[str, Mapping[str, Any]] = {}
    records: dict[str, Sequence[TrialRecord]] = {}
    at_verdicts = len(parts)
    run2a, recs2a = read_exp2a(exp2a) if exp2a is not None else (None, [])
    if run2a is not None and recs2a:
        summaries["exp2a"] = {**summarize_exp2a(recs2a, float(run2a["timeout_s"])),
                              "algorithm": run2a.get("planner")}
        parts.append(_sec_exp2a(summaries["exp2a"], run2a, cfg, str(exp2a)))
    checks = []
    for exp in ORDER:
        log = read_trial_log(out, exp)
        recs = log.records
        records[exp] = recs
        old = read_summary(out / exp / "summary.json")
        checks.append(check_log(out, exp, log, old))
        if on_log is not None:
            on_log(checks[-1])
        if not recs or old is None:
            missing.append(exp)
            continue
        summary = summarize(exp, recs, cfg, thresholds_g=thresholds_g, threshold_g=threshold_g)
        summary["run"].update({k: v for k, v in old["run"].items()
                               if k not in summary["run"]})
        for k in ("load_g", "load_source", "goals", "closed_loop_target_g"):
            if k in old:
                summary[k] = old[k]
        if exp == "exp2c":
            summary["thresholds_source"] = thresholds_source
        theirs = cfg.thesis.get("exp3", {}).get("threshold_g")
        if exp == "exp3" and theirs is not None:  # our bites at the thesis' threshold too
            summary["at_thesis_threshold"] = meaningful_at(recs, cfg.exp3.systems, theirs)
        fig = figure(exp, recs, summary, cfg, own_folder(out, exp))
        rel = f"{exp}/{fig.name}" if fig else None
        npath = out / exp / "notes.md"
        notes = (read_text(npath, "notes", ResultsError) if npath.exists()
                 or npath.is_symlink() else "")
        parts.append(section(exp, summary, cfg, rel, notes) + replays(exp, recs, summary, out))
        summaries[exp] = summary
        m = old["run"].get("machine")
        if m:
            machines[exp] = (m, old["run"].get("date"))
    parts.insert(at_verdicts, hypotheses_section(summaries, cfg)
                 + "\n" + deviations_section(cfg, deviation_facts(summaries, records, out, cfg)))
    parts.insert(at_verdicts, _logs_section(checks))
    flagged = [c.experiment for c in checks if c.short or not c.log.state.clean]
    if flagged:
        parts.insert(2, f"**Warning: the trial logs of {', '.join(flagged)} are damaged or "
                        "short of the trials their runs promised; see Trial logs below. The "
                        "numbers of this page are over the trials found.**\n")
    parts.append(cross_checks(out))
    if missing:
        parts.append("## Not run yet\n\n" + ", ".join(missing) + " (no trials or no "
                     "summary under this directory).\n")
        for exp in missing:  # why not: the experiment's notes, when someone wrote them
            npath = out / exp / "notes.md"
            if npath.exists() or npath.is_symlink():
                parts.append(f"**{TITLES.get(exp, exp)}.** "
                             + read_text(npath, "notes", ResultsError).strip() + "\n")
    if machines:
        rows = [[e, m.get("host"), m.get("platform"), m.get("python"), m.get("cpus"),
                 m.get("load_avg"), d] for e, (m, d) in machines.items()]
        parts.append("## Machine and date\n\n" + _table(
            ["experiment", "host", "platform", "python", "CPUs",
             "load average (1/5/15 min) when the run ended", "date (UTC) the run ended"],
            rows) + "\n\nThe machine's 2 cores were shared with other work during every run: "
            "wall times are upper bounds, and planning budgets are wall-clock (see Exp. 2c).\n")
    md = "\n".join(parts)
    md_path = out / "report.md"
    _write_generated(md_path, md, on_kept)
    from markdown_it import MarkdownIt

    body = MarkdownIt("commonmark").enable("table").render(md)
    html = ("<!doctype html><html><head><meta charset='utf-8'><title>Articutool experiments"
            "</title><style>body{font-family:sans-serif;max-width:1100px;margin:auto;padding:1em}"
            "table{border-collapse:collapse;font-size:90%}td,th{border:1px solid #ccc;"
            "padding:3px 6px}img{max-width:100%}code,pre{background:#f4f4f4}</style></head>"
            f"<body>{body}</body></html>\n")
    html_path = out / "report.html"
    _write_generated(html_path, html, on_kept)
    return md_path, html_path


_MARK = "<!-- written by articutool experiment report; sha256 "


def _ours(text: str) -> bool:
    """Whether ``text`` is a report as this command wrote it: it ends in the mark carrying
    the SHA-256 of everything before it (any edit changes that)."""
    body, sep, tail = text.rpartition(_MARK)
    digest = tail.removesuffix(" -->\n")
    return bool(sep) and hashlib.sha256(body.encode("utf-8")).hexdigest() == digest


def _write_generated(path: Path, text: str, on_kept: Callable[[Path, Path], None] | None
                     ) -> None:
    """Write ``text`` and its mark to ``path`` (:func:`articutool.datafile.replace_own`:
    never through a link). A file there that is not, unchanged, one this command wrote (a
    user edited it, or an older version wrote it) is first kept as ``<name>.edited-<UTC
    time>`` (never overwritten) and ``on_kept(path, kept)`` is told; a link, FIFO or folder
    there is refused (:class:`~articutool.datafile.ResultsError`)."""
    from articutool.datafile import read_own_bytes, replace_own

    old = read_own_bytes(path, "report")
    if old is not None and not _ours(old.decode("utf-8", errors="replace")):
        stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%SZ")
        kept = path.with_name(f"{path.name}.edited-{stamp}")
        n = 1
        while kept.exists() or kept.is_symlink():
            n += 1
            kept = path.with_name(f"{path.name}.edited-{stamp}-{n}")
        os.link(path, kept, follow_symlinks=False)  # fails rather than replace anything
        if on_kept is not None:
            on_kept(path, kept)
    text = text if text.endswith("\n") else text + "\n"
    digest = hashlib.sha256(text.encode("utf-8")).hexdigest()
    replace_own(path, f"{text}{_MARK}{digest} -->\n")
