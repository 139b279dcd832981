"""The Articutool link on Eclipse Zenoh (zenoh-python 1.x), keyed as rmw_zenoh keys ROS 2.

See ``articutool.link.transport`` for the key-expression mapping and its deviations.
Reconnection is Zenoh's: a session keeps retrying its ``connect`` endpoints (every
``reconnect_period``), and declared subscribers and queryables survive a reconnection, so
neither side re-declares anything after the link comes back.
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
from collections.abc import Callable
from typing import Literal

import zenoh

from articutool.link.config import LinkConfig
from articutool.link.transport import (
    Endpoint,
    Handle,
    LinkTimeoutError,
    Responder,
    Transport,
    key_expr,
)

__all__ = ["ZenohTransport", "zenoh_config"]

_log = logging.getLogger(__name__)


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
    for path, value in cfg.extra.items():
        z.insert_json5(path, json.dumps(value))
    return z


class _ZHandle(Handle):
    def __init__(self, entity: object) -> None:
        self._entity = entity

    def close(self) -> None:
        with contextlib.suppress(Exception):  # already closed with the session
            self._entity.undeclare()  # type: ignore[attr-defined]


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

    def __init__(self, cfg: LinkConfig, role: Literal["tool", "client"]) -> None:
        self.cfg = cfg
        self.role = role
        self._session = zenoh.open(zenoh_config(cfg, role))
        self._pubs: dict[str, zenoh.Publisher] = {}
        self._lock = threading.Lock()
        self._closed = False

    def _key(self, ep: Endpoint, exact: bool) -> str:
        return key_expr(self.cfg.domain_id, ep, with_hash=exact or self.cfg.type_hash_in_keys)

    def publish(self, ep: Endpoint, payload: bytes) -> None:
        with self._lock:
            if self._closed:
                return
            pub = self._pubs.get(ep.name)
            if pub is None:
                pub = self._pubs[ep.name] = self._session.declare_publisher(
                    self._key(ep, exact=True))
        pub.put(payload)

    def subscribe(self, ep: Endpoint, callback: Callable[[bytes], None]) -> Handle:
        def on_sample(sample: zenoh.Sample) -> None:
            callback(sample.payload.to_bytes())
        return _ZHandle(self._session.declare_subscriber(
            self._key(ep, exact=False), _guard(on_sample, ep.name)))

    def serve(self, ep: Endpoint, handler: Callable[[bytes, Responder], None]) -> Handle:
        def on_query(query: zenoh.Query) -> None:
            data = query.payload.to_bytes() if query.payload is not None else b""
            once = threading.Lock()

            def respond(reply: bytes) -> None:
                if not once.acquire(blocking=False):
                    return
                try:
                    query.reply(query.key_expr, reply, attachment=query.attachment)
                finally:
                    query.drop()  # finalise: the querier learns no more replies are coming

            handler(data, _guard(respond, ep.name))
        return _ZHandle(self._session.declare_queryable(
            self._key(ep, exact=True), _guard(on_query, ep.name)))

    def call(self, ep: Endpoint, payload: bytes, timeout: float) -> bytes:
        replies = self._session.get(self._key(ep, exact=False), payload=payload,
                                    timeout=float(timeout))
        errors = []
        for reply in replies:
            if reply.ok is not None:
                return reply.ok.payload.to_bytes()
            errors.append(reply.err.payload.to_string() if reply.err else "?")
        detail = f" (errors: {errors})" if errors else ""
        raise LinkTimeoutError(f"no reply from {ep.name} within {timeout:g} s{detail}")

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
        try:
            self._session.close()
        except Exception:
            _log.exception("closing the zenoh session failed")
