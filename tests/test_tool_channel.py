"""The loop's end of the channel to the link process never blocks the loop and never loses an
answer; the link's end never runs a command after its caller gave up (``tool/channel.py``).
Both ends on a real socket pair; the runtime is the real one on the simulated wrist."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np

from articutool.spec import Spec
from articutool.tool import channel as ch
from articutool.tool.api import Mode
from articutool.tool.drivers import make_drivers
from articutool.tool.drivers.sim import SimWrist
from articutool.tool.runtime import ToolRuntime
from articutool.trajectory import JointTrajectory


def _runtime(spec: Spec) -> tuple[ToolRuntime, SimWrist]:
    sim = SimWrist(spec, seed=0)
    rt = ToolRuntime(spec, *make_drivers(spec, "sim", sim=sim), clock=sim.clock)
    rt.open()
    return rt, sim


def _tick(rt: ToolRuntime, sim: SimWrist, work: ch.LoopChannel, n: int = 1) -> None:
    for _ in range(n):
        sim.step(rt.period)
        rt.tick(sim.time, rt.period)
        work.work_once()


def test_a_link_process_that_reads_nothing_never_blocks_the_loop_nor_loses_answers(
        spec: Spec) -> None:
    rt, sim = _runtime(spec)
    loop_end, link_end = socket.socketpair()
    channel = ch.LoopChannel(ch.FrameReader(loop_end), rt)
    channel.start()
    for i in range(40):  # commands, and nobody reads the reports
        ch.send_frame(link_end, ("call", i, "set_mode", (Mode.DISABLED,), time.monotonic() + 60))
    worst = 0.0
    for _ in range(2000):  # 40 s of ticks: the socket buffer fills after a few hundred
        t0 = time.thread_time()  # CPU time: a blocked send would hang here, not cost CPU
        _tick(rt, sim, channel)
        worst = max(worst, time.thread_time() - t0)
    assert channel.stalled_sends > 0 and not channel.lost
    assert worst < 0.05, worst  # one failed send per tick, never a wait
    # the link side catches up: every answer arrives, in order
    reader = ch.FrameReader(link_end)
    answered: list[int] = []
    deadline = time.monotonic() + 10
    while len(answered) < 40 and time.monotonic() < deadline:
        _tick(rt, sim, channel)
        try:
            while True:
                msg = reader.read(0.01)
                answered += [cid for cid, _ in msg[3]]  # type: ignore[index]
        except TimeoutError:
            pass
    assert answered == list(range(40))
    rt.close()


def test_a_command_past_its_deadline_is_not_run(spec: Spec) -> None:
    rt, sim = _runtime(spec)
    loop_end, link_end = socket.socketpair()
    channel = ch.LoopChannel(ch.FrameReader(loop_end), rt)
    channel.start()
    _tick(rt, sim, channel, 50)
    ch.send_frame(link_end, ("call", 1, "set_mode", (Mode.LEVELING,), time.monotonic() - 1))
    _tick(rt, sim, channel)
    reader = ch.FrameReader(link_end)
    answers = []
    while not answers:
        answers = reader.read(5)[3]  # type: ignore[index]
    assert answers == [(1, ("expired", None))]
    assert rt.mode is Mode.DISABLED
    rt.close()


def test_the_proxy_serves_the_runtime_across_the_channel(spec: Spec) -> None:
    rt, sim = _runtime(spec)
    loop_end, link_end = socket.socketpair()
    channel = ch.LoopChannel(ch.FrameReader(loop_end), rt, extra={"loop_realtime": 1.0})
    ch.send_frame(loop_end, channel.report())  # the first state, as at start-up
    channel.start()
    proxy = ch.LoopProxy(ch.FrameReader(link_end), spec)
    stop = threading.Event()

    def loop() -> None:
        while not stop.is_set():
            _tick(rt, sim, channel)
            time.sleep(0.002)
    th = threading.Thread(target=loop, daemon=True)
    th.start()
    try:
        assert proxy.first_report.wait(5)
        assert proxy.state().extra["loop_realtime"] == 1.0
        ok, msg = proxy.set_mode(Mode.LEVELING)
        assert ok, msg
        assert proxy.state().mode is Mode.LEVELING  # the answer is never newer than the state
        ok, msg = proxy.start_primitive("HOMING", [1.0])
        assert not ok and "leveling" in msg
        assert proxy.set_mode(Mode.DISABLED)[0]
        names = rt.joint_names
        q = np.array(proxy.state().position)
        traj = JointTrajectory(names, np.array([0.5, 1.0]), np.vstack([q, q + 0.05]),
                               np.zeros((2, 2)))
        ok, msg = proxy.follow_trajectory(proxy.prevalidate_trajectory(traj))
        assert ok, msg
        assert proxy.state().mode is Mode.TRAJECTORY
        assert proxy.cancel_primitive() is False
    finally:
        stop.set()
        th.join(5)
    proxy.close()
    _tick(rt, sim, channel)
    assert channel.lost  # the loop sees the link process go
    assert proxy.set_mode(Mode.LEVELING) == (False, "refused: the tool's loop process has ended")
    rt.close()
