"""The Articutool link on Eclipse Zenoh (zenoh-python 1.x), keyed as rmw_zenoh keys ROS 2.

See ``articutool.link.transport`` for the key-expression mapping and its deviations.
Reconnection is Zenoh's: a session keeps retrying its ``connect`` endpoints (every
``reconnect_period``), and declared subscribers and queryables survive a reconnection, so
neither side re-declares anything after the link comes back.

Shutdown: zenoh-python runs each Python callback in its own thread (``pyo3-closure``), which
ends only *after* its subscriber or queryable is dropped, asynchronously. A thread still
alive when the interpreter finalises dies trying to take the GIL, and the forced unwind
through Rust aborts the process ("FATAL: exception not rethrown", SIGABRT: ``articutool tool``
did this on Ctrl-C in 10 of 20 runs under load). :meth:`ZenohTransport.close` therefore
waits, bounded, until zenoh has dropped every callback and joins those threads.
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import logging
import re
import socket
import threading
import time
from collections.abc import Callable
from typing import Any, Literal

import zenoh

from articutool.link.auth import AuthError, Sender, Signer, Verifier, claim, sender_of
from articutool.link.config import ConfigError, LinkConfig
from articutool.link.transport import (
    Endpoint,
    Handle,
    LinkOpenError,
    LinkRefusedError,
    LinkTimeoutError,
    RefusalError,
    Transport,
    key_expr,
)

__all__ = ["ZenohTransport", "exposure", "zenoh_config"]

_log = logging.getLogger(__name__)
_DRAIN_S = 5.0  # bound on waiting for zenoh's callback threads to end at close
_REFUSED = "articutool refused: "  # prefix of our error replies (zenoh sends its own too)


def _reason(err: Exception) -> str:
    """A zenoh error without its Rust source locations (`` at /…/x.rs:61.``)."""
    return re.sub(r"\s+at \S+\.rs:\d+\.?", "", str(err)).strip()


def zenoh_config(cfg: LinkConfig, role: Literal["tool", "client"]) -> zenoh.Config:
    """The zenoh session config for ``role`` (loopback defaults, no multicast scouting)."""
    listen, connect = cfg.endpoints(role)
    z = zenoh.Config()
    z.insert_json5("mode", json.dumps(cfg.mode))
    z.insert_json5("scouting/multicast/enabled", json.dumps(cfg.multicast_scouting))
    z.insert_json5("listen/endpoints", json.dumps(list(listen)))
    z.insert_json5("connect/endpoints", json.dumps(list(connect)))
    period_ms = int(cfg.reconnect_period * 1000)
    # Start even when the other side is down, and keep retrying at a short fixed period.
    z.insert_json5("connect/timeout_ms", "-1" if cfg.mode == "peer" else "0")
    z.insert_json5("connect/exit_on_failure", "false")
    z.insert_json5("connect/retry", json.dumps(
        {"period_init_ms": period_ms, "period_max_ms": period_ms, "period_increase_factor": 1}))
    if cfg.paired:  # mutual TLS on every tls/ endpoint (a tcp/ one stays plain)
        tls = "transport/link/tls/"
        z.insert_json5(tls + "root_ca_certificate", json.dumps(cfg.tls_root_ca))
        z.insert_json5(tls + "enable_mtls", "true")
        # The PC does not know the Pi's address at pairing: the CA signature is checked.
        z.insert_json5(tls + "verify_name_on_connect", "false")
        for side in ("listen", "connect"):
            z.insert_json5(f"{tls}{side}_certificate", json.dumps(cfg.tls_certificate))
            z.insert_json5(f"{tls}{side}_private_key", json.dumps(cfg.tls_private_key))
    for path, value in cfg.extra.items():
        try:
            z.insert_json5(path, json.dumps(value))
        except (zenoh.ZError, TypeError, ValueError) as err:
            raise ConfigError(f"extra[{path!r}]: zenoh does not accept {value!r} there: "
                              f"{_reason(err)}") from None
    return z


_ZENOH_DEFAULT_LISTEN = {"router": ["tcp/[::]:7447"], "peer": ["tcp/[::]:0"]}


def _loopback(host: str) -> bool:
    """Whether ``host`` (an IP literal or a name) resolves to loopback addresses only: a name
    is resolved, never judged by its spelling ('127.x.example', 'localhost.example' are not
    loopback unless they resolve there)."""
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    try:
        infos = socket.getaddrinfo(host, None)
    except (OSError, UnicodeError):
        return False
    addrs = {ipaddress.ip_address(str(i[4][0]).split("%", 1)[0]) for i in infos}

    def lo(a: ipaddress.IPv4Address | ipaddress.IPv6Address) -> bool:
        mapped = getattr(a, "ipv4_mapped", None)
        return a.is_loopback or (mapped is not None and mapped.is_loopback)
    return bool(addrs) and all(lo(a) for a in addrs)


def exposure(cfg: LinkConfig, role: Literal["tool", "client"] = "tool") -> list[str]:
    """How anyone but a local process could reach a session of ``role`` opened with
    ``cfg`` and, unless it requires signatures, command it; [] if nobody.

    Read from the zenoh config the session would open with, after every way of setting it
    (flags, the link config's fields, its raw ``extra`` zenoh settings, zenoh's defaults):
    each listen and connect endpoint that is neither a Unix socket, nor on a host that
    resolves to loopback only, nor TLS with mutual authentication by the pairing CA; and
    multicast scouting (it connects to peers found on the network).
    """
    z = zenoh_config(cfg, role)

    def get(path: str) -> Any:
        return json.loads(z.get_json(path))
    mode = get("mode") or "peer"
    mtls = bool(get("transport/link/tls/enable_mtls")) and bool(
        get("transport/link/tls/root_ca_certificate"))
    out = []
    for side in ("listen", "connect"):
        eps = get(f"{side}/endpoints")
        if isinstance(eps, dict):  # per-mode lists, zenoh's default for listen
            eps = eps.get(mode, _ZENOH_DEFAULT_LISTEN.get(mode, []) if side == "listen" else [])
        for e in eps if isinstance(eps, list) else [eps]:
            proto, _, rest = str(e).partition("/")
            host = rest.split("?", 1)[0].split("#", 1)[0].rpartition(":")[0]
            if proto == "unixsock-stream" or (proto == "tls" and mtls) or (
                    proto in ("tcp", "udp", "tls", "quic", "ws") and host and _loopback(host)):
                continue
            out.append(f"{side} endpoint {e}")
    if get("scouting/multicast/enabled") is not False:  # zenoh's default is on
        out.append("multicast scouting (it connects to peers found on the network)")
    return out


class _ZHandle(Handle):
    def __init__(self, entity: object) -> None:
        self._entity = entity

    def close(self) -> None:
        with contextlib.suppress(Exception):  # already closed with the session
            self._entity.undeclare()  # type: ignore[attr-defined]


class _Dropped:
    """A callback's drop hook: zenoh calls it last, on the callback's own thread."""

    def __init__(self) -> None:
        self.event = threading.Event()
        self.thread: threading.Thread | None = None

    def __call__(self) -> None:
        self.thread = threading.current_thread()
        self.event.set()

    def wait(self, deadline: float) -> bool:
        """Until the callback was dropped and its thread ended (or ``deadline``)."""
        if not self.event.wait(max(0.0, deadline - time.monotonic())):
            return False
        th = self.thread
        if th is not None and th is not threading.current_thread():
            th.join(max(0.0, deadline - time.monotonic()))
            return not th.is_alive()
        return True


def _guard(fn: Callable[..., None], what: str) -> Callable[..., None]:
    """Callbacks run on zenoh threads: never let an exception escape into zenoh."""
    def wrapped(*a: object) -> None:
        try:
            fn(*a)
        except Exception:
            _log.exception("link callback for %s raised", what)
    return wrapped


class ZenohTransport(Transport):
    """A zenoh session speaking the Articutool endpoints."""

    def __init__(self, cfg: LinkConfig, role: Literal["tool", "client"],
                 identity: str | None = None) -> None:
        self.cfg = cfg
        self.role = role
        self.identity = identity or cfg.identity or (cfg.tool_id if role == "tool" else "")
        self._signer: Signer | None = None
        self._verifier: Verifier | None = None
        if cfg.paired:
            try:
                self._signer = Signer(cfg.tls_certificate, cfg.tls_private_key)  # type: ignore[arg-type]
                self._verifier = Verifier(cfg.tls_root_ca, cfg.peers,  # type: ignore[arg-type]
                                          cfg.auth_window)
            except (OSError, ValueError) as err:
                raise LinkOpenError(f"cannot load the pairing files: {err}") from None
            self.identity = self._signer.identity
        try:
            self._session = zenoh.open(zenoh_config(cfg, role))
        except zenoh.ZError as err:
            listen, connect = cfg.endpoints(role)
            raise LinkOpenError(f"cannot open the link (listen={list(listen)}, connect="
                                f"{list(connect)}): {_reason(err)}") from None
        self._pubs: dict[str, zenoh.Publisher] = {}
        self._drops: list[_Dropped] = []
        self._lock = threading.Lock()
        self._closed = False

    def _callback(self, fn: Callable[..., None], what: str) -> zenoh.handlers.Callback:
        drop = _Dropped()
        with self._lock:
            self._drops.append(drop)
        return zenoh.handlers.Callback(_guard(fn, what), drop)

    def _key(self, ep: Endpoint, exact: bool) -> str:
        return key_expr(self.cfg.domain_id, ep, with_hash=exact or self.cfg.type_hash_in_keys)

    def _attachment(self, ep: Endpoint, payload: bytes) -> bytes:
        """Signed with the paired key, else a bare claim of this device's name."""
        if self._signer is not None:
            return self._signer.attachment(ep.name, payload)
        return claim(self.identity)

    def _sender(self, ep: Endpoint, payload: bytes, att: zenoh.ZBytes | None) -> Sender:
        raw = att.to_bytes() if att is not None else None
        if self._verifier is None:
            return sender_of(raw)
        try:
            return self._verifier.verify(ep.name, payload, raw)
        except AuthError as err:
            return Sender(sender_of(raw).identity, False, "", str(err))
        except Exception as err:  # any other failure is a refusal too: counted and answered
            return Sender(None, False, "", "not a paired PC: the signature could not be "
                          f"checked ({type(err).__name__})")

    def _too_big(self, ep: Endpoint, size: int, max_bytes: int | None) -> bool:
        if max_bytes is not None and size > max_bytes:
            self._dropped(ep, f"oversized ({size} > {max_bytes} bytes)")
            return True
        return False

    def publish(self, ep: Endpoint, payload: bytes) -> None:
        with self._lock:
            if self._closed:
                return
            pub = self._pubs.get(ep.name)
            if pub is None:
                pub = self._pubs[ep.name] = self._session.declare_publisher(
                    self._key(ep, exact=True))
        pub.put(payload, attachment=self._attachment(ep, payload))

    def subscribe(self, ep: Endpoint, callback: Callable[..., None], with_sender: bool = False,
                  max_bytes: int | None = None) -> Handle:
        def on_sample(sample: zenoh.Sample) -> None:
            if self._too_big(ep, len(sample.payload), max_bytes):  # before copying it
                return
            data = sample.payload.to_bytes()
            if with_sender:
                callback(data, self._sender(ep, data, sample.attachment))
            else:
                callback(data)
        return _ZHandle(self._session.declare_subscriber(
            self._key(ep, exact=False), self._callback(on_sample, ep.name)))

    def serve(self, ep: Endpoint, handler: Callable[..., None], with_sender: bool = False,
              max_bytes: int | None = None) -> Handle:
        def on_query(query: zenoh.Query) -> None:
            size = len(query.payload) if query.payload is not None else 0
            if self._too_big(ep, size, max_bytes):
                query.drop()
                return
            data = query.payload.to_bytes() if query.payload is not None else b""
            once = threading.Lock()

            def respond(reply: bytes) -> None:
                if not once.acquire(blocking=False):
                    return
                try:
                    query.reply(query.key_expr, reply, attachment=query.attachment)
                finally:
                    query.drop()  # finalise: the querier learns no more replies are coming

            try:
                if with_sender:
                    handler(data, _guard(respond, ep.name),
                            self._sender(ep, data, query.attachment))
                else:
                    handler(data, _guard(respond, ep.name))
            except RefusalError as why:  # tell the caller at once, with the reason
                if once.acquire(blocking=False):
                    try:
                        query.reply_err(f"{_REFUSED}{why}")
                    finally:
                        query.drop()
        return _ZHandle(self._session.declare_queryable(
            self._key(ep, exact=True), self._callback(on_query, ep.name)))

    def call(self, ep: Endpoint, payload: bytes, timeout: float) -> bytes:
        replies = self._session.get(self._key(ep, exact=False), payload=payload,
                                    attachment=self._attachment(ep, payload),
                                    timeout=float(timeout))
        errors = []
        for reply in replies:
            if reply.ok is not None:
                return reply.ok.payload.to_bytes()
            errors.append(reply.err.payload.to_string() if reply.err else "?")
        refused = [e[len(_REFUSED):] for e in errors if e.startswith(_REFUSED)]
        if refused:
            raise LinkRefusedError(f"{ep.name}: the tool refused: {'; '.join(refused)}")
        detail = f" (errors: {errors})" if errors else ""  # zenoh's own, e.g. 'Timeout'
        raise LinkTimeoutError(f"no reply from {ep.name} within {timeout:g} s{detail}")

    def close(self) -> None:
        """Close the session, then wait (bounded) until zenoh's callback threads have ended."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            drops = list(self._drops)
        try:
            self._session.close()
        except Exception:
            _log.exception("closing the zenoh session failed")
        deadline = time.monotonic() + _DRAIN_S
        if not all([d.wait(deadline) for d in drops]):
            _log.warning("zenoh callback threads still running %.0f s after close", _DRAIN_S)
