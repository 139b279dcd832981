"""MuJoCo-backed twins of the tool's drivers, so the unchanged ``ToolRuntime`` runs in physics.

Same interfaces (``articutool.tool.drivers.base``) and the same checks as the hardware
drivers and their kinematic twins (``articutool.tool.drivers.sim``):

- :class:`MjMotorDriver`: the pitch and roll joints are driven by MuJoCo velocity servos with
  the XC430's torque limit (``spec.motors.stall_torque_nm``) and the time constant and
  reflected inertia of ``physics.toml``; commands beyond ``spec.wrist.max_velocity`` are
  refused. Position mode tracks with ``spec.primitives.position_gain``. Torque off removes the
  servo (the gearbox friction stays). Hitting a joint stop faster than
  ``hard_stop_velocity`` raises OVERLOAD and drops that motor's torque, as a real XC430 does.
- :class:`MjImuDriver`: MuJoCo's accelerometer and gyro at the IMU site on F0, so the filter
  sees the arm's real accelerations and contacts; plus white noise at the datasheet densities
  and a constant gyro bias.
- :class:`MjFTDriver`: MuJoCo's force and torque sensors at the utensil mount, i.e. between
  the roll output and the utensil (the HEX21's place): it feels the utensil, the food on it
  and every contact; plus white noise. Taring is the shared ``FTDriver`` logic.

The world (:class:`articutool.sim.world.FeedingWorld`) owns them. Its builder
(:func:`articutool.sim.build.build_parts`) hands the motor driver a
:class:`~articutool.tool.drivers.motor_model.MotorPlant` (the joint state and clock of the
world's MuJoCo data); the world applies ``motors.model.velocity_targets`` to its servos before
each physics step, calls
``motors.check_stops`` and pushes the sensors' samples (``push``) after it. The drivers
never see the world.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numpy.typing import ArrayLike, NDArray

from articutool.spec import Spec
from articutool.tool.drivers.base import FTSample, HardwareError, ImuSample
from articutool.tool.drivers.motor_model import ModelMotorDriver, MotorModel, MotorPlant
from articutool.tool.drivers.sim import (
    QueuedFTDriver,
    QueuedImuDriver,
    SampleQueue,
    imu_noise_sigmas,
)

__all__ = ["MjFTDriver", "MjImuDriver", "MjMotorDriver"]

_QUEUE_LEN = 512


class MjMotorDriver(ModelMotorDriver):
    """The pitch/roll motor pair as MuJoCo velocity servos: the shared
    :class:`~articutool.tool.drivers.motor_model.MotorModel` over the physics (see module
    doc); the world applies :meth:`MotorModel.velocity_targets` to its servos."""

    def __init__(self, spec: Spec, plant: MotorPlant, joint_range: ArrayLike,
                 hard_stop_velocity: float = 0.5) -> None:
        model = MotorModel(spec.wrist.velocity_limits, spec.wrist.limits,
                           spec.primitives.position_gain)
        super().__init__(model, plant)
        self.joint_range = np.asarray(joint_range, dtype=np.float64).reshape(2, 2)
        self._hard_stop = float(hard_stop_velocity)

    def check_stops(self) -> None:
        """OVERLOAD when a joint reaches its stop (``joint_range``, the MJCF's) faster than
        the hard-stop speed."""
        q, qd = self.plant.position(), self.plant.velocity()
        lo, hi = self.joint_range[:, 0], self.joint_range[:, 1]
        for i in range(2):
            at_stop = q[i] <= lo[i] + 1e-3 or q[i] >= hi[i] - 1e-3
            if at_stop and abs(qd[i]) > self._hard_stop and self.model.torque[i]:
                self.model.raise_error(i, HardwareError.OVERLOAD)


class MjImuDriver(QueuedImuDriver):
    """The IMU on F0: MuJoCo accelerometer + gyro, datasheet noise, constant gyro bias."""

    def __init__(self, spec: Spec, gyro_bias: ArrayLike, noise: bool,
                 rng: np.random.Generator) -> None:
        super().__init__(SampleQueue("IMU", _QUEUE_LEN))
        self.gyro_bias = np.asarray(gyro_bias, dtype=np.float64).reshape(3)
        self._sigma = imu_noise_sigmas(spec) if noise else (0.0, 0.0)
        self._rng = rng

    def push(self, accel: NDArray[np.float64], gyro: NDArray[np.float64],
             stamp: float) -> None:
        """One sample of MuJoCo's accelerometer and gyro (IMU frame), with noise and bias."""
        sa, sg = self._sigma
        if sa:
            accel = accel + self._rng.normal(0.0, sa, 3)
        if sg:
            gyro = gyro + self._rng.normal(0.0, sg, 3)
        self.samples.push(ImuSample(accel=accel, gyro=gyro + self.gyro_bias, stamp=stamp,
                                    temperature=30.0))


class MjFTDriver(QueuedFTDriver):
    """The F/T sensor between roll output and utensil; keeps the tared samples it returned
    (``history``) so the world can report the mass it measures."""

    def __init__(self, spec: Spec, noise: bool, rng: np.random.Generator) -> None:
        super().__init__(SampleQueue("F/T sensor", _QUEUE_LEN), spec.ft.tare_samples)
        self._sigma = (np.repeat([spec.ft.force_noise_n, spec.ft.torque_noise_nm], 3)
                       if noise else np.zeros(6))
        self._rng = rng
        self.history: deque[FTSample] = deque(maxlen=4 * int(spec.ft.rate_hz))

    def push(self, force: NDArray[np.float64], torque: NDArray[np.float64],
             stamp: float) -> None:
        """One sample of MuJoCo's force and torque sensors (sensor frame), with noise."""
        w = np.concatenate([force, torque]) + self._rng.normal(0.0, 1.0, 6) * self._sigma
        self.samples.push(FTSample(force=w[:3], torque=w[3:], temperature=32.0, stamp=stamp))

    def read_all(self) -> list[FTSample]:
        """Tared samples since the last call (also kept in ``history``)."""
        out = super().read_all()
        self.history.extend(out)
        return out
