"""studies/dam_break_solvers.py: the energy balance reads the share of released energy a
liquid loses or makes, and the committed JSON holds every variant with its errors as the
study computes them from its fronts."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from conftest import STUDIES, import_study


def _study():  # type: ignore[no-untyped-def]
    return import_study("dam_break_solvers")


@given(lost=st.floats(min_value=-0.5, max_value=0.9), pe=st.floats(min_value=1e-3, max_value=10.0))
def test_the_energy_balance_reads_the_share_the_liquid_loses(lost: float, pe: float) -> None:
    study = _study()
    released = np.linspace(0.0, 0.4 * pe, 9)
    samples = [(0.01 * k, (1.0 - lost) * r, pe - r) for k, r in enumerate(released)]
    got = study.energy_balance(samples)
    assert got["lost_share"][0] is None  # nothing released yet
    assert all(x == pytest.approx(lost, abs=1e-3) for x in got["lost_share"][1:])
    assert got["released_j"][-1] == pytest.approx(0.4 * pe, rel=1e-4)


def test_tait_s_sound_speed() -> None:
    assert _study().sound_speed(5.0e4) == pytest.approx(math.sqrt(350.0))


def test_the_committed_runs_are_the_study_s_variants_with_their_errors() -> None:
    study = _study()
    doc = json.loads((STUDIES / "results" / "dam_break_solvers.json").read_text())
    assert [r["variant"] for r in doc["runs"]] == [v[0] for v in study.VARIANTS]
    for r in doc["runs"]:
        rel = [(s - m) / m for s, m in zip(r["measured_z_star"], r["law_z_star"], strict=True)]
        assert r["rel_error"] == pytest.approx(rel, abs=1e-4)
        assert r["max_rel_error_to_Z3"] == pytest.approx(max(map(abs, rel)), abs=1e-4)
        assert r["pass"] == (r["max_rel_error_to_Z3"] <= 0.10)
    assert study.table(doc).count("\n") == len(doc["runs"]) + 1
