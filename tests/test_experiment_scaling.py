"""benchmarks/experiment_scaling.py: the same trials on a local pool and on a Dask
cluster give the same outcomes, the JSON has every field, an outcome that differs is caught
(a timing-dependent field is not an outcome), and bad input exits 2. No timing is asserted."""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
ROW_FIELDS = {"kind", "workers", "executor", "trials", "wall_clock_s", "trial_wall_sum_s",
              "speedup", "efficiency", "outcomes_equal", "differing", "timing_fields_moved",
              "loadavg_start", "lost", "errors"}


@pytest.fixture
def scaling(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCH))
    return importlib.import_module("experiment_scaling")


@pytest.mark.slow  # Exp. 2b with the SPH water, once per condition on each executor
def test_exp2b_on_a_local_pool_and_on_dask_gives_the_same_outcomes(scaling, tmp_path,
                                                                   monkeypatch) -> None:
    pytest.importorskip("distributed")
    monkeypatch.chdir(tmp_path)  # MuJoCo writes MUJOCO_LOG.TXT on a warning
    doc = scaling.measure("exp2b", 1, [1], root=tmp_path / "roots")
    out = tmp_path / "s.json"
    scaling.write_json(out, doc)
    doc = json.loads(out.read_text())
    assert doc["timing"].startswith("wall clock") and "loadavg_start" in doc["machine"]
    assert [(r["kind"], r["workers"]) for r in doc["rows"]] == [("local", 1), ("dask", 1)]
    n = len(doc["conditions"])  # 1 trial per condition
    for r in doc["rows"]:
        assert r.keys() >= ROW_FIELDS
        assert (r["trials"], r["lost"], r["errors"]) == (n, 0, 0)
        assert r["outcomes_equal"] and r["differing"] == {}
        assert r["efficiency"] == pytest.approx(r["speedup"], abs=1e-3)
    local, dask = doc["rows"]
    assert local["speedup"] == 1.0
    assert "Dask cluster" in dask["executor"] and "cluster_start_s" in dask
    # The trials ran into the temporary roots, each its own log, never results/.
    for kind in ("local", "dask"):
        assert (tmp_path / "roots" / f"{kind}-1" / "exp2b" / "trials.jsonl").exists()
    assert not (tmp_path / "results" / "experiments").exists()
    table = scaling.table(doc)
    assert table.count("| yes |") == 2 and "Dask LocalCluster" in table


def test_an_outcome_that_differs_is_caught_and_a_timing_field_is_not_an_outcome(
        scaling) -> None:
    ref = [{"trial": 0, "food": "pecans", "capacity_g": 7.1, "wall_time_s": 1.0, "pid": 1,
            "sim_time_s": 10.0, "x": float("nan")},
           {"trial": 1, "food": "water", "capacity_g": 19.0, "wall_time_s": 1.0, "pid": 1}]
    timing_only = [dict(ref[0], wall_time_s=3.0, pid=2, sim_time_s=10.2), dict(ref[1], pid=3)]
    c = scaling.compare(ref, timing_only)
    assert c["outcomes_equal"] and c["timing_fields_moved"] == {"0": ["sim_time_s"]}
    other = [dict(ref[0], capacity_g=7.2), {**ref[1], "spilled": 0.1}]
    c = scaling.compare(ref, other)
    assert not c["outcomes_equal"]
    assert c["differing"] == {"0": ["capacity_g"], "1": ["spilled"]}
    assert scaling.compare(ref, ref[:1])["differing"] == {"1": ["missing"]}


@pytest.mark.parametrize(("argv", "field"), [
    (["--workers", "2"], "--workers"), (["--workers", "0", "1"], "--workers"),
    (["--trials", "0"], "--trials"), (["--experiment", "exp9"], "--experiment"),
    (["--experiment", "capacity", "--load-g", "pecans=5"], "--load-g"),
    (["--load-g", "pecans=x"], "--load-g"), (["--load-g", "pecans=5"], "--load-g")])
def test_bad_input_exits_2_naming_the_field(scaling, tmp_path, capsys, argv, field) -> None:
    with pytest.raises(SystemExit) as ex:
        scaling.main([*argv, "--out-json", str(tmp_path / "s.json")])
    assert ex.value.code == 2 and field in capsys.readouterr().err
    assert not (tmp_path / "s.json").exists()


def test_table_of_a_missing_json_exits_2_naming_it(scaling, tmp_path, capsys) -> None:
    with pytest.raises(SystemExit) as ex:
        scaling.main(["--table", "--out-json", str(tmp_path / "none.json")])
    assert ex.value.code == 2 and "--out-json" in capsys.readouterr().err
