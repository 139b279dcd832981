"""The tool server's link counters: every message it refused, dropped or handled, under one
lock of their own, so a count is never lost between the threads that receive messages, run
commands and publish health."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field, fields

__all__ = ["LinkCounters"]


@dataclass
class LinkCounters:
    """How many of each event the tool server has seen since it started (published in its
    health diagnostics). Increment with :meth:`bump`; read one with ``counters["name"]`` or
    all at one instant with :meth:`snapshot`."""

    decode_errors: int = 0  # a message that did not decode
    handler_errors: int = 0  # a handler raised (the call is answered with the error)
    rejected_trajectories: int = 0  # a JointTrajectory the tool refused
    link_losses: int = 0  # the commanding PC went silent past client_timeout
    ticks: int = 0  # publishing steps
    refused_unpaired: int = 0  # an unsigned or foreign command on a paired tool
    refused_lease: int = 0  # a command from a device that does not hold the lease
    lease_takeovers: int = 0  # a device took the lease from a silent holder
    oversized: int = 0  # a message above its size limit, dropped before decoding
    rate_limited: int = 0  # a message above a sender's rate, dropped
    dropped_excess: int = 0  # a command refused because the inbox was full
    commands: int = 0  # commands the loop ran
    superseded: int = 0  # a queued motion command a stop discarded before it ran
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False, compare=False)

    def bump(self, name: str, n: int = 1) -> int:
        """Add ``n`` to counter ``name`` and return its new value (KeyError for a name that
        is not a counter)."""
        if name not in _NAMES:
            raise KeyError(name)
        with self._lock:
            value = getattr(self, name) + n
            setattr(self, name, value)
            return value

    def __getitem__(self, name: str) -> int:
        if name not in _NAMES:
            raise KeyError(name)
        return int(getattr(self, name))

    def snapshot(self) -> dict[str, int]:
        """Every counter, read at one instant."""
        with self._lock:
            return {k: int(getattr(self, k)) for k in _NAMES}


# The counters' names in field order (the health message lists them so): every field but the lock.
_NAMES = tuple(f.name for f in fields(LinkCounters) if f.name != "_lock")
