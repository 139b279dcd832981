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

from articutool.experiments import exp2a as bench
from articutool.experiments.analysis import completeness, representative_trials, summarize
from articutool.experiments.markdown import num, table
from articutool.experiments.records import TrialRecord
from articutool.experiments.unit import Experiment, registry, unit
from articutool.experiments.verdicts import TEST_NAMES, Verdict, code_versions
from articutool.thresholds import Grams

if TYPE_CHECKING:
    from articutool.experiments.runner import TrialLog

__all__ = ["CROSS_CHECKS", "HONESTY", "LogCheck", "check_log", "cross_checks",
           "deviation_facts", "deviations_section", "figure", "hypotheses_section", "order",
           "read_summary", "section", "verdicts", "write_report"]


def order() -> list[Experiment]:
    """The experiments in the report's order (the thesis')."""
    return sorted(registry().values(), key=lambda e: e.order)

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

    n = (summary or {}).get("run", {}).get("trials_per_condition")
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        return LogCheck(experiment, log, None, {})
    path = out / experiment / "run.json"
    pinned = read_own_json(path, "the run's settings")
    conds = None
    if pinned is not None:
        try:
            conds = [unit(experiment).condition.model_validate(c) for c in pinned["conditions"]]
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
            + table(["experiment", "lines read", "records accepted", "bad lines",
                      "trials per condition (promised)", "found per condition", "status"],
                     rows) + "\n")


# ------------------------------------------------------------------------ figures --
def figure(exp: str, records: Sequence[TrialRecord], summary: Mapping[str, Any], cfg: Any,
           directory: Path) -> Path | None:
    """Write the experiment's figure into ``directory``; None if there is nothing to draw."""
    ok = [r for r in records if not r.error]
    if not ok:
        return None
    return unit(exp).figure(ok, summary, cfg, directory)


