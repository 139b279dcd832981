"""Food primitives (thesis §4.4; docs/hardware.md §6) run closed-loop against a simple wrist."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.tool.api import PrimitiveStatus
from articutool.tool.kinematics import rotation, up_vector, wrap_angle
from articutool.tool.primitive_base import Primitive, PrimitiveError
from articutool.tool.primitives import (
    make_primitive,
    primitive_names,
    register_primitive,
    unregister_primitive,
)
from conftest import packaged_spec

SPEC = packaged_spec()
DT = SPEC.wrist.period
VMAX = SPEC.wrist.velocity_limits
TOL = SPEC.primitives.position_tolerance
PITCH_LO, PITCH_HI = SPEC.wrist.pitch_limits
BUDGET = SPEC.wrist.roll_turn_budget * 2 * math.pi
TWO_PI = 2 * math.pi


class Plant:
    """Motors with a first-order lag, velocity-limited at the motors' physical limit."""

    def __init__(self, q0, lag: float = 0.0, substeps: int = 5) -> None:
        self.q = np.array(q0, dtype=float)
        self.v = np.zeros(2)
        self.lag, self.n = lag, substeps

    def step(self, cmd: np.ndarray, dt: float) -> None:
        h = dt / self.n
        a = 1.0 - math.exp(-h / self.lag) if self.lag > 0 else 1.0
        cmd = np.clip(cmd, -SPEC.wrist.motor_max_velocity, SPEC.wrist.motor_max_velocity)
        for _ in range(self.n):
            self.v = self.v + a * (cmd - self.v)
            self.q = self.q + self.v * h


class Run:
    """Outcome of running a primitive to completion."""

    def __init__(self, prim, plant, qs, cmds, pct, feedback):
        self.prim, self.plant = prim, plant
        self.qs, self.cmds, self.pct, self.feedback = (
            np.array(qs),
            np.array(cmds),
            np.array(pct),
            feedback,
        )


def run(name, params, q0=(0.0, 0.0), lag=0.0, measure=lambda q: q, on_tick=None):
    prim = make_primitive(name, params, SPEC, q0)
    plant = Plant(q0, lag)
    qs, cmds, pct, fb = [plant.q.copy()], [], [prim.percent_complete], []
    for k in range(int(prim.timeout / DT) + 5):  # it must end by itself (success or timeout)
        if on_tick is not None:
            on_tick(k, prim)
        cmd = prim.step(measure(plant.q.copy()), DT)
        cmds.append(cmd)
        plant.step(cmd, DT)
        qs.append(plant.q.copy())
        pct.append(prim.percent_complete)
        fb.append(prim.feedback)
        if prim.done:
            break
    assert prim.done, "primitive did not finish"
    return Run(prim, plant, qs, cmds, pct, fb)


def assert_well_behaved(r: Run, success: bool = True) -> None:
    assert np.isfinite(r.cmds).all()
    assert (np.abs(r.cmds) <= VMAX + 1e-12).all()
    assert (r.qs[:, 0] >= PITCH_LO - 1e-9).all() and (r.qs[:, 0] <= PITCH_HI + 1e-9).all()
    assert (np.abs(r.qs[:, 1]) <= BUDGET + 1e-9).all()
    assert (np.diff(r.pct) >= 0).all() and r.pct[0] == 0.0
    ok, _, final = r.prim.result()
    assert ok is success
    if success:
        assert r.pct[-1] == 100.0 and (r.pct[:-1] < 100.0).all()
    np.testing.assert_allclose(final, r.qs[-2], atol=1e-12)  # the last measured joints
    assert all(isinstance(f, str) and f for f in r.feedback)
    np.testing.assert_array_equal(r.prim.step(r.plant.q, DT), [0.0, 0.0])  # done: zero after


LAGS = [0.0, 0.05]


