"""X-series Dynamixel register units: pure conversions, no ``dynamixel_sdk``.

The spec validates ``motors.bus_watchdog_s`` against the Bus Watchdog register with
``bus_watchdog_units``, and the driver (``tool/drivers/dynamixel.py``) writes the registers
with all of them: one definition, importable on a PC without the SDK (docs/hardware.md §3,
ROBOTIS e-manual X-series control table; thesis §3.2). numpy is imported by the array
conversions that use it, so validating the spec does not load it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import ArrayLike, NDArray

__all__ = [
    "bus_watchdog_units",
    "position_limit_ticks",
    "rad_s_to_velocity_units",
    "rad_to_ticks",
    "ticks_to_rad",
    "to_signed32",
    "to_unsigned32",
    "turns_lost_in_reboot",
    "velocity_limit_units",
    "velocity_unit_rad_s",
    "velocity_units_to_rad_s",
]

_VELOCITY_LIMIT_MAX_UNITS = 1023  # Velocity Limit register range (e-manual)
_POSITION_TICKS_MAX = 4095  # single-turn position range
_WATCHDOG_UNIT_S = 0.020  # Bus Watchdog register unit (e-manual)
_WATCHDOG_MAX_UNITS = 127

def velocity_unit_rad_s(unit_rpm: float) -> float:
    """rad/s represented by one velocity unit (0.229 rev/min → ≈ 0.02398 rad/s)."""
    return unit_rpm * 2.0 * math.pi / 60.0


def rad_s_to_velocity_units(qd: ArrayLike, unit_rpm: float) -> NDArray[np.int64]:
    """Joint rate (rad/s) → Goal Velocity units, rounded to nearest."""
    import numpy as np

    return np.rint(np.asarray(qd, dtype=np.float64) / velocity_unit_rad_s(unit_rpm)).astype(
        np.int64
    )


def velocity_units_to_rad_s(units: ArrayLike, unit_rpm: float) -> NDArray[np.float64]:
    """Present Velocity units → rad/s."""
    import numpy as np

    return np.asarray(units, dtype=np.float64) * velocity_unit_rad_s(unit_rpm)


def velocity_limit_units(max_velocity: ArrayLike, unit_rpm: float) -> NDArray[np.int64]:
    """Velocity Limit register value for a joint speed limit (rad/s), rounded *down* so the
    motor never allows more than the spec; refuses limits beyond the register range."""
    import numpy as np

    v = np.asarray(max_velocity, dtype=np.float64)
    units = np.floor(v / velocity_unit_rad_s(unit_rpm) + 1e-9).astype(np.int64)
    if (units < 1).any() or (units > _VELOCITY_LIMIT_MAX_UNITS).any():
        raise ValueError(
            f"velocity limit {v} rad/s gives {units} units; the register allows "
            f"1..{_VELOCITY_LIMIT_MAX_UNITS}"
        )
    return units


def bus_watchdog_units(timeout_s: float) -> int:
    """Bus Watchdog register value (20 ms units) for a timeout; refuses one the register cannot
    hold exactly (1..127 units)."""
    if not math.isfinite(timeout_s):
        raise ValueError(f"bus watchdog timeout must be finite; got {timeout_s}")
    units = round(timeout_s / _WATCHDOG_UNIT_S)
    if not 1 <= units <= _WATCHDOG_MAX_UNITS or abs(units * _WATCHDOG_UNIT_S - timeout_s) > 1e-9:
        raise ValueError(
            f"bus watchdog timeout {timeout_s} s is not a multiple of {_WATCHDOG_UNIT_S} s in "
            f"[{_WATCHDOG_UNIT_S}, {_WATCHDOG_MAX_UNITS * _WATCHDOG_UNIT_S:g}] s"
        )
    return units


def turns_lost_in_reboot(before_ticks: int, after_ticks: int, ticks_per_rev: int) -> int:
    """Whole turns (as ticks) to add to the position a motor reports after a reboot, given the
    (unwrapped) ticks before it: the reboot keeps the angle within the turn and loses the turn
    count, and the joint cannot move half a turn while the motor boots."""
    return round((before_ticks - after_ticks) / ticks_per_rev) * ticks_per_rev


def rad_to_ticks(q: ArrayLike, zero_ticks: ArrayLike, ticks_per_rev: int) -> NDArray[np.int64]:
    """Joint angle (rad) → encoder ticks, given the ticks at which the joint reads 0."""
    import numpy as np

    q = np.asarray(q, dtype=np.float64)
    return np.rint(q * ticks_per_rev / (2.0 * math.pi)).astype(np.int64) + np.asarray(
        zero_ticks, dtype=np.int64
    )


def ticks_to_rad(
    ticks: ArrayLike, zero_ticks: ArrayLike, ticks_per_rev: int
) -> NDArray[np.float64]:
    """Encoder ticks → joint angle (rad)."""
    import numpy as np

    t = np.asarray(ticks, dtype=np.int64) - np.asarray(zero_ticks, dtype=np.int64)
    return t.astype(np.float64) * (2.0 * math.pi / ticks_per_rev)


def to_signed32(x: int) -> int:
    """Interpret a 32-bit register value as two's complement."""
    x &= 0xFFFFFFFF
    return x - (1 << 32) if x & 0x80000000 else x


def to_unsigned32(x: int) -> int:
    """Encode a signed integer as a 32-bit two's-complement register value."""
    if not -(1 << 31) <= x < (1 << 31):
        raise ValueError(f"{x} does not fit a signed 32-bit register")
    return x & 0xFFFFFFFF


def position_limit_ticks(
    limits: ArrayLike, zero_ticks: ArrayLike, ticks_per_rev: int
) -> NDArray[np.int64]:
    """(2, 2) joint limits (rad) → (2, 2) [min, max] ticks, clipped to the single-turn
    range 0..4095 that position mode accepts."""
    import numpy as np

    lim = np.asarray(limits, dtype=np.float64)
    z = np.asarray(zero_ticks, dtype=np.int64)[:, None]
    ticks = rad_to_ticks(lim, z, ticks_per_rev)
    return np.clip(ticks, 0, _POSITION_TICKS_MAX)
