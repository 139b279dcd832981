"""The tool runtime on the simulated wrist: mode rules, faults, trajectories, statistics,
threads and the ``articutool tool`` command.

The simulation and the loop are stepped alternately (``sim.step(DT)``, ``rt.tick(sim.time,
DT)``), so everything but the real-time tests runs faster than real time.
"""

from __future__ import annotations

import io
import logging
import math
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from articutool.onboard import format_status, main, real_time_clock, run_tool
from articutool.tool.api import Mode, ToolAPI
from articutool.tool.drivers.base import DriverError, HardwareError, ImuSample
from articutool.tool.drivers.sim import (
    SimImuDriver,
    SimMotorDriver,
    SimWrist,
    axis_angle_rotation,
)
from articutool.tool.runtime import ToolRuntime
from articutool.trajectory import JointTrajectory
from articutool.verify.verifier import verify_trajectory
from conftest import packaged_spec

SPEC = packaged_spec()
DT = SPEC.wrist.period
PITCH, ROLL = SPEC.wrist.joint_names
R0 = axis_angle_rotation([0.0, 1.0, 0.0], -math.pi / 2)  # F0 +x (up at q = 0) along world z


class SpyMotors(SimMotorDriver):
    """The simulated motors, recording commands; ``fail_reads`` makes ``read`` raise."""

    def __init__(self, sim: SimWrist) -> None:
        super().__init__(sim)
        self.commands: list[np.ndarray] = []
        self.stops = 0
        self.reboots = 0
        self.fail_reads = False

    def set_velocity(self, qd) -> None:
        super().set_velocity(qd)
        self.commands.append(np.asarray(qd, dtype=float).copy())

    def stop(self) -> None:
        super().stop()
        self.stops += 1

    def clear_errors(self) -> None:
        super().clear_errors()
        self.reboots += 1

    def read(self):
        if self.fail_reads:
            raise DriverError("no status packet from ID 2")
        return super().read()


def make(spec=SPEC, q0=(0.0, 0.0), base=R0, **kw):
    sim = SimWrist(SPEC, q0=q0, seed=3, gyro_bias=(0.01, -0.01, 0.005))
    sim.set_base_pose(base)
    motors = SpyMotors(sim)
    rt = ToolRuntime(spec, motors, sim.imu_driver(), sim.ft_driver(), clock=sim.clock, **kw)
    rt.open()
    return sim, rt, motors


def run(sim, rt, seconds):
    for _ in range(round(seconds / DT)):
        sim.step(DT)
        rt.tick(sim.time, DT)
    return rt.state()


def ready(**kw):
    """A runtime that has run 0.5 s in DISABLED (filter initialised, joints known)."""
    sim, rt, motors = make(**kw)
    run(sim, rt, 0.5)
    return sim, rt, motors


def assert_stopped(sim, rt, motors):
    """Safe state: DISABLED, the last motor write a stop, and the joints come to rest."""
    assert rt.mode is Mode.DISABLED
    n = len(motors.commands)
    stops = motors.stops
    q = sim.q
    run(sim, rt, 0.3)
    assert len(motors.commands) == n  # no velocity command since the fault
    assert motors.stops > stops  # the motors are told to stop every tick
    assert np.abs(sim.qd).max() < 1e-3  # at rest (the motor lag decays as exp(-t/30 ms))
    return q


# ------------------------------------------------------------------------ protocol --
def test_runtime_implements_the_tool_api():
    """Every ToolAPI method, called on the runtime driving the simulated wrist, does what the
    protocol says: observable in the joints, the mode, the fault and the telemetry."""
    api_methods = {n for n in vars(ToolAPI) if not n.startswith("_")}
    covered = set()
    sim, rt, motors = ready(base=axis_angle_rotation([1.0, 0.0, 0.0], 0.4) @ R0)
    api: ToolAPI = rt

    st0 = api.state()  # state: a fresh snapshot of the real joints at each tick
    covered.add("state")
    assert st0.mode is Mode.DISABLED and st0.joint_names == (PITCH, ROLL) and st0.fault == ""
    np.testing.assert_allclose(st0.position, sim.q, atol=1e-9)
    assert run(sim, rt, 0.1).stamp == pytest.approx(st0.stamp + 0.1)

    assert api.set_mode(Mode.LEVELING)[0]  # set_mode: LEVELING levels the tilted tool...
    covered.add("set_mode")
    tilt0 = sim.tilt_error()
    assert run(sim, rt, 1.5).mode is Mode.LEVELING
    assert math.degrees(tilt0) > 20.0 and math.degrees(sim.tilt_error()) < 1.5
    assert api.set_mode(Mode.DISABLED)[0]  # ...and DISABLED stops the motors
    assert_stopped(sim, rt, motors)

    assert api.primitive_status() is None  # primitive_status: None before any primitive
    covered.add("primitive_status")
    q = sim.q
    assert api.start_primitive("TILT", [0.5, 1.0, 2.0])[0]  # start_primitive: the roll tilts
    covered.add("start_primitive")
    run(sim, rt, 0.6)
    status = api.primitive_status()
    assert api.state().mode is Mode.PRIMITIVE and status.name == "TILT" and not status.done
    assert 0.0 < status.percent_complete < 100.0 and sim.q[1] - q[1] > 0.4
    assert api.cancel_primitive()  # cancel_primitive: stops it, with a failed result
    covered.add("cancel_primitive")
    status = api.primitive_status()
    assert status.done and not status.success and status.message == "cancelled"
    assert_stopped(sim, rt, motors)
    assert not api.cancel_primitive()

    q = sim.q
    traj = JointTrajectory((PITCH, ROLL), np.array([0.0, 1.0]), np.array([q, q + [0.2, -0.3]]),
                           np.zeros((2, 2)))
    assert api.follow_trajectory(traj)[0]  # follow_trajectory: the joints follow it
    covered.add("follow_trajectory")
    st = run(sim, rt, 1.5)
    assert st.mode is Mode.TRAJECTORY
    np.testing.assert_allclose(st.position, q + [0.2, -0.3], atol=0.01)

    assert api.clear_fault() == (False, "no fault to clear")  # clear_fault: reboots on request
    covered.add("clear_fault")
    sim.set_hardware_error("pitch", HardwareError.OVERLOAD)
    assert "OVERLOAD" in run(sim, rt, DT).fault
    assert api.clear_fault()[0] and motors.reboots == 0
    run(sim, rt, DT)
    assert motors.reboots == 1 and api.set_mode(Mode.DISABLED)[0] and api.state().fault == ""

    assert covered == api_methods  # a new ToolAPI method needs its behaviour checked here


