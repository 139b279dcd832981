"""The report's cross-checks: the water's static-tilt table, the slosh model's per-trial
comparison and the noodle mechanisms' table, read from their JSON files in the results
directory, "not yet measured" when a file is missing."""

from __future__ import annotations

import json
from pathlib import Path

from articutool.experiments.report import cross_checks


def test_missing_cross_checks_say_not_yet_measured_with_the_command(tmp_path: Path) -> None:
    md = cross_checks(tmp_path)
    assert md.count("Not yet measured") == 3
    assert f"articutool sim-calibrate --food water --json > {tmp_path}" in md
    assert "studies/transport_spill.py --out" in md
    assert f"articutool sim-calibrate --food noodles --json > {tmp_path}" in md


def test_the_noodle_mechanisms_table_reads_the_calibration(tmp_path: Path) -> None:
    calib = json.loads((Path(__file__).parents[1] / "results" / "noodles" /
                        "calibration.json").read_text())
    (tmp_path / "strand_laws_noodles.json").write_text(json.dumps(calib))
    md = cross_checks(tmp_path)
    assert "| capstan, fork-wide bar | 10.95 mm | hold ratio 5.42 | e^(μπ) = 6.59 | pass |" in md
    assert "| capstan, frictionless bar | 10.95 mm | hold ratio 1.00 | e^(μπ) = 1.00 | pass |" in md
    assert "capstan, one tine" in md and "| reported |" in md
    assert "tack, on the fork" in md and "All pass: **True**" in md
    assert "| tack, across a strand at 90° | 1 contact |" in md
    assert "| tack, a settled nest's strand contacts summed | seed 8200," in md


def test_the_static_tilt_table_and_the_slosh_rows_are_read_from_their_files(
        tmp_path: Path) -> None:
    rows = [{"tilt_cmd_deg": 12.0, "tilt_deg": 12.1, "spilled_g": 0.4, "hydrostatic_g": 0.9}]
    (tmp_path / "static_tilt_water.json").write_text(json.dumps({"static_tilt": {
        "load_g": 8.0, "utensil": "soup_spoon", "hold_s": 3.0, "rate_rad_s": 0.15,
        "tip": {"kept_g": 7.9, "rows": rows, "onset_deg": 12.1,
                "hydrostatic_onset_deg": 10.5}}}))
    # simulated_spill_g also counts what ran off while the load was placed; the transport's
    # own spill is lost_g, which the table prints (and the agreement counts).
    (tmp_path / "slosh_crosscheck.json").write_text(json.dumps({
        "load_g": 8.0, "summary": {"prediction": {"spill_threshold_g": 0.05}}, "trials": [
            {"goal": "centre", "condition": "locked", "scale": 1.0, "seed": 9700000,
             "max_tilt_deg": 17.8, "predicted_spill_g": 2.78, "simulated_spill_g": 0.42,
             "lost_g": 0.0},
            {"goal": "left", "condition": "leveling", "scale": 1.0, "seed": 9700001,
             "max_tilt_deg": 3.0, "predicted_spill_g": 0.0, "simulated_spill_g": 0.61,
             "lost_g": 0.0}]}))
    md = cross_checks(tmp_path)
    assert md.count("Not yet measured") == 1  # only the noodles' table, not written here
    assert "| 12.1 | 0.40 | 0.90 |" in md and "onset 12.1° in the world, 10.5°" in md
    assert "| centre | locked | 1.00 | 9700000 | 17.8 | 2.78 | 0.00 |" in md
    assert "0.42" not in md and "0.61" not in md
    assert "in 1 of 2 transports (50 %)" in md


def test_an_unreadable_cross_check_is_said_not_raised(tmp_path: Path) -> None:
    (tmp_path / "slosh_crosscheck.json").write_text("{not json")
    md = cross_checks(tmp_path)
    assert "could not be read" in md


def test_the_sph_liquids_checks_are_tabled_beside_their_laws(tmp_path: Path) -> None:
    """``sim-calibrate --food water --json`` on the SPH liquid writes its checks under
    ``liquid``: every static tilt (load, direction, particle size), the weighing, the dam break
    and the slosh modes reach the report, and the deviation row's onset is the 8 g load's over
    the tip at the experiments' particle size."""
    from articutool.experiments.report import _crosscheck_facts

    def tilt(load: float, direction: str, r: float, onset: float, law: float) -> dict:
        return {"load_g": load, "direction": direction, "particle_radius_mm": r,
                "kept_g": load - 0.01, "grams_tolerance": 0.15,
                "onset": {"measured_deg": onset, "law_deg": law, "tolerance_deg": 1.5,
                          "passes": abs(onset - law) <= 1.5},
                "holds": [{"tilt_deg": 15.0, "spilled_g": 2.53, "hydrostatic_g": 2.49},
                          {"tilt_deg": 20.0, "spilled_g": 4.66, "hydrostatic_g": 4.64}],
                "passes": abs(onset - law) <= 1.5}

    liquid = {"backend": "SPlisHSPlasH (pysplishsplash)", "version": "2.19.0",
              "particle_radius_mm": 1.0, "particle_radii_checked_mm": [1.0, 0.75],
              "static_tilt": [tilt(8.0, "tip", 0.75, 11.9, 10.6), tilt(8.0, "tip", 1.0, 10.9, 10.6),
                              tilt(10.0, "side", 1.0, 9.0, 11.0)],
              "weighing": {"held_g": 8.0, "ft_sensor_g": 7.99, "scale_g": 8.01,
                           "tolerance": 0.01, "passes": True},
              "dynamic": [{"check": "dam_break", "max_rel_error_to_Z3": 0.162,
                           "tolerance": 0.1, "pass": False},
                          {"check": "slosh_modes", "tolerance": 0.1, "pass": True,
                           "along": {"measured_hz": 3.1, "law_hz": 3.0,
                                     "measured_damping_ratio": 0.05},
                           "across": {"measured_hz": 4.2, "law_hz": 4.1,
                                      "measured_damping_ratio": 0.04}}],
              "passes": False}
    (tmp_path / "static_tilt_water.json").write_text(json.dumps(
        {"food": "water", "liquid": liquid}))
    md = cross_checks(tmp_path)
    assert "| 8 | tip | 1.00 | 7.99 | 10.9° / 10.6° | 2.53 / 2.49 · 4.66 / 4.64 | pass |" in md
    assert "| 10 | side | 1.00 | 9.99 | 9.0° / 11.0° | 2.53 / 2.49 · 4.66 / 4.64 | **fail** |" in md
    assert "| 8 | tip | 0.75 |" in md and "All pass: **False**" in md
    assert "reads 7.99 g on the F/T sensor and 8.01 g on the scale" in md
    assert "up to Z = 3, 16.2 % (within 10 %): **fail**. What is known of the lead" in md
    assert "along 3.10 Hz against 3.00 Hz" in md and "across 4.20 Hz against 4.10 Hz" in md
    facts = _crosscheck_facts(tmp_path)
    assert facts["water_onset_deg"] == "10.9°" and facts["water_onset_hydro_deg"] == "10.6°"
