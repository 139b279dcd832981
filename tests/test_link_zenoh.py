"""Two real processes on loopback: the fake tool served over Zenoh, the client in pytest."""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from articutool.link import cli as link_cli
from articutool.link import messages as m
from articutool.link.client import ArticutoolClient, ToolSilentError
from articutool.link.config import LinkConfig
from conftest import free_port, wait_until

HERE = Path(__file__).parent


class ToolProcess:
    def __init__(self, port: int, *extra: str) -> None:
        env = dict(os.environ, PYTHONPATH=str(HERE.parent / "src"))
        self.proc = subprocess.Popen(
            [sys.executable, str(HERE / "link_fake_tool.py"), "--listen",
             f"tcp/127.0.0.1:{port}", *extra],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)

    def stop(self) -> str:
        if self.proc.returncode is None:
            try:  # closing stdin asks the tool to stop cleanly
                out, _ = self.proc.communicate(input="", timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                out, _ = self.proc.communicate(timeout=5)
            return out
        return ""

    def kill(self) -> None:
        self.proc.kill()
        self.proc.wait(timeout=5)


@pytest.fixture
def port() -> int:
    return free_port()


@pytest.fixture
def cfg(port: int) -> LinkConfig:
    return LinkConfig(connect=(f"tcp/127.0.0.1:{port}",), listen=(), tool_timeout=0.5,
                      heartbeat_period=0.05, call_timeout=2.0)


@pytest.fixture
def tool(port: int) -> Iterator[ToolProcess]:
    t = ToolProcess(port)
    yield t
    t.stop()


@pytest.fixture
def client(cfg: LinkConfig, tool: ToolProcess) -> Iterator[ArticutoolClient]:
    c = ArticutoolClient(cfg)
    assert c.wait_for_tool(15.0), "tool process never heard"
    yield c
    c.close()


def test_mode_switch_twirl_cancel_and_refusal(client: ArticutoolClient,
                                              tool: ToolProcess) -> None:
    assert client.set_mode("leveling", 5.0, -2.5) == (True, "mode LEVELING")
    res = client.run_primitive("TWIRL", [0.5], timeout=10)
    assert not res.success and "leveling" in res.message  # refused while leveling
    assert client.set_mode("disabled")[0]

    fb: list = []
    res = client.run_primitive("TWIRL", [0.5], fb.append, timeout=10)
    assert res.success and res.status == m.GoalStatus.SUCCEEDED, res
    np.testing.assert_allclose(res.final_joint_values, [0.1, 0.2 + math.pi], rtol=1e-6)
    assert fb and all(0 <= f.percent_complete <= 100 for f in fb)

    res = client.run_primitive("SLOW", [], timeout=0.5)
    assert not res.success and res.status == m.GoalStatus.CANCELED

    res = client.run_primitive("NOPE", [1, 2], timeout=10)
    assert not res.success and "unknown primitive" in res.message

    st = client.latest_state()
    assert st is not None and st.joint_names == ("pitch", "roll")
    assert st.battery_voltage == pytest.approx(11.9, rel=1e-6)
    calls = tool.stop()
    assert "start SLOW" in calls and "cancel" in calls


def test_link_loss_is_detected_and_the_client_recovers(port: int, cfg: LinkConfig) -> None:
    first = ToolProcess(port)
    c = ArticutoolClient(cfg)
    second = None
    try:
        assert c.wait_for_tool(15.0)
        assert c.set_mode("leveling")[0]
        first.kill()  # the tool vanishes without a goodbye
        assert wait_until(lambda: not c.tool_alive)  # the client calls the tool silent
        with pytest.raises(ToolSilentError):
            c.set_mode("disabled")
        second = ToolProcess(port)  # tool restarts on the same endpoint
        assert c.wait_for_tool(15.0)
        assert c.set_mode("disabled") == (True, "mode DISABLED")
    finally:
        c.close()
        first.stop()
        if second is not None:
            second.stop()


def _cli(cfg_port: int, *argv: str, capsys: pytest.CaptureFixture) -> tuple[int, str]:
    parser = argparse.ArgumentParser(prog="articutool")
    link_cli.add_commands(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["client", "--connect", f"tcp/127.0.0.1:{cfg_port}", "--wait",
                              "15", *argv])
    code = args.func(args)
    return code, capsys.readouterr().out


def test_cli_commands(port: int, tool: ToolProcess, capsys: pytest.CaptureFixture) -> None:
    assert _cli(port, "mode", "leveling", "--pitch-offset", "3", capsys=capsys)[0] == 0
    code, out = _cli(port, "primitive", "TWIRL", "1", "--json", capsys=capsys)
    assert code == 1  # refused while leveling → success=false → non-zero
    assert json.loads(out)["success"] is False
    assert _cli(port, "mode", "disabled", capsys=capsys)[0] == 0
    code, out = _cli(port, "primitive", "TWIRL", "1", "--json", capsys=capsys)
    d = json.loads(out)
    assert code == 0 and d["success"] is True and set(d) == {"success", "message",
                                                              "final_joint_values"}
    assert d["final_joint_values"] == pytest.approx([0.1, 0.2 + 2 * math.pi], rel=1e-6)
    code, out = _cli(port, "state", "--json", capsys=capsys)
    assert code == 0 and json.loads(out)["joint_names"] == ["pitch", "roll"]
    with pytest.raises(SystemExit) as e:
        _cli(port, "mode", "sideways", capsys=capsys)
    assert e.value.code == 2
    with pytest.raises(SystemExit) as e:
        _cli(port, "primitive", "TWIRL", "abc", capsys=capsys)
    assert e.value.code == 2