def test_nothing_is_allowed_before_the_first_tick():
    _, rt, motors = make()
    assert rt.set_mode(Mode.LEVELING)[0] is False
    ok, msg = rt.start_primitive("HOMING", [1.0])
    assert not ok and "joint state" in msg
    assert not motors.commands


# ---------------------------------------------------------------------- mode rules --
def test_leveling_levels_a_tilted_tool_and_holds_offsets():
    base = axis_angle_rotation([1.0, 0.3, 0.0], 0.4) @ R0
    sim, rt, _ = ready(base=base)
    assert math.degrees(sim.tilt_error()) > 15
    ok, msg = rt.set_mode(Mode.LEVELING)
    assert ok, msg
    st = run(sim, rt, 2.0)
    assert st.mode is Mode.LEVELING and math.degrees(sim.tilt_error()) < 1.5
    assert abs(st.extra["tilt_deg"] - math.degrees(sim.tilt_error())) < 1.0
    q_level = sim.q
    ok, msg = rt.set_mode(Mode.LEVELING, pitch_offset_deg=0.0, roll_offset_deg=20.0)
    assert ok, msg
    run(sim, rt, 2.0)
    # The roll offset is applied about the roll joint on top of the level configuration.
    assert abs(math.degrees(sim.q[1] - q_level[1]) - 20.0) < 1.5
    assert abs(math.degrees(sim.tilt_error()) - 20.0) < 2.0


@pytest.mark.parametrize(("pitch", "roll", "field"), [
    (120.0, 0.0, "pitch_offset_deg"), (0.0, float("nan"), "roll_offset_deg"),
    (0.0, "x", "roll_offset_deg")])
def test_bad_offsets_are_refused_naming_the_field(pitch, roll, field):
    sim, rt, motors = ready()
    ok, msg = rt.set_mode(Mode.LEVELING, pitch, roll)
    assert not ok and field in msg and "degrees" in msg
    assert rt.mode is Mode.DISABLED
    run(sim, rt, 0.2)
    assert not motors.commands


@pytest.mark.parametrize("mode", [Mode.PRIMITIVE, Mode.TRAJECTORY, 7, "LEVELING"])
def test_set_mode_refuses_other_modes(mode):
    _, rt, _ = ready()
    ok, msg = rt.set_mode(mode)
    assert not ok and msg
    assert rt.mode is Mode.DISABLED


def test_primitive_is_refused_while_leveling():
    _, rt, _ = ready()
    assert rt.set_mode(Mode.LEVELING)[0]
    ok, msg = rt.start_primitive("TWIRL_CW", [1.0, 2.0])
    assert not ok and "leveling" in msg
    assert rt.mode is Mode.LEVELING and rt.primitive_status() is None


def test_primitive_is_refused_while_another_runs():
    sim, rt, _ = ready()
    ok, msg = rt.start_primitive("TWIRL_CW", [1.0, 2.0])
    assert ok, msg
    run(sim, rt, 0.2)
    ok, msg = rt.start_primitive("HOMING", [1.0])
    assert not ok and "TWIRL_CW" in msg and "running" in msg
    assert rt.primitive_status().name == "TWIRL_CW" and not rt.primitive_status().done


def test_primitive_runs_to_completion_then_disables():
    sim, rt, _ = ready()
    ok, _ = rt.start_primitive("TWIRL_CCW", [1.0, 3.0])
    assert ok and rt.mode is Mode.PRIMITIVE
    run(sim, rt, 0.5)
    mid = rt.primitive_status()
    assert not mid.done and 0 < mid.percent_complete < 100
    run(sim, rt, 4.0)
    st = rt.primitive_status()
    assert st.done and st.success and st.percent_complete == 100
    assert st.final_joint_values[1] == pytest.approx(-2 * math.pi, abs=0.05)
    assert rt.mode is Mode.DISABLED and np.abs(sim.qd).max() < 1e-3