# ------------------------------------------------------------------ end states --
@pytest.mark.parametrize("lag", LAGS)
@pytest.mark.parametrize(
    ("name", "sign", "rotations", "speed", "q0"),
    [
        ("TWIRL_CW", 1, 2.0, 3.0, (0.0, 0.0)),
        ("TWIRL_CCW", -1, 1.5, 2.0, (0.2, 0.4)),
        ("TWIRL_CW", 1, 0.25, 0.5, (-0.3, -6.0)),
    ],
)
def test_twirl_travels_exactly_the_requested_turns(lag, name, sign, rotations, speed, q0):
    r = run(name, [rotations, speed], q0, lag)
    assert_well_behaved(r)
    travel = r.qs[-1, 1] - q0[1]
    assert travel == pytest.approx(sign * TWO_PI * rotations, abs=2 * TOL)
    assert np.abs(r.cmds[:, 1]).max() == pytest.approx(speed)  # at the requested speed
    assert np.abs(r.qs[:, 0] - q0[0]).max() < TOL  # pitch untouched
    assert f"{sign * travel / TWO_PI:.2f} turns" in r.prim.result()[1]


def test_twirl_integrates_a_wrapped_roll_reading():
    """A driver reporting roll wrapped to (−π, π] still gets the full number of turns."""
    r = run(
        "TWIRL_CCW", [2.5, 4.0], (0.0, 0.5), measure=lambda q: np.array([q[0], wrap_angle(q[1])])
    )
    assert r.qs[-1, 1] - 0.5 == pytest.approx(-TWO_PI * 2.5, abs=2 * TOL)


@pytest.mark.parametrize("lag", LAGS)
def test_vibrate_oscillates_at_the_amplitude_and_returns_to_the_start_roll(lag):
    f, a, duration, q0 = 4.0, 0.12, 1.5, (0.1, -0.7)
    r = run("VIBRATE_ROLL", [f, a, duration], q0, lag)
    assert_well_behaved(r)
    assert abs(r.qs[-1, 1] - q0[1]) <= 2 * TOL
    dev = r.qs[:, 1] - q0[1]
    assert np.abs(r.cmds[:, 1]).max() <= a * TWO_PI * f + 1e-9
    if lag == 0.0:  # the ideal plant follows A·sin(2πft) exactly at the ticks
        n = int(duration / DT)
        t = np.arange(n + 1) * DT
        np.testing.assert_allclose(dev[: n + 1], a * np.sin(TWO_PI * f * t), atol=1e-9)
    else:  # a lagging motor still shakes, with a smaller amplitude
        assert 0.3 * a < np.abs(dev).max() <= a + TOL
    assert np.abs(r.qs[:, 0] - q0[0]).max() < TOL


@pytest.mark.parametrize("lag", LAGS)
@pytest.mark.parametrize("target", [0.8, -1.2])
def test_tilt_reaches_target_holds_then_returns(lag, target):
    velocity, hold, q0 = 1.0, 1.0, (0.05, 0.3)
    r = run("TILT", [target, velocity, hold], q0, lag)
    assert_well_behaved(r)
    at_target = np.abs(r.qs[:, 1] - (q0[1] + target)) <= 2 * TOL
    assert at_target.sum() * DT >= hold  # held for at least the hold time
    assert abs(r.qs[-1, 1] - q0[1]) <= 2 * TOL  # back to the start (level) roll
    assert np.abs(r.cmds[:, 1]).max() == pytest.approx(velocity)
    first, last = np.flatnonzero(at_target)[[0, -1]]
    assert at_target[first : last + 1].all()  # one contiguous hold, no bouncing


