"""studies/dam_break_references.py: a front read against measured points gives no error and
no lag where it is the measurement, the lag a shift in time makes, and the committed JSON is
what the study computes from the committed calibration today."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from conftest import STUDIES, import_study


def _study():  # type: ignore[no-untyped-def]
    return import_study("dam_break_references")


@pytest.fixture
def study():  # type: ignore[no-untyped-def]
    return _study()


def _front(t: np.ndarray) -> np.ndarray:
    return 1.0 + 0.2 * t + 0.3 * t ** 2 / (1.0 + 0.2 * t)  # increasing, Ritter-like later


@given(shift=st.floats(min_value=-0.3, max_value=0.3))
def test_a_front_shifted_in_time_lags_by_the_shift_and_errs_in_its_direction(shift: float) -> None:
    study = _study()
    t_sim = np.linspace(0.0, 4.0, 4001)
    t_ref = np.array([0.8, 1.2, 2.0, 2.5])
    z_ref = _front(t_ref)
    # the simulated front reaches every Z ``shift`` earlier than the measured one
    got = study.compare(t_sim, _front(t_sim + shift), t_ref, z_ref, z_limit=10.0)
    assert np.allclose(got["lag_t_star"], shift, atol=2e-3)
    assert all(np.sign(e) == np.sign(shift) or abs(e) < 1e-3 for e in got["rel_error"])
    same = study.compare(t_sim, _front(t_sim), t_ref, z_ref, z_limit=10.0)
    assert same["max_abs_rel_error"] < 1e-4 and np.allclose(same["lag_t_star"], 0.0, atol=2e-3)


def test_only_measured_points_within_the_limit_and_the_run_are_compared(study) -> None:
    t_sim = np.linspace(0.0, 2.0, 201)
    got = study.compare(t_sim, _front(t_sim), np.array([0.0, 1.0, 1.9, 2.5]),
                        np.array([1.0, 1.5, 2.9, 3.1]), z_limit=3.0)
    assert got["t_star"] == [1.0, 1.9]


def test_the_committed_json_is_what_the_study_computes_today(study, tmp_path) -> None:
    out = tmp_path / "refs.json"
    assert study.main(["--out", str(out)]) == 0
    ours = json.loads(out.read_text())
    committed = json.loads((STUDIES / "results" / "dam_break_references.json").read_text())
    for key in ("against", "koshizuka_oka_as_front_against_martin_moyce_57mm",
                "particles_across_column"):
        assert ours[key] == committed[key]
