"""The network cannot slow the loop: bounded inbox, one command per tick,
size and rate limits, and a flood against a real tool process."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.client import ArticutoolClient, LinkError
from articutool.link.config import LinkConfig
from articutool.link.memory_transport import MemoryBus, MemoryTransport
from articutool.link.server import ToolServer
from articutool.link.transport import Names, RateGate, key_expr
from articutool.link.zenoh_transport import ZenohTransport
from articutool.tool.api import Mode
from conftest import free_port, wait_until
from link_fake_tool import FakeTool

HERE = Path(__file__).parent
CFG = LinkConfig(tool_timeout=0.5, client_timeout=1.0, heartbeat_period=0.05,
                 call_timeout=2.0, publish_rate_hz=50, inbox_size=3)


class LoopTool(FakeTool):
    """A FakeTool with a loop hook: the test plays the loop and calls the hook per tick."""

    def __init__(self) -> None:
        super().__init__()
        self.hook = None

    def set_link_work(self, work):  # type: ignore[no-untyped-def]
        self.hook = work


def _tick(tool: LoopTool) -> None:
    assert tool.hook is not None
    tool.hook()


def test_the_loop_runs_one_command_per_tick_stops_first_and_excess_is_refused() -> None:
    bus = MemoryBus()
    tool = LoopTool()
    server = ToolServer(tool, MemoryTransport(bus, "tool"), CFG, loop=tool)
    server.start()
    # The calls wait for the test's ticks: a loaded machine may take long to get there.
    client = ArticutoolClient(CFG.replace(call_timeout=60.0), MemoryTransport(bus, "pc-1"),
                              sender="pc-1")
    replies: list[tuple[bool, str]] = []
    try:
        assert client.wait_for_tool(30.0) and tool.hook is not None
        threads = [threading.Thread(target=lambda o=o: replies.append(
            client.set_mode("leveling", o))) for o in (1.0, 2.0, 3.0, 4.0, 5.0)]
        for i, th in enumerate(threads):
            th.start()  # in this order: each queued or refused before the next is sent
            assert wait_until(lambda n=i + 1: len(server.inbox.commands) + len(replies) == n,
                              30.0)
        assert len(replies) == 2  # 3 queued, 2 refused at once
        assert all(not ok and "inbox is full" in msg for ok, msg in replies)
        assert tool.calls == []  # nothing ran between ticks
        stop = threading.Thread(target=lambda: replies.append(client.set_mode("disabled")))
        stop.start()
        assert wait_until(lambda: len(server.inbox.stops) == 1, 3.0)
        # the stop supersedes the three queued: each refused, none left to run
        assert wait_until(lambda: len(replies) == 5, 30.0) and not server.inbox.commands
        assert all(not ok and "superseded by a stop" in msg for ok, msg in replies[2:])
        _tick(tool)  # the stop, alone
        assert tool.calls == ["set_mode DISABLED"]
        _tick(tool)  # nothing left: a tick with an empty inbox does nothing
        assert tool.calls == ["set_mode DISABLED"]
        stop.join(timeout=30)
        after = threading.Thread(target=lambda: replies.append(client.set_mode("leveling", 6.0)))
        after.start()  # a command sent after the stop runs normally
        assert wait_until(lambda: len(server.inbox.commands) == 1, 30.0)
        _tick(tool)
        for th in (*threads, stop, after):
            th.join(timeout=30)
        assert tool.calls == ["set_mode DISABLED", "set_mode LEVELING"]
        assert replies[5][0] and replies[6][0]  # the stop, then the later LEVELING
        assert tool.offsets == (6.0, 0.0)
        assert server.counters["dropped_excess"] == 2
        assert server.counters["superseded"] == 3
        assert server.counters["commands"] == 2
    finally:
        client.close()
        server.stop()
        bus.close()


def test_oversized_payloads_are_dropped_unread_and_counted() -> None:
    bus = MemoryBus()
    tool = FakeTool()
    cfg = CFG.replace(max_trajectory_bytes=4096, max_request_bytes=256)
    server = ToolServer(tool, MemoryTransport(bus, "tool"), cfg)
    server.start()
    raw = MemoryTransport(bus, "pc-1")
    n = Names(tool_id=cfg.tool_id)
    try:
        raw.publish(n.joint_trajectory, b"\x00\x01\x00\x00" + bytes(5000))
        req = cdr.encode(m.soc_request(Mode.LEVELING, 0.0, 0.0), n.set_orientation_control
                       .request_type)
        padded = req + bytes(300)
        try:
            raw.call(n.set_orientation_control, padded, 0.3)
            answered = True
        except TimeoutError:
            answered = False
        assert not answered
        assert wait_until(lambda: server.counters["oversized"] == 2, 2.0)
        assert server.counters["decode_errors"] == 0  # never reached the decoder
        assert tool.calls == [] and tool.trajectories == []
    finally:
        server.stop()
        bus.close()


def test_rate_gate_passes_the_rate_and_drops_the_rest() -> None:
    t = [0.0]
    gate = RateGate(100.0, burst=5)
    gate._clock = lambda: t[0]
    gate._t = 0.0
    passed = sum(gate.allow() for _ in range(50))  # a burst at one instant
    assert passed == 5
    t[0] = 1.0  # one second later: the bucket refilled to its burst, not to 100
    assert sum(gate.allow() for _ in range(50)) == 5
    got = 0
    for i in range(1000):  # 1000 attempts over 1 s: about the rate
        t[0] = 2.0 + i / 1000
        got += gate.allow()
    assert 95 <= got <= 106


@pytest.mark.floods
def test_a_flood_is_dropped_and_counted_and_a_stop_still_gets_through() -> None:
    """Two processes: 2 s of ~2000 goals/s and 4 MB trajectories at the fake tool, while
    a client's DISABLED is answered. (Loop timing under a flood is measured, not asserted:
    benchmarks/bench_link_flood.py.)"""
    port = free_port()
    env = dict(os.environ, PYTHONPATH=str(HERE.parent / "src"))
    proc = subprocess.Popen([sys.executable, str(HERE / "link_fake_tool.py"), "--listen",
                             f"tcp/127.0.0.1:{port}"], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, env=env)
    cfg = LinkConfig(connect=(f"tcp/127.0.0.1:{port}",), listen=(), tool_timeout=1.0,
                     heartbeat_period=0.05, call_timeout=30.0)
    client = ArticutoolClient(cfg, sender="caregiver")
    flood = ZenohTransport(cfg, "client", identity="flooder")
    try:
        assert client.wait_for_tool(60.0)
        names = Names(tool_id=cfg.tool_id)
        key = key_expr(0, names.send_goal)
        big = b"\x00\x01\x00\x00" + bytes(4_000_000)
        stop_reply: list[tuple[bool, str]] = []
        end = time.monotonic() + 2.0
        asked = False
        while time.monotonic() < end:
            for _ in range(20):
                p = cdr.encode(m.send_goal_request(uuid.uuid4().bytes, "TWIRL", [0.1]),
                             names.send_goal.request_type)
                flood._session.get(key, handler=lambda _r: None, payload=p, timeout=1.0)
            flood.publish(names.joint_trajectory, big)
            if not asked and time.monotonic() > end - 1.5:
                asked = True
                threading.Thread(target=lambda: stop_reply.append(
                    client.set_mode("disabled"))).start()
            time.sleep(0.01)
        assert wait_until(lambda: bool(stop_reply), 5.0)
        assert stop_reply[0][0], stop_reply
        # Beyond the rate a caller is told so by the tool (an error reply), not left to time
        # out: 300 calls sent at once (the limit being 200/s, burst 40) are all answered,
        # each refusal naming its reason (the rate, or the 16 commands the inbox holds).
        cf = names.clear_fault
        req = cdr.encode(m.trigger_request(), cf.request_type)
        replies: list[str] = []
        for _ in range(300):
            flood._session.get(key_expr(0, cf), payload=req, timeout=10.0, handler=lambda r: (
                replies.append("" if r.ok is not None else r.err.payload.to_string())))
        assert wait_until(lambda: len(replies) == 300, 15.0), len(replies)
        refusals = [r for r in replies if r]
        assert any("rate limited" in r for r in refusals), replies[:3]
        assert all("rate limited" in r or "inbox is full" in r for r in refusals), refusals
        assert wait_until(lambda: (client.latest_state() is not None and client.latest_state()
                                   .extra.get("link_rate_limited", 0) > 0), 3.0)
        extra = client.latest_state().extra
        assert extra["link_oversized"] > 0  # the 4 MB trajectories (limit 1 MiB)
    finally:
        flood.close()
        client.close()
        out, _ = proc.communicate(input="", timeout=60)
    calls = next(ln for ln in out.splitlines() if ln.startswith("CALLS"))[6:].split(";")
    assert "set_mode DISABLED" in calls
    assert calls.count("start TWIRL") >= 1  # the flood's goals did reach the tool, bounded


def test_link_loss_is_the_lease_holders_silence_not_any_clients() -> None:
    """Policy 'cancel': the commanding PC goes silent while an observer chats on; the
    running primitive is cancelled (the observer's heartbeats do not hide it)."""
    bus = MemoryBus()
    tool = FakeTool()
    cfg = CFG.replace(link_loss_policy="cancel", client_timeout=0.5)
    server = ToolServer(tool, MemoryTransport(bus, "tool"), cfg)
    server.start()
    holder_tr = MemoryTransport(bus, "pc-1")
    holder = ArticutoolClient(cfg, holder_tr, sender="pc-1")
    observer = ArticutoolClient(cfg, MemoryTransport(bus, "pc-2"), sender="pc-2")
    try:
        assert holder.wait_for_tool(5.0) and observer.wait_for_tool(5.0)
        def run() -> None:
            with contextlib.suppress(LinkError):  # the holder is cut off: it sees silence
                holder.run_primitive("SLOW", [], timeout=30.0)
        threading.Thread(target=run, daemon=True).start()
        assert wait_until(lambda: tool.mode == Mode.PRIMITIVE, 3.0)
        holder_tr.connected = False  # the PC that commands is gone; pc-2 keeps beating
        assert wait_until(lambda: "cancel" in tool.calls, 3.0), tool.calls
        assert server.counters["link_losses"] == 1
    finally:
        observer.close()
        holder_tr.connected = True
        holder.close()
        server.stop()
        bus.close()


def test_prevalidated_trajectories_leave_the_loop_only_the_start_to_check() -> None:
    import numpy as np
    import pytest

    from articutool.spec import load_spec
    from articutool.tool.drivers import make_drivers
    from articutool.tool.drivers.sim import SimWrist
    from articutool.tool.runtime import ToolRuntime
    from articutool.trajectory import JointTrajectory, TrajectoryError

    spec = load_spec()
    sim = SimWrist(spec)
    rt = ToolRuntime(spec, *make_drivers(spec, "sim", sim=sim), clock=sim.clock)
    with rt:
        for _ in range(5):
            sim.step(spec.wrist.period)
            rt.tick(sim.time, spec.wrist.period)
        names = tuple(rt.state().joint_names)
        q = np.array(rt.state().position)
        far = JointTrajectory(names, np.array([0.0, 1.0]), np.vstack([q + 0.5, q + 0.5]),
                              np.zeros((2, 2)))
        pre = rt.prevalidate_trajectory(far)  # within the limits: passes the link's part
        ok, msg = rt.follow_trajectory(pre)  # the loop still checks the start
        assert not ok and "first point (t = 0)" in msg
        lim = spec.wrist.limits[0][1]
        out = JointTrajectory(names, np.array([0.5, 1.0]),
                              np.array([[lim + 0.1, q[1]], [lim + 0.1, q[1]]]),
                              np.zeros((2, 2)))
        with pytest.raises(TrajectoryError, match=r"spec\.wrist limits"):
            rt.prevalidate_trajectory(out)
        fast = JointTrajectory(names, np.array([0.02, 1.0]), np.vstack([q + 0.3, q + 0.3]),
                               np.zeros((2, 2)))  # reaching the first point needs speed
        ok, msg = rt.follow_trajectory(rt.prevalidate_trajectory(fast))
        assert not ok and "interpolated trajectory" in msg  # the new first segment, checked
        good = JointTrajectory(names, np.array([0.5, 1.0]), np.vstack([q, q + 0.05]),
                               np.zeros((2, 2)))
        assert rt.follow_trajectory(rt.prevalidate_trajectory(good))[0]


def test_a_flood_of_malformed_payloads_logs_a_few_lines_and_counts_them_all(caplog) -> None:  # type: ignore[no-untyped-def]
    """One WARNING per malformed payload would be ~1 800 lines/s under a flood."""
    import logging

    bus = MemoryBus()
    server = ToolServer(FakeTool(), MemoryTransport(bus, "tool"), CFG.replace(
        max_rate_hz=100_000))  # every payload reaches the decoder
    server.start()
    raw = MemoryTransport(bus, "pc-1")
    ep = Names(tool_id=CFG.tool_id).client_heartbeat
    try:
        with caplog.at_level(logging.WARNING, logger="articutool.link"):
            for i in range(3000):
                raw.publish(ep, b"\x00\x01\x00\x00" + i.to_bytes(2, "little"))
            assert wait_until(lambda: server.counters["decode_errors"] == 3000, 10.0)
            assert wait_until(lambda: "3000 decode_errors so far" in caplog.text, 2.0)
        lines = [r for r in caplog.records if "malformed" in r.getMessage()]
        assert len(lines) == 13, len(lines)  # the first 10, then 1 in 1000
    finally:
        server.stop()
        bus.close()


_OPS = ("disable", "level", "cancel_all", "cancel_other", "goal", "tick")


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(_OPS), st.sampled_from(("pc-1", "pc-2"))),
                max_size=60))
