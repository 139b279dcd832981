"""Who may reach the tool's commands, and how often (thesis §3.2.2, §4.5).

On a paired tool (``LinkConfig.requires_pairing``) a command must come from a verified paired
PC; the refusal names the real reason (clock out of sync, replay, expired certificate; "not a
paired PC" only when it is not). Every *sender* — its verified identity, and on a paired tool
all unverified senders as one — gets ``max_rate_hz`` messages per endpoint (a token bucket,
``RateGate``), so one sender's flood never uses another's. Each dropped, refused or malformed
message is counted in the server's health counters and logged: the first few of each kind,
then one in a thousand with the count, so a flood cannot flood the log.

:class:`Admission` shares the server's counters and lock; ``ToolServer``
(``link/server.py``) composes it.
"""

from __future__ import annotations

import logging
import threading
from collections import OrderedDict

from articutool.link.auth import Sender
from articutool.link.config import LinkConfig
from articutool.link.counters import LinkCounters
from articutool.link.transport import Endpoint, RateGate, RefusalError

__all__ = ["Admission"]

_log = logging.getLogger(__name__)
_MAX_GATES = 1024  # per-sender rate gates kept (oldest forgotten: a fresh gate is full)
_LOGGED = 10  # log lines per kind of dropped/refused/malformed message, then 1 in _EVERY
_EVERY = 1000


class Admission:
    """The pairing check, the per-sender rate gates and the counted, throttled log."""

    def __init__(self, cfg: LinkConfig, counters: LinkCounters,
                 lock: threading.RLock) -> None:
        self.cfg = cfg
        self.counters = counters
        self._lock = lock
        self._gates: OrderedDict[tuple[str, str], RateGate] = OrderedDict()

    def note(self, key: str, fmt: str, *args: object) -> None:
        """Count one dropped, refused or malformed message under ``key`` and log it: the
        first few of each kind, then one in _EVERY with the count (a flood must not flood
        the log)."""
        n = self.counters.bump(key)
        if n <= _LOGGED or n % _EVERY == 0:
            _log.warning(fmt + "; %d %s so far", *args, n, key)

    def admit(self, sender: Sender, what: str) -> tuple[str | None, str]:
        """(the client's identity, '') if it may command, else (None, the refusal naming
        the real reason: a paired PC whose clock is off is told so); counted, logged."""
        if self.cfg.requires_pairing and not (sender.verified and sender.role == "pc"):
            why = sender.refused or (f"{sender.identity!r} is not a PC" if sender.verified
                                     else "not a paired PC: not signed")
            self.note("refused_unpaired", "refused %s (%s)", what, why)
            return None, f"refused: {why}"
        return sender.identity or "anonymous", ""

    def sender_key(self, sender: Sender) -> str:
        """Whose rate limit a message counts against: the verified identity; on a paired
        tool every unverified sender shares one (a claimed name proves nothing)."""
        if sender.verified or not self.cfg.requires_pairing:
            return sender.identity or "anonymous"
        return "(unverified)"

    def within_rate(self, ep: Endpoint, sender: Sender) -> bool:
        """Take one of the sender's ``max_rate_hz`` tokens on ``ep``; False (counted) if it
        has none left. One sender's flood never uses another's."""
        k = (ep.name, self.sender_key(sender))
        with self._lock:
            gate = self._gates.get(k)
            if gate is None:
                gate = self._gates[k] = RateGate(self.cfg.max_rate_hz)
                if len(self._gates) > _MAX_GATES:
                    self._gates.popitem(last=False)
            else:
                self._gates.move_to_end(k)
        if gate.allow():
            return True
        self.note("rate_limited", "dropped a message on %s (rate, from %s)", ep.name, k[1])
        return False

    def rate_limit(self, ep: Endpoint, sender: Sender) -> None:
        """Raise RefusalError (an immediate error reply) when the sender is over its rate."""
        if not self.within_rate(ep, sender):
            raise RefusalError(f"rate limited: more than {self.cfg.max_rate_hz:g} requests/s from "
                          f"{self.sender_key(sender)} on {ep.name}")
