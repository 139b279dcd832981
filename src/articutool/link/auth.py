"""Who sent a link message: signatures with the paired certificates.

A paired sender attaches (as the Zenoh attachment) its certificate, a timestamp, a random
nonce and an ECDSA P-256 signature over the key expression, the timestamp, the nonce and the
payload's SHA-256. :class:`Verifier` accepts it when the certificate was issued by the
pairing CA (and, if the tool lists ``peers``, names one of them), is within its validity,
the signature holds, the timestamp is within ``window`` seconds of the tool's clock (the PC's
and the tool's clocks are synchronised already, for trajectory start times) and the nonce was
not seen within that window (no replay on a plain link). The verified identity is the
certificate's common name. Certificates already verified are cached by their bytes.

Replay protection keys on what cannot be re-encoded: the signer's public key
(DER SubjectPublicKeyInfo, canonical), the nonce and the timestamp. ECDSA signatures are
malleable (``s → n − s`` verifies too), so a certificate's bytes are not a stable name for
it: a captured command re-sent with a re-encoded certificate is the same command. A message
already seen is refused before its signature is checked, so a replay flood costs a lookup.

An unpaired sender (no ``tls_*`` in its config) attaches only ``{"id": name}``: a claim,
never trusted by a tool that requires pairing, and used as a name only on an unpaired
(loopback, development) link, where nothing is authenticated.

This module is pure apart from reading key files: no threads, no I/O per message.
"""

from __future__ import annotations

import base64
import datetime as dt
import hashlib
import json
import os
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID

__all__ = ["AuthError", "Sender", "Signer", "Verifier", "claim", "sender_of"]

_CONTEXT = b"articutool-link-v1\0"
_MAX_ATTACHMENT = 8192  # bytes; a certificate is ~700
_MAX_DEPTH = 4  # JSON nesting of an attachment (ours are flat objects)
_MAX_DIGITS = 20  # digits of an integer in an attachment (a timestamp in ns has 19)
_T_MAX = 2**63  # timestamps are int64 nanoseconds, as time.time_ns() and ROS stamps


class AuthError(ValueError):
    """A signature is missing, malformed or does not verify (the message says which)."""


@dataclass(frozen=True)
class Sender:
    """Who sent a message: ``identity`` (verified CN, or the claimed name on an unpaired link)
    and whether it was verified; ``refused`` says why a signature failed ('' if none did)."""

    identity: str | None = None
    verified: bool = False
    role: str = ""
    refused: str = ""


def _digest(key: str, t_ns: int, nonce: bytes, payload: bytes) -> bytes:
    return (_CONTEXT + key.encode() + b"\0" + str(t_ns).encode() + b"\0" + nonce
            + hashlib.sha256(payload).digest())


def claim(name: str) -> bytes:
    """The unsigned attachment of an unpaired sender (a name, not a proof)."""
    return json.dumps({"id": name}).encode()


class Signer:
    """Signs outgoing messages with a device's key and certificate."""

    def __init__(self, cert_path: str | Path, key_path: str | Path) -> None:
        cert = x509.load_pem_x509_certificate(Path(cert_path).read_bytes())
        key = serialization.load_pem_private_key(Path(key_path).read_bytes(), None)
        if not isinstance(key, ec.EllipticCurvePrivateKey):
            raise ValueError(f"{key_path}: not an EC private key (made by articutool pair)")
        self._key = key
        self._cert_b64 = base64.b64encode(cert.public_bytes(serialization.Encoding.DER)).decode()
        cn = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
        self.identity = str(cn[0].value) if cn else ""

    def attachment(self, key: str, payload: bytes) -> bytes:
        """The attachment for ``payload`` sent on key expression ``key``."""
        t_ns, nonce = time.time_ns(), os.urandom(12)
        sig = self._key.sign(_digest(key, t_ns, nonce, payload), ec.ECDSA(hashes.SHA256()))
        return json.dumps({"c": self._cert_b64, "t": t_ns, "n": nonce.hex(),
                           "s": base64.b64encode(sig).decode()}).encode()