@pytest.mark.parametrize("lag", LAGS)
@pytest.mark.parametrize("q0", [(0.2, 0.3), (-0.4, 2.8)])
def test_noodle_shed_pitches_up_vibrates_and_returns(lag, q0):
    up_deg, pitch_speed, delay, f, a_deg, vib = 30.0, 1.5, 0.4, 5.0, 4.0, 0.8
    r = run("NOODLE_SHED", [up_deg, pitch_speed, delay, f, a_deg, vib], q0, lag)
    assert_well_behaved(r)
    # Pitched by 30°, in the direction that raises the utensil tip towards the tool's up.
    i = np.argmax(np.abs(r.qs[:, 0] - q0[0]))
    assert abs(r.qs[i, 0] - q0[0]) == pytest.approx(math.radians(up_deg), abs=3 * TOL)
    # tip · up(q0) = cos θr0 · sin(p0 − p): pitch can tilt the tip out of the level plane
    # only by |cos θr0| of the angle; "up" must make it positive.
    tip_rise = rotation(r.qs[i])[:, 2] @ up_vector(q0)
    expected = abs(math.cos(q0[1])) * math.sin(math.radians(up_deg))
    assert tip_rise == pytest.approx(expected, abs=0.02) and tip_rise > 0
    # Roll vibrated while pitched up, then everything back at the start.
    pitched = np.abs(r.qs[:, 0] - r.qs[i, 0]) < 2 * TOL
    assert np.abs(r.qs[pitched, 1] - q0[1]).max() > 0.3 * math.radians(a_deg)
    np.testing.assert_allclose(r.qs[-1], q0, atol=2 * TOL)
    assert np.abs(r.cmds[:, 0]).max() == pytest.approx(pitch_speed)


@pytest.mark.parametrize("lag", LAGS)
@pytest.mark.parametrize("angle_deg", [40.0, -65.0])
def test_deposit_bite_rolls_by_degrees_pauses_then_returns_to_the_start(lag, angle_deg):
    speed, pause, q0 = 1.5, 0.6, (0.1, 2 * math.pi + 0.2)  # after a twirl: returns to the start
    r = run("DEPOSIT_BITE", [angle_deg, speed, pause], q0, lag)
    assert_well_behaved(r)
    out = np.abs(r.qs[:, 1] - (q0[1] + math.radians(angle_deg))) <= 2 * TOL
    assert out.sum() * DT >= pause  # paused there for at least the pause
    np.testing.assert_allclose(r.qs[-1], q0, atol=2 * TOL)  # back to the start, not to 0
    assert np.abs(r.cmds[:, 1]).max() == pytest.approx(speed)


@pytest.mark.parametrize("lag", LAGS)
@pytest.mark.parametrize("q0", [(0.2, 0.3), (-0.3, 2.9)])
def test_settle_toss_tilts_the_tip_up_flicks_past_the_start_and_returns(lag, q0):
    tilt_deg, tilt_speed, flick_speed = 25.0, 1.0, 3.0
    r = run("SETTLE_TOSS", [tilt_deg, tilt_speed, flick_speed], q0, lag)
    assert_well_behaved(r)
    i = int(np.argmax(np.abs(r.qs[:, 0] - q0[0])))
    assert abs(r.qs[i, 0] - q0[0]) == pytest.approx(math.radians(tilt_deg), abs=3 * TOL)
    assert rotation(r.qs[i])[:, 2] @ up_vector(q0) > 0  # the tip went up
    sign = math.copysign(1.0, r.qs[i, 0] - q0[0])
    past = -sign * (r.qs[i:, 0] - q0[0])  # beyond the start on the flick side
    assert past.max() >= SPEC.primitives.settle_toss_overshoot_rad - TOL
    assert np.abs(r.cmds[:, 0]).max() == pytest.approx(flick_speed)  # the flick at full speed
    np.testing.assert_allclose(r.qs[-1], q0, atol=2 * TOL)
    assert np.abs(r.qs[:, 1] - q0[1]).max() < 2 * TOL  # roll held throughout


def test_settle_toss_whose_flick_would_pass_the_pitch_limit_is_refused():
    q0 = (PITCH_HI - 0.05, 0.0)  # the flick goes +pitch at roll 0: no room past the start
    with pytest.raises(PrimitiveError, match="settle_toss_overshoot_rad"):
        make_primitive("SETTLE_TOSS", [10.0, 1.0, 2.0], SPEC, q0)


@pytest.mark.parametrize("lag", LAGS)
@pytest.mark.parametrize("q0", [(0.7, -9.0), (-1.2, 2.0), (0.0, 0.0)])
def test_homing_brings_both_joints_to_zero(lag, q0):
    r = run("HOMING", [2.0], q0, lag)
    assert_well_behaved(r)
    np.testing.assert_allclose(r.qs[-1], [0.0, 0.0], atol=2 * TOL)


