"""The hardware spec loads, and bad values fail with a message naming the field."""

import tomllib

import pytest

from articutool.cli import main
from articutool.spec import SpecError, default_spec_path, load_spec


def _spec_text() -> str:
    return default_spec_path().read_text()


def _write(tmp_path, text):
    p = tmp_path / "spec.toml"
    p.write_text(text)
    return p


def test_default_spec_has_the_reference_values():
    s = load_spec()
    assert s.wrist.loop_rate_hz == 50.0
    assert s.wrist.max_velocity == (4.0, 4.0)
    assert s.wrist.pitch_limits == pytest.approx((-1.5707963, 1.5707963))
    assert set(s.utensils) == {"fork", "spoon", "soup_spoon"}
    assert s.arm.joint_names[0] == "j2n6s200_joint_1"
    assert set(s.arm.configurations) >= {"Home", "AbovePlate", "Resting"}
    assert "Staging" in s.arm.poses
    assert s.controller.kp == 5.0 and s.filter.gain_acc == 0.1


@pytest.mark.parametrize(
    ("old", "new", "field"),
    [
        ("max_velocity = [4.0, 4.0]", "max_velocity = [-4.0, 4.0]", "wrist.max_velocity"),
        ("max_velocity = [4.0, 4.0]", "max_velocity = [nan, 4.0]", "wrist.max_velocity"),
        ("max_velocity = [4.0, 4.0]", "max_velocity = [9.0, 4.0]", "motor_max_velocity"),
        ("pitch_limits = [-1.5707963267948966, 1.5707963267948966]",
         "pitch_limits = [1.0, -1.0]", "pitch_limits"),
        ("loop_rate_hz = 50.0", "loop_rate_hz = inf", "wrist.loop_rate_hz"),
        ("gain_acc = 0.1", "gain_acc = 1.5", "filter.gain_acc"),
        ("tip_z = 0.070", "tip_z = -0.070", "utensils.fork.tip_z"),
        ("kp = 5.0", "kp = 5.0\nkq = 1.0", "controller.kq"),
        ("max_hold_s = 30.0", "max_hold_s = 1e9", "primitives.max_hold_s"),
        ("max_duration_s = 120.0", "max_duration_s = inf", "primitives.max_duration_s"),
        ("max_vibrate_s = 30.0", "max_vibrate_s = 0.0", "primitives.max_vibrate_s"),
        ("limit_gain = 5.0", "limit_gain = -1.0", "controller.limit_gain"),
        ("reboot_below_c = 70.0", "reboot_below_c = nan", "motors.reboot_below_c"),
    ],
)
def test_bad_values_name_the_field(tmp_path, old, new, field):
    text = _spec_text()
    assert old in text
    with pytest.raises(SpecError, match=field.replace(".", r"\.")):
        load_spec(_write(tmp_path, text.replace(old, new, 1)))


def test_unknown_utensil_and_configuration_are_named():
    s = load_spec()
    with pytest.raises(SpecError, match=r"unknown utensil 'knife'.*fork"):
        s.utensil("knife")
    with pytest.raises(KeyError, match="Nowhere"):
        s.arm.configuration("Nowhere")


def test_malformed_and_missing_files(tmp_path):
    with pytest.raises(SpecError, match="not valid TOML"):
        load_spec(_write(tmp_path, "version = = 1"))
    with pytest.raises(SpecError, match="cannot read"):
        load_spec(tmp_path / "missing.toml")
    with pytest.raises(SpecError, match="arm"):
        load_spec(_write(tmp_path, "version = 1\n"))


def test_spec_round_trips_through_the_validated_model():
    s = load_spec()
    raw = tomllib.loads(_spec_text())
    assert s.model_dump()["wrist"]["roll_turn_budget"] == raw["wrist"]["roll_turn_budget"]


def test_cli_info(capsys, tmp_path):
    assert main(["info", "--json"]) == 0
    assert '"loop_rate_hz": 50.0' in capsys.readouterr().out
    assert main(["info"]) == 0
    bad = _write(tmp_path, _spec_text().replace("gain_acc = 0.1", "gain_acc = -1"))
    assert main(["info", "--spec", str(bad)]) == 2
    assert "filter.gain_acc" in capsys.readouterr().err