class Verifier:
    """Checks attachments against the pairing CA (thread-safe)."""

    def __init__(self, ca_path: str | Path, peers: tuple[str, ...] | None = None,
                 window: float = 30.0, max_nonces: int = 200_000) -> None:
        self._ca = x509.load_pem_x509_certificate(Path(ca_path).read_bytes())
        self.peers = None if peers is None else frozenset(peers)
        self.window = float(window)
        self._certs: dict[bytes, tuple[str, str, object, dt.datetime, bytes]] = {}
        self._nonces: OrderedDict[bytes, float] = OrderedDict()
        self._max_nonces = max_nonces
        self._lock = threading.Lock()

    def _cert(self, der: bytes) -> tuple[str, str, object, bytes]:
        with self._lock:
            hit = self._certs.get(der)
        now = dt.datetime.now(dt.UTC)
        if hit is None:
            try:
                cert = x509.load_der_x509_certificate(der)
                cert.verify_directly_issued_by(self._ca)
            except (ValueError, TypeError, InvalidSignature) as err:
                raise AuthError(f"certificate not issued by the pairing CA ({err or 'bad'})") \
                    from None
            if now < cert.not_valid_before_utc:
                raise AuthError("certificate not yet valid")
            cn = cert.subject.get_attributes_for_oid(NameOID.COMMON_NAME)
            ou = cert.subject.get_attributes_for_oid(NameOID.ORGANIZATIONAL_UNIT_NAME)
            pub = cert.public_key()
            spki = pub.public_bytes(serialization.Encoding.DER,
                                    serialization.PublicFormat.SubjectPublicKeyInfo)
            hit = (str(cn[0].value) if cn else "", str(ou[0].value) if ou else "",
                   pub, cert.not_valid_after_utc, hashlib.sha256(spki).digest())
            with self._lock:
                if len(self._certs) > 1024:  # bounded: paired devices are few
                    self._certs.clear()
                self._certs[der] = hit
        name, role, pub, until, key_id = hit
        if now > until:
            raise AuthError(f"certificate of {name!r} expired on {until:%Y-%m-%d}")
        if self.peers is not None and name not in self.peers:
            raise AuthError(f"{name!r} is not among the paired peers {sorted(self.peers)}")
        return name, role, pub, key_id

    def verify(self, key: str, payload: bytes, attachment: bytes | None) -> Sender:
        """The verified sender of ``payload`` on ``key``; AuthError says why not. Every
        malformed attachment is an AuthError, never another exception."""
        if not attachment:
            raise AuthError("not a paired PC: no signature")
        if len(attachment) > _MAX_ATTACHMENT:
            raise AuthError(f"not a paired PC: attachment of {len(attachment)} bytes is too "
                            f"large (at most {_MAX_ATTACHMENT})")
        a = _load(attachment)
        try:
            if not isinstance(a, dict):
                raise ValueError("not a JSON object")
            t_ns = a["t"]
            if isinstance(t_ns, bool) or not isinstance(t_ns, int) or not 0 <= t_ns < _T_MAX:
                raise ValueError("timestamp 't' must be an integer of nanoseconds since 1970")
            der = base64.b64decode(a["c"], validate=True)
            nonce, sig = bytes.fromhex(a["n"]), base64.b64decode(a["s"], validate=True)
        except (ValueError, KeyError, TypeError) as err:
            claimed = a.get("id") if isinstance(a, dict) else None
            why = (f"unsigned claim to be {str(claimed)[:64]!r}" if claimed
                   else f"malformed ({str(err)[:200]})")
            raise AuthError(f"not a paired PC: no valid signature: {why}") from None
        name, role, pub, key_id = self._cert(der)
        skew = time.time() - t_ns * 1e-9
        if abs(skew) > self.window:
            raise AuthError(
                f"clocks not synchronised (or a replay): the message's timestamp is "
                f"{abs(skew):.1f} s {'behind' if skew > 0 else 'ahead of'} the tool's clock "
                f"(limit {self.window:g} s, auth_window); synchronise the PC's and the tool's "
                "clocks (NTP)")
        tag = hashlib.sha256(key_id + nonce + str(t_ns).encode()).digest()[:16]
        with self._lock:
            seen = tag in self._nonces
        if seen:  # before the signature check: a replay flood costs a lookup
            raise AuthError(f"replayed: this signed message from {name!r} was already received "
                            "(each is accepted once)")
        try:
            pub.verify(sig, _digest(key, t_ns, nonce, payload),  # type: ignore[attr-defined]
                       ec.ECDSA(hashes.SHA256()))
        except InvalidSignature:
            raise AuthError(f"signature of {name!r} does not match the message") from None
        now = time.monotonic()
        with self._lock:
            if tag in self._nonces:  # a twin verified on another thread meanwhile
                raise AuthError(f"replayed: this signed message from {name!r} was already "
                                "received (each is accepted once)")
            self._nonces[tag] = now
            while self._nonces and (len(self._nonces) > self._max_nonces
                                    or next(iter(self._nonces.values())) < now - 2 * self.window):
                self._nonces.popitem(last=False)
        return Sender(name, True, role)


def _load(attachment: bytes) -> object:
    """The attachment's JSON; AuthError for anything that is not plain, shallow JSON.

    An attacker controls these bytes: ``Infinity``/``NaN`` (Python's json accepts them), a
    number of hundreds of digits, brackets nested thousands deep (the parser recurses and
    raises RecursionError) and invalid UTF-8 are each refused here as a malformed signature.
    """
    depth = 0
    for byte in attachment:  # bounded by _MAX_ATTACHMENT; strings may hold brackets, so
        if byte in b"[{":    # this over-counts, which only refuses nonsense earlier
            depth += 1
            if depth > _MAX_DEPTH:
                raise AuthError("not a paired PC: no valid signature: malformed (nested "
                                f"deeper than {_MAX_DEPTH})")
        elif byte in b"]}":
            depth -= 1

    def constant(name: str) -> object:
        raise ValueError(f"{name} is not JSON")
    try:
        return json.loads(attachment, parse_constant=constant, parse_int=_bounded_int)
    except (ValueError, TypeError, RecursionError, OverflowError) as err:
        raise AuthError("not a paired PC: no valid signature: malformed "
                        f"({type(err).__name__}: {str(err)[:200]})") from None


def _bounded_int(text: str) -> int:
    if len(text.lstrip("-")) > _MAX_DIGITS:
        raise ValueError(f"an integer of {len(text)} digits")
    return int(text)


def sender_of(attachment: bytes | None) -> Sender:
    """The unverified claim in an attachment (unpaired links): ``Sender(name)`` or empty;
    a malformed attachment is no claim."""
    if not attachment or len(attachment) > _MAX_ATTACHMENT:
        return Sender()
    try:
        a = _load(attachment)
    except AuthError:
        return Sender()
    name = a.get("id") if isinstance(a, dict) else None
    return Sender(str(name)[:64]) if isinstance(name, str) and name else Sender()
