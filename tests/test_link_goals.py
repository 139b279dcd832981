"""Every goal gets its own result: the ToolServer identifies goals by
the goal id it started, never by comparing primitive statuses.

Over the in-process transport, against the fake tool and against the real ``ToolRuntime`` on
``SimWrist`` stepped in real time; the two-process versions are in ``test_tool_cli.py``.
"""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Iterator

import pytest

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.client import ArticutoolClient
from articutool.link.config import LinkConfig
from articutool.link.memory_transport import MemoryBus, MemoryTransport
from articutool.link.server import ToolServer
from articutool.link.transport import Names
from articutool.spec import load_spec
from articutool.tool.api import PrimitiveStatus
from articutool.tool.drivers.base import HardwareError
from conftest import wait_until
from link_fake_tool import FakeTool

CFG = LinkConfig(tool_timeout=0.5, client_timeout=0.5, heartbeat_period=0.05, call_timeout=2.0,
                 publish_rate_hz=50)
NAMES = Names(CFG.namespace)


def send_goal(tr: MemoryTransport, gid: bytes, name: str, params: list[float]) -> bool:
    ep = NAMES.send_goal
    reply = tr.call(ep, cdr.encode(m.send_goal_request(gid, name, params), ep.request_type), 2.0)
    return bool(cdr.decode(reply, ep.response_type).accepted)


def get_result(tr: MemoryTransport, gid: bytes, timeout: float) -> m.PrimitiveResult:
    ep = NAMES.get_result
    req = cdr.encode(cdr.msg(ep.request_type, goal_id=m.goal_uuid(gid)), ep.request_type)
    return m.result_from_msg(cdr.decode(tr.call(ep, req, timeout), ep.response_type))


def test_a_goal_finishing_between_ticks_gets_its_result_when_the_next_goal_starts() -> None:
    bus = MemoryBus()
    tool = FakeTool()
    # One tick at start, then none for 1000 s: the test decides when the server ticks.
    server = ToolServer(tool, MemoryTransport(bus), CFG, rate_hz=1e-3)
    server.start()
    tr = MemoryTransport(bus)
    try:
        a, b = uuid.uuid4().bytes, uuid.uuid4().bytes
        assert send_goal(tr, a, "TWIRL", [0.25])
        assert wait_until(lambda: tool.primitive_status().done, 10.0)  # A ended, no tick saw it
        assert send_goal(tr, b, "TWIRL", [0.25])
        res_a = get_result(tr, a, 2.0)  # answered, not lost
        assert res_a.success and res_a.status == m.GoalStatus.SUCCEEDED
        assert wait_until(lambda: tool.primitive_status().done, 10.0)
        server.tick()
        res_b = get_result(tr, b, 2.0)
        assert res_b.success and res_b.status == m.GoalStatus.SUCCEEDED
        assert res_b.final_joint_values != res_a.final_joint_values  # B's own result
    finally:
        server.stop()
        bus.close()


def test_an_identical_status_twice_is_the_new_goals_own_result() -> None:
    """HOMING at home ends at once with the same status every time (item 9)."""
    bus = MemoryBus()
    tool = FakeTool()
    server = ToolServer(tool, MemoryTransport(bus), CFG)
    server.start()
    client = ArticutoolClient(CFG, MemoryTransport(bus))
    try:
        assert client.wait_for_tool(5.0)
        results = [client.run_primitive("HOMING", [2.0], timeout=5.0) for _ in range(4)]
        assert [r.status for r in results] == [m.GoalStatus.SUCCEEDED] * 4, results
        assert all(r.final_joint_values == (0.0, 0.0) for r in results)
    finally:
        client.close()
        server.stop()
        bus.close()


