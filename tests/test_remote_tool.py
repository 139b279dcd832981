"""RemoteTool: the link client as the ToolAPI the feeding tree drives. Against the
real runtime (``ToolRuntime`` on ``SimWrist`` in real time) behind a ``ToolServer`` on the
memory transport, and over a link that carries nothing: the link's failures become refusals,
never exceptions, and every goal is answered."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import pytest

from articutool.link.client import ArticutoolClient
from articutool.link.memory_transport import MemoryBus, MemoryTransport
from articutool.link.remote_tool import RemoteTool
from articutool.tool.api import Mode, PrimitiveStatus
from articutool.trajectory import JointTrajectory
from conftest import wait_until
from test_link_goals import CFG, _RealTool


def _answer(tool: RemoteTool, within_s: float = 5.0) -> PrimitiveStatus:
    def done() -> bool:
        st = tool.primitive_status()
        return st is not None and st.done

    assert wait_until(done, within_s), f"no answer within {within_s} s: {tool.primitive_status()}"
    return tool.primitive_status()  # type: ignore[return-value]


@pytest.fixture
def real() -> Iterator[tuple[_RealTool, RemoteTool]]:
    r = _RealTool()
    # The runtime here runs in real time in this process: a 2 s silence bound, not the 0.5 s of
    # the link tests, so a loaded machine (load 35) that starves its thread is not "silence".
    client = ArticutoolClient(CFG.replace(tool_timeout=2.0), MemoryTransport(r.bus),
                              sender="pc-1")
    assert client.wait_for_tool(5.0)
    yield r, RemoteTool(client)
    client.close()
    r.close()


def test_a_primitive_runs_to_its_result_and_a_refusal_names_the_tools_reason(
        real: tuple[_RealTool, RemoteTool]) -> None:
    rt, tool = real
    assert tool.start_primitive("TWIRL_CW", [0.2, 2.0]) == (True, "goal sent")
    assert tool.start_primitive("TWIRL_CW", [0.2, 2.0])[0] is False  # its goal still runs
    done = _answer(tool)
    assert done.success and done.name == "TWIRL_CW"
    assert rt.rt.primitive_status() is not None and rt.rt.primitive_status().success
    assert tool.start_primitive("NO_SUCH_PRIMITIVE", [])[0]  # sent; the tool refuses it
    refused = _answer(tool)
    assert not refused.success and "NO_SUCH_PRIMITIVE" in refused.message, refused


def test_a_cancel_and_a_mode_change_reach_the_tool_and_state_is_fresh(
        real: tuple[_RealTool, RemoteTool]) -> None:
    rt, tool = real
    t0 = time.monotonic()
    assert tool.start_primitive("TWIRL_CW", [3.0, 1.0])[0]
    assert wait_until(lambda: rt.rt.mode == Mode.PRIMITIVE)
    assert tool.cancel_primitive()
    st = _answer(tool)
    assert not st.success and rt.rt.mode == Mode.DISABLED
    assert not tool.cancel_primitive()  # nothing of this object's runs now
    ok, msg = tool.set_mode(Mode.LEVELING)
    assert ok, msg
    assert wait_until(lambda: tool.state().mode == Mode.LEVELING)
    s = tool.state()
    # Stamped on this process's monotonic clock when it arrived: after the test began.
    assert t0 <= s.stamp <= time.monotonic(), (t0, s.stamp)


def test_over_a_link_that_carries_nothing_every_call_is_refused_and_the_goal_answered() -> None:
    bus = MemoryBus()
    client = ArticutoolClient(CFG, MemoryTransport(bus), sender="pc-1")
    tool = RemoteTool(client)
    try:
        assert math.isinf(tool.state().stamp) and tool.state().stamp < 0  # nothing heard: stale
        for ok, msg in (tool.set_mode(Mode.DISABLED), tool.clear_fault(),
                        tool.follow_trajectory(JointTrajectory(
                            ("pitch", "roll"), [0.0], [[0.0, 0.0]], [[0.0, 0.0]]))):
            assert ok is False and msg.startswith("link: "), msg
        assert tool.start_primitive("TWIRL_CW", [1.0, 1.0])[0]
        st = _answer(tool)
        assert not st.success and st.message.startswith("link: "), st
        assert not tool.cancel_primitive()
        ok, msg = tool.set_mode(Mode.PRIMITIVE)  # bad input: refused naming it, nothing sent
        assert not ok and "mode must be" in msg, msg
    finally:
        client.close()
        bus.close()