@pytest.mark.parametrize(("name", "params"), [("DEPOSIT_BITE", [60.0, 2.0, 0.5]),
                                             ("SETTLE_TOSS", [25.0, 1.0, 3.0])])
def test_upstreams_deposit_bite_and_settle_toss_run_on_the_simulated_wrist(name, params):
    sim, rt, _ = ready()
    q0 = sim.q.copy()
    ok, msg = rt.start_primitive(name, params)
    assert ok, msg
    peak = np.zeros(2)
    for _ in range(round(8.0 / DT)):
        sim.step(DT)
        rt.tick(sim.time, DT)
        peak = np.maximum(peak, np.abs(sim.q - q0))
        if rt.mode is Mode.DISABLED:
            break
    st = rt.primitive_status()
    assert st.done and st.success, st.message
    moved = 1 if name == "DEPOSIT_BITE" else 0  # roll out and back; pitch tilt and flick
    assert peak[moved] == pytest.approx(math.radians(params[0]), abs=0.05)
    np.testing.assert_allclose(sim.q, q0, atol=0.03)  # back at the start
    assert not rt.fault


@pytest.mark.parametrize("change", ["leveling", "disabled", "trajectory"])
def test_mode_change_aborts_a_running_primitive(change):
    sim, rt, _ = ready()
    assert rt.start_primitive("TWIRL_CW", [2.0, 3.0])[0]
    run(sim, rt, 0.5)
    if change == "leveling":
        assert rt.set_mode(Mode.LEVELING)[0]
        target = "LEVELING"
    elif change == "disabled":
        assert rt.set_mode(Mode.DISABLED)[0]
        target = "DISABLED"
    else:
        q = sim.q
        tr = JointTrajectory((PITCH, ROLL), np.array([0.5]), q[None, :], np.zeros((1, 2)))
        ok, msg = rt.follow_trajectory(tr)
        assert ok, msg
        target = "TRAJECTORY"
    st = rt.primitive_status()
    assert st.done and not st.success
    assert st.message == f"aborted by mode change to {target}"
    assert rt.mode.name == target
    run(sim, rt, 0.5)
    assert rt.primitive_status() == st  # a dead primitive stays dead


def test_cancel_primitive_stops_the_motors():
    sim, rt, motors = ready()
    assert rt.cancel_primitive() is False
    assert rt.start_primitive("VIBRATE_ROLL", [2.0, 0.1, 3.0])[0]
    run(sim, rt, 0.3)
    stops = motors.stops
    assert rt.cancel_primitive() is True
    assert motors.stops > stops  # at once, not at the next tick
    st = rt.primitive_status()
    assert st.done and not st.success and st.message == "cancelled"
    assert_stopped(sim, rt, motors)
    assert rt.cancel_primitive() is False


@pytest.mark.parametrize(("name", "params", "word"), [
    ("TWIRL_CW", [1.0], "parameter"), ("TWIRL_CW", [1.0, 99.0], "speed_rad_s"),
    ("SPIN", [1.0], "unknown primitive"), ("TWIRL_CW", [float("nan"), 1.0], "rotations"),
    ("TWIRL_CW", [10.0, 1.0], "budget"),
    ("VIBRATE_ROLL", [5.0, 0.1, 1e9], "max_vibrate_s"), ("TILT", [0.5, 1.0, 1e9], "max_hold_s"),
    ("NOODLE_SHED", [20.0, 1.0, 1e9, 5.0, 3.0, 1.0], "max_hold_s"),
    ("TWIRL_CW", [1.0, 1e-6], "max_duration_s")])
def test_bad_primitive_requests_are_refused_without_motion(name, params, word):
    sim, rt, motors = ready()
    ok, msg = rt.start_primitive(name, params)
    assert not ok and word in msg
    assert rt.mode is Mode.DISABLED
    run(sim, rt, 0.2)
    assert not motors.commands and rt.primitive_status() is None


# ------------------------------------------------------------------------- faults --
def test_stale_imu_while_leveling_stops_the_motors():
    sim, rt, motors = ready(base=axis_angle_rotation([1.0, 0.0, 0.0], 0.3) @ R0)
    assert rt.set_mode(Mode.LEVELING)[0]
    run(sim, rt, 0.2)
    sim.set_imu_stale(True)
    ticks = 0
    while not rt.fault and ticks < 10:
        sim.step(DT)
        st = rt.tick(sim.time, DT)
        ticks += 1
    assert "IMU data stale" in st.fault and st.mode is Mode.DISABLED
    assert ticks == 3  # the first tick more than two periods after the last sample
    assert_stopped(sim, rt, motors)
    ok, msg = rt.set_mode(Mode.LEVELING)
    assert not ok and "stale" in msg
    ok, msg = rt.set_mode(Mode.DISABLED)  # always possible, but the fault stays
    assert ok and "persists" in msg and rt.fault
    sim.set_imu_stale(False)
    run(sim, rt, 0.2)
    ok, msg = rt.set_mode(Mode.LEVELING)
    assert ok and "cleared fault" in msg and rt.fault == ""
    run(sim, rt, 1.0)
    assert rt.mode is Mode.LEVELING and math.degrees(sim.tilt_error()) < 1.5


