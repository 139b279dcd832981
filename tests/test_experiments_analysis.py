"""Outcome classification of hand-built trial records at the boundaries (through
``classify_bite``), and the experiments' summaries of known records."""

from __future__ import annotations

import json

import pytest

from articutool.experiments.analysis import classify, summarize
from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.records import TrialRecord
from articutool.experiments.unit import unit
from articutool.experiments.units.exp2c import classify_exp2c
from conftest import trial_record

PIECE = 0.9163  # one pecan piece (g)


def rec(delivered: float, table: float = 0.0, critical: float = 0.0, shed: float = 0.0,
        completed: bool = True, experiment: str = "exp2c", **extra) -> TrialRecord:
    """A trial record of ``experiment`` as its protocol writes it (the masses it records)."""
    masses = {"delivered_g": delivered, "spilled_by_place": {"table": table,
                                                             "critical": critical},
              "spilled_g": table + critical, "shed_g": shed, "completed": completed,
              "held_g": delivered + table + critical + shed}
    own = unit(experiment).outcome.model_fields
    return trial_record(experiment, **{k: v for k, v in masses.items() if k in own}, **extra)


def bite(delivered: float, planning_attempts: int, **kw) -> TrialRecord:
    """An Exp. 3 bite that planned ``planning_attempts`` times to Staging."""
    return rec(delivered, experiment="exp3", planning_attempts=planning_attempts,
               planning_attempts_by_goal={"Staging": planning_attempts}, **kw)


@pytest.fixture(scope="module")
def cfg() -> ExperimentsConfig:
    return ExperimentsConfig.load()


def test_exactly_at_the_threshold_is_trivial_and_just_above_is_meaningful() -> None:
    assert classify(rec(3.0), 3.0) == "trivial_success"
    assert classify(rec(3.0 + 1e-6), 3.0) == "meaningful_success"
    assert classify_exp2c(rec(1.83), 1.83) == "trivial_success"
    assert classify_exp2c(rec(1.84), 1.83) == "meaningful_success"


def test_a_spill_of_one_piece_is_a_failure_whatever_was_delivered() -> None:
    assert classify(rec(9.0, table=PIECE), 3.0) == "table_spill"
    assert classify(rec(9.0, critical=PIECE), 3.0) == "user_spill"
    assert classify(rec(9.0, table=PIECE, critical=PIECE), 3.0) == "user_spill"
    assert classify_exp2c(rec(9.0, table=PIECE), 1.83) == "transport_failure"
    assert classify_exp2c(rec(9.0, critical=PIECE), 1.83) == "transport_failure"


def test_a_shed_into_the_bowl_is_no_spill() -> None:
    r = rec(4.0, shed=6.0)
    assert classify(r, 3.0) == "meaningful_success"
    assert classify_exp2c(r, 1.83) == "meaningful_success"
    # Even when the shed leaves too little: that is a trivial success, not a failure.
    assert classify_exp2c(rec(1.0, shed=9.0), 1.83) == "trivial_success"


def test_an_unfinished_trial_without_spill_is_failed_and_a_spill_outranks_it() -> None:
    assert classify(rec(0.0, completed=False), 3.0) == "failed"
    assert classify(rec(0.0, table=PIECE, completed=False), 3.0) == "table_spill"


def test_exp2c_summary_counts_classes_and_tests_with_fisher(cfg) -> None:
    recs = []
    for k in range(10):  # control: all spill; primitive: 9 meaningful, 1 trivial
        recs.append(rec(5.0, table=PIECE, food="pecans", condition="control", trial=k))
        recs.append(rec(5.0 if k else 1.0, shed=2.0, food="pecans", condition="primitive",
                        trial=k))
    recs.append(trial_record("exp2c", food="pecans", condition="primitive", error="boom"))
    s = summarize("exp2c", recs, cfg, thresholds_g={"pecans": 1.83})
    f = s["foods"]["pecans"]
    assert f["control"]["counts"] == {"meaningful_success": 0, "trivial_success": 0,
                                      "transport_failure": 10, "failed": 0}
    assert f["primitive"]["counts"]["meaningful_success"] == 9
    assert f["primitive"]["counts"]["trivial_success"] == 1
    from scipy.stats import fisher_exact

    assert f["fisher_meaningful"]["p"] == pytest.approx(fisher_exact([[9, 1], [0, 10]]).pvalue)
    assert s["run"]["errors"] == 1 and f["primitive"]["n"] == 10  # the error is left out