def test_status_reports_feedback_and_result():
    prim = make_primitive("TWIRL_CW", [1.0, 2.0], SPEC, [0.0, 0.0])
    plant = Plant([0.0, 0.0])
    for _ in range(40):
        plant.step(prim.step(plant.q, DT), DT)
    s = prim.status()
    assert isinstance(s, PrimitiveStatus) and s.name == "TWIRL_CW" and not s.done
    assert 0 < s.percent_complete < 100 and "turns" in s.feedback
    assert s.final_joint_values == ()
    with pytest.raises(RuntimeError, match="still running"):
        prim.result()


# ----------------------------------------------------------- cancel / timeout --
def test_cancel_stops_with_failure_and_zero_commands():
    def cancel_at(k, prim):
        if k == 30:
            assert prim.cancel() is True

    r = run("TILT", [1.0, 1.0, 2.0], (0.0, 0.0), on_tick=cancel_at)
    assert_well_behaved(r, success=False)
    ok, msg, _ = r.prim.result()
    assert (ok, msg) == (False, "cancelled")
    assert r.pct[-1] < 100.0
    assert r.prim.cancel() is False  # already done
    assert len(r.cmds) == 31 and (r.cmds[-1] == 0).all()


def test_a_stalled_joint_times_out_and_stops():
    prim = make_primitive("TWIRL_CW", [1.0, 2.0], SPEC, [0.0, 0.0])
    cmds = []
    for _ in range(int(3 * prim.timeout / DT)):
        cmds.append(prim.step([0.0, 0.0], DT))  # the roll never moves
        if prim.done:
            break
    ok, msg, _ = prim.result()
    assert not ok and "timed out" in msg and "twirl" in msg
    assert prim.elapsed == pytest.approx(prim.timeout, abs=2 * DT)
    np.testing.assert_array_equal(prim.step([0.0, 0.0], DT), [0.0, 0.0])


@pytest.mark.parametrize(("q", "dt"), [((math.nan, 0.0), DT), ((0.0, 0.0), 0.0), ((0.0,), DT)])
def test_bad_step_input_is_a_value_error(q, dt):
    prim = make_primitive("HOMING", [1.0], SPEC, [0.5, 0.5])
    with pytest.raises(ValueError):
        prim.step(q, dt)
    assert not prim.done and prim.percent_complete == 0.0


# -------------------------------------------------------------------- budgets --
def test_twirl_beyond_the_cable_budget_is_refused_with_the_numbers():
    net = 1.5
    with pytest.raises(PrimitiveError) as e:
        make_primitive("TWIRL_CW", [2.0, 2.0], SPEC, [0.0, net * TWO_PI])
    msg = str(e.value)
    assert "rotations" in msg and "+1.50 turns" in msg and "+3.50 turns" in msg
    assert f"±{SPEC.wrist.roll_turn_budget:g} turns" in msg
    # The other way, and exactly up to the budget, is fine.
    make_primitive("TWIRL_CCW", [4.0, 2.0], SPEC, [0.0, net * TWO_PI])
    r = run("TWIRL_CW", [SPEC.wrist.roll_turn_budget - net, 4.0], (0.0, net * TWO_PI))
    assert r.prim.result()[0] and r.qs[:, 1].max() <= BUDGET + 1e-9


def test_vibration_and_tilt_beyond_the_budget_are_refused():
    edge = (0.0, BUDGET - 0.05)
    with pytest.raises(PrimitiveError, match=r"amplitude_rad.*cable budget"):
        make_primitive("VIBRATE_ROLL", [2.0, 0.1, 1.0], SPEC, edge)
    with pytest.raises(PrimitiveError, match=r"target_roll_rad.*cable budget"):
        make_primitive("TILT", [0.5, 1.0, 0.0], SPEC, edge)
    make_primitive("TILT", [-0.5, 1.0, 0.0], SPEC, edge)