def test_stale_imu_does_not_stop_a_primitive_which_runs_on_the_encoders():
    sim, rt, _ = ready()
    assert rt.start_primitive("TWIRL_CW", [1.0, 3.0])[0]
    sim.set_imu_stale(True)
    st = run(sim, rt, 0.5)
    assert st.fault == "" and st.mode is Mode.PRIMITIVE and st.extra["imu_stale"] == 1.0
    assert "IMU stale" in format_status(st)


def test_motor_hardware_error_stops_and_only_an_explicit_clear_reboots():
    sim, rt, motors = ready(base=axis_angle_rotation([1.0, 0.0, 0.0], 0.3) @ R0)
    assert rt.set_mode(Mode.LEVELING)[0]
    run(sim, rt, 0.2)
    sim.set_hardware_error("roll", HardwareError.OVERLOAD)
    st = run(sim, rt, DT)
    assert st.fault == "motor hardware error: roll: OVERLOAD"
    assert_stopped(sim, rt, motors)
    for _ in range(3):  # neither a refused LEVELING nor DISABLED reboots the motors
        ok, msg = rt.set_mode(Mode.LEVELING)
        assert not ok and "clear_fault" in msg
        assert rt.set_mode(Mode.DISABLED)[0]
        run(sim, rt, 0.1)
    assert motors.reboots == 0 and rt.fault
    ok, msg = rt.clear_fault()
    assert ok and "reboot" in msg
    run(sim, rt, DT)  # the loop reboots the motors and re-enables torque
    assert motors.reboots == 1 and motors.torque_enabled
    ok, msg = rt.set_mode(Mode.LEVELING)
    assert ok and rt.fault == ""
    run(sim, rt, 1.0)
    assert math.degrees(sim.tilt_error()) < 1.5


def test_an_overheated_motor_is_not_rebooted_until_it_has_cooled():
    """At 80 °C the XC430 shuts down (OVERHEATING). Requests of any kind must not reboot it
    while it is still hot; an explicit clear once it has cooled does."""
    sim, rt, motors = ready()
    sim.set_motor_temperature(80.0)
    sim.set_hardware_error("pitch", HardwareError.OVERHEATING)
    run(sim, rt, DT)
    assert "OVERHEATING" in rt.fault
    for _ in range(2):
        assert not rt.set_mode(Mode.LEVELING)[0]
        run(sim, rt, DT)
    ok, msg = rt.clear_fault()
    assert not ok and "80" in msg and "reboot_below_c" in msg
    run(sim, rt, 0.1)
    assert motors.reboots == 0 and "OVERHEATING" in rt.fault
    sim.set_motor_temperature(SPEC.motors.reboot_below_c - 5.0)
    run(sim, rt, DT)  # the runtime reads the cooler temperature
    ok, msg = rt.clear_fault()
    assert ok, msg
    run(sim, rt, DT)
    assert motors.reboots == 1
    assert rt.set_mode(Mode.DISABLED) == (True, "DISABLED (cleared fault: motor hardware "
                                                "error: pitch: OVERHEATING)")
    assert rt.clear_fault() == (False, "no fault to clear")


def test_failed_motor_read_is_a_fault_until_the_motors_answer():
    sim, rt, motors = ready()
    assert rt.start_primitive("TWIRL_CW", [1.0, 2.0])[0]
    run(sim, rt, 0.2)
    motors.fail_reads = True
    st = run(sim, rt, DT)
    assert "motor read failed" in st.fault and st.mode is Mode.DISABLED
    assert rt.primitive_status().message.startswith("aborted by fault")
    assert not rt.set_mode(Mode.LEVELING)[0]
    motors.fail_reads = False
    run(sim, rt, DT)
    assert rt.set_mode(Mode.LEVELING)[0] and rt.fault == ""


class StuckMotors(SpyMotors):
    """Motors whose stop can fail: ``fail_stops`` makes ``stop`` raise and leaves the motors
    running at their last goal, as a cut bus does."""

    def __init__(self, sim: SimWrist) -> None:
        super().__init__(sim)
        self.fail_stops = False

    def stop(self) -> None:
        if self.fail_stops:
            raise DriverError("stop not confirmed: no status packet")
        super().stop()


def test_a_failed_stop_is_a_fault_and_telemetry_keeps_the_command_written():
    sim = SimWrist(SPEC, seed=3)
    sim.set_base_pose(R0)
    motors = StuckMotors(sim)
    rt = ToolRuntime(SPEC, motors, sim.imu_driver(), clock=sim.clock)
    rt.open()
    run(sim, rt, 0.5)
    assert rt.start_primitive("TWIRL_CW", [1.0, 2.0])[0]
    run(sim, rt, 0.3)
    written = motors.commands[-1]
    assert abs(written[1]) > 0.5
    motors.fail_stops = True
    assert rt.cancel_primitive()  # the stop it sends fails
    st = rt.state()
    assert "motor stop failed" in st.fault and st.mode is Mode.DISABLED
    # The motors still run at the last goal, and telemetry says so, not "0".
    st = run(sim, rt, 0.1)
    assert abs(sim.qd[1]) > 0.5
    assert (st.extra["command_pitch"], st.extra["command_roll"]) == tuple(written)
    assert st.extra["motor_stop_failures"] >= 1
    assert rt.set_mode(Mode.DISABLED) == (True, "DISABLED; fault persists: "
                                          "the motors do not confirm a stop")
    assert not rt.set_mode(Mode.LEVELING)[0]
    motors.fail_stops = False
    st = run(sim, rt, 0.1)  # DISABLED stops every tick: now confirmed
    assert (st.extra["command_pitch"], st.extra["command_roll"]) == (0.0, 0.0)
    assert rt.set_mode(Mode.DISABLED)[0] and rt.fault == ""
    rt.close()