def test_exp2c_without_thresholds_reports_only_spill(cfg) -> None:
    recs = [rec(5.0, table=PIECE, food="pecans", condition="control"),
            rec(5.0, food="pecans", condition="primitive")]
    s = summarize("exp2c", recs, cfg, thresholds_g=None)
    assert "counts" not in s["foods"]["pecans"]["control"]
    assert s["foods"]["pecans"]["control"]["spill"]["k"] == 1


def test_exp3_summary_four_classes_and_planning_attempts(cfg) -> None:
    recs = [bite(5.0, system="articutool", planning_attempts=1),
            bite(2.0, system="articutool", planning_attempts=2),
            bite(5.0, table=PIECE, system="baseline", planning_attempts=3),
            bite(5.0, critical=PIECE, system="baseline", planning_attempts=2)]
    s = summarize("exp3", recs, cfg, threshold_g=3.0)
    a, b = s["systems"]["articutool"], s["systems"]["baseline"]
    assert s["threshold_g"] == 3.0
    assert a["counts"]["meaningful_success"] == 1 and a["counts"]["trivial_success"] == 1
    assert b["counts"]["table_spill"] == 1 and b["counts"]["user_spill"] == 1
    assert a["planning_attempts"]["mean"] == 1.5 and b["planning_attempts"]["mean"] == 2.5
    # Attempts count to Staging only: a bite that failed planning to Resting has none.
    failed = rec(0.0, completed=False, experiment="exp3", system="articutool",
                 planning_attempts=3, planning_attempts_by_goal={"Resting": 3})
    s2 = summarize("exp3", [*recs, failed], cfg, threshold_g=3.0)
    assert s2["systems"]["articutool"]["planning_attempts"]["n"] == 2
    assert s2["systems"]["articutool"]["counts"]["failed"] == 1
    # A configurable threshold: at 1.5 g the 2 g bite is meaningful too.
    assert summarize("exp3", recs, cfg, threshold_g=1.5)["systems"]["articutool"][
        "counts"]["meaningful_success"] == 2


def test_exp2b_summary_welch_on_spilled_mass(cfg) -> None:
    recs = [rec(2.5, experiment="exp2b", food="pecans", system="articutool", goal="centre",
                planning_attempts=1, max_tilt_deg=3.0) for _ in range(4)]
    recs += [rec(2.5 - x, table=x, experiment="exp2b", food="pecans", system="baseline",
                 goal="left", planning_attempts=1, max_tilt_deg=17.0)
             for x in (0.0, PIECE, PIECE, 0.0)]
    s = summarize("exp2b", recs, cfg)
    e = s["spilled_g"]["pecans"]
    assert e["articutool"]["mean"] == 0.0 and e["baseline"]["mean"] == pytest.approx(PIECE / 2)
    assert e["baseline"]["nonzero"]["k"] == 2
    from scipy.stats import ttest_ind

    ref = ttest_ind([0.0] * 4, [0.0, PIECE, PIECE, 0.0], equal_var=False)
    assert e["welch"]["p"] == pytest.approx(ref.pvalue)
    assert s["per_goal"]["pecans"]["baseline"]["left"]["n"] == 4