@register_primitive
class _PushRoll(Primitive):
    """Test-only: push both joints outwards at a constant speed for ``duration_s``."""

    name = "TEST_PUSH"
    parameter_names = ("speed_rad_s", "duration_s")

    def _plan(self, speed, duration):
        from articutool.tool.phases import Phase

        class Push(Phase):
            def step(self, prim, t, q, dt):
                return np.array([speed, speed]), min(t / duration, 1.0), t >= duration

        return [Push("push", self.q_start, [speed, speed], duration)]


def test_step_never_commands_past_the_pitch_limit_or_the_roll_budget():
    """Even a primitive that asks for it cannot push a joint past its bound."""
    q0 = (PITCH_HI - 0.3, BUDGET - 0.3)
    r = run("TEST_PUSH", [4.0, 1.0], q0)
    assert r.qs[:, 0].max() == pytest.approx(PITCH_HI, abs=1e-12)
    assert r.qs[:, 1].max() == pytest.approx(BUDGET, abs=1e-12)
    assert (r.qs[:, 0] <= PITCH_HI + 1e-12).all() and (r.qs[:, 1] <= BUDGET + 1e-12).all()


def test_noodle_shed_beyond_the_pitch_limit_is_refused():
    q0 = (PITCH_LO + math.radians(20), 0.0)  # only 20° of room to pitch up
    with pytest.raises(PrimitiveError, match=r"pitch_up_deg.*\(0, 20\]"):
        make_primitive("NOODLE_SHED", [25, 1, 0, 5, 5, 1], SPEC, q0)
    make_primitive("NOODLE_SHED", [19, 1, 0, 5, 5, 1], SPEC, q0)


# ------------------------------------------------------------------- registry --
def test_registry_lists_the_thesis_primitives_and_unknown_names_list_them():
    for name in ("TWIRL_CW", "TWIRL_CCW", "VIBRATE_ROLL", "TILT", "NOODLE_SHED", "HOMING"):
        assert name in primitive_names()
    # the upstream tool's whole registry (articutool_control/orientation_control.py)
    upstream = {"TWIRL_CW", "TWIRL_CCW", "VIBRATE_ROLL", "DEPOSIT_BITE", "SETTLE_TOSS",
                "NOODLE_SHED", "HOMING"}
    assert upstream <= set(primitive_names())
    with pytest.raises(PrimitiveError, match=r"unknown primitive 'SPIN'.*HOMING.*TWIRL_CW"):
        make_primitive("SPIN", [1.0], SPEC, [0.0, 0.0])


def test_a_new_primitive_is_one_registered_class():
    @register_primitive
    class WigglePitch(Primitive):
        """Pitch to +angle and back."""

        name = "TEST_WIGGLE_PITCH"
        parameter_names: ClassVar = ("angle_rad", "speed_rad_s")

        def _plan(self, angle, speed):
            self._speed("speed_rad_s", speed, 0)
            out = self.q_start + [angle, 0.0]
            return [
                self.move("out", self.q_start, out, speed),
                self.move("back", out, self.q_start, speed),
            ]

    try:
        r = run("TEST_WIGGLE_PITCH", [0.4, 1.0], (0.1, 0.2))
        assert_well_behaved(r)
        assert r.qs[:, 0].max() == pytest.approx(0.5, abs=2 * TOL)
        np.testing.assert_allclose(r.qs[-1], (0.1, 0.2), atol=2 * TOL)
        with pytest.raises(PrimitiveError, match="'speed_rad_s' must be in \\(0, 4\\]"):
            make_primitive("TEST_WIGGLE_PITCH", [0.4, 9.0], SPEC, (0.0, 0.0))

        class Clash(WigglePitch):
            pass

        with pytest.raises(ValueError, match="already registered"):
            register_primitive(Clash)
    finally:
        unregister_primitive("TEST_WIGGLE_PITCH")
    assert "TEST_WIGGLE_PITCH" not in primitive_names()


