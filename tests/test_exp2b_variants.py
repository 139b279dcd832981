"""Exp. 2b's variants: this stack's systems run beside the thesis' two, never instead of them."""

from __future__ import annotations

from typing import Any

import pytest

from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.design import conditions
from articutool.experiments.report import section
from articutool.experiments.units.exp2b import summarize_exp2b
from conftest import trial_record


def _cfg(**variants: Any) -> ExperimentsConfig:
    data = ExperimentsConfig.load().model_dump()
    data["exp2b"]["variants"] = variants
    return ExperimentsConfig.model_validate(data)


def test_variants_are_conditions_after_the_thesis_systems() -> None:
    cfg = _cfg(checked={"system": "baseline", "foods": ["water"]})
    conds = [c.fields() for c in conditions("exp2b", cfg)]
    thesis = [{"food": f, "system": s} for f in cfg.exp2b.foods for s in cfg.exp2b.systems]
    assert conds == thesis + [{"food": "water", "system": "checked"}]


@pytest.mark.parametrize(("variants", "field"), [
    ({"baseline": {"system": "baseline", "foods": ["water"]}}, "the name of a thesis system"),
    ({"x": {"system": "baseline", "leveling": "apparent", "foods": ["water"]}}, "apparent"),
    ({"x": {"system": "articutool", "foods": ["soup"]}}, "variants.x.foods"),
    ({"x": {"system": "robot", "foods": ["water"]}}, "system"),
])
def test_a_wrong_variant_is_refused_naming_it(variants: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        _cfg(**variants)


def _rec(system: str, spilled: float, seed: int, checks: list[dict] | None = None) -> Any:
    return trial_record("exp2b", food="water", system=system, goal="g", seed=seed,
                        spilled_g=spilled, completed=True, planning_attempts=1,
                        max_tilt_deg=5.0, held_g=7.0, motion_time_s=10.0 + spilled,
                        spilled_by_place={"table": spilled},
                        **({"food_checks": checks} if checks is not None else {}))


def test_a_variant_is_summarised_against_its_thesis_system_and_reported_beside() -> None:
    cfg = _cfg(checked={"system": "baseline", "foods": ["water"]})
    recs = ([_rec("articutool", 0.0, k) for k in range(4)]
            + [_rec("baseline", 0.5 if k < 3 else 0.0, k) for k in range(4)]
            + [_rec("checked", 0.2 if k == 0 else 0.0, k,
                    [{"wrist": "locked", "scale": 0.8 if k else 1.0,
                      "predicted_spill_g": 0.0}]) for k in range(4)])
    s = summarize_exp2b(recs, cfg)
    v = s["variants"]["checked"]["water"]
    assert (v["spills"]["k"], v["base_spills"]["k"], v["retimed"], v["checks"]) == (1, 3, 3, 4)
    # The thesis' comparison is the thesis systems alone.
    assert s["spilled_g"]["water"]["baseline"]["n"] == 4
    assert set(s["spilled_g"]["water"]) >= {"articutool", "baseline"}
    assert "checked" not in s["spilled_g"]["water"]
    s["run"] = {"trials": len(recs)}
    md = section("exp2b", s, cfg, None)
    assert "beside the thesis' two" in md and "checked (baseline + food-aware check)" in md
