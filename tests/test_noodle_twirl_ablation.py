"""studies/noodle_twirl_ablation.py: its no-twirl condition is the shipped
noodle strategy with exactly the two twirl stages emptied, loadable by the real action
library; the statistics pair the conditions; bad input exits 2. The runs themselves (Exp. 1
bites, a minute each) are the benchmark, not a test."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

from articutool.feeding.strategies import StrategyLibrary
from articutool.spec import load_spec

STUDIES = Path(__file__).resolve().parents[1] / "studies"


@pytest.fixture
def ablation(monkeypatch):
    monkeypatch.syspath_prepend(str(STUDIES))
    return importlib.import_module("noodle_twirl_ablation")


def test_the_no_twirl_variant_differs_only_by_the_twirls(ablation, tmp_path) -> None:
    spec = load_spec()
    shipped = StrategyLibrary.load(spec)
    variant = StrategyLibrary.load(spec, ablation.no_twirl_library(tmp_path / "s.toml"))
    a = shipped.for_food("noodles", "articutool")["noodles_twirl"]
    b = variant.for_food("noodles", "articutool")["noodles_twirl"]
    assert not a.stages.pre_move_into.is_none and not a.stages.post_move_into.is_none
    assert b.stages.pre_move_into.is_none and b.stages.post_move_into.is_none
    assert b.stages.post_acquisition == a.stages.post_acquisition
    assert b.model_dump(exclude={"stages"}) == a.model_dump(exclude={"stages"})
    # every other strategy is untouched
    for food in ("pecans", "water", "noodles"):
        for system in ("articutool", "baseline"):
            sa, sb = shipped.for_food(food, system), variant.for_food(food, system)
            assert sa.keys() == sb.keys()
            assert all(sa[k] == sb[k] for k in sa if k != "noodles_twirl")


def test_summary_compares_every_pair_of_conditions(ablation) -> None:
    runs = [{"condition": c, "seed": s, "mass_g": m, "acquired_g": m + 1.0,
             "end_state": "completed"}
            for c, ms in (("articutool", (2.0, 1.0, 3.0)), ("articutool_no_twirl", (0.0, 1.0, 0.0)),
                          ("baseline", (0.0, 0.0, 1.0)))
            for s, m in enumerate(ms)]
    s = ablation.summarise(runs)
    assert s["articutool"]["mass_g"]["mean"] == pytest.approx(2.0)
    assert s["articutool_no_twirl"]["acquired_g"]["mean"] == pytest.approx(4 / 3)
    assert set(s["welch_mass"]) == {"articutool vs articutool_no_twirl",
                                    "articutool vs baseline",
                                    "articutool_no_twirl vs baseline"}
    paired = s["twirl_vs_no_twirl"]["paired_wilcoxon"]  # same seeds: 2-0, 1-1, 3-0
    assert (paired["pairs"], paired["twirl_more"], paired["still_more"]) == (3, 2, 0)
    assert "welch_t" in s["twirl_vs_no_twirl"] and "mann_whitney_u" in s["twirl_vs_no_twirl"]
    assert "| articutool | 3 | 2.00 ± 1.00 |" in ablation.table({"summary": s})


def test_bad_seed_count_exits_2(ablation, capsys) -> None:
    assert ablation.main(["--seeds", "0", "--out", "/nonexistent/x.json"]) == 2
    assert "--seeds must be in 1..1000" in capsys.readouterr().err