def test_stops_are_never_refused_and_go_first_whatever_the_order(ops) -> None:  # type: ignore[no-untyped-def]
    """As a property over every interleaving of requests and loop ticks: no
    stop is refused, at most one DISABLED and one cancel wait, a tick with a stop waiting runs
    a stop, and every request is answered exactly once (equal stops joined, not dropped)."""
    tool = LoopTool()
    bus = MemoryBus()
    server = ToolServer(tool, MemoryTransport(bus, "tool"), CFG.replace(inbox_size=2),
                        loop=tool)
    try:
        _play(server, tool, ops)
    finally:
        bus.close()


def _play(server: ToolServer, tool: LoopTool, ops: list[tuple[str, str]]) -> None:
    from articutool.link.auth import Sender
    from articutool.link.transport import RefusalError

    n = server.names
    answers: dict[int, list[object]] = {}
    stops: set[int] = set()

    def send(i: int, handler, ep, request, who: str) -> None:  # type: ignore[no-untyped-def]
        answers[i] = []
        try:
            handler(cdr.encode(request, ep.request_type), answers[i].append,
                    Sender(who, True, "pc"))
        except RefusalError as why:  # an error reply (rate, inbox full)
            answers[i].append(f"error: {why}")

    for i, (op, who) in enumerate(ops):
        if op == "tick":
            waiting = len(server.inbox.stops)
            calls = len(tool.calls)
            server.work_once()
            if waiting:  # a stop ran (a cancel may find nothing left to cancel), nothing else
                assert tool.calls[calls:] in ([], ["set_mode DISABLED"], ["cancel"])
            continue
        if op == "disable":
            stops.add(i)
            send(i, server.handlers.on_set_mode, n.set_orientation_control,
                 m.soc_request(Mode.DISABLED, 0.0, 0.0), who)
        elif op == "level":
            send(i, server.handlers.on_set_mode, n.set_orientation_control,
                 m.soc_request(Mode.LEVELING, 1.0, 0.0), who)
        elif op in ("cancel_all", "cancel_other"):
            stops.add(i)
            gid = None if op == "cancel_all" else uuid.uuid4().bytes
            send(i, server.handlers.on_cancel, n.cancel_goal, m.cancel_request(gid), who)
        else:
            send(i, server.handlers.on_send_goal, n.send_goal,
                 m.send_goal_request(uuid.uuid4().bytes, "SLOW", []), who)
        assert len(server.inbox.stops) <= 2
    while server.inbox.stops or server.inbox.commands:
        server.work_once()
    assert all(len(a) == 1 for a in answers.values()), answers
    for i in stops:
        reply = answers[i][0]
        assert isinstance(reply, bytes), reply  # a reply, not an error
        if ops[i][0] == "disable":
            assert cdr.decode(reply, n.set_orientation_control.response_type).success


