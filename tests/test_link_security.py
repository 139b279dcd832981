"""Only the paired PC moves the utensil: two real processes.

The fake tool (``link_fake_tool.py``) runs in its own process, paired by ``articutool pair``
and listening on mutual TLS and, in one test, also on a plain loopback port (what a local
process can still reach). Clients run in pytest. ``CALLS`` (printed by the tool on exit) is
what reached the tool's API.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.client import ArticutoolClient, ToolConflictError
from articutool.link.config import LinkConfig, load_config
from articutool.link.pairing import pair
from articutool.link.transport import Names
from articutool.link.zenoh_transport import ZenohTransport
from conftest import free_port, wait_until

HERE = Path(__file__).parent
FAST = {"tool_timeout": 0.5, "heartbeat_period": 0.05, "call_timeout": 2.0}


class Tool:
    """``link_fake_tool.py`` (or another ``script`` here) in its own process."""

    def __init__(self, *args: str, script: str = "link_fake_tool.py") -> None:
        env = dict(os.environ, PYTHONPATH=str(HERE.parent / "src"))
        self.proc = subprocess.Popen([sys.executable, str(HERE / script), *args],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                                     env=env)

    def output(self) -> str:
        """Close its stdin (it ends then) and return what it printed."""
        try:
            out, _ = self.proc.communicate(input="", timeout=15)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            out, _ = self.proc.communicate(timeout=5)
        return out

    def calls(self) -> list[str]:
        """Stop the tool; the API calls it received."""
        out = self.output()
        line = next((ln for ln in out.splitlines() if ln.startswith("CALLS")), "CALLS ")
        return [c for c in line[6:].split(";") if c]


@pytest.fixture(scope="module")
def paired(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("pairing")
    pair(d / "ours", "wrist-1", ["pc-1", "pc-2"])
    pair(d / "theirs", "wrist-1", ["pc-1"])  # same names, another CA: not paired with ours
    return d


def _client(paired: Path, who: str, port: int, **kw: object) -> ArticutoolClient:
    cfg = load_config(paired / who / "link.toml").replace(
        connect=(f"tls/127.0.0.1:{port}",), listen=(), **FAST, **kw)
    return ArticutoolClient(cfg)


@pytest.fixture
def tool(paired: Path) -> Iterator[tuple[Tool, int, int]]:
    """A paired tool on mutual TLS (port p) and on plain loopback TCP (port q)."""
    p, q = free_port(), free_port()
    t = Tool("--link-config", str(paired / "ours" / "wrist-1" / "link.toml"),
             "--listen", f"tls/127.0.0.1:{p}", "--listen", f"tcp/127.0.0.1:{q}",
             "--client-timeout", "0.6")
    yield t, p, q
    if t.proc.returncode is None:
        t.calls()


def test_unpaired_are_refused_and_the_tool_does_not_move(paired: Path,
                                                          tool: tuple[Tool, int, int]) -> None:
    t, p, q = tool
    # 1. Certificates from another CA: mutual TLS never lets the session in.
    with _client(paired / "theirs", "pc-1", p) as evil:
        assert not evil.wait_for_tool(2.0)
    # 2. Plain TCP on the tool's loopback port: telemetry is readable, commands are not.
    plain = LinkConfig(connect=(f"tcp/127.0.0.1:{q}",), listen=(), tool_id="wrist-1", **FAST)
    with ArticutoolClient(plain, sender="pc-1") as local:  # claims a paired name
        assert local.wait_for_tool(15.0)
        before = local.latest_state()
        assert before is not None and before.mode.name == "DISABLED"
        ok, msg = local.set_mode("leveling")
        assert not ok and "not a paired PC" in msg
        res = local.run_primitive("TWIRL", [1.0], timeout=3.0)
        assert not res.success
        local.follow_trajectory(_traj())  # dropped by the tool
        assert wait_until(lambda: (local.latest_state() or before).extra.get(
            "link_refused_unpaired", 0) >= 3, 5.0)
        after = local.latest_state()
        assert after is not None and after.mode.name == "DISABLED"
        assert after.position == before.position  # nothing moved
    # 3. A paired PC over TLS works.
    with _client(paired / "ours", "pc-1", p) as pc:
        assert pc.wait_for_tool(15.0)
        assert pc.set_mode("leveling")[0]
        assert pc.set_mode("disabled")[0]
        assert pc.run_primitive("TWIRL", [0.25], timeout=10.0).success
    calls = t.calls()
    assert calls == ["set_mode LEVELING", "set_mode DISABLED", "start TWIRL"], calls


def _traj() -> object:
    import numpy as np

    from articutool.trajectory import JointTrajectory
    return JointTrajectory(("pitch", "roll"), np.array([0.5, 1.0]), np.zeros((2, 2)),
                           np.zeros((2, 2)))


def test_one_commander_lease_take_over_and_forged_heartbeats(
        paired: Path, tool: tuple[Tool, int, int]) -> None:
    t, p, q = tool
    one = _client(paired / "ours", "pc-1", p)
    two = _client(paired / "ours", "pc-2", p)
    try:
        assert one.wait_for_tool(15.0) and two.wait_for_tool(15.0)
        assert one.set_mode("leveling")[0]  # pc-1 takes the lease
        ok, msg = two.set_mode("leveling", 5.0)
        assert not ok and "pc-1 holds the command lease" in msg
        res = two.run_primitive("TWIRL", [0.25], timeout=3.0)
        assert not res.success and "pc-1 holds" in res.message
        assert two.set_mode("disabled")[0]  # a stop is always accepted
        assert one.set_mode("leveling")[0]  # pc-1 still holds the lease
        assert wait_until(lambda: two.lease_holder() == "pc-1", 3.0)
        # pc-1 goes silent without releasing; a plain-TCP process forges its heartbeat.
        one._stop.set()
        one._beat.join(timeout=2)
        forger = ZenohTransport(LinkConfig(connect=(f"tcp/127.0.0.1:{q}",), listen=(),
                                           tool_id="wrist-1"), "client", identity="pc-1")
        ep = Names(tool_id="wrist-1").client_heartbeat
        end = time.monotonic() + 1.5
        while time.monotonic() < end:  # longer than the tool's client_timeout (0.6 s)
            forger.publish(ep, cdr.encode(m.heartbeat_msg(time.time(), "pc-1"), ep.type))
            time.sleep(0.05)
        ok, msg = two.set_mode("leveling")  # the lease expired: the forgery kept nothing
        assert ok, msg
        forger.close()
        # pc-1 comes back, is refused, and takes over explicitly (audited).
        ok, msg = one.set_mode("disabled")
        assert ok  # a stop
        ok, msg = one.set_mode("leveling")
        assert not ok and "pc-2 holds" in msg
        assert one.take_over()[0]
        assert one.set_mode("leveling", 2.0)[0]
        assert wait_until(lambda: (two.latest_state() or one.latest_state()).extra.get(
            "link_lease_takeovers", 0) >= 1, 3.0)
    finally:
        one.close()
        two.close()
    calls = t.calls()
    assert calls.count("set_mode LEVELING") == 4, calls
    assert "start TWIRL" not in calls
    audit = [json.loads(ln) for ln in
             (paired / "ours" / "wrist-1" / "audit.jsonl").read_text().splitlines()]
    assert {"event": "take_over", "client": "pc-1", "previous_holder": "pc-2"}.items() <= \
        next(a for a in audit if a["event"] == "take_over").items()
    assert any(a["event"] == "lease_expired" and a["client"] == "pc-1" for a in audit)


def test_tools_by_identity_independent_and_duplicates_refused() -> None:
    pa, pb, pc = free_port(), free_port(), free_port()
    a = Tool("--listen", f"tcp/127.0.0.1:{pa}", "--tool-id", "wrist-a")
    b = Tool("--listen", f"tcp/127.0.0.1:{pb}", "--tool-id", "wrist-b")
    both = (f"tcp/127.0.0.1:{pa}", f"tcp/127.0.0.1:{pb}")
    try:
        ca = ArticutoolClient(LinkConfig(connect=both, listen=(), tool_id="wrist-a", **FAST))
        try:
            assert ca.wait_for_tool(15.0)
            assert ca.set_mode("leveling")[0]  # one command: only wrist-a
            assert wait_until(lambda: ca.latest_state() is not None and
                              ca.latest_state().mode.name == "LEVELING", 3.0)
            # A second tool claiming wrist-a appears: the client stops mixing streams.
            dup = Tool("--listen", f"tcp/127.0.0.1:{pc}", "--tool-id", "wrist-a")
            try:
                ca2 = ArticutoolClient(LinkConfig(connect=(*both, f"tcp/127.0.0.1:{pc}"),
                                                  listen=(), tool_id="wrist-a", **FAST))
                try:
                    with pytest.raises(ToolConflictError, match="2 tools answer"):
                        assert ca2.wait_for_tool(15.0)  # raises if both were heard by now
                        wait_until(lambda: bool(ca2.conflict), 3.0)
                        ca2.set_mode("disabled")  # else this does
                    assert ca2.latest_state() is None
                finally:
                    ca2.close()
            finally:
                assert dup.calls() == []
        finally:
            ca.close()
    finally:
        calls_a, calls_b = a.calls(), b.calls()
    assert calls_a == ["set_mode LEVELING"] and calls_b == []
