"""An attachment that is not a signature is an authentication failure like any other: refused,
counted, logged within the throttle and answered, never an exception in the tool. Two real
processes: the fake tool (``link_fake_tool.py``, paired, listening on mutual TLS and on plain
loopback TCP; or unpaired) and, in pytest, a raw Zenoh session or a flooder process sending
crafted attachments (``link_flooder.MALFORMED``)."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.auth import AuthError, Verifier, sender_of
from articutool.link.client import ArticutoolClient
from articutool.link.config import LinkConfig, load_config
from articutool.link.pairing import pair
from articutool.link.transport import Names, key_expr
from articutool.link.zenoh_transport import zenoh_config
from articutool.tool.api import Mode
from conftest import free_port, wait_until
from link_flooder import MALFORMED
from test_link_security import FAST

HERE = Path(__file__).parent


class FakeTool:
    """``link_fake_tool.py`` in its own process; its stderr (the tool's log) in a file."""

    def __init__(self, tmp: Path, *args: str) -> None:
        self.log = tmp / "tool.log"
        env = dict(os.environ, PYTHONPATH=str(HERE.parent / "src"))
        with self.log.open("w") as err:
            self.proc = subprocess.Popen([sys.executable, str(HERE / "link_fake_tool.py"),
                                          *args], stdin=subprocess.PIPE,
                                         stdout=subprocess.PIPE, stderr=err, text=True, env=env)

    def stop(self) -> str:
        """Stop it; its log (the API calls that reached it: ``calls``)."""
        try:
            out, _ = self.proc.communicate(input="", timeout=60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            out, _ = self.proc.communicate(timeout=5)
        line = next((ln for ln in out.splitlines() if ln.startswith("CALLS")), "CALLS ")
        self.calls = [c for c in line[6:].split(";") if c]
        return self.log.read_text()


@pytest.fixture(scope="module")
def paired(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("pairing")
    pair(d, "wrist-1", ["pc-1"])
    return d


@pytest.fixture
def tool(paired: Path, tmp_path: Path) -> Iterator[tuple[FakeTool, int, int]]:
    """A paired tool on mutual TLS (port p) and plain loopback TCP (port q)."""
    p, q = free_port(), free_port()
    t = FakeTool(tmp_path, "--link-config", str(paired / "wrist-1" / "link.toml"),
                 "--listen", f"tls/127.0.0.1:{p}", "--listen", f"tcp/127.0.0.1:{q}")
    yield t, p, q
    if t.proc.poll() is None:
        t.stop()


def _call(session: zenoh.Session, key: str, payload: bytes, attachment: bytes,
          response_type: str) -> object | None:
    """One request with ``attachment``: the decoded reply, or None if none came."""
    for reply in session.get(key, payload=payload, attachment=attachment, timeout=3.0):
        if reply.ok is not None:
            return cdr.decode(reply.ok.payload.to_bytes(), response_type)
    return None


def _session(port: int) -> zenoh.Session:
    cfg = LinkConfig(connect=(f"tcp/127.0.0.1:{port}",), listen=(), tool_id="wrist-1")
    return zenoh.open(zenoh_config(cfg, "client"))


def _soc(names: Names) -> tuple[str, bytes, str]:
    ep = names.set_orientation_control
    payload = cdr.encode(m.soc_request(Mode.LEVELING, 0.0, 0.0), ep.request_type)
    return key_expr(0, ep), payload, ep.response_type


def test_each_malformed_attachment_is_answered_as_a_refusal_and_counted(
        paired: Path, tool: tuple[FakeTool, int, int]) -> None:
    """``t: Infinity``, a 400-digit timestamp and 4 000 nested brackets raised OverflowError
    or RecursionError past the verifier: no reply, a traceback each, not counted."""
    t, p, q = tool
    key, payload, rtype = _soc(Names(tool_id="wrist-1"))
    cfg = load_config(paired / "pc-1" / "link.toml").replace(
        connect=(f"tls/127.0.0.1:{p}",), listen=(), **FAST)
    with ArticutoolClient(cfg) as pc:
        assert pc.wait_for_tool(60.0)
        before = pc.latest_state()
        assert before is not None
        refused0 = before.extra.get("link_refused_unpaired", 0)
        session = _session(q)
        try:
            for name, attachment in MALFORMED.items():
                reply = _call(session, key, payload, attachment, rtype)
                assert reply is not None, f"{name}: no reply"
                assert not reply.success and "not a paired PC" in reply.message, (name, reply)
        finally:
            session.close()
        n = len(MALFORMED)
        assert wait_until(lambda: (pc.latest_state() or before).extra.get(
            "link_refused_unpaired", 0) >= refused0 + n, 5.0)
        assert pc.set_mode("leveling")[0] and pc.set_mode("disabled")[0]  # still serving
    log = t.stop()
    assert "Traceback" not in log, log[-3000:]
    assert "OverflowError" not in log and "RecursionError" not in log


@pytest.mark.floods
def test_a_flood_of_malformed_attachments_costs_no_traceback_and_every_one_is_counted(
        paired: Path, tool: tuple[FakeTool, int, int]) -> None:
    """15 000 such messages once gave 3 746 tracebacks in the tool's log, none counted.
    Whatever the load: every request answered was refused and counted, nothing is counted
    that was not sent, and none reached the tool's API. (How much of a flood a loaded machine
    serves is measured, not asserted: benchmarks/bench_link_flood.py.)"""
    t, p, q = tool
    cfg = load_config(paired / "pc-1" / "link.toml").replace(
        connect=(f"tls/127.0.0.1:{p}",), listen=(), **FAST)
    flood = subprocess.Popen(
        [sys.executable, str(HERE / "link_flooder.py"), "--connect", f"tcp/127.0.0.1:{q}",
         "--mode", "malformed", "--rate", "1500", "--seconds", "4"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
        env=dict(os.environ, PYTHONPATH=str(HERE.parent / "src")))
    flood.wait(timeout=60)  # it ends after --seconds (or when its stdin closes)
    out, _ = flood.communicate(timeout=10)
    _, sent, _, _, answered = next(ln for ln in out.splitlines() if ln.startswith("SENT")).split()
    sent, answered = int(sent), int(answered)
    assert answered > 0, out  # the flood reached the tool
    with ArticutoolClient(cfg) as pc:
        assert pc.wait_for_tool(60.0)
        st = pc.latest_state()
        assert st is not None
        assert pc.set_mode("disabled")[0]
    counted = st.extra.get("link_refused_unpaired", 0)
    assert answered <= counted <= sent, (answered, counted, sent)
    log = t.stop()
    assert t.calls == ["set_mode DISABLED"]  # the paired PC's stop alone reached the API
    assert log.count("Traceback") == 0, log[-3000:]
    assert log.count("refused_unpaired so far") <= 10 + sent // 1000  # the throttled log


def test_an_unpaired_tool_answers_a_malformed_claim(tmp_path: Path) -> None:
    """On an unpaired link the attachment is only a name; a malformed one is no name (the
    command is answered), not a RecursionError in the transport's thread."""
    q = free_port()
    t = FakeTool(tmp_path, "--listen", f"tcp/127.0.0.1:{q}")
    try:
        ep = Names().set_orientation_control
        key, rtype = key_expr(0, ep), ep.response_type
        payload = cdr.encode(m.soc_request(Mode.DISABLED, 0.0, 0.0), ep.request_type)
        session = _session(q)
        try:
            assert wait_until(lambda: _call(session, key, payload, b"{}", rtype) is not None,
                              15.0)
            for name, attachment in MALFORMED.items():
                reply = _call(session, key, payload, attachment, rtype)
                assert reply is not None and reply.success, (name, reply)
        finally:
            session.close()
    finally:
        log = t.stop()
    assert "Traceback" not in log, log[-3000:]


@pytest.mark.parametrize("name", sorted(MALFORMED))
def test_the_verifier_raises_only_auth_errors(paired: Path, name: str) -> None:
    v = Verifier(paired / "pc-1" / "ca.pem")
    with pytest.raises(AuthError, match="not a paired PC"):
        v.verify("/k", b"payload", MALFORMED[name])
    assert sender_of(MALFORMED[name]).identity is None
