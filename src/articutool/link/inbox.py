"""The link's command inbox: decoded, validated ToolAPI calls waiting for the tool's loop, and
the I/O that must never run on the loop's thread (thesis §3.2.2, §4.5).

The network cannot slow the loop, and no flood can hold back a stop. Commands wait in a bounded
inbox (``inbox_size``; a full inbox refuses the command, ``dropped_excess``). Stops (DISABLED,
a cancel) are never refused for room: a stop identical to one already waiting joins it and gets
the same answer, so the stops waiting (served first) stay as few as their kinds. A stop
supersedes the motion queued before it: a DISABLED discards every queued command that would
move the wrist or change its mode (mode requests, primitive goals, trajectories: those
submitted with a ``discard`` answer), a cancel of goal G discards G's queued start
(:meth:`CommandInbox.discard`); each discarded command is answered through its own reply path
(``superseded``), and commands queued after the stop run normally. Queued commands that do not
move the wrist (clear_fault) stay queued. A loop in this process given to the server (a
``LinkWorkLoop``: ``ToolRuntime``) runs at most one queued call per tick
(:meth:`CommandInbox.work_once`, via its ``set_link_work``); without one (the proxy of a loop
in another process, a runtime the simulation ticks, a test double) a worker thread does.
Replies and publishes that follow a command are sent from a ``link-io`` thread, never from the
thread that ran the command: a send can block on a congested or dead peer.

:class:`CommandInbox` shares the server's counters, lock and stop event; ``ToolServer``
(``link/server.py``) composes it.
"""

from __future__ import annotations

import logging
import threading
from collections import OrderedDict, deque
from collections.abc import Callable
from functools import partial
from typing import NamedTuple

from articutool.link.auth import Sender
from articutool.link.counters import LinkCounters
from articutool.link.transport import Responder

__all__ = ["SUPERSEDED", "CommandInbox"]

_log = logging.getLogger(__name__)

# The refusal a motion command gets when a stop that arrived after it discards it.
SUPERSEDED = "superseded by a stop that arrived before it ran"


class _Queued(NamedTuple):
    """A queued ToolAPI call: ``discard`` (motion commands only) answers it when a stop
    supersedes it, with ``True`` when a cancel of its own goal (``key``) discards it."""

    work: Callable[[], None]
    discard: Callable[[bool], None] | None
    key: object


