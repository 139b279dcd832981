"""``articutool tool`` and ``articutool client`` as real processes on loopback:
repeated identical goals, a tool that cannot serve, bad input, Ctrl-C.

Every wait is bounded (subprocess timeouts, bounded polls), so a failure cannot hang the suite.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from articutool.link.client import ArticutoolClient
from articutool.link.config import LinkConfig
from articutool.spec import load_spec
from articutool.tool.api import Mode
from conftest import CLI, free_port, run_cli, wait_until

HERE = Path(__file__).parent
ENV = dict(os.environ, PYTHONPATH=str(HERE.parent / "src"), PYTHONUNBUFFERED="1")


class Tool:
    """``articutool tool --driver sim --no-level`` listening on a free loopback port."""

    def __init__(self, port: int, *extra: str) -> None:
        self.port = port
        self.endpoint = f"tcp/127.0.0.1:{port}"
        self.proc = subprocess.Popen([*CLI, "tool", "--no-level", "--listen", self.endpoint,
                                      *extra], stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, env=ENV)
        first = self.proc.stdout.readline()  # the first status line: loop and link are up
        assert "DISABLED" in first, (first, self.proc.stderr.read() if not first else "")

    def interrupt(self, timeout: float = 30.0) -> tuple[int, str, str]:
        """SIGINT (Ctrl-C); returns (exit code, stdout, stderr)."""
        self.proc.send_signal(signal.SIGINT)
        out, err = self.proc.communicate(timeout=timeout)
        return self.proc.returncode, out, err

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.communicate(timeout=10)


@pytest.fixture
def tool() -> Iterator[Tool]:
    t = Tool(free_port())
    yield t
    t.kill()


def client_cfg(tool: Tool) -> LinkConfig:
    return LinkConfig(connect=(tool.endpoint,), listen=(), tool_timeout=1.0,
                      heartbeat_period=0.05, call_timeout=5.0)


def test_identical_goals_twice_in_a_row_each_return(tool: Tool) -> None:
    """Item 9: HOMING while at home never returned the second time (4 of 4 runs)."""
    for _ in range(3):
        r = run_cli("client", "--connect", tool.endpoint, "--wait", "20", "primitive", "HOMING",
                    "2.0", "--json")
        assert r.returncode == 0, r
        assert '"success": true' in r.stdout


def test_a_second_tool_on_the_same_endpoint_exits_2_before_any_motion(tool: Tool) -> None:
    r = run_cli("tool", "--listen", tool.endpoint, "--duration", "30")
    assert r.returncode == 2, r
    assert tool.endpoint in r.stderr and "in use" in r.stderr
    assert "Traceback" not in r.stderr + r.stdout
    assert "LEVELING" not in r.stdout and "stopped" not in r.stdout  # the loop never ran
    # ... and the first tool still serves.
    with ArticutoolClient(client_cfg(tool)) as c:
        assert c.wait_for_tool(20.0)
        assert c.set_mode("disabled")[0]


@pytest.mark.parametrize("argv, field", [
    (("tool", "--listen", "tcp/127.0.0.1:notaport", "--duration", "30"), "listen"),
    (("tool", "--listen", "foo/bar", "--duration", "30"), "listen"),
    (("client", "--connect", "foo/bar", "state"), "connect"),
])
def test_a_malformed_endpoint_exits_2_naming_the_field(argv: tuple[str, ...],
                                                       field: str) -> None:
    r = run_cli(*argv)
    assert r.returncode == 2, r
    assert field in r.stderr and "tcp/127.0.0.1:7447" in r.stderr  # the allowed form
    assert "Traceback" not in r.stderr and r.stdout == ""


def test_a_non_utf8_link_config_exits_2(tmp_path: Path) -> None:
    f = tmp_path / "link.toml"
    f.write_bytes(b'listen = ["tcp/127.0.0.1:7447"]\n# \xff\xfe\n')
    for argv in (("client", "--link-config", str(f), "state"),
                 ("tool", "--link-config", str(f), "--duration", "30")):
        r = run_cli(*argv)
        assert r.returncode == 2, r
        assert str(f) in r.stderr and "UTF-8" in r.stderr and "Traceback" not in r.stderr


def test_client_wait_is_bounded() -> None:
    """A huge --wait is refused: it would wait forever for a tool that is not there."""
    for bad in ("1e300", "3601", "0", "nan"):
        r = run_cli("client", "--connect", "tcp/127.0.0.1:9", "--wait", bad, "state", timeout=60)
        assert r.returncode == 2, r
        assert "--wait" in r.stderr and "Traceback" not in r.stderr and r.stdout == ""
    assert "(0, 3600]" in run_cli("client", "--wait", "1e300", "state", timeout=60).stderr


def test_hardware_driver_without_hardware_is_one_clear_line() -> None:
    r = run_cli("tool", "--driver", "hardware", "--no-serve", "--duration", "30")
    assert r.returncode == 2, r
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "port" in lines[0], r.stderr


BAD_CLIENT_NUMBERS = [
    (("--wait", "nan", "state"), "--wait"),
    (("--wait", "0", "state"), "--wait"),
    (("--wait", "-1", "state"), "--wait"),
    (("primitive", "HOMING", "2.0", "--timeout", "0"), "--timeout"),
    (("primitive", "HOMING", "2.0", "--timeout", "nan"), "--timeout"),
    (("primitive", "HOMING", "2.0", "--timeout", "-3"), "--timeout"),
    (("mode", "leveling", "--pitch-offset", "1e39"), "--pitch-offset"),
    (("mode", "leveling", "--roll-offset=-1e39"), "--roll-offset"),
]


def test_bad_client_numbers_exit_2_before_anything_is_sent() -> None:
    port = free_port()
    fake = subprocess.Popen([sys.executable, str(HERE / "link_fake_tool.py"), "--listen",
                             f"tcp/127.0.0.1:{port}"], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, env=ENV)
    try:
        results = [(run_cli("client", "--connect", f"tcp/127.0.0.1:{port}", *argv, timeout=30),
                    field) for argv, field in BAD_CLIENT_NUMBERS]
        calls, _ = fake.communicate(input="", timeout=20)
    finally:
        if fake.poll() is None:
            fake.kill()
            fake.communicate(timeout=10)
    for r, field in results:
        assert r.returncode == 2, r
        assert field in r.stderr and "Traceback" not in r.stderr, r
    assert "start" not in calls and "set_mode" not in calls, calls  # nothing reached the tool


def test_offset_range_in_the_message_comes_from_the_spec() -> None:
    lo, hi = (math.degrees(v) for v in load_spec().wrist.limits[0])
    r = run_cli("client", "--connect", f"tcp/127.0.0.1:{free_port()}", "--wait", "1", "mode",
                "leveling", "--pitch-offset", "1e39")
    assert r.returncode == 2 and f"[{lo:g}, {hi:g}]" in r.stderr, r


def test_ctrl_c_on_client_primitive_cancels_it(tool: Tool) -> None:
    c = subprocess.Popen([*CLI, "client", "--connect", tool.endpoint, "--wait", "20",
                          "primitive", "TWIRL_CW", "1", "0.5"], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, env=ENV)
    try:
        line = c.stderr.readline()  # the first feedback line: the twirl is running
        assert "%" in line, line
        c.send_signal(signal.SIGINT)
        out, err = c.communicate(timeout=30)
    finally:
        if c.poll() is None:
            c.kill()
            c.communicate(timeout=10)
    assert c.returncode == 130, (out, err)
    assert "cancel" in (out + err)
    with ArticutoolClient(client_cfg(tool)) as cl:
        assert cl.wait_for_tool(20.0)
        assert wait_until(lambda: (s := cl.latest_state()) is not None
                          and s.mode is Mode.DISABLED, 10.0), cl.latest_state()
        # The wrist stops (the motors' velocity lag lets the last few ticks coast down) and
        # stays stopped: the roll no longer changes.
        assert wait_until(lambda: max(abs(v) for v in cl.latest_state().velocity) < 0.05,
                          10.0), cl.latest_state()
        st = cl.latest_state()
        roll = st.position[1]
        assert wait_until(lambda: cl.latest_state().stamp >= st.stamp + 0.5, 10.0)
        assert abs(cl.latest_state().position[1] - roll) < 0.01


def _cpu_hog() -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-c", "while True: pass"])


def _sigint_runs(n: int) -> None:
    hog = _cpu_hog()  # the abort showed under load
    try:
        for _ in range(n):
            t = Tool(free_port())
            try:
                code, out, err = t.interrupt()
            finally:
                t.kill()
            assert code == 0, err[-2000:]
            assert "stopped: motors stopped, torque off, drivers closed" in out
            assert "Traceback" not in err
    finally:
        hog.kill()
        hog.wait(timeout=10)


def test_sigint_stops_the_tool_cleanly() -> None:
    """Item 7: Ctrl-C aborted with SIGABRT ('FATAL: exception not rethrown') under load."""
    _sigint_runs(2)


@pytest.mark.slow
def test_sigint_stops_the_tool_cleanly_20_times_under_load() -> None:
    _sigint_runs(20)