# ----------------------------------------------------------------- validation --
GOOD = {
    "TWIRL_CW": [1.0, 2.0],
    "TWIRL_CCW": [1.0, 2.0],
    "VIBRATE_ROLL": [5.0, 0.05, 1.0],
    "TILT": [0.5, 1.0, 1.0],
    "NOODLE_SHED": [30.0, 1.0, 0.5, 5.0, 5.0, 1.0],
    "HOMING": [1.0],
    "DEPOSIT_BITE": [45.0, 1.0, 0.5],
    "SETTLE_TOSS": [20.0, 1.0, 3.0],
}
# Per parameter: values that must be refused (beyond the NaN/inf every parameter refuses).
V_ROLL, V_MIN = float(VMAX[1]), float(VMAX.min())
P_MAX_HOLD = SPEC.primitives.max_hold_s
BAD = {
    "TWIRL_CW": {"rotations": [0.0, -1.0], "speed_rad_s": [0.0, -1.0, V_ROLL * 1.01]},
    "TWIRL_CCW": {"rotations": [0.0, -2.0], "speed_rad_s": [0.0, V_ROLL + 1]},
    "VIBRATE_ROLL": {
        "frequency_hz": [0.0, -5.0, SPEC.wrist.loop_rate_hz / 2],
        "amplitude_rad": [0.0, -0.1, 0.2],  # 0.2 rad at 5 Hz is 6.3 rad/s peak
        "duration_s": [-0.1],
    },
    "TILT": {
        "target_roll_rad": [4.0, -4.0],
        "velocity_rad_s": [0.0, -1.0, V_ROLL * 2],
        "hold_s": [-1.0],
    },
    "NOODLE_SHED": {
        "pitch_up_deg": [0.0, -10.0, 95.0],
        "pitch_speed_rad_s": [0.0, float(VMAX[0]) + 0.5],
        "delay_s": [-0.5],
        "vibrate_frequency_hz": [0.0, -1.0, 30.0],
        "vibrate_amplitude_deg": [0.0, -3.0, 20.0],  # 20° at 5 Hz ≈ 11 rad/s peak
        "vibrate_duration_s": [-1.0],
    },
    "HOMING": {"speed_rad_s": [0.0, -1.0, V_MIN + 0.1]},
    "DEPOSIT_BITE": {
        "roll_angle_deg": [181.0, -200.0],
        "roll_speed_rad_s": [0.0, -1.0, V_ROLL * 2],
        "pause_s": [-1.0, P_MAX_HOLD + 1],
    },
    "SETTLE_TOSS": {
        "tilt_angle_deg": [0.0, -10.0, 95.0],
        "tilt_speed_rad_s": [0.0, -1.0, float(VMAX[0]) + 0.5],
        "flick_speed_rad_s": [0.0, float(VMAX[0]) + 0.5],
    },
}


@st.composite
def bad_requests(draw):
    name = draw(st.sampled_from(sorted(GOOD)))
    params = list(GOOD[name])
    cls_names = list(BAD[name])
    i = draw(st.integers(0, len(params) - 1))
    pname = cls_names[i]
    bad = draw(st.sampled_from([math.nan, math.inf, -math.inf, *BAD[name][pname]]))
    params[i] = bad
    return name, params, pname


@settings(max_examples=150, deadline=None)
@given(bad_requests())
def test_bad_parameters_are_refused_naming_the_parameter(req):
    name, params, pname = req
    with pytest.raises(PrimitiveError, match=f"'{pname}'") as e:
        make_primitive(name, params, SPEC, (0.0, 0.0))
    msg = str(e.value)
    assert name in msg and ("must be" in msg or "above" in msg)


@settings(max_examples=60, deadline=None)
@given(st.sampled_from(sorted(GOOD)), st.integers(0, 8))
def test_wrong_parameter_count_is_refused(name, n):
    if n == len(GOOD[name]):
        n += 1
    with pytest.raises(PrimitiveError, match=f"takes {len(GOOD[name])} parameter"):
        make_primitive(name, [1.0] * n, SPEC, (0.0, 0.0))


