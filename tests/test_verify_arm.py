"""Plan-then-verify on the real Jaco + Articutool model, and the `articutool verify` CLI."""

import json
from pathlib import Path

import numpy as np
import pytest

from articutool.arm.model import ArmModel
from articutool.cli import main
from articutool.trajectory import JointTrajectory
from articutool.verify.verifier import verify_trajectory

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="module")
def model(spec):
    return ArmModel(spec, utensil="spoon")


def test_feasible_example_levels_the_spoon_tip_at_every_sample(spec, model):
    traj = JointTrajectory.load(EXAMPLES / "transport_feasible.json")
    rep = verify_trajectory(traj, model, spec)
    assert rep.feasible, rep.message
    w = rep.wrist_trajectory
    q_arm, _ = traj.sample(w.times)
    for qa, qw in zip(q_arm[::7], w.positions[::7], strict=True):
        tip = model.tip_pose(np.r_[qa, qw])
        # The tip's y axis is the utensil's up vector (Eq. 4.1): it must point along world z.
        np.testing.assert_allclose(tip[:3, 1], [0.0, 0.0, 1.0], atol=1e-9)
    # Eq. 4.7 rates agree with the derivative of the leveling positions along the real arm.
    fd = np.gradient(w.positions, w.times, axis=0)
    np.testing.assert_allclose(w.velocities[2:-2], fd[2:-2], atol=0.02)


def test_flip_example_is_a_branch_switch(spec, model):
    traj = JointTrajectory.load(EXAMPLES / "transport_flip.json")
    rep = verify_trajectory(traj, model, spec)
    assert not rep.feasible and rep.reason == "discontinuity"
    assert 0 < rep.first_failure_time < traj.duration
    assert abs(rep.wrist_trajectory.positions[-1, 0]) == pytest.approx(np.pi / 2, abs=0.05)


def test_cli_exit_codes_and_json(spec, tmp_path, capsys):
    assert main(["verify", str(EXAMPLES / "transport_feasible.json"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["feasible"] is True and out["velocity_margin"] > 0
    assert main(["verify", str(EXAMPLES / "transport_flip.json")]) == 1
    assert "INFEASIBLE (discontinuity)" in capsys.readouterr().out

    wrist = tmp_path / "wrist.json"
    assert main(["verify", str(EXAMPLES / "transport_feasible.json"),
                 "--wrist-out", str(wrist)]) == 0
    w = JointTrajectory.load(wrist)
    assert w.joint_names == spec.wrist.joint_names
    # Refuses to overwrite what a user saved.
    before = wrist.read_bytes()
    assert main(["verify", str(EXAMPLES / "transport_feasible.json"),
                 "--wrist-out", str(wrist)]) == 2
    assert wrist.read_bytes() == before


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("{not json", "not valid JSON"),
        ('{"joint_names": ["a"], "points": []}', "points must be a non-empty list"),
        ('{"joint_names": ["a"], "points": [{"positions": [NaN], "velocities": [0], '
         '"time_from_start": 0}]}', "finite"),
        ('{"joint_names": ["a"], "points": [{"positions": [0], "velocities": [0], '
         '"time_from_start": 0}]}', "missing"),
        ('{"joint_names": ["a"], "points": [{"positions": [0], "velocities": [0, 1], '
         '"time_from_start": 0}]}', "velocities must be a list of 1 numbers"),
    ],
)
def test_cli_bad_input_exit_2(tmp_path, capsys, content, message):
    f = tmp_path / "t.json"
    f.write_text(content)
    assert main(["verify", str(f)]) == 2
    assert message in capsys.readouterr().err


def test_cli_unknown_utensil_and_bad_step(capsys):
    f = str(EXAMPLES / "transport_feasible.json")
    assert main(["verify", f, "--utensil", "knife"]) == 2
    assert "soup_spoon" in capsys.readouterr().err
    assert main(["verify", f, "--max-step-deg", "-1"]) == 2
    assert "max_step_deg" in capsys.readouterr().err


def test_non_monotonic_times_are_rejected(tmp_path, capsys):
    d = json.loads((EXAMPLES / "transport_feasible.json").read_text())
    d["points"][5]["time_from_start"] = d["points"][4]["time_from_start"]
    f = tmp_path / "t.json"
    f.write_text(json.dumps(d))
    assert main(["verify", str(f)]) == 2
    assert "point 5" in capsys.readouterr().err
