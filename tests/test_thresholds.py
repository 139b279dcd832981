"""Thresholds derived from our own Exp. 1 summary (read by ``articutool meal``, Exp. 2c/3)."""

import json

from articutool.thresholds import exp1_means


def test_means_come_from_the_exp1_summary_and_skip_foods_without_one(tmp_path) -> None:
    (tmp_path / "exp1").mkdir()
    (tmp_path / "exp1" / "summary.json").write_text(json.dumps({"acquired_g": {
        "rice": {"articutool": {"mean": 4.25}, "fork": {"mean": 1.0}},
        "water": {"articutool": {"mean": None}},
        "pecans": {"fork": {"mean": 2.0}},
    }}), encoding="utf-8")
    assert exp1_means(tmp_path) == {"rice": 4.25}


def test_no_exp1_run_gives_no_thresholds(tmp_path) -> None:
    assert exp1_means(tmp_path) == {}