def test_report_puts_ours_beside_the_thesis_and_lists_what_did_not_run(cfg, tmp_path) -> None:
    from articutool.experiments import report
    from articutool.experiments.runner import log_path

    recs = [rec(8.0 - x, critical=x, experiment="exp2b", food="water", system=s,
                goal="centre", planning_attempts=1, max_tilt_deg=3.0, trial=k)
            for k, (s, x) in enumerate([("articutool", 0.0), ("baseline", 0.42),
                                        ("articutool", 0.0), ("baseline", 0.0)])]
    log = log_path(tmp_path, "exp2b")
    log.parent.mkdir(parents=True)
    log.write_text("".join(json.dumps(r.to_log()) + "\n" for r in recs))
    (tmp_path / "exp2b" / "summary.json").write_text(json.dumps(
        {"run": {"command": "articutool experiment exp2b --trials 2", "machine": {
            "host": "h", "cpus": 2}, "date": "2026-01-01"}}))
    (tmp_path / "exp2b" / "notes.md").write_text("Why: our water does not slosh.")
    (tmp_path / "exp3").mkdir()  # not run, with the reason why
    (tmp_path / "exp3" / "notes.md").write_text("Not run: a trial costs an hour of CPU.")
    md_path, html_path = report.write_report(tmp_path, cfg, )
    md = md_path.read_text()
    assert "| water | baseline | 2 | 0.21 ± 0.30" in md
    assert "1.31" in md and "0.0030" in md  # the thesis' water figures beside ours
    assert "water, baseline: spilled 0.21 g vs the thesis' 1.31 g (-1.10 g)" in md
    assert "Why: our water does not slosh." in md
    assert "articutool experiment exp2b --trials 2" in md
    assert "Not run yet" in md and "exp1" in md.split("Not run yet")[1]
    assert "Not run: a trial costs an hour of CPU." in md.split("Not run yet")[1]
    assert (tmp_path / "exp2b" / "exp2b.png").exists()
    assert "<img" in html_path.read_text()


def test_no_summary_reads_the_thesis_numbers(cfg) -> None:
    # The thesis' results in experiments.toml are printed beside ours only: no outcome,
    # threshold or statistic may change if they are removed.
    blind = cfg.model_copy(update={"thesis": {}})
    runs = {
        "exp1": ([rec(0.0, experiment="exp1", food=f, system=s, mass_g=m)
                  for f in ("pecans", "water", "noodles")
                  for s, m in (("articutool", 1.8), ("articutool", 0.9), ("baseline", 0.9),
                               ("baseline", 0.0))], {}),
        "exp2b": ([rec(2.5 - x, table=x, experiment="exp2b", food=f, system=s, goal="left",
                       planning_attempts=1, max_tilt_deg=5.0) for f in ("pecans", "water")
                   for s, x in (("articutool", 0.0), ("baseline", PIECE))], {}),
        "exp2c": ([rec(d, table=t, food=f, condition=c) for f in ("pecans", "water")
                   for c, d, t in (("control", 5.0, PIECE), ("primitive", 2.0, 0.0))],
                  {"thresholds_g": {"pecans": 1.5, "water": 0.0}}),
        "exp3": ([bite(d, system=s, planning_attempts=1) for s, d in (("articutool", 5.0),
                                                                      ("baseline", 1.0))],
                 {"threshold_g": 0.0}),
    }
    for exp, (recs, kw) in runs.items():
        assert summarize(exp, recs, blind, **kw) == summarize(exp, recs, cfg, **kw), exp


