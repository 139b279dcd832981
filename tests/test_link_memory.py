"""Tool server + PC client over the in-process transport, with the fake ToolAPI."""

from __future__ import annotations

import contextlib
import json
import math
import time
from collections.abc import Iterator

import numpy as np
import pytest

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.client import ArticutoolClient, ToolSilentError
from articutool.link.config import ConfigError, LinkConfig, load_config
from articutool.link.memory_transport import MemoryBus, MemoryTransport
from articutool.link.server import ToolServer
from articutool.tool.api import Mode
from articutool.trajectory import JointTrajectory
from conftest import wait_until
from link_fake_tool import FakeTool

CFG = LinkConfig(tool_timeout=0.3, client_timeout=0.3, heartbeat_period=0.05, call_timeout=1.0,
                 publish_rate_hz=50)


class Rig:
    def __init__(self, cfg: LinkConfig) -> None:
        self.bus = MemoryBus()
        self.tool = FakeTool()
        self.tool_tr = MemoryTransport(self.bus)
        self.server = ToolServer(self.tool, self.tool_tr, cfg)
        self.server.start()
        self.client_tr = MemoryTransport(self.bus)
        self.client = ArticutoolClient(cfg, self.client_tr)
        assert self.client.wait_for_tool(5.0)

    def close(self) -> None:
        self.client.close()
        self.server.stop()
        self.bus.close()


@pytest.fixture
def rig() -> Iterator[Rig]:
    r = Rig(CFG)
    yield r
    r.close()


def test_mode_switch_reaches_the_tool_and_telemetry_reports_it(rig: Rig) -> None:
    assert rig.client.set_mode("leveling", 10, -5) == (True, "mode LEVELING")
    assert rig.tool.mode == Mode.LEVELING and rig.tool.offsets == (10.0, -5.0)
    assert wait_until(lambda: rig.client.latest_state().mode == Mode.LEVELING)
    ok, msg = rig.client.set_mode(Mode.DISABLED, 200, 0)
    assert not ok and "pitch_offset" in msg
    with pytest.raises(ValueError, match="leveling"):
        rig.client.set_mode("twirl")


def test_twirl_runs_with_feedback_and_final_joint_values(rig: Rig) -> None:
    fb: list = []
    res = rig.client.run_primitive("TWIRL", [1.0], fb.append, timeout=5)
    assert res.success and res.status == m.GoalStatus.SUCCEEDED
    np.testing.assert_allclose(res.final_joint_values, [0.1, 0.2 + 2 * math.pi], rtol=1e-6)
    assert len(fb) >= 3
    pct = [f.percent_complete for f in fb]
    assert pct == sorted(pct) and 0 < pct[-1] <= 100
    assert all(len(f.current_joint_values) == 2 and f.name == "TWIRL" for f in fb)


def test_refusals_carry_the_tools_message(rig: Rig) -> None:
    res = rig.client.run_primitive("JUGGLE", [], timeout=5)
    assert not res.success and "unknown primitive" in res.message
    assert res.status == m.GoalStatus.ABORTED
    res = rig.client.run_primitive("TWIRL", [7.0], timeout=5)
    assert not res.success and "[-2, 2]" in res.message
    rig.client.set_mode("leveling")
    res = rig.client.run_primitive("TWIRL", [1.0], timeout=5)
    assert not res.success and "leveling" in res.message


def test_cancel_and_timeout_stop_the_primitive(rig: Rig) -> None:
    res = rig.client.run_primitive("SLOW", [], timeout=0.3)
    assert not res.success and "timed out" in res.message
    assert res.status == m.GoalStatus.CANCELED and "cancel" in rig.tool.calls
    assert rig.client.cancel() is False  # nothing running any more


