"""Floods a tool's command endpoints from its own process, as an attacker
who reaches the tool's port would::

    python tests/link_flooder.py --connect ENDPOINT --mode MODE [--rate HZ] [--seconds S]
        [--tool-id NAME] [--cert PEM] [--capture FILE] [--link-config FILE]

Modes (every request is sent with its reply ignored, ``--rate`` requests per second in
batches every 10 ms, round robin over the endpoints named):

- ``unsigned``: set_orientation_control (DISABLED and LEVELING), cancel_goal (all goals),
  send_goal, clear_fault and get_result, each claiming to be ``pc-1`` (unsigned);
- ``forged``: the same requests carrying a paired PC's real certificate (``--cert``, public)
  with a fresh timestamp and nonce and a random signature, so the tool must check each
  signature;
- ``signed``: the same requests signed by the paired PC of ``--link-config`` (its session
  is then mutual TLS as that PC's): a paired PC flooding, which must not use another's share;
- ``replay``: one captured signed request (``--capture``: JSON with key, payload and
  attachment, hex) sent again and again;
- ``cancels``: cancel_goal for all goals and for random goal ids (fills an unpaired tool's
  stop queue unless equal stops join);
- ``malformed``: the commands of ``unsigned`` (not get_result) with attachments that are not
  valid signature JSON (:data:`MALFORMED`: ``Infinity`` and 400-digit timestamps, brackets
  nested 4 000 deep, invalid UTF-8, wrong types), which the verifier must refuse like any
  unsigned message.

Prints ``SENT <n> <seconds> ANSWERED <replies>`` on exit (stdin closed, or after
``--seconds``; the replies to the last requests are awaited up to their 1 s timeout).
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import sys
import threading
import time
import uuid

import zenoh

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.auth import claim
from articutool.link.config import LinkConfig, load_config
from articutool.link.transport import Endpoint, Names, key_expr
from articutool.link.zenoh_transport import zenoh_config
from articutool.tool.api import Mode


def requests(names: Names) -> list[tuple[Endpoint, bytes]]:
    """One request of each command kind the flood sends."""
    soc = names.set_orientation_control
    out = [(soc, cdr.encode(m.soc_request(Mode.DISABLED, 0.0, 0.0), soc.request_type)),
           (soc, cdr.encode(m.soc_request(Mode.LEVELING, 0.0, 0.0), soc.request_type)),
           (names.cancel_goal, cdr.encode(m.cancel_request(None), names.cancel_goal.request_type)),
           (names.send_goal, cdr.encode(m.send_goal_request(uuid.uuid4().bytes, "TWIRL", [0.1]),
                                      names.send_goal.request_type)),
           (names.clear_fault, cdr.encode(m.trigger_request(), names.clear_fault.request_type))]
    gr = names.get_result
    out.append((gr, cdr.encode(cdr.msg(gr.request_type, goal_id=m.goal_uuid(uuid.uuid4().bytes)),
                             gr.request_type)))
    return out


def _signed_shape(t: str) -> bytes:
    return b'{"c": "AAAA", "t": ' + t.encode() + b', "n": "00112233445566778899aabb", "s": "AAAA"}'


MALFORMED: dict[str, bytes] = {
    "t_infinity": _signed_shape("Infinity"),
    "t_minus_infinity": _signed_shape("-Infinity"),
    "t_nan": _signed_shape("NaN"),
    "t_400_digits": _signed_shape("9" * 400),
    "t_1e400": _signed_shape("1e400"),
    "t_2_pow_64": _signed_shape(str(2**64)),
    "t_negative": _signed_shape("-5"),
    "t_string": _signed_shape('"123"'),
    "nested_4000": b"[" * 4000 + b"]" * 4000,
    "nested_objects": b'{"a":' * 1300 + b"1" + b"}" * 1300,
    "not_utf8": b"\xff\xfe\x00{",
    "wrong_types": b'{"c": 5, "t": 1, "n": [], "s": {}}',
    "a_list": b'[1, 2, 3]',
    "id_is_an_object": b'{"id": {"name": "pc-1"}}',
}
"""Attachments that are not signatures, by name: each must be refused as unsigned."""


def forged(cert_b64: str) -> bytes:
    """A paired PC's certificate with a random (wrong) signature, fresh time and nonce."""
    return json.dumps({"c": cert_b64, "t": time.time_ns(), "n": os.urandom(12).hex(),
                       "s": base64.b64encode(os.urandom(72)).decode()}).encode()


