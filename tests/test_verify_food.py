"""Food-aware verification: the dish's pose along a trajectory, the prediction for a load
carried by the leveling, locked or slosh-free wrist, and the ``verify --load`` CLI."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from articutool.arm.model import ArmModel
from articutool.food.definitions import load_food_definitions
from articutool.food.loads import LoadError, food_load, parse_load
from articutool.planning.timing import time_parameterize
from articutool.tool.following import TrajectoryFollower
from articutool.trajectory import JointTrajectory
from articutool.verify.food import (
    dish_poses,
    food_check,
    predict_transport,
    slosh_free_wrist,
    spill_model,
)
from articutool.verify.verifier import verify_trajectory
from conftest import assert_refused, packaged_spec, run_cli

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SPEC = packaged_spec()
MODEL = ArmModel(SPEC, "soup_spoon")
FOODS = load_food_definitions()
WATER = food_load(FOODS["water"], 8.0)
PATH = JointTrajectory.load(EXAMPLES / "transport_feasible.json")


def _timed(k: float) -> JointTrajectory:
    """The example path, TOPP-RA timed at k × the arm's speed and k² × its acceleration."""
    return time_parameterize(PATH.positions, PATH.joint_names, SPEC.arm.max_velocity * k,
                             SPEC.arm.max_acceleration * k * k)


def test_the_dish_pose_is_the_kinematic_models() -> None:
    # the dish point, moved to the tip, is Pinocchio's tip frame, for any arm and wrist
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.5, 1.5, (6, 8))
    R0, p0 = MODEL.tool_base_poses(q[:, :6])
    u = SPEC.utensil("soup_spoon")
    zc = u.tip_z - SPEC.utensil("soup_spoon").physics.bowl[0] / 2
    R, p = dish_poses(SPEC, "soup_spoon", R0, p0, q[:, 6:], 0.004)
    for k in range(q.shape[0]):
        T = MODEL.tip_pose(q[k])
        R_roll = T[:3, :3] @ np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        np.testing.assert_allclose(R[k], R_roll, atol=1e-12)
        np.testing.assert_allclose(p[k], T[:3, 3] + R_roll @ [0.004, 0.0, zc - u.tip_z],
                                   atol=1e-12)


def test_a_level_dish_at_rest_keeps_its_load() -> None:
    still = JointTrajectory(PATH.joint_names, np.array([0.0, 2.0]),
                            np.tile(PATH.positions[0], (2, 1)), np.zeros((2, 6)))
    rep = verify_trajectory(still, MODEL, SPEC, load=WATER)
    assert rep.feasible and rep.food is not None
    assert rep.food.prediction.spilled_g == 0.0
    assert rep.food.prediction.peak_apparent_tilt_deg < 1e-6
    d = rep.to_dict()["food"]
    for key in ("peak_apparent_tilt_deg", "peak_surface_tilt_deg", "min_margin_deg",
                "spilled_g", "spill_free", "model", "load"):
        assert key in d


def test_acceleration_tilts_the_liquid_and_slosh_free_leveling_takes_it_out() -> None:
    fast = _timed(1.0)
    lev = verify_trajectory(fast, MODEL, SPEC, load=WATER)
    sf = verify_trajectory(fast, MODEL, SPEC, load=WATER, slosh_free=True)
    assert lev.feasible and sf.feasible and sf.slosh_free.ok
    assert sf.food.wrist == "slosh_free"
    p_lev, p_sf = lev.food.prediction, sf.food.prediction
    assert p_lev.peak_apparent_tilt_deg > 1.5
    assert p_lev.peak_surface_tilt_deg > p_lev.peak_apparent_tilt_deg  # it sloshes
    # Less slosh, not none: the wrist takes out the acceleration it can follow (smoothed by
    # σ ≥ 80 ms), so part of what excites the dish's modes remains.
    assert p_sf.peak_surface_tilt_deg < 0.8 * p_lev.peak_surface_tilt_deg
    # slower: less tilt
    slow = verify_trajectory(_timed(0.5), MODEL, SPEC, load=WATER)
    assert slow.food.prediction.peak_apparent_tilt_deg < 0.5 * p_lev.peak_apparent_tilt_deg


def test_the_slosh_free_wrist_is_what_the_tool_accepts() -> None:
    res = slosh_free_wrist(_timed(1.0), MODEL, SPEC, "soup_spoon")
    assert res.ok
    TrajectoryFollower(SPEC).prevalidate(res.wrist)  # raises if the tool would refuse it
    both = res.combined()
    assert both.joint_names == (*SPEC.arm.joint_names, *SPEC.wrist.joint_names)
    # the arm holds still during the lead-in and out; the wrist starts and ends level
    lead = both.times <= 3 * res.sigma_s - 1e-9
    assert np.ptp(both.positions[lead, :6], axis=0).max() < 1e-12
    rep = verify_trajectory(PATH, MODEL, SPEC)
    assert np.allclose(res.wrist.positions[0], rep.wrist_trajectory.positions[0], atol=1e-6)
    assert np.allclose(res.wrist.positions[-1], rep.wrist_trajectory.positions[-1], atol=1e-6)