class _RealTool:
    """``ToolRuntime`` on ``SimWrist`` stepped in real time, served on a MemoryBus."""

    def __init__(self) -> None:
        from articutool.tool.drivers import make_drivers
        from articutool.tool.drivers.sim import SimWrist
        from articutool.tool.runtime import ToolRuntime

        spec = load_spec()
        self.sim = SimWrist(spec)
        self.rt = ToolRuntime(spec, *make_drivers(spec, "sim", sim=self.sim),
                              clock=self.sim.clock)
        self.rt.open()
        self.stop = threading.Event()
        self.threads = [threading.Thread(target=self.rt.run, args=(self.stop,), daemon=True),
                        threading.Thread(target=self._step, daemon=True)]
        for th in self.threads:
            th.start()
        self.bus = MemoryBus()
        self.server = ToolServer(self.rt, MemoryTransport(self.bus), CFG, loop=self.rt)
        self.server.start()

    def _step(self) -> None:
        last = time.monotonic()
        while not self.stop.wait(0.002):
            now = time.monotonic()
            self.sim.step(max(now - last, 1e-6))
            last = now

    def close(self) -> None:
        self.server.stop()
        self.stop.set()
        for th in self.threads:
            th.join(timeout=5)
        self.rt.close()
        self.bus.close()


@pytest.fixture
def real() -> Iterator[_RealTool]:
    r = _RealTool()
    yield r
    r.close()


def test_real_runtime_back_to_back_goals_from_two_clients(real: _RealTool) -> None:
    c1 = ArticutoolClient(CFG, MemoryTransport(real.bus))
    c2 = ArticutoolClient(CFG, MemoryTransport(real.bus))
    try:
        assert c1.wait_for_tool(5.0) and c2.wait_for_tool(5.0)
        # Identical goals back to back, alternating clients, the tool at home throughout.
        for c in (c1, c2, c1, c2):
            res = c.run_primitive("HOMING", [2.0], timeout=10.0)
            assert res.status == m.GoalStatus.SUCCEEDED, res
        # A real motion on one client while the other asks: the other is refused (busy),
        # the first gets its own result, and both goals end.
        fb: list[PrimitiveStatus] = []
        out: dict[str, m.PrimitiveResult] = {}
        th = threading.Thread(target=lambda: out.setdefault(
            "twirl", c1.run_primitive("TWIRL_CW", [0.25, 2.0], fb.append, timeout=20.0)))
        th.start()
        assert wait_until(lambda: bool(fb), 10.0)  # c1's primitive is running
        busy = c2.run_primitive("HOMING", [2.0], timeout=10.0)
        th.join(timeout=30)
        assert not th.is_alive()
        assert busy.status == m.GoalStatus.ABORTED and "running" in busy.message, busy
        assert out["twirl"].status == m.GoalStatus.SUCCEEDED, out["twirl"]
        # ... and straight after it, from the other client, the way home.
        res = c2.run_primitive("HOMING", [2.0], timeout=10.0)
        assert res.status == m.GoalStatus.SUCCEEDED, res
    finally:
        c1.close()
        c2.close()



def test_a_hardware_fault_is_cleared_over_the_link_only_explicitly(real: _RealTool) -> None:
    # A refused LEVELING request must not reboot the motors; clear_fault does,
    # and only once the overheated motor has cooled below spec.motors.reboot_below_c.
    client = ArticutoolClient(CFG, MemoryTransport(real.bus))
    try:
        assert client.wait_for_tool(2.0)
        real.sim.set_motor_temperature(85.0)
        real.sim.set_hardware_error("roll", HardwareError.OVERHEATING)
        assert wait_until(lambda: bool(real.rt.state().fault), 10.0)
        for _ in range(2):
            ok, msg = client.set_mode("leveling")
            assert not ok and "clear_fault" in msg
        ticks = real.rt.stats.ticks
        assert wait_until(lambda: real.rt.stats.ticks >= ticks + 5)
        assert real.rt.state().fault  # two refusals rebooted nothing
        ok, msg = client.clear_fault()
        assert not ok and "reboot_below_c" in msg  # still hot
        real.sim.set_motor_temperature(40.0)  # read back at the next tick
        assert wait_until(lambda: client.clear_fault()[0], 10.0)
        assert wait_until(lambda: client.set_mode("leveling")[0], 10.0)
        assert wait_until(lambda: not real.rt.state().fault, 10.0)
    finally:
        client.close()
