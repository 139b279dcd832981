"""What ``--record FILE.mcap`` costs per tool tick: one tick's telemetry (joint states, IMU,
health, battery, as the tool publishes them at 50 Hz) encoded and written to MCAP.

    .venv/bin/python -m pytest benchmarks/test_bench_recording.py --benchmark-only
"""

import tempfile
from pathlib import Path

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.recording import McapRecorder
from articutool.tool.api import Mode, ToolState

STATE = ToolState(stamp=1.0, mode=Mode.LEVELING, joint_names=("atool_pitch", "atool_roll"),
                  position=(0.1, -0.25), velocity=(0.5, 0.0),
                  orientation_wxyz=(0.9, 0.1, -0.2, 0.3), angular_velocity=(0.01, 0.02, 0.03),
                  linear_acceleration=(0.1, 0.2, 9.81), battery_voltage=11.9,
                  loop_period_mean=0.02, loop_jitter=0.0004, loop_overruns=1, fault="",
                  extra={"imu_stale": 0.0})
T = 1_700_000_000.0


def test_record_one_tick_of_telemetry(benchmark):
    with tempfile.TemporaryDirectory() as d, McapRecorder(Path(d) / "b.mcap") as rec:
        def tick():
            for topic, typename, msg in (
                    ("/a/joint_states", cdr.JOINT_STATE, m.joint_state_msg(STATE, T)),
                    ("/a/imu/data", cdr.IMU, m.imu_msg(STATE, T)),
                    ("/a/health", cdr.DIAGNOSTIC_ARRAY, m.health_msg(STATE, T, {})),
                    ("/a/battery", cdr.BATTERY_STATE, m.battery_msg(STATE, T))):
                rec.write_msg(topic, typename, msg, T)
        benchmark(tick)
        assert rec.count > 0