def _inbox(size: int = 8):  # type: ignore[no-untyped-def]
    from articutool.link.counters import LinkCounters
    from articutool.link.inbox import CommandInbox
    return CommandInbox(size, LinkCounters(), threading.RLock(), threading.Event())


def test_a_disabled_supersedes_the_motion_queued_before_it_and_nothing_after() -> None:
    inbox = _inbox()
    ran: list[str] = []
    answered: list[tuple[str, bool]] = []

    def queue(name: str, motion: bool = True, key: object = None) -> None:
        assert inbox.submit(lambda: ran.append(name), key=key, discard=(
            (lambda cancelled: answered.append((name, cancelled))) if motion else None))
    queue("leveling")
    queue("goal", key=("goal", b"g"))
    queue("trajectory")
    queue("clear_fault", motion=False)
    stopped: list[object] = []
    inbox.submit_stop("disable", lambda: ran.append("disable") or "ok", stopped.append,
                      supersede=True)
    # answered as the stop arrives, before any tick: superseded, not cancelled
    assert answered == [("leveling", False), ("goal", False), ("trajectory", False)]
    queue("after")
    while inbox.stops or inbox.commands:
        inbox.work_once()
    assert ran == ["disable", "clear_fault", "after"]  # the queued motion never ran
    assert stopped == ["ok"]
    c = inbox.counters
    assert (c["superseded"], c["commands"], c["handler_errors"]) == (3, 3, 0)