def test_a_failed_stop_at_shutdown_is_reported(caplog):
    sim = SimWrist(SPEC, seed=3)
    sim.set_base_pose(R0)
    motors = StuckMotors(sim)
    rt = ToolRuntime(SPEC, motors, sim.imu_driver(), clock=sim.clock)
    rt.open()
    run(sim, rt, 0.2)
    motors.fail_stops = True
    stop = threading.Event()
    stop.set()
    with caplog.at_level(logging.ERROR):
        rt.run(stop)  # the loop's exit stops the motors
        rt.close()
    assert "motor stop failed" in rt.fault
    assert not rt.motors_stopped
    assert any("motor stop failed" in r.getMessage() for r in caplog.records)


def _narrow_spec(pitch_limit):
    w = SPEC.wrist.model_copy(update={"pitch_limits": (-pitch_limit, pitch_limit)})
    return SPEC.model_copy(update={"wrist": w})


def test_joint_limit_violation_stops_and_recovery_only_moves_back():
    # The runtime's limits are narrower than the simulated hardware's: like a pitch encoder
    # zero that is off by 0.5 rad, the wrist reads beyond the envelope.
    spec = _narrow_spec(1.0)
    sim, rt, motors = ready(spec=spec)
    sim.set_joint_positions([1.3, 0.0])
    st = run(sim, rt, DT)
    assert st.fault.startswith("joint limit violation: atool_pitch = 1.3")
    assert_stopped(sim, rt, motors)
    assert not rt.start_primitive("HOMING", [1.0])[0]  # refused while the fault is set
    # Acknowledging the fault arms a recovery: commands back inside are allowed ...
    assert rt.set_mode(Mode.DISABLED)[0] and rt.fault == ""
    assert rt.start_primitive("HOMING", [1.0])[0]
    run(sim, rt, 3.0)
    assert rt.fault == "" and rt.primitive_status().success
    assert np.abs(sim.q).max() < 0.02
    # ... and one that drives a joint further out faults again.
    sim.set_joint_positions([1.3, 0.0])
    run(sim, rt, DT)
    assert rt.fault and rt.set_mode(Mode.LEVELING)[0]
    rt.controller.update = lambda *a, **k: np.array([0.5, 0.0])
    st = run(sim, rt, DT)
    assert "further out" in st.fault and st.mode is Mode.DISABLED


def test_exception_in_the_controller_is_caught_and_stops_the_motors():
    sim, rt, motors = ready()
    assert rt.set_mode(Mode.LEVELING)[0]
    run(sim, rt, 0.2)
    original = rt.controller.update

    def boom(*args, **kwargs):
        raise RuntimeError("boom")

    rt.controller.update = boom
    st = rt.tick(sim.time + DT, DT)  # returns normally
    assert st.fault == "exception in control loop: RuntimeError: boom"
    assert_stopped(sim, rt, motors)
    rt.controller.update = original
    assert rt.set_mode(Mode.LEVELING)[0] and rt.fault == ""


def test_non_finite_command_is_a_fault():
    sim, rt, motors = ready()
    assert rt.set_mode(Mode.LEVELING)[0]
    rt.controller.update = lambda *a, **k: np.array([np.nan, 0.0])
    st = run(sim, rt, DT)
    assert "non-finite joint command" in st.fault
    assert_stopped(sim, rt, motors)


class BatchStampedImu(SimImuDriver):
    """Stamps every sample of a read with the read time, as the serial IMU driver does."""

    def read_all(self):
        return [ImuSample(s.accel, s.gyro, self.sim.time) for s in super().read_all()]


def test_imu_batches_with_one_stamp_are_fused_and_gaps_reinitialise_the_filter():
    sim = SimWrist(SPEC, seed=5)
    sim.set_base_pose(axis_angle_rotation([1.0, 0.0, 0.0], 0.3) @ R0)
    rt = ToolRuntime(SPEC, SimMotorDriver(sim), BatchStampedImu(sim), clock=sim.clock)
    rt.open()
    for _ in range(40):  # two samples per read, sharing one stamp
        sim.step(2 * DT)
        rt.tick(sim.time, 2 * DT)
    st = rt.state()
    assert st.extra["imu_filter_resets"] == 0 and st.extra["imu_stale"] == 0.0
    assert st.extra["tilt_deg"] == pytest.approx(math.degrees(sim.tilt_error()), abs=1.0)
    sim.set_imu_stale(True)
    run(sim, rt, 0.3)
    sim.set_imu_stale(False)
    st = run(sim, rt, 0.3)
    assert st.extra["imu_filter_resets"] == 1 and st.fault == ""  # DISABLED: no fault