# ----------------------------------------------------------------------- sections --
def _count(n: int, noun: str) -> str:
    """``n`` and ``noun``, plural unless ``n`` is 1: "1 error", "2 errors"."""
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _run_line(s: Mapping[str, Any]) -> str:
    r = s.get("run", {})
    w = r.get("wall_time_per_trial_s") or {}
    resets = r.get("physics_resets", 0)
    parts = [f"{r.get('trials', 0)} trials ({r.get('trials_per_condition', '?')} per "
             f"condition; {_count(r.get('errors', 0), 'error')}"
             + (f", of them {_count(resets, 'run')} that MuJoCo reset after a numerical "
                "instability, not counted" if resets else "") + ")"]
    if w.get("mean") is not None:
        parts.append(f"wall time per trial {w['mean']:.1f} ± {num(w.get('sd'), 1)} s, "
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


def _liquid_tip_onset(lq: Mapping[str, Any], load_g: float = 8.0) -> Mapping[str, Any]:
    """The SPH liquid's onset over the tip for ``load_g`` at the experiments' particle size
    (``sim-calibrate --food water --json``'s ``liquid``): ``measured_deg`` and ``law_deg``."""
    for t in lq.get("static_tilt", []):
        if (t.get("direction") == "tip" and t.get("load_g") == load_g
                and t.get("particle_radius_mm") == lq.get("particle_radius_mm")):
            return t.get("onset", {})
    return {}


def _sec_liquid(lq: Mapping[str, Any]) -> str:
    """The SPH liquid's checks, each beside its law (``sim-calibrate --food water --json``'s
    ``liquid``): the static tilt per load, direction and particle size against the dish's
    hydrostatics, the weighing, the dam break and the slosh modes."""
    from articutool.sim.liquid_tilt import check_passes

    def verdict(result: Mapping[str, Any]) -> str:
        return "pass" if check_passes(result) else "**fail**"

    tilts = lq.get("static_tilt", [])
    holds = [f"{h['tilt_deg']:g}°" for h in (tilts[0].get("holds", []) if tilts else [])]
    rows = []
    for t in tilts:
        on = t.get("onset", {})
        rows.append([num(t.get("load_g"), 0), t.get("direction", "–"),
                     num(t.get("particle_radius_mm")), num(t.get("kept_g")),
                     f"{num(on.get('measured_deg'), 1)}° / {num(on.get('law_deg'), 1)}°",
                     " · ".join(f"{num(h.get('spilled_g'))} / {num(h.get('hydrostatic_g'))}"
                                for h in t.get("holds", [])),
                     verdict(t)])
    tol = tilts[0] if tilts else {}
    out = (f"{lq.get('backend', 'SPH')} {lq.get('version', '')}; the experiments' particles "
           f"{num(lq.get('particle_radius_mm'))} mm in radius, the checks at "
           + " and ".join(f"{num(r)} mm" for r in lq.get("particle_radii_checked_mm", []))
           + f". All pass: **{lq.get('passes', '?')}**.\n\n"
           "**Static tilt**: each load poured into the soup spoon's dish, settled level, tilted "
           "quasi-statically over the tip or sideways and held at "
           + (", ".join(holds) or "each tilt")
           + "; the onset (the tilt at which the first grams leave) and the grams spilled at "
           "each hold, in the liquid / by the dish's hydrostatics for the volume kept (onset "
           f"within {num((tol.get('onset') or {}).get('tolerance_deg'), 1)}°, grams within "
           f"{100 * float(tol.get('grams_tolerance', 0.0)):.0f} %).\n\n"
           + table(["load (g)", "direction", "particle radius (mm)", "kept (g)",
                    "onset, liquid / law", "spilled at each hold, liquid / law (g)",
                    "verdict"], rows) + "\n\n")
    w = lq.get("weighing") or {}
    if w:
        out += (f"**Weighing**: a still {num(w.get('held_g'))} g load reads "
                f"{num(w.get('ft_sensor_g'))} g on the F/T sensor and {num(w.get('scale_g'))} g "
                f"on the scale (within {100 * float(w.get('tolerance', 0.0)):g} %): "
                f"{verdict(w)}.\n\n")
    for d in lq.get("dynamic", []):
        if d.get("check") == "dam_break":
            out += (f"**Dam break** (Martin & Moyce 1952, n² = 2): the surge front's largest "
                    f"error up to Z = 3, {100 * float(d.get('max_rel_error_to_Z3', 0.0)):.1f} % "
                    f"(within {100 * float(d.get('tolerance', 0.0)):g} %): "
                    f"{verdict(d)}."
                    + ("" if d.get("pass") else " What is known of the lead, and what is not: "
                       "docs/food.md, the liquid engine.") + "\n\n")
        elif d.get("check") == "slosh_modes":
            modes = "; ".join(
                f"{axis} {num(m.get('measured_hz'))} Hz against {num(m.get('law_hz'))} Hz "
                f"(damping ratio {num(m.get('measured_damping_ratio'), 3)})"
                for axis in ("along", "across") if (m := d.get(axis)))
            out += (f"**First slosh modes** against the linear model (within "
                    f"{100 * float(d.get('tolerance', 0.0)):g} %): {modes}: "
                    f"{verdict(d)}.\n\n")
    return out


def _sec_static_tilt(d: Mapping[str, Any]) -> str:
    """The liquid's static-tilt test beside hydrostatics (``sim-calibrate --food water
    --json``: the SPH liquid's checks under ``liquid``, the spheres' ``static_tilt``)."""
    if isinstance(d.get("liquid"), Mapping):
        return _sec_liquid(d["liquid"])
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
                f"{num(v.get('kept_g'))} g): spill onset {num(v.get('onset_deg'), 1)}° in the "
                f"world, {num(v.get('hydrostatic_onset_deg'), 1)}° by hydrostatics.\n\n"
                + table(["tilt (°)", "spilled, particles (g)", "spilled, hydrostatics (g)"],
                         rows) + "\n\n")
    return out


