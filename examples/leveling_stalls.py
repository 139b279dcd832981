"""Leveling from static random base tilts: how many starts reach level, how many
stall and say so, how many stay tilted silently. Prints one line per tilt range.

    PYTHONPATH=src python examples/leveling_stalls.py [--starts 99]
"""

from __future__ import annotations

import argparse
import logging
import math

import numpy as np

from articutool.spec import load_spec
from articutool.tool.api import Mode
from articutool.tool.drivers.sim import SimWrist, axis_angle_rotation
from articutool.tool.runtime import ToolRuntime

SPEC = load_spec()
R0 = axis_angle_rotation([0.0, 1.0, 0.0], -math.pi / 2)  # up vector at q = 0 along world +z


def level_from(R: np.ndarray, seed: int, seconds: float = 6.0) -> str:
    """Level for ``seconds`` on a still base at ``R``; the outcome in words."""
    sim = SimWrist(SPEC, seed=seed, gyro_bias=(0.012, -0.02, 0.015))
    rt = ToolRuntime(SPEC, sim.motor_driver(), sim.imu_driver(), sim.ft_driver(),
                     clock=sim.clock)
    rt.open()
    sim.set_base_pose(R)
    dt = SPEC.wrist.period
    for _ in range(round(1.0 / dt)):
        sim.step(dt)
        rt.tick(sim.time, dt)
    assert rt.set_mode(Mode.LEVELING)[0]
    for _ in range(round(seconds / dt)):
        sim.step(dt)
        st = rt.tick(sim.time, dt)
    c = SPEC.controller
    if math.degrees(sim.tilt_error()) < c.stall_deg + 0.5:
        return "level"
    if st.extra.get("leveling_stalled", 0.0) == 1.0:
        return "stalled, reported"
    moving = math.hypot(st.extra["command_pitch"], st.extra["command_roll"]) >= c.kp * c.deadband
    return "tilted, still moving" if moving else "tilted, silent"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=99)
    n = ap.parse_args().starts
    logging.disable(logging.WARNING)
    for lo, hi, seed in ((0.0, 30.0, 2), (60.0, 120.0, 1)):
        rng = np.random.default_rng(seed)
        counts: dict[str, int] = {}
        for k in range(n):
            tilt = math.radians(rng.uniform(lo, hi))
            az, yaw = rng.uniform(0.0, 2 * math.pi, size=2)
            axis = np.array([math.cos(az), math.sin(az), 0.0])
            R = axis_angle_rotation(axis, tilt) @ axis_angle_rotation([0, 0, 1], yaw) @ R0
            out = level_from(R, k)
            counts[out] = counts.get(out, 0) + 1
        print(f"base tilted {lo:g}-{hi:g}°, {n} static starts, 6 s of LEVELING: {counts}")


if __name__ == "__main__":
    main()
