"""FULL_ORIENTATION (``SetOrientationControl`` mode 2): the wrist holds a target utensil
orientation given as a quaternion in a gravity-aligned robot base, in its 50 Hz loop.

The attitude IK (both branches, whole turns) is checked against the forward kinematics; the
closed loop runs the real runtime (filter, controller) on the simulated wrist carried like an
arm transport at the Jaco's joint speed, the error being the ground truth from the simulation:
the angle between the tip's vector that the target holds vertical and the world vertical.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.rotations import matrix_to_quaternion
from articutool.tool.api import Mode
from articutool.tool.drivers.sim import axis_angle_rotation
from articutool.tool.kinematics import (
    attitude_jacobian,
    attitude_solutions,
    leveling_solutions,
    rotation,
    up_vector,
)
from articutool.tool.modes import attitude_target, requested_mode
from conftest import packaged_spec
from test_tool_closed_loop import JACO_MAX_RATE, R0, make, run_loop, transport_motion

SPEC = packaged_spec()
DT = SPEC.wrist.period
Z = np.array([0.0, 0.0, 1.0])
LIMITS = SPEC.wrist.limits


def _xyzw(R: np.ndarray) -> tuple[float, float, float, float]:
    w, x, y, z = matrix_to_quaternion(R)
    return float(x), float(y), float(z), float(w)


def _attitude_error_deg(sim, R_target: np.ndarray) -> float:
    """Ground truth: angle between the world vertical seen from the tip and from the target."""
    R_base, _, _ = sim.base_state()
    seen = (R_base @ rotation(sim.q)).T @ Z
    want = R_target.T @ Z
    return math.degrees(math.acos(float(np.clip(seen @ want, -1.0, 1.0))))


unit = st.tuples(*[st.floats(-1, 1)] * 3).map(np.array).filter(lambda v: np.linalg.norm(v) > 0.1)
joints = st.tuples(st.floats(-1.5, 1.5), st.floats(-3.1, 3.1)).map(np.array)


@settings(max_examples=300, deadline=None)
@given(q=joints, g=unit)
def test_every_attitude_solution_turns_g_onto_v_and_one_is_the_configuration_it_came_from(q, g):
    g = g / np.linalg.norm(g)
    v = rotation(q) @ g
    sols = attitude_solutions(g, v, LIMITS)
    found = sols.q[sols.valid]
    assert len(found) > 0
    for qs in found:
        np.testing.assert_allclose(rotation(qs) @ g, v, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(q=joints)
def test_leveling_is_the_attitude_of_the_tip_up_vector(q):
    v = up_vector(q)
    a, b = leveling_solutions(v, LIMITS), attitude_solutions([0.0, 1.0, 0.0], v, LIMITS)
    np.testing.assert_allclose(a.q[a.valid], b.q[b.valid], atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(q=joints, g=unit)
def test_the_attitude_jacobian_is_the_derivative_of_the_turned_vector(q, g):
    eps = 1e-6
    num = np.stack([(rotation(q + d) @ g - rotation(q - d) @ g) / (2 * eps)
                    for d in (np.array([eps, 0.0]), np.array([0.0, eps]))], axis=-1)
    np.testing.assert_allclose(attitude_jacobian(q, g), num, atol=1e-6)


def test_mode_2_is_full_orientation_and_bad_targets_are_named():
    assert requested_mode(2) is Mode.FULL_ORIENTATION
    np.testing.assert_allclose(attitude_target((0.0, 0.0, 0.0, 2.0)), Z)  # normalised
    for bad in ((0.0, 0.0, 0.0, 0.0), (math.nan, 0.0, 0.0, 1.0), (1.0, 2.0), "x"):
        with pytest.raises(ValueError, match="target_orientation_robot_base"):
            attitude_target(bad)


def test_the_wrist_reaches_the_commanded_orientation_and_holds_it_while_the_base_moves():
    sim, rt = make()
    motion, peak, duration = transport_motion(3.0, 6.0, JACO_MAX_RATE, 0.0)
    sim.set_base_motion(lambda t: motion(t) if t >= 3.0 else (R0, np.zeros(3), np.zeros(3)))
    run_loop(sim, rt, 1.0)  # the filter initialises (DISABLED)
    target = R0 @ rotation([0.3, 0.5])  # a utensil orientation in the (still) base
    assert _attitude_error_deg(sim, target) > 30.0  # far from it at the start
    ok, msg = rt.set_mode(Mode.FULL_ORIENTATION, target_xyzw=_xyzw(target))
    assert ok and "heading" in msg, msg
    run_loop(sim, rt, 2.0)
    assert _attitude_error_deg(sim, target) < 1.5  # reached (deadband 0.86°)
    errors, states = [], []
    for _ in range(round((duration + 1.0) / DT)):
        sim.step(DT)
        states.append(rt.tick(sim.time, DT))
        errors.append(_attitude_error_deg(sim, target))
    ups = np.array([motion(t)[0].T @ Z for t in np.arange(3.0, 3.0 + duration, 0.1)])
    sweep = max(math.degrees(math.acos(np.clip(u @ ups[0], -1, 1))) for u in ups)
    print(f"\nFULL_ORIENTATION under a {peak:.2f} rad/s transport sweeping {sweep:.0f}°: "
          f"max {max(errors):.2f}°, RMS {math.sqrt(np.mean(np.square(errors))):.2f}°")
    assert sweep > 30.0  # the base really moved
    assert all(s.mode is Mode.FULL_ORIENTATION and not s.fault for s in states)
    assert not any(s.extra["leveling_stalled"] for s in states)
    assert max(errors) < 3.0 and errors[-1] < 1.5


def test_an_unreachable_target_is_refused_saying_so_and_nothing_moves():
    sim, rt = make()
    sim.set_base_pose(axis_angle_rotation([1.0, 0.0, 0.0], -math.pi / 2))  # pitch axis up
    run_loop(sim, rt, 1.0)
    q0 = sim.q.copy()
    target = axis_angle_rotation([1.0, 0.0, 0.0], math.pi / 4)  # needs the pitch axis level
    ok, msg = rt.set_mode(Mode.FULL_ORIENTATION, target_xyzw=_xyzw(target))
    assert not ok and "out of reach" in msg and "refused, not clipped" in msg, msg
    assert "nearest reachable attitude is" in msg
    run_loop(sim, rt, 0.5)
    assert rt.mode is Mode.DISABLED and np.allclose(sim.q, q0, atol=1e-6)


def test_full_orientation_keeps_levelings_rules_primitives_refused_stale_imu_faults():
    sim, rt = make()
    sim.set_base_pose(R0)
    run_loop(sim, rt, 1.0)
    ok, msg = rt.set_mode(Mode.FULL_ORIENTATION, target_xyzw=_xyzw(R0 @ rotation([0.2, 0.0])))
    assert ok, msg
    ok, msg = rt.start_primitive("HOMING", [1.0])
    assert not ok and "refused while full orientation" in msg
    run_loop(sim, rt, 0.5)
    sim.set_imu_stale(True)
    st_ = run_loop(sim, rt, 0.2)
    assert st_.mode is Mode.DISABLED and "IMU" in st_.fault
    sim.set_imu_stale(False)
    run_loop(sim, rt, 0.2)
    ok, msg = rt.set_mode(Mode.DISABLED)
    assert ok and rt.mode is Mode.DISABLED


def test_a_base_motion_taking_the_target_out_of_reach_clips_it_and_reports_the_stall():
    """Rolling the base until the pitch axis is vertical leaves no configuration that holds
    this target (its vertical has a component along the tip's roll axis): the wrist comes to
    rest at the nearest reachable attitude, without chatter or fault, and says it stalled."""
    sim, rt = make()

    def motion(t):  # the base rolls −90° about world x between t = 3 and 6 s
        s = min(max((t - 3.0) / 3.0, 0.0), 1.0)
        rate = -math.pi / 2 * math.pi / 6 * math.sin(math.pi * s) if 0 < s < 1 else 0.0
        angle = -math.pi / 2 * (1 - math.cos(math.pi * s)) / 2
        return axis_angle_rotation([1.0, 0.0, 0.0], angle) @ R0, np.array([rate, 0, 0]), \
            np.zeros(3)
    sim.set_base_motion(motion)
    run_loop(sim, rt, 1.0)
    target = R0 @ rotation([0.3, 0.5])
    assert rt.set_mode(Mode.FULL_ORIENTATION, target_xyzw=_xyzw(target))[0]
    run_loop(sim, rt, 8.0)
    states = []
    for _ in range(round(2.0 / DT)):
        sim.step(DT)
        states.append(rt.tick(sim.time, DT))
    g = target.T @ Z  # the best any configuration can do: |v_y| = 1 > ρ = |g_xy| in F0
    best = math.degrees(math.pi / 2 - math.asin(math.hypot(g[0], g[1])))
    assert _attitude_error_deg(sim, target) == pytest.approx(best, abs=0.5)
    assert all(s.mode is Mode.FULL_ORIENTATION and not s.fault for s in states)
    assert states[-1].extra["leveling_stalled"] == 1.0
    commands = np.array([[s.extra["command_pitch"], s.extra["command_roll"]] for s in states])
    assert np.abs(commands).max() < 0.05  # at rest: no chatter


def test_an_unreachable_target_is_refused_without_scipy(monkeypatch):
    """The tool's core install (the Pi) has no SciPy: refusing an unreachable target needs
    only NumPy (the nearest reachable attitude in closed form over the roll)."""
    import sys

    monkeypatch.setitem(sys.modules, "scipy", None)
    monkeypatch.setitem(sys.modules, "scipy.optimize", None)
    sim, rt = make()
    sim.set_base_pose(axis_angle_rotation([1.0, 0.0, 0.0], -math.pi / 2))  # pitch axis up
    run_loop(sim, rt, 1.0)
    target = axis_angle_rotation([1.0, 0.0, 0.0], math.pi / 4)  # needs the pitch axis level
    ok, msg = rt.set_mode(Mode.FULL_ORIENTATION, target_xyzw=_xyzw(target))
    assert not ok and "nearest reachable attitude is" in msg, msg


@pytest.mark.parametrize("q, g", [
    ((0.0, 0.0), (1.0, 1.96e-9, 0.0)),        # v_y a hair inside ρ: arcsin lost half the digits
    ((0.0, 2.3733680406119793e-08), (1.0, 0.0, 0.0)),  # |v_xz| tiny: ρ² − v_y² lost them all
])
def test_an_attitude_at_the_edge_of_the_roll_circle_keeps_its_digits(q, g):
    g = np.asarray(g) / np.linalg.norm(g)
    v = rotation(np.asarray(q)) @ g
    sols = attitude_solutions(g, v, LIMITS)
    for qs in sols.q[sols.valid]:
        np.testing.assert_allclose(rotation(qs) @ g, v, atol=1e-12)
