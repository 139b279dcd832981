"""In-process transport for unit tests: a bus shared by several ``MemoryTransport`` objects.

Delivery is asynchronous on one dispatcher thread per bus (like a network, a publisher never
runs its subscribers' code). ``MemoryTransport.connected = False`` cuts one participant off
the bus, which is how unit tests simulate a lost link.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable

from articutool.link.auth import Sender
from articutool.link.transport import (
    Endpoint,
    Handle,
    LinkRefusedError,
    LinkTimeoutError,
    RefusalError,
    Transport,
)

__all__ = ["MemoryBus", "MemoryTransport"]

_log = logging.getLogger(__name__)


class _Handle(Handle):
    def __init__(self, registry: dict, key: str, item: object, lock: threading.Lock) -> None:
        self._registry, self._key, self._item, self._lock = registry, key, item, lock

    def close(self) -> None:
        with self._lock:
            items = self._registry.get(self._key, [])
            if self._item in items:
                items.remove(self._item)


class MemoryBus:
    """The shared medium; call :meth:`close` to stop its dispatcher thread."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.subs: dict[str, list[tuple]] = {}  # (transport, callback, with_sender, max_bytes)
        self.services: dict[str, list[tuple]] = {}
        self._q: queue.Queue[Callable[[], None] | None] = queue.Queue()
        self._thread = threading.Thread(target=self._run, name="memory-bus", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while (job := self._q.get()) is not None:
            try:
                job()
            except Exception:  # a faulty callback must not stop the bus
                _log.exception("memory bus callback raised")

    def post(self, job: Callable[[], None]) -> None:
        """Run ``job`` on the dispatcher thread."""
        self._q.put(job)

    def close(self) -> None:
        """Stop the dispatcher."""
        self._q.put(None)
        self._thread.join(timeout=5)


class MemoryTransport(Transport):
    """One participant on a :class:`MemoryBus`."""

    def __init__(self, bus: MemoryBus, identity: str | None = None,
                 verified: bool = False) -> None:
        self.bus = bus
        self.connected = True
        self.sender = Sender(identity, verified)  # what receivers are told (no signatures)

    @staticmethod
    def _deliver(cb: Callable, args: tuple, with_sender: bool, sender: Sender) -> None:
        cb(*args, sender) if with_sender else cb(*args)

    def publish(self, ep: Endpoint, payload: bytes) -> None:
        if not self.connected:
            return
        with self.bus.lock:
            targets = [(t, cb, ws, mb) for t, cb, ws, mb in self.bus.subs.get(ep.name, [])
                       if t.connected]
        data = bytes(payload)
        for t, cb, ws, mb in targets:
            if mb is not None and len(data) > mb:  # the receiver drops it and is told
                t._dropped(ep, f"oversized ({len(data)} > {mb} bytes)")
                continue
            self.bus.post(lambda cb=cb, ws=ws: self._deliver(cb, (data,), ws, self.sender))

    def subscribe(self, ep: Endpoint, callback: Callable[..., None], with_sender: bool = False,
                  max_bytes: int | None = None) -> Handle:
        item = (self, callback, with_sender, max_bytes)
        with self.bus.lock:
            self.bus.subs.setdefault(ep.name, []).append(item)
        return _Handle(self.bus.subs, ep.name, item, self.bus.lock)

    def serve(self, ep: Endpoint, handler: Callable[..., None], with_sender: bool = False,
              max_bytes: int | None = None) -> Handle:
        item = (self, handler, with_sender, max_bytes)
        with self.bus.lock:
            self.bus.services.setdefault(ep.name, []).append(item)
        return _Handle(self.bus.services, ep.name, item, self.bus.lock)

    def call(self, ep: Endpoint, payload: bytes, timeout: float) -> bytes:
        with self.bus.lock:
            servers = [it for it in self.bus.services.get(ep.name, []) if it[0].connected]
        if not self.connected or not servers:
            raise LinkTimeoutError(f"no server for {ep.name}")
        done = threading.Event()
        box: list[bytes] = []
        refused: list[str] = []
        server, handler, ws, mb = servers[0]

        def respond(reply: bytes) -> None:
            if server.connected and self.connected and not done.is_set():
                box.append(bytes(reply))
                done.set()

        def serve() -> None:
            try:
                self._deliver(handler, (data, respond), ws, self.sender)
            except RefusalError as why:
                refused.append(str(why))
                done.set()

        data = bytes(payload)
        if mb is not None and len(data) > mb:
            server._dropped(ep, f"oversized ({len(data)} > {mb} bytes)")
        else:
            self.bus.post(serve)
        if not done.wait(timeout):
            raise LinkTimeoutError(f"no reply from {ep.name} within {timeout:g} s")
        if refused:
            raise LinkRefusedError(f"{ep.name}: the tool refused: {refused[0]}")
        return box[0]

    def close(self) -> None:
        self.connected = False
        with self.bus.lock:
            for reg in (self.bus.subs, self.bus.services):
                for key in reg:
                    reg[key] = [it for it in reg[key] if it[0] is not self]