def test_busy_tool_refuses_a_second_goal(rig: Rig) -> None:
    other = ArticutoolClient(CFG, MemoryTransport(rig.bus))
    try:
        import threading
        box: list = []
        t = threading.Thread(target=lambda: box.append(rig.client.run_primitive("SLOW", [],
                                                                                timeout=5)))
        t.start()
        assert wait_until(lambda: rig.tool.mode == Mode.PRIMITIVE)
        res = other.run_primitive("TWIRL", [1.0], timeout=5)
        assert not res.success and "busy" in res.message
        assert rig.client.cancel()
        t.join(5)
        assert box[0].status == m.GoalStatus.CANCELED and not box[0].success
    finally:
        other.close()


def test_trajectory_is_forwarded(rig: Rig) -> None:
    traj = JointTrajectory(("pitch", "roll"), np.array([0.0, 1.0]), np.array([[0, 0], [0.2, 0.3]]),
                           np.zeros((2, 2)))
    rig.client.follow_trajectory(traj)
    assert wait_until(lambda: len(rig.tool.trajectories) == 1)
    np.testing.assert_array_equal(rig.tool.trajectories[0].positions, traj.positions)
    bad = JointTrajectory(("a", "b"), np.array([0.0]), np.zeros((1, 2)), np.zeros((1, 2)))
    rig.client.follow_trajectory(bad)
    assert wait_until(lambda: rig.server.counters["rejected_trajectories"] == 1)


def test_a_future_header_stamp_delays_the_start(rig: Rig) -> None:
    """time 0 of a wrist trajectory is its header.stamp (item 7), or arrival if zero."""
    traj = JointTrajectory(("pitch", "roll"), np.array([0.0, 1.0]), np.array([[0, 0], [0.2, 0.3]]),
                           np.zeros((2, 2)))
    rig.client.follow_trajectory(traj)
    rig.client.follow_trajectory(traj, start_at=time.time() + 30.0)
    assert wait_until(lambda: len(rig.tool.start_delays) == 2)
    now_delay, later_delay = rig.tool.start_delays
    assert now_delay == 0.0
    assert 0.0 < later_delay <= 30.0
    with pytest.raises(ValueError, match="start_at"):
        rig.client.follow_trajectory(traj, start_at=math.nan)


def test_malformed_payloads_are_counted_and_nothing_crashes(rig: Rig) -> None:
    evil = MemoryTransport(rig.bus)
    n = rig.server.names
    evil.publish(n.joint_trajectory, b"\x00\x01\x00\x00\xff\xff\xff\xff")
    evil.publish(n.client_heartbeat, b"garbage")
    with pytest.raises(TimeoutError):  # no reply to a malformed request
        evil.call(n.set_orientation_control, b"\x00\x01\x00", timeout=0.3)
    evil.publish(n.joint_states, b"\x00\x01\x00\x00\x01")  # lies to the client
    assert wait_until(lambda: rig.server.counters["decode_errors"] == 3)
    assert wait_until(lambda: rig.client.counters["decode_errors"] >= 1)
    assert rig.client.set_mode("disabled")[0]  # both sides still work
    assert wait_until(lambda: rig.client.latest_state() is not None)


def test_silent_tool_is_detected_within_the_bound_and_recovers(rig: Rig) -> None:
    rig.tool_tr.connected = False
    assert wait_until(lambda: not rig.client.tool_alive, 5.0)
    with pytest.raises(ToolSilentError, match="last heard"):
        rig.client.set_mode("leveling")
    rig.tool_tr.connected = True
    assert rig.client.wait_for_tool(2.0)
    assert rig.client.set_mode("leveling")[0]


@pytest.mark.parametrize("policy", ["continue", "cancel"])
def test_link_loss_policy_for_a_running_primitive(policy: str) -> None:
    r = Rig(CFG.replace(link_loss_policy=policy))
    try:
        import threading
        threading.Thread(target=lambda: _swallow(r.client.run_primitive, "SLOW", [], timeout=5),
                         daemon=True).start()
        assert wait_until(lambda: r.tool.mode == Mode.PRIMITIVE)
        r.client_tr.connected = False  # the PC vanishes
        assert wait_until(lambda: r.server.counters["link_losses"] == 1, 3.0)
        if policy == "cancel":
            assert wait_until(lambda: "cancel" in r.tool.calls and r.tool.mode == Mode.DISABLED)
        else:
            time.sleep(0.1)  # a window in which nothing may happen
            assert "cancel" not in r.tool.calls and r.tool.mode == Mode.PRIMITIVE
    finally:
        r.client_tr.connected = True
        r.close()