def test_report_recomputes_the_thesis_exp3_p_value_from_its_counts(cfg) -> None:
    """The thesis prints p < 0.00012 for 14/20 against 7/20 trials without spill; Fisher's
    exact test on those counts gives p ≈ 0.056. The report prints both and says which is
    which."""
    from articutool.experiments import report
    from articutool.experiments.units.exp3 import thesis_exp3_no_spill

    r = thesis_exp3_no_spill(cfg.thesis["exp3"])
    assert r is not None and r.table == ((14, 6), (7, 13))
    assert r.p == pytest.approx(0.056, abs=5e-4)
    recs = [bite(5.0, system="articutool", planning_attempts=1),
            bite(5.0, table=PIECE, system="baseline", planning_attempts=3)]
    md = report.section("exp3", summarize("exp3", recs, cfg, threshold_g=3.0), cfg, None)
    assert "as printed: < 0.00012" in md
    assert ("recomputed here from the thesis' own counts (14/20 vs 7/20 trials without "
            "spill, Fisher's exact test, two-sided): p = 0.056") in md
    # Without the thesis' counts nothing is made up: only the printed value stays.
    blind = {k: v for k, v in cfg.thesis["exp3"].items() if k != "baseline"}
    assert thesis_exp3_no_spill(blind) is None


def test_every_comparison_the_verdicts_read_is_in_the_summaries(cfg) -> None:
    recs = [rec(0.0, experiment="exp1", food=f, system=s, mass_g=m)
            for f in cfg.exp1.foods for s, m in (("articutool", 2.0), ("articutool", 1.0),
                                                 ("baseline", 1.0), ("baseline", 0.0))]
    c = summarize("exp1", recs, cfg)["acquired_g"]["pecans"]["compare"]
    assert set(c["p"]) == {"welch", "mann_whitney"}
    assert c["effect"]["welch"]["estimate"] == pytest.approx(1.0)
    assert set(c["effect"]) == {"welch", "bootstrap"}
    bites = [bite(5.0, system="articutool", planning_attempts=1),
             bite(0.0, system="baseline", planning_attempts=2)]
    s = summarize("exp3", bites, cfg, threshold_g=3.0)
    assert s["compare_meaningful"]["effect"]["newcombe"]["estimate"] == 1.0
    assert {"compare_no_spill", "compare_planning_attempts"} <= set(s)


def test_exp2b_spill_comparison_carries_the_spill_frequency_beside_the_masses(cfg) -> None:
    recs = [rec(8.0 - x, critical=x, experiment="exp2b", food="water", system=s,
                goal="centre", planning_attempts=1, max_tilt_deg=3.0)
            for s, x in (("articutool", 0.0), ("articutool", 0.0), ("baseline", 0.1),
                         ("baseline", 0.2))]
    c = summarize("exp2b", recs, cfg)["spilled_g"]["water"]["compare"]
    assert set(c["p"]) == {"welch", "mann_whitney", "fisher"}


def test_the_food_aware_baselines_checks_of_another_wrist_are_counted(cfg) -> None:
    # The committed run's defect: a leveling wrist modelled under the locked spoon.
    def checked(wrist: str) -> TrialRecord:
        return rec(8.0, experiment="exp2b", food="water", system="baseline_food_aware",
                   goal="centre", planning_attempts=1, max_tilt_deg=17.0,
                   food_checks=[{"wrist": wrist, "scale": 1.0}])

    base = [rec(8.0, experiment="exp2b", food="water", system="baseline", goal="centre",
                planning_attempts=1, max_tilt_deg=17.0)]
    s = summarize("exp2b", [checked("leveling"), checked("locked"), *base], cfg)
    v = s["variants"]["baseline_food_aware"]["water"]
    assert v["checks"] == 2 and v["checks_of_carried_wrist"] == 1


def test_our_bites_at_another_threshold(cfg) -> None:
    from articutool.experiments.units.exp3 import meaningful_at

    bites = [bite(5.0, system="articutool", planning_attempts=1),
             bite(2.0, system="articutool", planning_attempts=1),
             bite(0.5, system="baseline", planning_attempts=1)]
    at = meaningful_at(bites, cfg.exp3.systems, 3.0)
    assert at["meaningful_success"] == {"articutool": 1, "baseline": 0}
    assert at["n"] == {"articutool": 2, "baseline": 1} and "fisher" in at
    assert meaningful_at(bites, cfg.exp3.systems, 0.4)["meaningful_success"]["baseline"] == 1