def test_a_stop_without_supersede_and_a_cancel_discard_only_their_goal() -> None:
    inbox = _inbox()
    ran: list[str] = []
    answered: list[tuple[str, bool]] = []
    for name in ("a", "b", "leveling"):
        key = ("goal", name) if name != "leveling" else None
        assert inbox.submit(lambda n=name: ran.append(n), key=key,
                            discard=lambda cancelled, n=name: answered.append((n, cancelled)))
    assert inbox.discard(lambda k: k == ("goal", "a")) == [("goal", "a")]
    assert answered == [("a", True)]  # cancelled, answered once
    inbox.submit_stop(("cancel", "x"), lambda: None, lambda _: None)  # a cancel: no supersede
    while inbox.stops or inbox.commands:
        inbox.work_once()
    assert ran == ["b", "leveling"]
    assert inbox.counters["superseded"] == 1 and inbox.counters["commands"] == 3


def test_through_the_link_a_disabled_refuses_queued_motion_and_a_cancel_its_queued_goal() -> None:
    import numpy as np

    from articutool.link.auth import Sender
    from articutool.trajectory import JointTrajectory

    tool = LoopTool()
    bus = MemoryBus()
    server = ToolServer(tool, MemoryTransport(bus, "tool"), CFG.replace(inbox_size=8),
                        loop=tool)
    n, h, pc = server.names, server.handlers, Sender("pc-1", True, "pc")
    got: dict[str, list[bytes]] = {k: [] for k in ("level", "goal", "fault", "stop",
                                                  "goal2", "cancel", "after")}
    try:
        def soc(mode: Mode, into: str) -> None:
            h.on_set_mode(cdr.encode(m.soc_request(mode, 1.0, 0.0),
                                     n.set_orientation_control.request_type),
                          got[into].append, pc)
        g1, g2 = uuid.uuid4().bytes, uuid.uuid4().bytes
        soc(Mode.LEVELING, "level")
        h.on_send_goal(cdr.encode(m.send_goal_request(g1, "SLOW", []), n.send_goal.request_type),
                       got["goal"].append, pc)
        traj = JointTrajectory(("pitch", "roll"), np.array([0.5, 1.0]), np.zeros((2, 2)),
                               np.zeros((2, 2)))
        h.on_trajectory(cdr.encode(m.trajectory_msg(traj), n.joint_trajectory.type), pc)
        h.on_clear_fault(cdr.encode(m.trigger_request(), n.clear_fault.request_type),
                         got["fault"].append, pc)
        assert len(server.inbox.commands) == 4 and tool.calls == []
        soc(Mode.DISABLED, "stop")
        level = cdr.decode(got["level"][0], n.set_orientation_control.response_type)
        assert not level.success and "superseded by a stop" in level.message
        assert cdr.decode(got["goal"][0], n.send_goal.response_type).accepted
        res = h.goals.get(g1).result  # what get_result answers
        assert res.status == m.GoalStatus.ABORTED and "superseded" in res.message
        assert server.counters["rejected_trajectories"] == 1
        # a goal queued after the stop, then cancelled before it starts
        h.on_send_goal(cdr.encode(m.send_goal_request(g2, "SLOW", []), n.send_goal.request_type),
                       got["goal2"].append, pc)
        h.on_cancel(cdr.encode(m.cancel_request(g2), n.cancel_goal.request_type),
                    got["cancel"].append, pc)
        assert cdr.decode(got["goal2"][0], n.send_goal.response_type).accepted
        cancel = cdr.decode(got["cancel"][0], n.cancel_goal.response_type)
        assert cancel.return_code == 0 and len(cancel.goals_canceling) == 1
        res = h.goals.get(g2).result
        assert res.status == m.GoalStatus.CANCELED and not res.success
        soc(Mode.LEVELING, "after")  # after the stop: runs
        while server.inbox.stops or server.inbox.commands:
            server.work_once()
        assert tool.calls == ["set_mode DISABLED", "clear_fault", "set_mode LEVELING"]
        assert tool.trajectories == []
        assert cdr.decode(got["stop"][0], n.set_orientation_control.response_type).success
        assert cdr.decode(got["after"][0], n.set_orientation_control.response_type).success
        assert len(got["fault"]) == 1
        c = server.counters
        assert (c["superseded"], c["commands"]) == (4, 3)
    finally:
        bus.close()


def test_a_disabled_supersedes_a_command_that_arrived_before_it_but_is_queued_after() -> None:
    inbox = _inbox()
    ran: list[str] = []
    answered: list[bool] = []
    arrived = inbox.epoch  # a trajectory arrives; its handler is still decoding it
    inbox.submit_stop("disable", lambda: ran.append("disable"), lambda _: None, supersede=True)
    assert inbox.submit(lambda: ran.append("early"), discard=answered.append, since=arrived)
    assert answered == [False] and not inbox.commands  # answered, never queued
    assert inbox.submit(lambda: ran.append("later"), discard=answered.append,
                        since=inbox.epoch)  # arrived after the stop: runs
    inbox.submit_stop(("cancel", "g"), lambda: None, lambda _: None)  # a cancel: no epoch
    assert inbox.submit(lambda: ran.append("last"), discard=answered.append,
                        since=inbox.epoch)
    while inbox.stops or inbox.commands:
        inbox.work_once()
    assert ran == ["disable", "later", "last"]
    assert inbox.counters["superseded"] == 1