def _swallow(fn, *a, **k) -> None:  # type: ignore[no-untyped-def]
    with contextlib.suppress(Exception):
        fn(*a, **k)


def test_config_validation_and_files(tmp_path) -> None:  # type: ignore[no-untyped-def]
    assert LinkConfig().endpoints("tool") == (("tcp/127.0.0.1:7447",), ())
    assert LinkConfig().endpoints("client") == ((), ("tcp/127.0.0.1:7447",))
    with pytest.raises(ConfigError, match="link_loss_policy"):
        LinkConfig(link_loss_policy="panic")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="tool_timeout"):
        LinkConfig(tool_timeout=-1)
    with pytest.raises(ConfigError, match="connect"):
        LinkConfig(connect="tcp/1.2.3.4:7447")  # type: ignore[arg-type]
    f = tmp_path / "link.toml"
    f.write_text('[link]\nconnect = ["tcp/10.0.0.2:7447"]\nlink_loss_policy = "cancel"\n')
    c = load_config(f)
    assert c.connect == ("tcp/10.0.0.2:7447",) and c.link_loss_policy == "cancel"
    j = tmp_path / "link.json"
    j.write_text(json.dumps({"mode": "peer", "listne": []}))
    with pytest.raises(ConfigError, match="listne"):
        load_config(j)


def test_action_protocol_details_for_a_ros2_style_client(rig: Rig) -> None:
    """A raw client (as a ROS 2 node would be) sees accept, status, result and cancel codes."""
    raw = MemoryTransport(rig.bus)
    n = rig.server.names
    statuses: list = []
    raw.subscribe(n.status, lambda d: statuses.append(cdr.decode(d, n.status.type)))
    gid = bytes(range(1, 17))
    req = cdr.encode(m.send_goal_request(gid, "TWIRL", [0.25]), n.send_goal.request_type)
    assert cdr.decode(raw.call(n.send_goal, req, 1.0), n.send_goal.response_type).accepted
    # the same goal id again is rejected
    assert not cdr.decode(raw.call(n.send_goal, req, 1.0), n.send_goal.response_type).accepted
    get = cdr.encode(cdr.msg(n.get_result.request_type, goal_id=m.goal_uuid(gid)),
                   n.get_result.request_type)
    res = m.result_from_msg(cdr.decode(raw.call(n.get_result, get, 5.0),
                                     n.get_result.response_type))
    assert res.success and res.status == m.GoalStatus.SUCCEEDED
    cancel = cdr.encode(m.cancel_request(gid), n.cancel_goal.request_type)
    R = cdr.typestore().types[n.cancel_goal.response_type]
    assert cdr.decode(raw.call(n.cancel_goal, cancel, 1.0),
                    n.cancel_goal.response_type).return_code == R.ERROR_GOAL_TERMINATED
    unknown = cdr.encode(m.cancel_request(bytes([9] * 16)), n.cancel_goal.request_type)
    assert cdr.decode(raw.call(n.cancel_goal, unknown, 1.0),
                    n.cancel_goal.response_type).return_code == R.ERROR_UNKNOWN_GOAL_ID
    assert wait_until(lambda: any(
        m.uuid_bytes(s.goal_info.goal_id) == gid and s.status == m.GoalStatus.SUCCEEDED
        for a in statuses for s in a.status_list))
    raw.close()


def test_a_raising_tool_api_becomes_a_refusal_not_a_silent_link(rig: Rig) -> None:
    def boom(*_: object) -> tuple[bool, str]:
        raise RuntimeError("motor bus down")
    rig.tool.set_mode = boom  # type: ignore[method-assign]
    ok, msg = rig.client.set_mode("leveling")
    assert not ok and "motor bus down" in msg
    assert rig.server.counters["handler_errors"] == 1
