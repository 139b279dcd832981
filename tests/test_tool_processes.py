"""``articutool tool`` is two processes: the loop (drivers, 50 Hz) and the link (Zenoh and
its server). The link process never outlives the loop, and a tool whose link process dies
stops its motors and exits 1 (no stop could reach it any more). Real processes throughout."""

from __future__ import annotations

import contextlib
import os
import signal
from pathlib import Path

import pytest

from articutool.link.client import ArticutoolClient
from conftest import free_port, wait_until
from test_tool_cli import Tool, client_cfg


def _children(pid: int) -> list[int]:
    out: list[int] = []
    for task in Path(f"/proc/{pid}/task").glob("*"):
        with contextlib.suppress(OSError):
            out += [int(c) for c in (task / "children").read_text().split()]
    return out


def _link_pids(tool: Tool) -> list[int]:
    return [p for p in _children(tool.proc.pid)
            if b"articutool.onboard_link" in Path(f"/proc/{p}/cmdline").read_bytes()]


def _link_pid(tool: Tool) -> int:
    assert wait_until(lambda: _link_pids(tool), 10.0), "no link process"
    return _link_pids(tool)[0]


def _ended(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


def _gone(pid: int, timeout: float = 20.0) -> bool:
    return wait_until(lambda: _ended(pid), timeout)


def test_the_loop_and_the_link_run_in_two_processes_at_their_priorities() -> None:
    tool = Tool(free_port())
    try:
        link = _link_pid(tool)
        with ArticutoolClient(client_cfg(tool)) as pc:
            assert pc.wait_for_tool(20.0)
            st = pc.latest_state()
            assert st is not None and "loop_realtime" in st.extra
            assert pc.set_mode("leveling")[0]  # commands cross both processes
            assert pc.set_mode("disabled")[0]
            assert pc.run_primitive("HOMING", [2.0], timeout=20.0).success
        # the link process is never real-time; the loop's is when the system allows it
        assert os.sched_getscheduler(link) & ~getattr(os, "SCHED_RESET_ON_FORK", 0) \
            == os.SCHED_OTHER
        if st.extra["loop_realtime"] == 1.0:
            loop_policies = {os.sched_getscheduler(int(t.name)) & ~os.SCHED_RESET_ON_FORK
                             for t in Path(f"/proc/{tool.proc.pid}/task").glob("*")}
            assert os.SCHED_FIFO in loop_policies
        else:
            assert os.getpriority(os.PRIO_PROCESS, link) == 10  # below the loop
        code, out, err = tool.interrupt()
    finally:
        tool.kill()
    assert code == 0, err[-2000:]
    assert "stopped: motors stopped, torque off, drivers closed" in out
    assert _gone(link), "the link process outlived the tool"


def test_sigterm_stops_both_processes_cleanly() -> None:
    tool = Tool(free_port())
    try:
        link = _link_pid(tool)
        tool.proc.send_signal(signal.SIGTERM)
        out, err = tool.proc.communicate(timeout=30)
    finally:
        tool.kill()
    assert tool.proc.returncode == 0, err[-2000:]
    assert "stopped: motors stopped, torque off, drivers closed" in out
    assert "Traceback" not in err
    assert _gone(link)


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGSEGV])
def test_a_tool_whose_link_process_dies_stops_its_motors_and_exits_1(sig: int) -> None:
    tool = Tool(free_port())
    try:
        with ArticutoolClient(client_cfg(tool)) as pc:
            assert pc.wait_for_tool(20.0)
            assert pc.set_mode("leveling")[0]
            os.kill(_link_pid(tool), sig)
            out, err = tool.proc.communicate(timeout=30)
    finally:
        tool.kill()
    assert tool.proc.returncode == 1, (out[-2000:], err[-2000:])
    assert "the link process ended" in err and "the motors were stopped" in err
    assert "stopped: motors stopped, torque off, drivers closed" in out
