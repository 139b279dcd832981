"""The report's deviations table and the transport benchmark's claims: every figure the
table quotes is computed from the records, and a benchmark folder beside the results joins
the per-hypothesis table."""

from __future__ import annotations

import json
import string
from pathlib import Path

import numpy as np
import pytest

from articutool.experiments import report
from articutool.experiments.analysis import summarize
from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.exp2a import read_exp2a, summarize_exp2a
from articutool.experiments.runner import read_trial_log
from articutool.experiments.units.exp3 import meaningful_at
from articutool.thresholds import exp1_means

CFG = ExperimentsConfig.load()
RESULTS = Path(__file__).parents[1] / "results"


def _figures() -> set[str]:
    return {f for d in CFG.deviations for text in (d.thesis, d.ours, d.why)
            for _, f, _, _ in string.Formatter().parse(text) if f}


def test_every_figure_of_the_deviations_table_is_computed_from_the_committed_run() -> None:
    out = RESULTS / "experiments"
    recs = {e: read_trial_log(out, e).records for e in [u.name for u in report.order()]}
    means = exp1_means(out)
    summaries = {e: summarize(e, r, CFG, thresholds_g={f: means[f] for f in CFG.exp2c.foods},
                              threshold_g=means[CFG.exp3.food]) for e, r in recs.items()}
    summaries["exp2c"]["load_g"] = report.read_summary(out / "exp2c" / "summary.json")["load_g"]
    summaries["exp3"]["at_thesis_threshold"] = meaningful_at(
        recs["exp3"], CFG.exp3.systems, CFG.thesis["exp3"]["threshold_g"])
    run, bench = read_exp2a(RESULTS / "exp2a")
    assert run is not None
    summaries["exp2a"] = {**summarize_exp2a(bench, run["timeout_s"]), "algorithm": "rrtconnect"}
    facts = report.deviation_facts(summaries, recs, out, CFG)
    assert sorted(_figures() - set(facts)) == []
    # The figures a review recomputes from the files themselves: the water held once placed
    # (the records' held_g) and the speed-up both ways (the slosh cross-check's summary; the
    # row without that file is test_a_figure_not_measured_shows_a_dash_not_a_stale_number's).
    held = np.array([json.loads(line)["held_g"] for line in
                     (out / "exp2b" / "trials.jsonl").read_text().splitlines()
                     if json.loads(line)["food"] == "water"])
    assert facts["exp2b_water_held"] == f"{held.mean():.2f} ± {held.std(ddof=1):.2f} g"
    summ = json.loads((out / "slosh_crosscheck.json").read_text())["summary"]
    lev, sf = (summ["fastest_spill_free_scale"][k] for k in ("leveling", "slosh_free"))
    by = summ["by_condition_and_scale"]
    dur = by["leveling"][f"{float(lev)}"]["mean_duration_s"] / by["slosh_free"][
        f"{float(sf)}"]["mean_duration_s"]
    assert (facts["slosh_speedup_settings"], facts["slosh_speedup_durations"]) == (
        f"{sf / lev:.2f}", f"{dur:.2f}")
    md = report.deviations_section(CFG, facts)
    assert "{" not in md and md.count("\n| ") == len(CFG.deviations) + 1


def test_a_figure_not_measured_shows_a_dash_not_a_stale_number() -> None:
    md = report.deviations_section(CFG, {})
    assert "{" not in md and "–" in md


def test_the_benchmark_beside_the_results_joins_the_hypotheses(tmp_path: Path) -> None:
    out = tmp_path / "experiments"
    out.mkdir()
    bench = tmp_path / "exp2a"
    bench.mkdir()
    (bench / "run.json").write_text(json.dumps({"timeout_s": 60.0, "algorithm": "rrtconnect"}))
    lines = [{"system": s, "task_id": k, "seed": 0, "tolerance_deg": None, "success": True,
              "planning_time_s": (0.01 if s == "decoupled" else 0.1) * (1 + 0.01 * k)}
             for s in ("decoupled", "strict6") for k in range(12)]
    (bench / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in lines))
    md = report.write_report(out, CFG, exp2a=bench)[0].read_text()
    assert "Exp. 2a — transport planning benchmark" in md
    assert "the decoupled planner plans faster than strict6" in md
    assert "| strict6 | 12/12 |" in md
    assert "Where our protocol differs from the thesis'" in md
    none = report.write_report(out, CFG, exp2a=tmp_path / "nothing")[0].read_text()
    assert "| H2 | Fig. 6.2 | exp2a's claims |  | not run |" in none


@pytest.mark.parametrize("bad", ["{not json", "[1, 2]"])
def test_an_unreadable_benchmark_folder_is_refused_naming_it(tmp_path: Path, bad: str) -> None:
    from articutool.datafile import ResultsError

    (tmp_path / "run.json").write_text(bad)
    with pytest.raises(ResultsError, match=r"run\.json"):
        read_exp2a(tmp_path)


def test_a_benchmark_folder_that_is_not_one_exits_2_naming_the_option(tmp_path, capsys) -> None:
    import articutool.cli as cli

    assert cli.main(["experiment", "report", "--out", str(tmp_path), "--exp2a",
                     str(tmp_path / "missing")]) == 2
    assert "--exp2a" in capsys.readouterr().err


def test_the_water_models_deviation_names_the_load_model_the_world_builds(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The deviations table states the placed load's model from the physics file: the SPH
    liquid by default, the frictionless spheres when the file selects them."""
    from articutool.sim.params import PhysicsParams

    assert "SPlisHSPlasH" in report._physics_facts()["water_model"]
    p = PhysicsParams.load()
    spheres = p.model_copy(update={"foods": {**p.foods, "water": p.foods["water"].model_copy(
        update={"load_model": "spheres"})}})
    monkeypatch.setattr(PhysicsParams, "load", classmethod(lambda cls, path=None: spheres))
    text = report._physics_facts()["water_model"]
    assert "SPlisHSPlasH" not in text and "in a load placed on a spoon" in text


@pytest.mark.parametrize(("errors", "resets", "want", "not_want"), [
    (1, 1, "1 error, of them 1 run that MuJoCo reset", ("1 errors", "1 runs")),
    (2, 2, "2 errors, of them 2 runs that MuJoCo reset", ("2 error,", "2 run ")),
    (0, 0, "0 errors)", ("of them",)),
])
def test_run_line_counts_agree_with_their_nouns(errors: int, resets: int, want: str,
                                               not_want: tuple[str, ...]) -> None:
    line = report._run_line({"run": {"trials": 40, "trials_per_condition": 20,
                                     "errors": errors, "physics_resets": resets}})
    assert want in line
    for bad in not_want:
        assert bad not in line
