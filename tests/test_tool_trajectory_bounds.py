"""A wrist trajectory's length is bounded before it is sampled: a signed trajectory spanning
1e9 s asked the tool for 800 GiB (1e6 s, nanoseconds sent as seconds, ~10 GB on a Pi). Two
real processes: ``articutool tool`` (simulated wrist) and a client in pytest."""

from __future__ import annotations

import time

import numpy as np
import pytest

from articutool.link.client import ArticutoolClient
from articutool.spec import Spec
from articutool.tool.drivers.sim import SimWrist
from articutool.tool.runtime import ToolRuntime
from articutool.trajectory import JointTrajectory
from conftest import free_port, packaged_spec, wait_until
from test_tool_cli import Tool, client_cfg

NAMES = packaged_spec().wrist.joint_names


def _traj(end: float, start: float = 0.0) -> JointTrajectory:
    """Holds pitch 0, roll 0 from ``start`` to ``end`` seconds."""
    return JointTrajectory(NAMES, np.array([start, end]), np.zeros((2, 2)), np.zeros((2, 2)))


def _rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        return next(int(ln.split()[1]) for ln in f if ln.startswith("VmRSS:")) / 1024.0


def test_the_tool_refuses_trajectories_longer_than_the_bound_before_sampling_them(
        spec: Spec) -> None:
    tool = Tool(free_port())
    try:
        with ArticutoolClient(client_cfg(tool)) as pc:
            assert pc.wait_for_tool(20.0)

            def counter(key: str) -> float:
                st = pc.latest_state()
                return st.extra.get(key, 0.0) if st is not None else 0.0
            rejected = counter("link_rejected_trajectories")
            # 1e9 s first: before the bound the tool failed to allocate (MemoryError, a
            # handler error), and the 1e6 s one would then have taken ~10 GB here.
            for end in (1e9, 1e6, spec.primitives.max_duration_s + 1.0):
                pc.follow_trajectory(_traj(end))
                rejected += 1
                assert wait_until(lambda r=rejected: counter("link_rejected_trajectories") >= r,
                                  10.0), end
                assert counter("link_handler_errors") == 0
            # a start beyond the bound (header.stamp far ahead) is refused by the loop
            pc.follow_trajectory(_traj(2.0, 0.5), start_at=time.time() + 1e6)
            assert wait_until(lambda: counter("link_rejected_trajectories") >= rejected + 1, 10)
            st = pc.latest_state()
            assert st is not None and st.mode.name == "DISABLED"  # nothing moved
            pc.follow_trajectory(_traj(2.0, 0.5))  # a sound one is still followed
            assert wait_until(lambda: (pc.latest_state() or st).mode.name == "TRAJECTORY", 10)
            assert _rss_mb(tool.proc.pid) < 1000.0
            assert pc.set_mode("disabled")[0]
        code, _out, err = tool.interrupt()
    finally:
        tool.kill()
    assert code == 0, err
    assert "Traceback" not in err and "MemoryError" not in err
    assert "at most 120 s after its start (spec.primitives.max_duration_s)" in err
    assert "more than 120 s (spec.primitives.max_duration_s)" in err


@pytest.mark.parametrize("end", [1e9, 1e6, 120.5])
def test_the_runtime_says_why_a_long_trajectory_is_refused(spec: Spec, end: float) -> None:
    sim = SimWrist(spec, seed=0)
    rt = ToolRuntime(spec, sim.motor_driver(), sim.imu_driver(), clock=sim.clock)
    rt.open()
    rt.tick()
    ok, msg = rt.follow_trajectory(_traj(end, 0.5))
    assert not ok and "spec.primitives.max_duration_s" in msg and f"{end:g} s" in msg
    with pytest.raises(ValueError, match="max_duration_s"):
        rt.prevalidate_trajectory(_traj(end))
    ok, msg = rt.follow_trajectory(_traj(120.0, 0.5))  # the bound itself is allowed
    assert ok, msg
    rt.close()
