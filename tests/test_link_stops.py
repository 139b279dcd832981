"""Stops that always get through, replays that never do, refusals that say why: the tool
(``link_fake_tool.py``) and the flooders (``link_flooder.py``) each run in their own process;
the PCs run in pytest. ``CALLS`` (printed by the tool on exit) is what reached the tool's API.
How long stops take under the worst flood is measured, not asserted:
``benchmarks/bench_link_stops.py``."""

from __future__ import annotations

import base64
import json
import os
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.auth import Signer
from articutool.link.client import ArticutoolClient, LinkError
from articutool.link.config import LinkConfig, load_config
from articutool.link.pairing import pair
from articutool.link.transport import Names, key_expr
from articutool.tool.api import Mode
from conftest import free_port, wait_until
from test_link_security import FAST, Tool


class Flooder(Tool):
    """``link_flooder.py`` in its own process (ready once it printed READY)."""

    def __init__(self, *args: str) -> None:
        super().__init__(*args, script="link_flooder.py")
        assert self.proc.stdout is not None
        assert self.proc.stdout.readline().strip() == "READY"

    def stop(self) -> int:
        """Stop flooding; how many requests it sent."""
        return int(next((ln.split()[1] for ln in self.output().splitlines()
                         if ln.startswith("SENT")), "0"))


def _counter(client: ArticutoolClient, name: str) -> float:
    """A link counter from the tool's telemetry (0 before any telemetry arrived)."""
    s = client.latest_state()
    return float(s.extra.get(f"link_{name}", 0)) if s is not None else 0.0