def test_non_numeric_parameters_and_start_are_refused():
    with pytest.raises(PrimitiveError, match="must be numbers"):
        make_primitive("HOMING", ["fast"], SPEC, (0.0, 0.0))
    with pytest.raises(PrimitiveError, match="q_start"):
        make_primitive("HOMING", [1.0], SPEC, (0.0, math.nan))


@settings(max_examples=25, deadline=None)
@given(
    st.sampled_from(sorted(GOOD)),
    st.lists(st.floats(0.05, 3.0), min_size=6, max_size=6),
    st.tuples(st.floats(-1.4, 1.4), st.floats(-12.0, 12.0)),
)
def test_any_accepted_request_runs_safely_to_completion(name, raw, q0):
    """Random parameters: refused cleanly, or run to success within every limit."""
    params = raw[: len(GOOD[name])]
    try:
        make_primitive(name, params, SPEC, q0)
    except PrimitiveError:
        return
    r = run(name, params, q0, lag=0.03)
    assert np.isfinite(r.cmds).all() and (np.abs(r.cmds) <= VMAX + 1e-12).all()
    assert (np.diff(r.pct) >= 0).all()
    assert r.prim.result()[0], r.prim.result()[1]
    assert (np.abs(r.qs[:, 1]) <= max(BUDGET, abs(q0[1])) + 0.05).all()


# -------------------------------------------------------------- bounded primitives --
P = SPEC.primitives


@pytest.mark.parametrize(("name", "params", "pname", "key"), [
    ("VIBRATE_ROLL", [5.0, 0.1, 1e9], "duration_s", "max_vibrate_s"),
    ("TILT", [0.5, 1.0, 1e9], "hold_s", "max_hold_s"),
    ("DEPOSIT_BITE", [30.0, 1.0, 1e9], "pause_s", "max_hold_s"),
    ("NOODLE_SHED", [20.0, 1.0, 1e9, 5.0, 3.0, 1.0], "delay_s", "max_hold_s"),
    ("NOODLE_SHED", [20.0, 1.0, 1.0, 5.0, 3.0, 1e9], "vibrate_duration_s", "max_vibrate_s"),
])
def test_waits_and_vibrations_are_bounded_by_the_spec(name, params, pname, key):
    """A primitive that runs for ever would keep the tool moving after the PC is gone (the
    default link-loss policy lets a primitive finish): each duration has a maximum."""
    limit = getattr(P, key)
    with pytest.raises(PrimitiveError, match=f"'{pname}'") as e:
        make_primitive(name, params, SPEC, (0.0, 0.0))
    assert f"[0, {limit:g}] s" in str(e.value) and f"spec.primitives.{key}" in str(e.value)
    i = params.index(1e9)
    params[i] = limit  # the maximum itself is allowed
    make_primitive(name, params, SPEC, (0.0, 0.0))


@pytest.mark.parametrize(("name", "params", "pname"), [
    ("TWIRL_CW", [2.0, 1e-6], "speed_rad_s"),
    ("TILT", [1.0, 1e-6, 0.0], "velocity_rad_s"),
    ("HOMING", [1e-7], "speed_rad_s"),
    ("NOODLE_SHED", [20.0, 1e-7, 1.0, 5.0, 3.0, 1.0], "pitch_speed_rad_s"),
])
def test_slow_speeds_cannot_stretch_a_primitive_beyond_its_maximum_duration(name, params, pname):
    with pytest.raises(PrimitiveError, match=f"'{pname}'") as e:
        make_primitive(name, params, SPEC, (0.5, 2.0))
    msg = str(e.value)
    assert "spec.primitives.max_duration_s" in msg and f"{P.max_duration_s:g} s" in msg


def test_every_accepted_primitive_stops_within_its_bounded_timeout():
    """The longest primitive the spec allows still ends: its timeout is finite and bounded."""
    longest = make_primitive("NOODLE_SHED", [20.0, 1.0, P.max_hold_s, 5.0, 3.0,
                                             P.max_vibrate_s], SPEC, (0.0, 0.0))
    bound = P.timeout_factor * P.max_duration_s + P.timeout_margin_s
    assert longest.timeout <= bound