def main(argv: list[str]) -> int:
    """Flood until stdin closes or ``--seconds`` pass."""
    p = argparse.ArgumentParser()
    p.add_argument("--connect", required=True)
    p.add_argument("--mode", choices=("unsigned", "forged", "signed", "replay", "cancels",
                                     "malformed"),
                   required=True)
    p.add_argument("--rate", type=float, default=3000.0)
    p.add_argument("--seconds", type=float, default=3600.0)
    p.add_argument("--tool-id", default="wrist-1")
    p.add_argument("--cert", default=None)
    p.add_argument("--link-config", default=None)
    p.add_argument("--capture", default=None)
    a = p.parse_args(argv)
    base = load_config(a.link_config) if a.link_config else LinkConfig()
    cfg = base.replace(connect=(a.connect,), listen=(), tool_id=a.tool_id)
    names = Names(tool_id=a.tool_id)
    session = zenoh.open(zenoh_config(cfg, "client"))
    if a.mode == "replay":
        cap = json.loads(open(a.capture).read())  # noqa: SIM115 - read once, tiny
        plan = [(cap["key"], bytes.fromhex(cap["payload"]), lambda c=cap: bytes.fromhex(
            c["attachment"]))]
    else:
        reqs = requests(names)
        if a.mode == "cancels":
            cg = names.cancel_goal
            reqs = [(cg, cdr.encode(m.cancel_request(None), cg.request_type))] + [
                (cg, cdr.encode(m.cancel_request(uuid.uuid4().bytes), cg.request_type))
                for _ in range(3)]
        if a.mode == "forged":
            from cryptography import x509
            from cryptography.hazmat.primitives import serialization
            der = x509.load_pem_x509_certificate(open(a.cert, "rb").read()).public_bytes(  # noqa: SIM115
                serialization.Encoding.DER)
            b64 = base64.b64encode(der).decode()
            plan = [(key_expr(cfg.domain_id, ep), pl, lambda b=b64: forged(b))
                    for ep, pl in reqs]
        elif a.mode == "signed":
            from articutool.link.auth import Signer
            signer = Signer(cfg.tls_certificate, cfg.tls_private_key)  # type: ignore[arg-type]
            plan = [(key_expr(cfg.domain_id, ep), pl,
                     lambda n=ep.name, pl=pl: signer.attachment(n, pl)) for ep, pl in reqs]
        elif a.mode == "malformed":
            bad = list(MALFORMED.values())  # commands only: get_result is open to all
            plan = [(key_expr(cfg.domain_id, ep), pl, lambda b=b: b)
                    for b in bad for ep, pl in reqs if ep != names.get_result]
        else:
            unsigned = claim("pc-1")
            plan = [(key_expr(cfg.domain_id, ep), pl, lambda c=unsigned: c)
                    for ep, pl in reqs]
    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    end = time.monotonic() + a.seconds
    batch, sent, i = max(1, round(a.rate / 100)), 0, 0
    answered = [0]  # replies, each a refusal or an answer (the handler's thread counts)
    next_t = t0 = time.monotonic()
    print("READY", flush=True)
    while not stop.is_set() and time.monotonic() < end:
        for _ in range(batch):
            key, payload, attach = plan[i % len(plan)]
            i += 1
            session.get(key, handler=lambda _r: answered.__setitem__(0, answered[0] + 1),
                        payload=payload, attachment=attach(), timeout=1.0)
            sent += 1
        next_t += 0.01
        stop.wait(max(0.0, next_t - time.monotonic()))
    elapsed = time.monotonic() - t0
    late = time.monotonic() + 1.5  # past the requests' 1 s timeout
    while answered[0] < sent and time.monotonic() < late:
        time.sleep(0.05)
    session.close()
    print(f"SENT {sent} {elapsed:.3f} ANSWERED {answered[0]}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
