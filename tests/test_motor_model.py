"""The one simulated motor model: both simulated worlds' motor drivers keep the
Dynamixel X-series semantics of the Shutdown register — per the ROBOTIS XC430-W240 e-manual
("Shutdown" 63, default 52 = OVERHEATING | ELECTRICAL_SHOCK | OVERLOAD; "Hardware Error
Status" 70), a Shutdown error drops torque and blocks Torque Enable until reboot; any other
error bit is reported and does not block torque. The real driver leaves this to the motor
(tool/drivers/dynamixel.py: ``clear_errors`` reboots only motors with an error)."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from articutool.sim.mj_drivers import MjMotorDriver
from articutool.tool.drivers.base import HardwareError
from articutool.tool.drivers.motor_model import SHUTDOWN_BITS, MotorModel, MotorPlant
from articutool.tool.drivers.sim import SimWrist
from conftest import packaged_spec

SPEC = packaged_spec()
E = HardwareError
BITS = st.sampled_from(list(E)).flatmap(
    lambda b: st.lists(st.sampled_from(list(E)), max_size=3).map(lambda r: [b, *r]))


def test_the_shutdown_bits_are_the_default_shutdown_register() -> None:
    # e-manual: Shutdown (63) initial value 52 = 0b0011_0100
    assert int(SHUTDOWN_BITS) == 52
    assert SHUTDOWN_BITS == E.OVERHEATING | E.ELECTRICAL_SHOCK | E.OVERLOAD


def test_both_worlds_drive_the_one_model() -> None:
    assert isinstance(SimWrist(SPEC, noise=False, seed=0).motor_driver().model, MotorModel)
    assert issubclass(MjMotorDriver, type(SimWrist(SPEC, noise=False).motor_driver()).__base__)


@given(BITS, st.integers(0, 1))
def test_only_shutdown_bits_block_torque_on_the_kinematic_wrist(bits: list[E], joint: int) -> None:
    sim = SimWrist(SPEC, noise=False, seed=0)
    m = sim.motor_driver()
    m.open()
    m.enable_torque(True)
    err = 0
    for b in bits:
        err |= int(b)
        sim.set_hardware_error(joint, b)
    shutdown = bool(err & SHUTDOWN_BITS)
    # the error drops torque only if it is a shutdown error
    assert m.model.torque[joint] == (not shutdown)
    m.enable_torque(True)
    assert m.model.torque[joint] == (not shutdown)
    assert m.model.torque[1 - joint]
    assert m.read().hardware_error[joint] == err
    # reboot clears the bits; torque comes back off; then it can be enabled
    m.clear_errors()
    assert m.read().hardware_error == (0, 0)
    assert not m.model.torque[joint]
    m.enable_torque(True)
    assert m.torque_enabled


@given(BITS)
def test_a_shutdown_motor_holds_still_and_others_move(bits: list[E]) -> None:
    model = MotorModel(SPEC.wrist.velocity_limits, SPEC.wrist.limits, 10.0)
    model.enable_torque(True, (0.0, 0.0))
    for b in bits:
        model.raise_error(0, b)
    model.set_velocity((0.5, 0.5))
    blocked = bool(model.hw[0] & SHUTDOWN_BITS)
    np.testing.assert_array_equal(model.velocity_targets((0.0, 0.0)),
                                  (0.0 if blocked else 0.5, 0.5))


def mj_driver(q: tuple[float, float] = (0.0, 0.0),
              qd: tuple[float, float] = (0.0, 0.0)) -> MjMotorDriver:
    # A still plant: the driver under test reads the joint state from it (no MuJoCo needed)
    plant = MotorPlant(position=lambda: np.array(q), velocity=lambda: np.array(qd),
                       input_voltage=lambda: SPEC.motors.supply_v, temperature=lambda: 35.0,
                       stamp=lambda: 0.0)
    m = MjMotorDriver(SPEC, plant, [[-1.0, 1.0], [-3.0, 3.0]])
    m.open()
    m.enable_torque(True)
    return m


@given(BITS, st.integers(0, 1))
def test_only_shutdown_bits_block_torque_on_the_mujoco_wrist(bits: list[E], joint: int) -> None:
    # only the Shutdown register's bits, not INPUT_VOLTAGE or MOTOR_ENCODER
    m = mj_driver()
    for b in bits:
        m.model.raise_error(joint, b)
    shutdown = bool(m.read().hardware_error[joint] & SHUTDOWN_BITS)
    m.enable_torque(True)
    assert m.model.torque[joint] == (not shutdown)
    m.clear_errors()
    m.enable_torque(True)
    assert m.torque_enabled


def test_hitting_a_stop_fast_is_an_overload_on_the_mujoco_wrist() -> None:
    m = mj_driver(q=(1.0, 0.0), qd=(0.6, 0.0))  # at the pitch stop, faster than 0.5 rad/s
    m.check_stops()
    assert m.read().hardware_error == (int(E.OVERLOAD), 0)
    m.enable_torque(True)
    assert list(m.model.torque) == [False, True]
    slow = mj_driver(q=(1.0, 0.0), qd=(0.4, 0.0))
    slow.check_stops()
    assert slow.read().hardware_error == (0, 0)
