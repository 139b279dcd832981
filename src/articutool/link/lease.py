"""The command lease: one commander at a time (thesis §3.2.2, §4.5).

The first command from a client gives it the lease, which its heartbeats and commands renew
and which expires ``client_timeout`` seconds after it was last heard, or when it releases it.
Stops pass without touching it. ``take_over`` moves it at once and is audited: every
transition (granted, released, expired, take_over) is a JSON line kept in memory (last 100)
and, with ``audit_log``, appended to that file.

Pure state with no lock of its own: ``ToolServer`` (``link/server.py``) holds its lock around
every call, and counts the refusals and take-overs in its health counters.
"""

from __future__ import annotations

import json
import logging
import time
from collections import deque

__all__ = ["CommandLease"]

_log = logging.getLogger(__name__)


class CommandLease:
    """Who holds the command lease and when it was last heard (monotonic seconds)."""

    def __init__(self, client_timeout: float, tool_id: str, audit_log: str | None) -> None:
        self.client_timeout = client_timeout
        self.tool_id = tool_id
        self.audit_log = audit_log
        self.holder: str | None = None
        self.seen = 0.0
        self.audit: deque[str] = deque(maxlen=100)  # JSON lines, newest last

    def acquire(self, who: str, now: float, stop: bool = False) -> str:
        """'' if ``who`` may command now (taking a free or expired lease, renewing its own);
        else the refusal naming the holder. Stops pass without touching the lease."""
        self.expire(now)
        if self.holder is None and not stop:
            self.holder = who
            _log.info("command lease granted to %s", who)
            self.record("lease_granted", who, None)
        if self.holder == who:
            self.seen = now
            return ""
        if stop:
            return ""
        return (f"refused: {self.holder} holds the command lease (heard "
                f"{now - self.seen:.1f} s ago); it ends when {self.holder} releases "
                f"it or is silent for {self.client_timeout:g} s. Read-only access is "
                "open; stops (mode disabled, cancel) are always accepted; 'articutool "
                "client take-over' takes the lease (audited)")

    def renew(self, who: str, now: float) -> None:
        """``who`` was heard (a heartbeat): renew the lease if it holds it."""
        if self.holder == who:
            self.seen = now

    def expire(self, now: float) -> None:
        """End the lease of a holder silent for ``client_timeout``."""
        if self.holder is not None and now - self.seen > self.client_timeout:
            _log.warning("command lease of %s expired (silent %.1f s)", self.holder,
                         now - self.seen)
            self.record("lease_expired", self.holder, None)
            self.holder = None

    def take_over(self, who: str, now: float) -> str | None:
        """Give the lease to ``who`` at once; returns the previous holder (the caller logs
        and records the take-over)."""
        before = self.holder
        self.holder, self.seen = who, now
        return before

    def release(self, who: str) -> bool:
        """End ``who``'s lease; False if it does not hold it (the caller records it)."""
        if self.holder != who:
            return False
        self.holder = None
        return True

    def record(self, event: str, who: str | None, previous: str | None) -> None:
        """Record a lease transition: in memory (last 100) and, with ``audit_log``, one JSON
        line appended to that file (never raises: the audit must not stop a command)."""
        rec = {"time": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "tool_id": self.tool_id,
               "event": event, "client": who, "previous_holder": previous}
        self.audit.append(json.dumps(rec))
        if self.audit_log:
            try:
                with open(self.audit_log, "a", encoding="utf-8") as f:
                    f.write(json.dumps(rec) + "\n")
            except OSError as err:
                _log.error("cannot append to the audit log %s: %s", self.audit_log, err)