def _followed_by_the_tool(traj: JointTrajectory) -> JointTrajectory:
    """``traj`` as the tool's trajectory follower drives the simulated wrist (its motor lag)
    at the loop's rate: the positions read each tick."""
    from articutool.tool.drivers.sim import SimWrist

    wrist = SimWrist(SPEC)
    wrist.set_joint_positions(traj.positions[0])
    motors = wrist.motor_driver()
    motors.open()
    motors.enable_torque(True)
    follower = TrajectoryFollower(SPEC)
    follower.start(traj, 0.0)
    period = 1.0 / SPEC.wrist.loop_rate_hz
    ticks = math.ceil(traj.duration / period)
    t = np.minimum(period * np.arange(ticks + 1), traj.duration)
    q = [np.asarray(motors.read().position, dtype=float)]
    for k in range(ticks):
        motors.set_velocity(follower.command(q[-1], t[k]))
        wrist.step(t[k + 1] - t[k])
        q.append(np.asarray(motors.read().position, dtype=float))
    qs = np.array(q)
    return JointTrajectory(traj.joint_names, t, qs, np.gradient(qs, t, axis=0))


def test_the_check_verifies_the_slosh_free_wrist_the_tool_executes() -> None:
    """Plan-then-verify holds only if the wrist does what was verified: the prediction along
    the wrist as the tool's loop follows it agrees with the prediction along its plan."""
    res = slosh_free_wrist(_timed(1.0), MODEL, SPEC, "soup_spoon")
    assert res.ok
    model = spill_model(SPEC, "soup_spoon", WATER)
    planned = predict_transport(res.arm, res.wrist, MODEL, SPEC, "soup_spoon", model)
    done = predict_transport(res.arm, _followed_by_the_tool(res.wrist), MODEL, SPEC,
                             "soup_spoon", model)
    assert done.peak_surface_tilt_deg == pytest.approx(planned.peak_surface_tilt_deg, abs=0.5)
    assert done.peak_apparent_tilt_deg == pytest.approx(planned.peak_apparent_tilt_deg, abs=0.5)


def test_a_wrist_too_slow_for_slosh_free_leveling_falls_back() -> None:
    slow = SPEC.model_copy(update={"wrist": SPEC.wrist.model_copy(
        update={"max_velocity": (0.02, 0.02)})})
    res = slosh_free_wrist(_timed(1.0), ArmModel(slow, "soup_spoon"), slow, "soup_spoon")
    assert not res.ok and "tool accepts" in res.message


def test_the_locked_wrist_tilts_with_the_arm() -> None:
    fast = _timed(1.0)
    locked = food_check(fast, (0.0, 0.0), MODEL, SPEC, "soup_spoon", WATER, "locked")
    # the example path turns the tool base far from level: the locked dish pours
    assert locked.spills and locked.prediction.spilled_g > 4.0


def test_a_spill_makes_the_trajectory_infeasible() -> None:
    heavy = food_load(FOODS["water"], 16.5)
    rep = verify_trajectory(_timed(1.0), MODEL, SPEC, load=heavy)
    assert not rep.feasible and rep.reason == "spill"
    assert rep.food.prediction.spilled_g > 0 and rep.first_failure_time is not None
    assert "predicted to spill" in rep.message


def test_pieces_hold_until_the_repose_slope() -> None:
    pecans = food_load(FOODS["pecans"], 3.0)
    m = spill_model(SPEC, "spoon", pecans)
    onset = math.degrees(float(m.onset_tilt(0.0)))
    assert onset > pecans.repose_deg  # below the rim it must lean past the repose slope
    full = food_load(FOODS["pecans"], m.max_volume * m.density * 1e3 * 0.999)
    assert math.degrees(float(spill_model(SPEC, "spoon", full).onset_tilt(0.0))) < 0.2


@pytest.mark.parametrize("text,match", [
    ("water", "FOOD:GRAMS"), ("water:nan", "FOOD:GRAMS"), (":3", "FOOD:GRAMS")])
def test_malformed_loads(text: str, match: str) -> None:
    with pytest.raises(LoadError, match=match):
        parse_load(text)


def test_loads_that_cannot_be_modelled() -> None:
    with pytest.raises(LoadError, match=r"\[0, 16.79\] g"):
        spill_model(SPEC, "soup_spoon", food_load(FOODS["water"], 17.0))
    with pytest.raises(LoadError, match="≥ 0"):
        food_load(FOODS["water"], -0.1)
    with pytest.raises(LoadError, match="strands"):
        food_load(FOODS["noodles"], 3.0)
    with pytest.raises(LoadError, match="no dish"):
        spill_model(SPEC, "fork", WATER)


def test_the_cli_reports_every_figure_and_refuses_bad_loads(tmp_path: Path) -> None:
    traj = str(EXAMPLES / "transport_feasible.json")
    out = run_cli("verify", traj, "--utensil", "soup_spoon", "--load", "water:8", "--json")
    assert out.returncode == 0, out.stderr
    food = json.loads(out.stdout)["food"]
    assert food["spill_free"] and food["spilled_g"] == 0.0
    assert food["model"]["modes"][1]["frequency_hz"] == pytest.approx(2.96, abs=0.01)
    for load, field in (("soup:3", "--load food"), ("water:-2", "--load grams"),
                        ("water:nan", "--load"), ("water:20", "--load grams"),
                        ("noodles:2", "--load food")):
        assert_refused(run_cli("verify", traj, "--utensil", "soup_spoon", "--load", load),
                       field)
    assert_refused(run_cli("verify", traj, "--utensil", "fork", "--load", "water:2"),
                   "--utensil", "no dish")
    wout = tmp_path / "both.json"
    sf = run_cli("verify", traj, "--utensil", "soup_spoon", "--load", "water:8", "--slosh-free",
                 "--wrist-out", str(wout))
    assert sf.returncode == 0, sf.stderr
    assert len(JointTrajectory.load(wout).joint_names) == 8