def test_first_fault_is_kept_and_others_are_counted_once():
    sim, rt, _ = ready()
    assert rt.set_mode(Mode.LEVELING)[0]
    sim.set_imu_stale(True)
    run(sim, rt, 0.2)
    sim.set_hardware_error("pitch", HardwareError.OVERLOAD)
    st = run(sim, rt, 0.2)
    assert "IMU" in st.fault and st.extra["faults_total"] == 1.0


# -------------------------------------------------------------------- trajectories --
def _rot(axis, angle):
    return axis_angle_rotation(np.eye(3)[axis], angle)


class GimbalArm:
    """Tool base R = Rz(q1) Ry(q2) Rx(q3) R0 (the verifier's OrientationModel protocol)."""

    def tool_base_rotations(self, q):
        return np.stack([_rot(2, a) @ _rot(1, b) @ _rot(0, c) @ R0 for a, b, c in q[:, :3]])

    def tool_base_angular_velocity(self, q, qd):
        out = []
        for (a, b, _), (da, db, dc) in zip(q[:, :3], qd[:, :3], strict=True):
            out.append(np.array([0, 0, da]) + _rot(2, a) @ np.array([0, db, 0])
                       + _rot(2, a) @ _rot(1, b) @ np.array([dc, 0, 0]))
        return np.stack(out)


def _arm_transport(duration=4.0):
    """An arm trajectory (joints 1-3 drive the gimbal) tilting and turning at ≤ 0.6 rad/s;
    the remaining joints sit mid-range so the arm's limits are respected."""
    t = np.linspace(0.0, duration, 41)
    w = 2 * math.pi / duration
    amp = np.array([0.5, 0.35, 0.4])  # rad
    g = amp * (1 - np.cos(w * t))[:, None] / 2
    gd = amp * (w * np.sin(w * t))[:, None] / 2
    mid = (SPEC.arm.lower + SPEC.arm.upper) / 2
    q = np.tile(mid, (t.size, 1))
    qd = np.zeros_like(q)
    q[:, :3] += g
    qd[:, :3] = gd

    class Centred(GimbalArm):
        def tool_base_rotations(self, q):
            return super().tool_base_rotations(q[:, :3] - mid[:3])

        def tool_base_angular_velocity(self, q, qd):
            return super().tool_base_angular_velocity(q[:, :3] - mid[:3], qd)

    return JointTrajectory(tuple(SPEC.arm.joint_names), t, q, qd), Centred()


def test_trajectory_mode_follows_the_verifiers_wrist_trajectory():
    arm, model = _arm_transport()
    rep = verify_trajectory(arm, model, SPEC)
    assert rep.feasible, rep.message
    wtraj = rep.wrist_trajectory
    sim, rt, _ = ready(q0=tuple(wtraj.positions[0]))
    t_start = sim.time + DT  # the first TRAJECTORY tick

    def base(t):  # the arm executes its trajectory in sync with the wrist
        s = t - t_start
        qa = arm.sample(s)[0][None, :]
        qda = arm.sample(s)[1][None, :] if 0 <= s <= arm.duration else np.zeros((1, 6))
        return model.tool_base_rotations(qa)[0], model.tool_base_angular_velocity(qa, qda)[0]

    sim.set_base_motion(base)
    ok, msg = rt.follow_trajectory(wtraj)
    assert ok, msg
    errs, tilts = [], []
    while sim.time < t_start + wtraj.duration + 1.0:
        sim.step(DT)
        st = rt.tick(sim.time, DT)
        ref = wtraj.sample(sim.time - t_start)[0]  # where the wrist should be now
        errs.append(np.abs(st.position - ref).max())
        tilts.append(sim.tilt_error())
    print(f"\ntrajectory: {len(wtraj)} points, {wtraj.duration:.1f} s: tracking error max "
          f"{math.degrees(max(errs)):.2f}°, utensil tilt max {math.degrees(max(tilts)):.2f}°")
    assert rt.fault == "" and rt.mode is Mode.TRAJECTORY
    # Velocity feed-forward + P: tracking within a degree of the reference, and the
    # utensil level (the wrist trajectory is the verifier's leveling solution).
    assert max(errs) < math.radians(1.0)
    assert math.degrees(max(tilts)) < 1.5
    st = run(sim, rt, 1.0)  # holds the last point
    np.testing.assert_allclose(st.position, wtraj.positions[-1], atol=0.01)
    assert st.extra["trajectory_progress_pct"] == 100.0


def test_trajectory_starting_later_moves_smoothly_from_where_the_wrist_is():
    sim, rt, motors = ready()
    tr = JointTrajectory((ROLL, PITCH), np.array([1.0, 2.0]),  # columns in another order
                         np.array([[0.5, 0.2], [0.6, 0.3]]), np.zeros((2, 2)))
    ok, msg = rt.follow_trajectory(tr)
    assert ok, msg
    st = run(sim, rt, 3.0)
    np.testing.assert_allclose(st.position, [0.3, 0.6], atol=0.01)
    assert max(np.abs(c).max() for c in motors.commands) < 1.0  # no jump to the start


