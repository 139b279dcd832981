"""Device drivers behind one small interface (``base``), each with a simulated twin (``sim``).

The simulated wrist is the default everywhere; the hardware drivers import ``dynamixel_sdk``
and ``pyserial`` only when their modules are imported (``make_drivers``).
"""

from __future__ import annotations

from typing import Literal

from articutool.spec import Spec
from articutool.tool.drivers.base import FTDriver, ImuDriver, MotorDriver
from articutool.tool.drivers.sim import SimWrist

__all__ = ["make_drivers"]


def make_drivers(
    spec: Spec, kind: Literal["sim", "hardware"] = "sim", *, sim: SimWrist | None = None
) -> tuple[MotorDriver, ImuDriver, FTDriver]:
    """The (motor, IMU, F/T) drivers for ``--driver sim|hardware``, unopened.

    ``"sim"`` shares one ``SimWrist`` (created with defaults unless given); ``"hardware"``
    uses the ports in ``spec.motors`` / ``spec.imu`` / ``spec.ft``.
    """
    if kind == "sim":
        world = sim if sim is not None else SimWrist(spec)
        return world.motor_driver(), world.imu_driver(), world.ft_driver()
    if kind == "hardware":
        from articutool.tool.drivers.dynamixel import DynamixelDriver
        from articutool.tool.drivers.ft import ResenseFTDriver
        from articutool.tool.drivers.imu import OpenLogImuDriver

        return DynamixelDriver(spec), OpenLogImuDriver(spec), ResenseFTDriver(spec)
    raise ValueError(f"driver kind must be 'sim' or 'hardware'; got {kind!r}")