def _sec_slosh(d: Mapping[str, Any]) -> str:
    """The slosh model's predicted spill beside the particle world's, per trial, on the
    Exp. 2b paths (``studies/transport_spill.py``'s JSON)."""
    rows = []
    trials = d.get("trials", [])
    for t in trials:
        rows.append([t.get("goal", "–"), t.get("condition", t.get("wrist_used", "–")),
                     num(t.get("scale")), t.get("seed", "–"), num(t.get("max_tilt_deg"), 1),
                     num(t.get("predicted_spill_g")), num(t.get("lost_g"))])
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
    return head + table(["goal", "wrist", "speed scale", "seed", "max tilt (°)",
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
            rows.append([what, f"{num(v.get('bar_radius_mm'), 2)} mm",
                         f"hold ratio {num(v.get('hold_ratio'))}",
                         f"e^(μπ) = {num(v.get('law_e_mu_pi'))}", verdict(v)])
    for o in d.get("cantilever", {}).get("overhangs", []):
        rows.append(["bending, cantilever", f"{num(o.get('overhang_mm'), 1)} mm overhang",
                     f"tip falls {num(o.get('tip_fall_mm'))} mm",
                     f"elastica {num(o.get('law_elastica_mm'))} mm",
                     verdict(d.get("cantilever", {}))])
    for t in d.get("tack", {}).get("tests", []):
        rows.append([f"tack, on the {t.get('on', '?')}", f"{t.get('contacts_at_rest', '?')} "
                     "contacts", f"pull-off {num(t.get('pull_off_N_per_m'))} N/m",
                     f"{num(t.get('law_N_per_m'))} N/m (cited "
                     f"{'–'.join(num(x) for x in t.get('law_range_N_per_m', []))})", verdict(t)])
    c = d.get("tack_crossing")
    if c:
        rows.append(["tack, across a strand at 90°", f"{c.get('contacts_at_rest', '?')} contact",
                     f"pull-off {num(c.get('pull_off_N', 0) * 1e3)} mN",
                     f"{num(c.get('law_N', 0) * 1e3)} mN (the film's disk)", verdict(c)])
    n = d.get("tack_nest")
    if n:
        rows.append(["tack, a settled nest's strand contacts summed",
                     f"seed {n.get('seed', '?')}, {n.get('strand_contacts', '?')} contacts",
                     f"{num(n.get('adhesion_sum_N', 0) * 1e3)} mN",
                     f"{num(n.get('law_sum_N', 0) * 1e3)} mN (the film's law at each angle)",
                     verdict(n)])
    st = d.get("strand", {})
    if st:
        rows.append(["strand", f"{st.get('segments', '?')} segments of "
                     f"{num(st.get('segment_mm'))} mm", f"{num(st.get('mass_g'))} g, "
                     f"{num(st.get('diameter_mm'), 1)} mm",
                     f"cooked: {num(st.get('cited_mass_g'))} g, "
                     f"{'–'.join(num(x, 1) for x in st.get('cited_diameter_mm', []))} mm",
                     verdict(st)])
    bend = num(d.get("capstan_tine", {}).get("bending_over_tension"), 1)
    head = ("Each mechanism of the noodle strand alone, beside the law it should follow "
            "(tolerances: capstan on the bar within 20 % of e^(μπ), a frictionless bar "
            f"≤ 1.1; on a tine bending is {bend}× the tension, so no rope law applies and "
            f"it is reported). All pass: **{d.get('all_pass', '?')}**.\n\n")
    return head + table(["mechanism", "set-up", "simulated", "law", "verdict"], rows) + "\n"


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


def section(exp: str, summary: Mapping[str, Any], cfg: Any, figure_name: str | None,
            notes: str = "") -> str:
    """One experiment's Markdown: title, our numbers beside the thesis', the differences,
    ``notes`` (why we believe they differ), the figure and the run line."""
    u = unit(exp)
    md = f"## {u.title}\n\n{u.section(summary, cfg)}\n"
    diff = u.differences(summary, cfg)
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


_CI_METHODS = {"welch": "Welch's t interval of the difference of means",
               "bootstrap": "bias-corrected and accelerated bootstrap (9 999 resamples, fixed "
                            "seed)",
               "newcombe": "Newcombe's hybrid score interval of the difference of rates, "
                           "from the two Wilson intervals"}


def verdicts(summaries: Mapping[str, Mapping[str, Any]], thesis: Mapping[str, Any],
             alpha: float, tests: Mapping[str, Any]) -> list[Verdict]:
    """One :class:`Verdict` per claim, in the thesis' order (H1, H2, H3): the claims of every
    experiment that tests one (its ``verdicts``, :class:`~articutool.experiments.unit.
    Experiment`) and of the planning benchmark (:mod:`articutool.experiments.exp2a`).
    ``summaries`` maps an experiment to its summary (:mod:`articutool.experiments.analysis`);
    ``tests`` is ``experiments.toml [tests]``, the pre-registered test of each kind of claim.
    A missing experiment gives one "cannot test" row saying so."""
    sources = sorted([bench.BENCHMARK, *(u for u in registry().values() if u.hypothesis)],
                     key=lambda u: u.order)
    out: list[Verdict] = []
    for u in sources:
        s = summaries.get(u.name)
        rows = u.verdicts(s, thesis.get(u.name, {}), alpha, tests) if s else []
        why = "not run" if not s else "run, but no comparison could be formed" + (
            f" ({u.unjudged})" if u.unjudged else "")
        out += rows or [Verdict(u.hypothesis, u.thesis_figure, f"{u.name}'s claims", "", why,
                                "", "", "", "cannot test")]
    return out



def hypotheses_section(summaries: Mapping[str, Mapping[str, Any]], cfg: Any) -> str:
    """The per-hypothesis table (:func:`verdicts`), the
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
          + table(["H", "figure", "claim", "thesis", "ours", "pre-registered test (p)",
                    "difference [95 % CI] beside the thesis'", "other tests (p)", "verdict"],
                   rows) + "\n")
    from articutool.experiments.config import claims

    kinds = claims()
    pre = [[kinds.get(k, k), t.measure, TEST_NAMES[t.test], _CI_METHODS[t.ci], t.why]
           for k, t in cfg.tests.items()]
    md += ("\n**Pre-registered tests** (`experiments.toml [tests]`, chosen from the type of "
           "each measurement; chosen after the run at `68222c7` had been read, binding every "
           "run after it):\n\n"
           + table(["claims", "measurement", "test (two-sided)", "interval of the difference",
                     "why"], pre) + "\n")
    versions = code_versions({k: v for k, v in summaries.items() if k != bench.BENCHMARK.name})
    every = {v for vs in versions.values() for v in vs}
    n = sum(sum(vs.values()) for vs in versions.values())
    if len(every) == 1:
        md += f"\n**Code.** All {n} trials ran on one code version: {next(iter(every))}.\n"
    elif every:
        md += ("\n**Code.** The trials ran on more than one code version: " + "; ".join(
            f"{exp}: " + ", ".join(f"{k} ({c})" for k, c in vs.items())
            for exp, vs in versions.items()) + ".\n")
    return md


def deviation_facts(summaries: Mapping[str, Mapping[str, Any]],
                    records: Mapping[str, Sequence[TrialRecord]], out: Path, cfg: Any
                    ) -> dict[str, str]:
    """The figures the deviations table quotes (``{name}`` in ``experiments.toml
    [[deviations]]``), computed from the records, the summaries, the cross-checks' JSON
    and the physics file (each experiment's: :meth:`~articutool.experiments.unit.Experiment.
    facts`); a figure that cannot be formed is absent (shown as "–")."""
    f: dict[str, str] = {"plan_budget_s": f"{cfg.settings.plan_budget_s:g}"}

    f.update(bench.facts(summaries.get(bench.BENCHMARK.name)))
    for u in order():
        f.update(u.facts(summaries.get(u.name), records.get(u.name, ()), cfg))
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
    if isinstance(st, dict) and isinstance(st.get("liquid"), dict):
        onset = _liquid_tip_onset(st["liquid"])  # the SPH liquid: 8 g, the experiments' size
        tip = {"onset_deg": onset.get("measured_deg"),
               "hydrostatic_onset_deg": onset.get("law_deg")}
    else:
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
        bowl = (f"frictionless particles, {w.particle_radius * 1e3:g} mm in radius "
                f"({w.particle_mass(w.particle_radius) * 1e3:.2f} g each) in the bowl")
        if w.sph_load:
            bowl = (f"SPlisHSPlasH's liquid (DFSPH) in the bowl, particles "
                    f"{w.sph_bowl_particle_radius * 1e3:g} mm in radius, what a dip leaves "
                    f"in the dish handed over at {w.sph_particle_radius * 1e3:g} mm")
            load = (f"the same liquid, particles {w.sph_particle_radius * 1e3:g} mm "
                    "in radius, in a load placed on a spoon")
        else:
            spread = getattr(w, "load_radius_spread", 0.0)
            load = (f"frictionless particles {w.load_particle_radius * 1e3:g} mm"
                    + (f" ± {100 * spread:.0f} %" if spread else "")
                    + " in radius in a load placed on a spoon")
        f["water_model"] = f"{bowl} and {load}; no surface tension and no meniscus"
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
            + table(["what", "thesis", "ours", "why"], rows) + "\n")


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
            "spilled, then least food):\n\n" + table(["condition", "typical", "worst"], rows)
            + f"\n\n```sh\n{cmd}\n```\n")


# ------------------------------------------------------------------------- report --
def write_report(out: Path, cfg: Any, *,
                 settings: Mapping[str, Mapping[str, Any]] | None = None,
                 on_kept: Callable[[Path, Path], None] | None = None,
                 exp2a: Path | None = None,
                 on_log: Callable[[LogCheck], None] | None = None) -> tuple[Path, Path]:
    """Write ``out/report.md`` and ``out/report.html`` (figures in each experiment's
    directory); ``settings``: each experiment's analysis settings
    (:meth:`~articutool.experiments.unit.Experiment.analysis`: Exp. 2c's thresholds, Exp. 3's
    threshold). Experiments not yet run are listed as missing, with their ``notes.md`` (why
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
    from articutool.datafile import ResultsError, check_own, own_folder, read_text
    from articutool.experiments.runner import read_trial_log

    # The pages and the notes are checked before any work: a link, FIFO or folder there is
    # refused at once, not after every summary and figure.
    for page in ("report.md", "report.html"):
        check_own(out / page, "report")
    notes: dict[str, str | None] = {}
    for u in order():
        npath = out / u.name / "notes.md"
        notes[u.name] = (read_text(npath, "notes", ResultsError) if npath.exists()
                         or npath.is_symlink() else None)
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
    missing = []
    machines = {}
    summaries: dict[str, Mapping[str, Any]] = {}
    records: dict[str, Sequence[TrialRecord]] = {}
    at_verdicts = len(parts)
    run2a, recs2a = bench.read_exp2a(exp2a) if exp2a is not None else (None, [])
    if run2a is not None and recs2a:
        s2a = {**bench.summarize_exp2a(recs2a, float(run2a["timeout_s"])),
               "algorithm": run2a.get("planner")}
        summaries[bench.BENCHMARK.name] = s2a
        parts.append(bench.section_exp2a(s2a, run2a, cfg, str(exp2a)))
    checks = []
    for u in order():
        exp = u.name
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
        given = (settings or {}).get(exp, {})
        summary = summarize(exp, recs, cfg, **given)
        summary["run"].update({k: v for k, v in old["run"].items()
                               if k not in summary["run"]})
        summary.update({k: old[k] for k in u.noted_inputs if k in old})
        summary.update({k: given[k] for k in u.noted_settings if k in given})
        summary.update(u.report_extras(recs, cfg))
        fig = figure(exp, recs, summary, cfg, own_folder(out, exp))
        rel = f"{exp}/{fig.name}" if fig else None
        parts.append(section(exp, summary, cfg, rel, notes[exp] or "")
                     + replays(exp, recs, summary, out))
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
            text = notes[exp]
            if text is not None:
                parts.append(f"**{unit(exp).title}.** " + text.strip() + "\n")
    if machines:
        rows = [[e, m.get("host"), m.get("platform"), m.get("python"), m.get("cpus"),
                 m.get("load_avg"), d] for e, (m, d) in machines.items()]
        parts.append("## Machine and date\n\n" + table(
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