def test_trajectory_stamped_in_the_future_starts_at_that_stamp():
    """A JointTrajectory whose header.stamp lies ahead (synchronised with the arm) holds the
    present position until then and then follows the timing from that stamp, as ROS
    trajectory controllers do."""
    sim, rt, _ = ready()
    q0 = sim.q
    tr = JointTrajectory((PITCH, ROLL), np.array([0.0, 1.0, 2.0]),
                         np.array([q0, [0.3, 0.4], [0.3, 0.4]]), np.zeros((3, 2)))
    delay = 1.5
    t_start = sim.time + delay
    ok, msg = rt.follow_trajectory(tr, start_delay=delay)
    assert ok and "in 1.500 s" in msg
    run(sim, rt, delay - 2 * DT)  # before the stamp: holding still
    assert rt.mode is Mode.TRAJECTORY and np.abs(sim.q - q0).max() < 1e-3
    assert rt.state().extra["trajectory_progress_pct"] == 0.0
    errs = []
    while sim.time < t_start + tr.duration:
        sim.step(DT)
        st = rt.tick(sim.time, DT)
        errs.append(np.abs(st.position - tr.sample(max(sim.time - t_start, 0.0))[0]).max())
    assert max(errs) < math.radians(1.0)  # on the stamp's timing, not the call's
    np.testing.assert_allclose(sim.q, [0.3, 0.4], atol=0.01)
    for bad in (math.nan, math.inf, "soon"):
        ok, msg = rt.follow_trajectory(tr, start_delay=bad)
        assert not ok and "start_delay" in msg


def _traj(names=(PITCH, ROLL), t=(0.0, 1.0), q=((0.0, 0.0), (0.3, 0.3)), v=None):
    q = np.array(q, dtype=float)
    return JointTrajectory(tuple(names), np.array(t), q, np.zeros_like(q) if v is None else
                           np.array(v, dtype=float))


@pytest.mark.parametrize(("traj", "words"), [
    (_traj(names=("j1", "j2")), ["joint_names", PITCH]),
    (_traj(q=((0.0, 0.0), (2.0, 0.0))), [PITCH, "outside", "limits"]),
    (_traj(v=((0.0, 0.0), (0.0, 5.0))), [ROLL, "velocity", "max_velocity"]),
    (_traj(t=(0.0, 0.05), q=((0.0, 0.0), (0.0, 1.0))), ["interpolated", ROLL, "velocity"]),
    (_traj(q=((0.5, 0.0), (0.5, 0.0))), ["first point", "time_from_start"]),
    ("not a trajectory", ["JointTrajectory"]),
])
def test_bad_trajectories_are_refused_with_no_motion(traj, words):
    sim, rt, motors = ready()
    ok, msg = rt.follow_trajectory(traj)
    assert not ok
    for w in words:
        assert w in msg
    assert rt.mode is Mode.DISABLED
    q = sim.q
    run(sim, rt, 0.3)
    assert not motors.commands and np.abs(sim.q - q).max() < 1e-9


# ------------------------------------------------------------------- telemetry --
def test_loop_statistics_are_the_period_mean_and_jitter():
    sim, rt, _ = make()
    rng = np.random.default_rng(1)
    periods = DT + rng.normal(0.0, 0.002, 200).clip(-0.01, 0.01)
    t = 0.0
    for p in periods:
        sim.step(p)
        t += p
        st = rt.tick(t)
    # The first tick has no period before it.
    assert st.loop_period_mean == pytest.approx(periods[1:].mean(), rel=1e-9)
    assert st.loop_jitter == pytest.approx(periods[1:].std(ddof=1), rel=1e-6)
    assert st.extra["loop_period_max"] == pytest.approx(periods[1:].max())
    assert st.loop_overruns == 0
    assert st.extra["tick_compute_max_s"] >= st.extra["tick_compute_mean_s"] > 0


def test_battery_telemetry_from_the_motor_voltage_and_the_power_budget():
    sim, rt, _ = make()
    sim.set_battery(11.4)
    st = run(sim, rt, 10.0)
    assert st.battery_voltage == pytest.approx(11.4)
    used = SPEC.power.idle_w * 10.0 / 3600.0  # DISABLED draws the idle power
    assert st.extra["battery_used_wh"] == pytest.approx(used, rel=1e-6)
    assert st.extra["battery_remaining_pct"] == pytest.approx(
        100 * (1 - used / SPEC.power.battery_wh), rel=1e-9)
    assert st.extra["battery_runtime_h"] == pytest.approx(
        (SPEC.power.battery_wh - used) / SPEC.power.idle_w, rel=1e-9)


def test_state_carries_filter_and_ft_telemetry():
    sim, rt, _ = ready(base=axis_angle_rotation([1.0, 0.0, 0.0], 0.2) @ R0)
    sim.set_external_wrench([0.0, 0.0, -1.5])
    st = run(sim, rt, 1.0)
    assert st.extra["ft_fz"] == pytest.approx(-1.5, abs=0.1)
    assert np.linalg.norm(st.linear_acceleration) == pytest.approx(9.81, abs=0.1)
    assert np.linalg.norm(st.orientation_wxyz) == pytest.approx(1.0)
    assert st.extra["tilt_deg"] == pytest.approx(math.degrees(sim.tilt_error()), abs=1.0)


