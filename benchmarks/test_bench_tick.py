"""Per-tick cost of the tool loop (50 Hz: budget 20 ms; target well under 1 ms).

Three levels: the pure filter + controller pair the runtime runs each tick in LEVELING; a
whole ``ToolRuntime.tick`` on the simulated drivers (driver reads, filter, controller,
safety checks, command write, telemetry snapshot); and the same with the simulated world's
``step`` included (what a faster-than-real-time test pays per tick).

Run: ``.venv/bin/python -m pytest benchmarks/test_bench_tick.py --benchmark-only``.
"""

from __future__ import annotations

import math

import numpy as np

from articutool.rotations import quaternion_to_matrix
from articutool.spec import load_spec
from articutool.tool.api import Mode
from articutool.tool.controller import LevelingController
from articutool.tool.drivers.sim import SimWrist, axis_angle_rotation, constant_rate_motion
from articutool.tool.filter import ComplementaryFilter
from articutool.tool.runtime import ToolRuntime

SPEC = load_spec()
DT = SPEC.wrist.period
R0 = axis_angle_rotation([0.0, 1.0, 0.0], -math.pi / 2)


def test_bench_filter_plus_controller(benchmark):
    """One LEVELING tick's arithmetic: filter update → R_world←F0 → Alg. 1 with feed-forward."""
    filt = ComplementaryFilter.from_spec(SPEC.filter)
    ctrl = LevelingController.from_spec(SPEC)
    rng = np.random.default_rng(0)
    accel = np.array([1.2, -0.8, 9.7]) + rng.normal(0, 0.02, 3)
    gyro = np.array([0.3, -0.2, 0.5])
    q = np.array([0.1, -0.2])
    filt.update(accel, gyro, DT)

    def tick():
        quat = filt.update(accel, gyro, DT)
        R = ctrl.tool_base_orientation(quaternion_to_matrix(quat))
        return ctrl.update(R, q, DT, ctrl.tool_base_rate(gyro - filt.bias))

    cmd = benchmark(tick)
    assert np.isfinite(cmd).all() and np.abs(cmd).max() > 0


def _leveling_runtime():
    sim = SimWrist(SPEC, seed=0, gyro_bias=(0.01, -0.01, 0.005))
    sim.set_base_motion(constant_rate_motion([0.0, 0.0, 0.3], R0 @ axis_angle_rotation(
        [1.0, 0.0, 0.0], 0.2)))
    rt = ToolRuntime(SPEC, sim.motor_driver(), sim.imu_driver(), sim.ft_driver(),
                     clock=sim.clock)
    rt.open()
    for _ in range(25):
        sim.step(DT)
        rt.tick(sim.time, DT)
    ok, msg = rt.set_mode(Mode.LEVELING)
    assert ok, msg
    return sim, rt


def test_bench_runtime_tick_leveling(benchmark):
    """A whole runtime tick on the sim drivers (one IMU sample per tick, as at 50 Hz)."""
    sim, rt = _leveling_runtime()
    clock = [sim.time]

    def setup():  # the world advances outside the timed region
        sim.step(DT)
        clock[0] = sim.time
        return (), {}

    def tick():
        return rt.tick(clock[0], DT)

    benchmark.pedantic(tick, setup=setup, rounds=2000, iterations=1, warmup_rounds=50)
    st = rt.state()
    assert st.mode is Mode.LEVELING and st.fault == ""


def test_bench_runtime_tick_with_sim_step(benchmark):
    """Simulated world step + runtime tick: the cost of one closed-loop test tick."""
    sim, rt = _leveling_runtime()

    def tick():
        sim.step(DT)
        return rt.tick(sim.time, DT)

    benchmark(tick)
    assert rt.state().fault == ""
