"""Closed loop: the arm follows a transport while the onboard loop levels the spoon."""

import tomllib
from pathlib import Path

import pytest

from articutool.arm.model import ArmModel
from articutool.sim.transport import simulate_transport
from articutool.spec import default_spec_path, parse_spec
from articutool.trajectory import JointTrajectory

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
TRAJ = JointTrajectory.load(EXAMPLES / "transport_feasible.json")


@pytest.fixture(scope="module")
def model(spec):
    return ArmModel(spec)


@pytest.fixture(scope="module")
def result(spec, model):
    return simulate_transport(TRAJ, model, spec, seed=3)


def test_spoon_stays_level_while_the_tool_base_tilts(result):
    moving = (result.times >= 0) & (result.times <= result.duration_s)
    # Without the wrist the spoon would tilt with the tool base by tens of degrees.
    assert result.base_tilt_deg[moving].max() - result.base_tilt_deg[moving].min() > 20
    assert result.max_tilt_error_deg < 3.0
    assert result.rms_tilt_error_deg < 2.0
    assert result.final_tilt_error_deg < 1.5
    assert result.faults == ()


def test_wrist_starts_unlevel_and_the_loop_levels_it(result):
    assert result.tilt_deg[0] > 30  # wrist at zero over the bowl is far from level
    settled = (result.times > -0.5) & (result.times < 0)
    assert result.tilt_deg[settled].max() < 1.5


def test_reference_bias_alpha_absorbs_slow_arm_rotation(spec, model):
    # The reference configuration (bias_alpha 0.05) treats the slow transport rotation as gyro
    # bias; this is why the spec defaults to 0.01 (see hardware.toml [filter]).
    raw = tomllib.loads(default_spec_path().read_text())
    raw["filter"]["bias_alpha"] = 0.05
    ref = simulate_transport(TRAJ, model, parse_spec(raw), seed=3)
    ours = simulate_transport(TRAJ, model, spec, seed=3)
    assert ref.max_tilt_error_deg > 2 * ours.max_tilt_error_deg


def test_bad_arguments(spec, model):
    with pytest.raises(ValueError, match="settle_s"):
        simulate_transport(TRAJ, model, spec, settle_s=0.0)
    other = JointTrajectory(("a",) * 1, TRAJ.times, TRAJ.positions[:, :1], TRAJ.velocities[:, :1])
    with pytest.raises(ValueError, match="joint_names"):
        simulate_transport(other, model, spec)
    with pytest.raises(ValueError, match="hold_s"):
        simulate_transport(TRAJ, model, spec, hold_s=-1.0)
    with pytest.raises(ValueError, match="settle_s"):
        simulate_transport(TRAJ, model, spec, settle_s=float("nan"))