# ----------------------------------------------------------------------- threads --
def test_run_in_a_thread_with_concurrent_commands():
    """~1 s of real time: the loop thread, the simulated world advancing in real time and
    this thread hammering the API. No fault, no exception, statistics populated."""
    sim, rt, motors = make(base=axis_angle_rotation([1.0, 0.0, 0.0], 0.2) @ R0)
    rt.clock = real_time_clock(sim)  # the world advances as the loop reads the clock
    stop = threading.Event()
    errors: list[BaseException] = []

    def guarded(fn):
        def inner(*args):
            try:
                fn(*args)
            except BaseException as e:  # pragma: no cover - reported below
                errors.append(e)
        return inner

    threads = [threading.Thread(target=guarded(rt.run), args=(stop,))]
    for th in threads:
        th.start()
    t_end = time.monotonic() + 1.0
    stamps, answers = [], []
    # 1 s of calls racing the loop, and on until the loop ticked 11 times (a loaded machine
    # may give it fewer ticks in that second; 60 s only bounds a failing test)
    while time.monotonic() < t_end or (rt.stats.count <= 10 and time.monotonic() < t_end + 60):
        answers.append(rt.set_mode(Mode.LEVELING, 0.0, 5.0)[0])
        answers.append(rt.start_primitive("TILT", [0.2, 1.0, 0.0])[0])  # refused: leveling
        rt.primitive_status()
        stamps.append(rt.state().stamp)
        answers.append(rt.set_mode(Mode.DISABLED)[0])
        time.sleep(0.003)
    stop.set()
    for th in threads:
        th.join(timeout=5.0)
    assert not errors and not any(th.is_alive() for th in threads)
    st = rt.state()
    assert st.fault == "" and any(answers)
    assert np.all(np.diff(stamps) >= 0)
    assert st.loop_period_mean > 0 and math.isfinite(st.loop_jitter)
    assert rt.stats.count > 10
    rt.close()
    assert not motors.torque_enabled


# --------------------------------------------------------------------------- CLI --
def test_run_tool_levels_the_sim_and_stops_cleanly():
    sim = SimWrist(SPEC, seed=0)
    sim.set_base_pose(axis_angle_rotation([1.0, 0.0, 0.0], 0.3) @ R0)
    motors = SpyMotors(sim)
    rt = ToolRuntime(SPEC, motors, sim.imu_driver(), sim.ft_driver(),
                     clock=real_time_clock(sim))
    out = io.StringIO()
    rc = run_tool(rt, duration=1.2, level=True, out=out)
    text = out.getvalue()
    assert rc == 0
    assert "LEVELING with offsets" in text and "stopped: motors stopped" in text
    assert "FAULT" not in text
    assert not motors.torque_enabled and not motors._open


def test_run_tool_says_when_the_motors_did_not_confirm_the_stop():
    sim = SimWrist(SPEC, seed=0)
    sim.set_base_pose(R0)
    motors = StuckMotors(sim)
    rt = ToolRuntime(SPEC, motors, sim.imu_driver(), clock=sim.clock)
    out = io.StringIO()
    stop = threading.Event()
    threading.Timer(0.3, lambda: setattr(motors, "fail_stops", True)).start()
    threading.Timer(0.5, stop.set).start()
    rc = run_tool(rt, level=False, out=out, stop_event=stop)
    text = out.getvalue()
    assert rc == 1
    assert "stopped: motors stopped" not in text
    assert "motors did not confirm the stop" in text and "bus watchdog" in text


def test_tool_command_rejects_a_bad_duration():
    assert main(["--duration", "-1"]) == 2


def test_tool_command_exits_0_on_sigint():
    code = "import sys; from articutool.onboard import main; sys.exit(main(sys.argv[1:]))"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    # No link: the default endpoint may be in use (the tool then exits 2); Ctrl-C with the
    # link served, under load, is test_tool_cli.py::test_sigint_stops_the_tool_cleanly.
    p = subprocess.Popen([sys.executable, "-c", code, "--driver", "sim", "--no-serve"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        first = p.stdout.readline()  # the first status line: the loop is running
        assert "DISABLED" in first or "LEVELING" in first
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=20)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 0, err
    assert "stopped: motors stopped, torque off, drivers closed" in out


def test_the_state_reports_the_tools_own_joint_limits_through_the_link():
    """A tool built from a spec with other wrist limits reports those limits in its state,
    and they survive the link's health message: a client (the ROS 2 node's admission) learns
    the connected tool's limits, not the packaged spec's."""
    from articutool.link import messages as m
    from articutool.tool.telemetry import reported_limits
    narrow = SPEC.model_copy(update={"wrist": SPEC.wrist.model_copy(update={
        "pitch_limits": (-0.5, 0.6), "roll_limits": (-2.0, 2.5)})})
    _, rt, _ = ready(spec=narrow)
    state = rt.state()
    np.testing.assert_array_equal(reported_limits(state), [[-0.5, 0.6], [-2.0, 2.5]])
    back = m.state_from_msgs(m.joint_state_msg(state, 1.0), None,
                             m.health_msg(state, 1.0, {}), None, stamp=1.0)
    np.testing.assert_array_equal(reported_limits(back), [[-0.5, 0.6], [-2.0, 2.5]])
    assert reported_limits(None) is None