@pytest.fixture(scope="module")
def paired(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("pairing")
    pair(d, "wrist-1", ["pc-1", "pc-2"])
    return d


@pytest.fixture
def tool(paired: Path) -> Iterator[tuple[Tool, int, int]]:
    """A paired tool with a 50 Hz loop on mutual TLS (port p) and plain loopback (port q)."""
    p, q = free_port(), free_port()
    t = Tool("--link-config", str(paired / "wrist-1" / "link.toml"), "--listen",
             f"tls/127.0.0.1:{p}", "--listen", f"tcp/127.0.0.1:{q}", "--tick-hz", "50")
    yield t, p, q
    if t.proc.returncode is None:
        t.calls()


def _pc(paired: Path, who: str, port: int) -> ArticutoolClient:
    # A stop is answered whatever the load; how fast is measured (bench_link_stops.py).
    cfg = load_config(paired / who / "link.toml").replace(
        connect=(f"tls/127.0.0.1:{port}",), listen=(), **{**FAST, "call_timeout": 30.0})
    return ArticutoolClient(cfg)


def _stop(client: ArticutoolClient) -> tuple[bool, str]:
    try:
        return client.set_mode("disabled")
    except LinkError as err:
        return False, str(err)


@pytest.mark.floods
def test_floods_of_unsigned_and_forged_commands_never_hold_back_a_paired_pcs_stops(
        paired: Path, tool: tuple[Tool, int, int]) -> None:
    """A rate gate per endpoint, shared with the flood and run before the signature check,
    fails 38 of 40 of these stops 'rate limited': the gate is per verified sender."""
    t, p, q = tool
    pc = _pc(paired, "pc-1", p)
    floods = []
    try:
        assert pc.wait_for_tool(60.0)
        plain = f"tcp/127.0.0.1:{q}"
        floods = [Flooder("--connect", plain, "--mode", "unsigned", "--rate", "3000"),
                  Flooder("--connect", plain, "--mode", "forged", "--rate", "1000",
                          "--cert", str(paired / "pc-1" / "cert.pem"))]
        assert wait_until(lambda: _counter(pc, "refused_unpaired") > 0, 10.0)  # flood arrived
        before = _counter(pc, "refused_unpaired")
        stops = [_stop(pc) for _ in range(40)]
        refused = [s for s in stops if not s[0]]
        assert not refused, f"{len(refused)} of 40 stops refused: {refused[:3]}"
        ok, msg = pc.set_mode("leveling")  # pc-1's own commands have pc-1's own rate
        assert ok, msg
        assert _stop(pc)[0]
        # A second paired PC's cancel stops pc-1's primitive (before: failed 4 times in 7).
        result: list[object] = []
        th = threading.Thread(target=lambda: result.append(
            pc.run_primitive("SLOW", [], timeout=30.0)))
        th.start()
        assert wait_until(lambda: pc.latest_state().mode.name == "PRIMITIVE", 5.0)  # type: ignore[union-attr]
        with _pc(paired, "pc-2", p) as pc2:
            assert pc2.wait_for_tool(60.0)
            assert pc2.cancel()
        th.join(timeout=10)
        assert result and not result[0].success  # type: ignore[attr-defined]
        extra = pc.latest_state().extra  # type: ignore[union-attr]
        assert extra["link_refused_unpaired"] > before  # the floods went on meanwhile
    finally:
        sent = [f.stop() for f in floods]
        pc.close()
    assert min(sent) > 0, sent
    calls = t.calls()
    assert calls.count("set_mode DISABLED") == 41 and calls.count("set_mode LEVELING") == 1
    assert calls[-2:] == ["start SLOW", "cancel"], calls  # nothing of the floods' reached it


@pytest.mark.floods
def test_a_flood_of_cancels_never_fills_an_unpaired_tools_stops() -> None:
    """Unpaired (loopback) tool, a flood of cancels: equal stops join one another, so the
    cancels cannot fill the stop queue and real stops never get 'inbox is full'."""
    q = free_port()
    t = Tool("--listen", f"tcp/127.0.0.1:{q}", "--tool-id", "wrist-1", "--tick-hz", "50")
    cfg = LinkConfig(connect=(f"tcp/127.0.0.1:{q}",), listen=(), tool_id="wrist-1", **FAST)
    client = ArticutoolClient(cfg, sender="caregiver")
    flood = None
    try:
        assert client.wait_for_tool(60.0)
        flood = Flooder("--connect", f"tcp/127.0.0.1:{q}", "--mode", "cancels", "--rate",
                        "3000")
        time.sleep(0.5)  # the flood runs before the stops (the tool counts no joined cancel)
        stops = [_stop(client) for _ in range(20)]
        assert all(ok for ok, _ in stops), [s for s in stops if not s[0]][:3]
    finally:
        sent = flood.stop() if flood else 0
        client.close()
        calls = t.calls()
    assert sent > 0
    assert calls.count("set_mode DISABLED") == 20


def _capture(paired: Path, ep_name: str, payload: bytes) -> bytes:
    """pc-1's signed attachment for ``payload`` on ``ep_name`` (what a sniffer captures on a
    plain link)."""
    return Signer(paired / "pc-1" / "cert.pem", paired / "pc-1" / "key.pem").attachment(
        ep_name, payload)


def _malleate(attachment: bytes) -> bytes:
    """The same attachment with the certificate re-encoded: its CA signature (r, s) becomes
    (r, n - s), which verifies just as well (ECDSA is malleable)."""
    from cryptography.hazmat.primitives.asymmetric.utils import (
        decode_dss_signature,
        encode_dss_signature,
    )
    n = 0xFFFFFFFF00000000FFFFFFFFFFFFFFFFBCE6FAADA7179E84F3B9CAC2FC632551  # P-256 order
    a = json.loads(attachment)
    der = base64.b64decode(a["c"])

    def tlv(b: bytes, i: int) -> tuple[int, int, int]:  # (tag position, value start, end)
        ln = b[i + 1]
        if ln < 0x80:
            return i, i + 2, i + 2 + ln
        k = ln & 0x7F
        return i, i + 2 + k, i + 2 + k + int.from_bytes(b[i + 2:i + 2 + k], "big")

    def enc(tag: int, value: bytes) -> bytes:
        ln = len(value)
        size = bytes([ln]) if ln < 0x80 else bytes([0x80 | ((ln.bit_length() + 7) // 8)]) + \
            ln.to_bytes((ln.bit_length() + 7) // 8, "big")
        return bytes([tag]) + size + value

    _, start, end = tlv(der, 0)  # Certificate ::= SEQUENCE {tbs, algorithm, BIT STRING}
    parts, i = [], start
    while i < end:
        _, vs, ve = tlv(der, i)
        parts.append(der[i:ve])
        i = ve
    bits = parts[2]
    _, vs, ve = tlv(bits, 0)
    r, s = decode_dss_signature(bits[vs + 1:ve])  # after the unused-bits byte
    parts[2] = enc(0x03, b"\x00" + encode_dss_signature(r, n - s))
    a["c"] = base64.b64encode(enc(0x30, b"".join(parts))).decode()
    assert a["c"] != json.loads(attachment)["c"]
    return json.dumps(a).encode()


def _send(port: int, ep_name_key: str, payload: bytes, attachment: bytes,
          reply_type: str) -> tuple[object | None, str]:
    """One raw request over plain loopback: (decoded reply, '') or (None, the error)."""
    z = zenoh.Config()
    z.insert_json5("mode", '"peer"')
    z.insert_json5("scouting/multicast/enabled", "false")
    z.insert_json5("listen/endpoints", "[]")
    z.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    with zenoh.open(z) as session:
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            for reply in session.get(ep_name_key, payload=payload, attachment=attachment,
                                     timeout=2.0):
                if reply.ok is not None:
                    return cdr.decode(reply.ok.payload.to_bytes(), reply_type), ""
                return None, reply.err.payload.to_string()
            time.sleep(0.1)  # not connected yet
    raise AssertionError("no reply from the tool")


def test_a_replay_with_a_re_encoded_certificate_is_refused_and_nothing_moves(
        paired: Path, tool: tuple[Tool, int, int]) -> None:
    """The one-time cache keys on the signer's public key, not on the certificate's bytes:
    a malleated copy of a captured LEVELING is a replay, and the tool does not move."""
    t, p, q = tool
    soc = Names(tool_id="wrist-1").set_orientation_control
    key = key_expr(0, soc)
    payload = cdr.encode(m.soc_request(Mode.LEVELING, 0.0, 0.0), soc.request_type)
    att = _capture(paired, soc.name, payload)
    reply, err = _send(q, key, payload, att, soc.response_type)
    assert reply is not None and reply.success, err  # the original: accepted once
    with _pc(paired, "pc-2", p) as pc2:
        assert pc2.wait_for_tool(60.0)
        assert pc2.set_mode("disabled")[0]  # a stop from any paired PC
        assert wait_until(lambda: pc2.latest_state() is not None and
                          pc2.latest_state().mode.name == "DISABLED", 3.0)
        for again in (_malleate(att), att):
            reply, err = _send(q, key, payload, again, soc.response_type)
            assert reply is not None and not reply.success
            assert "replayed" in reply.message and "not a paired PC" not in reply.message
        seen = pc2.latest_state().stamp  # type: ignore[union-attr]
        assert wait_until(lambda: pc2.latest_state().stamp >= seen + 0.2)  # newer telemetry
        assert pc2.latest_state().mode.name == "DISABLED"  # type: ignore[union-attr]
    assert t.calls() == ["set_mode LEVELING", "set_mode DISABLED"]


def test_a_paired_pcs_refusals_name_the_real_reason(paired: Path,
                                                     tool: tuple[Tool, int, int]) -> None:
    """Clocks out of sync and replays are said as such (before: 'not a paired PC'); a
    refused goal's reason reaches the client although ROS's SendGoal reply has no text."""
    t, _, q = tool
    signer = Signer(paired / "pc-1" / "cert.pem", paired / "pc-1" / "key.pem")
    names = Names(tool_id="wrist-1")
    soc = names.set_orientation_control
    payload = cdr.encode(m.soc_request(Mode.LEVELING, 0.0, 0.0), soc.request_type)
    real = time.time_ns
    try:  # pc-1's clock 90 s behind the tool's
        time.time_ns = lambda: real() - 90 * 10**9  # type: ignore[assignment]
        late = signer.attachment(soc.name, payload)
        goal = cdr.encode(m.send_goal_request(os.urandom(16), "TWIRL", [0.1]),
                        names.send_goal.request_type)
        late_goal = signer.attachment(names.send_goal.name, goal)
    finally:
        time.time_ns = real  # type: ignore[assignment]
    reply, _ = _send(q, key_expr(0, soc), payload, late, soc.response_type)
    assert reply is not None and not reply.success
    assert "clocks not synchronised" in reply.message and "s behind" in reply.message
    assert "not a paired PC" not in reply.message
    reply, err = _send(q, key_expr(0, names.send_goal), goal, late_goal,
                       names.send_goal.response_type)
    assert reply is None and "clocks not synchronised" in err
    unsigned, err = _send(q, key_expr(0, names.send_goal), goal, b'{"id": "pc-1"}',
                          names.send_goal.response_type)
    assert unsigned is None and "not a paired PC" in err
    assert t.calls() == []