class CommandInbox:
    """The queued commands and stops, the worker and ``link-io`` threads."""

    def __init__(self, size: int, counters: LinkCounters, lock: threading.RLock,
                 stop: threading.Event) -> None:
        self.size = size
        self.counters = counters
        self._lock = lock
        self._stop = stop
        self.commands: deque[_Queued] = deque()
        # Stops waiting for the loop, by what they do: (run, answers); see submit_stop.
        self.stops: OrderedDict[object, tuple[Callable[[], object],
                                              list[Callable[[object], None]]]] = OrderedDict()
        # DISABLEDs queued so far: a handler reads it as its message arrives (``since``)
        self.epoch = 0
        self._worker: threading.Thread | None = None
        self._wake = threading.Condition()
        # Network I/O never runs on the thread that executes commands (the tool's loop): a
        # reply or publish may block on a congested or dead peer. It goes to link-io.
        self._exec_ident: int | None = None
        self._io: deque[Callable[[], None]] = deque()
        self._io_wake = threading.Condition()
        self._io_thread: threading.Thread | None = None

    # -- threads --
    def start_io(self) -> None:
        """Start the ``link-io`` thread."""
        self._io_thread = threading.Thread(target=self._run_io, name="link-io", daemon=True)
        self._io_thread.start()

    def start_worker(self) -> None:
        """Start a worker thread that drains the inbox (for an API without a loop)."""
        self._worker = threading.Thread(target=self._drain, name="link-worker", daemon=True)
        self._worker.start()

    def join(self) -> None:
        """Once the stop event is set: wake and join the threads (5 s each at most)."""
        with self._wake:
            self._wake.notify_all()
        if self._worker is not None:
            self._worker.join(timeout=5)
            self._worker = None
        if self._io_thread is not None:
            self._io_thread.join(timeout=5)
            self._io_thread = None

    # -- queueing --
    def submit(self, work: Callable[[], None], *,
               discard: Callable[[bool], None] | None = None, key: object = None,
               since: int | None = None) -> bool:
        """Queue a ToolAPI call for the loop; False (counted) when the inbox is full.

        A command that moves the wrist or changes its mode passes ``discard``: a stop that
        arrives before it runs discards it and calls ``discard(cancelled)`` instead (off the
        lock; ``cancelled`` is True when a cancel of its goal ``key`` discarded it). ``since``
        is :attr:`epoch` when its message arrived: a DISABLED queued while the handler was
        still decoding or checking it supersedes it too."""
        with self._lock:
            late = discard is not None and since is not None and since != self.epoch
            if not late and len(self.commands) >= self.size:
                self.counters.bump("dropped_excess")
                return False
            queued = _Queued(work, discard, key)
            if not late:
                self.commands.append(queued)
        if late:
            self._answer_discarded([queued], cancelled=False)
            return True
        with self._wake:
            self._wake.notify()
        return True

    def submit_stop(self, key: object, run: Callable[[], object],
                    answer: Callable[[object], None], *, supersede: bool = False) -> None:
        """Queue a stop for the loop, never refused: a stop equal to one waiting (same
        ``key``) joins it, the loop runs it once and every caller gets ``answer(result)``.
        Stops are idempotent, so this is the same as running each; and however many
        arrive, the stops waiting stay as few as their kinds. With ``supersede`` (DISABLED)
        every motion command queued before it is discarded, in the same step."""
        with self._lock:
            waiting = self.stops.get(key)
            if waiting is None:
                self.stops[key] = (run, [answer])
            else:
                waiting[1].append(answer)
            gone = []
            if supersede:
                self.epoch += 1
                gone = self._take(lambda _: True)
        with self._wake:
            self._wake.notify()
        self._answer_discarded(gone, cancelled=False)

    def discard(self, match: Callable[[object], bool]) -> list[object]:
        """Discard the queued motion commands whose ``key`` matches (a cancel of their goal),
        answer each with ``discard(True)`` and return their keys."""
        with self._lock:
            gone = self._take(match)
        self._answer_discarded(gone, cancelled=True)
        return [q.key for q in gone]

    def _take(self, match: Callable[[object], bool]) -> list[_Queued]:
        """Remove (lock held) the queued motion commands whose key matches; O(queue)."""
        gone = [q for q in self.commands if q.discard is not None and match(q.key)]
        if gone:
            self.commands = deque(q for q in self.commands
                                  if q.discard is None or not match(q.key))
        return gone

    def _answer_discarded(self, gone: list[_Queued], cancelled: bool) -> None:
        """Answer discarded commands (lock not held) and count them."""
        for q in gone:
            self.counters.bump("superseded")
            try:
                q.discard(cancelled)  # type: ignore[misc]
            except Exception:
                self.counters.bump("handler_errors")
                _log.exception("answering a superseded command failed")

    def _drain(self) -> None:
        """Worker thread (APIs without a loop): run queued commands one at a time."""
        while not self._stop.is_set():
            with self._lock:
                pending = bool(self.stops or self.commands)
            if not pending:
                with self._wake:
                    self._wake.wait(0.05)
                continue
            self.work_once()

    def work_once(self) -> None:
        """Run at most one queued ToolAPI call (stops first). Called once per loop tick; never
        raises."""
        with self._lock:
            if self.stops:
                _, (run, answers) = self.stops.popitem(last=False)
                work: Callable[[], None] | None = partial(self._run_stop, run, answers)
            else:
                work = self.commands.popleft().work if self.commands else None
        if work is None:
            return
        self._exec_ident = threading.get_ident()
        try:
            work()
            self.counters.bump("commands")
        except Exception:
            self.counters.bump("handler_errors")
            _log.exception("link command failed")

    @staticmethod
    def _run_stop(run: Callable[[], object], answers: list[Callable[[object], None]]) -> None:
        result = run()
        for answer in answers:
            answer(result)

    # -- I/O off the loop --
    def off_loop(self, io: Callable[[], None]) -> None:
        """Run network I/O now, unless on the command-executing thread: then on link-io."""
        if threading.get_ident() != self._exec_ident:
            io()
            return
        with self._io_wake:
            self._io.append(io)
            self._io_wake.notify()

    def replies_off_loop(self, fn: Callable[..., None]) -> Callable[..., None]:
        """A service handler whose ``respond`` never sends from the command thread."""
        def handler(data: bytes, respond: Responder, sender: Sender) -> None:
            fn(data, lambda reply: self.off_loop(lambda: respond(reply)), sender)
        return handler

    def _run_io(self) -> None:
        while True:
            with self._io_wake:
                while not self._io and not self._stop.is_set():
                    self._io_wake.wait(0.1)
                if not self._io:
                    return
                io = self._io.popleft()
            try:
                io()
            except Exception:
                self.counters.bump("handler_errors")
                _log.exception("link reply/publish failed")
