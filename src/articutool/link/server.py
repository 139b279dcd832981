"""Tool side of the link: serves a ``ToolAPI`` over a ``Transport`` (thesis §3.2.2, §4.5).

Served: the ``SetOrientationControl`` service, the ``ExecuteArticutoolPrimitive`` action
(send_goal / get_result / cancel_goal / feedback / status) and a joint-trajectory subscriber.
Published at the loop rate (spec ``wrist.loop_rate_hz``, 50 Hz): joint states, filtered IMU
orientation, health diagnostics (loop period/jitter/overruns, fault, mode, link counters) and
battery; a heartbeat and the action status every ``heartbeat_period``.

The 50 Hz control loop is the runtime's, not ours: this module only reads snapshots and
forwards commands, so a slow or lost link never delays the loop, and leveling goes on
whatever happens to the link.

Refusals: ROS 2's SendGoal response carries no text, so a primitive the tool refuses (unknown
name, bad parameters, busy, leveling) is *accepted then aborted* at once: get_result returns
``success=false`` with the tool's message and status ABORTED.

Goals are identified by their goal id (the goal table, ``link/goals.py``). Before starting
one the server settles the current goal (a goal that ended between two ticks gets its result
then), and while its goal still runs it refuses the new one itself, so no goal's final status
is ever overwritten unseen.

Who may command: on a paired tool (``LinkConfig.requires_pairing``) every command,
trajectory and client heartbeat must carry a paired PC's signature (``articutool.link.auth``);
anything else is refused (services answer ``success=false`` with the reason, topics are
dropped) and counted (``refused_unpaired``). Telemetry is open to any session that reached the
tool (on a paired tool, over mutual TLS, only paired devices reach it).

A paired PC's refusals say why: clocks out of sync, a replay, an expired
certificate; "not a paired PC" only when it is not. Refused goals and cancels, whose ROS
replies carry no text, are answered with an error naming the reason (the client reads it).

One commander at a time (``link/lease.py``): the first command from a client gives it the
*command lease*, which its heartbeats (and commands) renew and which expires
``client_timeout`` seconds after it was last heard, or when it calls ``release``. Another
client's commands are refused with a message naming the holder (``refused_lease``), except
stops: DISABLED and cancel are accepted from any admitted client, without moving the lease.
``take_over`` gives the lease to the caller at once and is audited (a WARNING log line
``AUDIT …``, the ``lease_takeovers`` counter and, with ``LinkConfig.audit_log``, a JSON line
per lease transition: granted, released, expired, take_over). On an unpaired link the names
are the clients' own claims, so the lease orders honest clients only.

The network cannot slow the loop, and no flood can hold back a stop: the
transport drops payloads above a per-type size (``max_trajectory_bytes``,
``max_request_bytes``) before copying them (``oversized``) and verifies the sender; this
server then refuses what is not admitted, limits each *sender* to ``max_rate_hz`` per
endpoint (``rate_limited``; a sender is its verified identity, and on a paired tool all
unverified senders share one limit), decodes and validates, and only then queues the
ToolAPI call in a bounded inbox (``inbox_size``; a full inbox refuses the command,
``dropped_excess``). Stops (DISABLED, a cancel) are never rate-limited and never refused
for room: a stop identical to one already waiting (every DISABLED; a cancel of the same
goal) joins it and gets the same answer, a cancel of a goal that is not running is
answered at once, so the stops waiting (served first) are one DISABLED and a cancel of
the running goal at most. Unsigned or replayed traffic on a paired tool is refused before
it reaches a gate or a queue. Replies and publishes that follow a command are sent from a
``link-io`` thread, never from the thread that ran the command (a send can block on a
congested or dead peer). Given a ``loop`` (a :class:`~articutool.tool.api.LinkWorkLoop`: a
``ToolRuntime`` running its own loop in this process) the loop drains the inbox, one command
per tick, after the tick; without one, a worker thread of this server does, one command at a
time: ``articutool tool`` serves a ``LoopProxy`` (``tool/channel.py``) in its link process,
which hands each command to the loop in the other process.

Link-loss policy (``LinkConfig.link_loss_policy``) when no client heartbeat or request has
arrived for ``client_timeout`` seconds: ``"continue"`` (default) lets a running primitive
finish; ``"cancel"`` cancels it (motors stop). Continue is the default because primitives are
short, bounded motions inside the wrist's limits that the tool supervises locally: stopping a
twirl or scoop halfway leaves food half-acquired and is no safer than finishing it, and the
PC (which moves the arm) is exactly the party that is gone. Trajectories are finite and run to
their end either way; leveling always continues (it is the point of the decoupling).

Where it lives: this module is the lifecycle and the publishing loop; the command handlers are
``link/handlers.py`` (an object :class:`ToolServer` owns), and it composes ``link/admission.py``
(pairing check, per-sender rates, the throttled log), ``link/inbox.py`` (the command inbox,
the stops, the ``link-io`` thread), ``link/lease.py`` and ``link/goals.py``.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.admission import Admission
from articutool.link.config import LinkConfig
from articutool.link.counters import LinkCounters
from articutool.link.goals import GoalTable
from articutool.link.handlers import CommandHandlers
from articutool.link.inbox import CommandInbox
from articutool.link.lease import CommandLease
from articutool.link.transport import Handle, Names, RefusalError, Transport
from articutool.tool.api import LinkWorkLoop, PrimitiveStatus, ToolAPI

__all__ = ["ToolServer", "serve_forever"]

_log = logging.getLogger(__name__)
_KEEP_GOALS = 32  # finished goals remembered for late get_result calls (GoalTable)


class ToolServer:
    """Serve ``api`` on ``transport``; :meth:`start` spawns the publishing thread. The
    handlers are a :class:`~articutool.link.handlers.CommandHandlers` (``handlers``); a
    ``loop`` runs the queued commands in its ticks (else a worker thread of this server)."""

    def __init__(self, api: ToolAPI, transport: Transport, config: LinkConfig | None = None,
                 rate_hz: float | None = None, *, loop: LinkWorkLoop | None = None) -> None:
        self.api = api
        self.transport = transport
        self.cfg = config or LinkConfig()
        if rate_hz is None:
            rate_hz = self.cfg.publish_rate_hz
        if rate_hz is None:
            from articutool.spec import load_spec
            rate_hz = load_spec().wrist.loop_rate_hz
        self.period = 1.0 / float(rate_hz)
        self.names = Names(self.cfg.namespace, self.cfg.tool_id)
        self.instance = uuid.uuid4().hex[:8]  # tells two tools claiming one identity apart
        self.counters = LinkCounters()
        self.lease = CommandLease(self.cfg.client_timeout, self.cfg.tool_id,
                                  self.cfg.audit_log)
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self.admission = Admission(self.cfg, self.counters, self._lock)
        self.inbox = CommandInbox(self.cfg.inbox_size, self.counters, self._lock, self._stop)
        self.goals = GoalTable(_KEEP_GOALS)
        self.handlers = CommandHandlers(api, transport, self.names, counters=self.counters,
                                        lease=self.lease, goals=self.goals,
                                        admission=self.admission, inbox=self.inbox,
                                        lock=self._lock)
        self._loop = loop
        self._loop_drains = False
        self._client_alive = False
        self._handles: list[Handle] = []
        self._thread: threading.Thread | None = None
        self._next_beat = 0.0

    # --------------------------------------------------------------- lifecycle --
    def start(self) -> None:
        """Declare the endpoints and start publishing."""
        n, t, small, h = self.names, self.transport, self.cfg.max_request_bytes, self.handlers
        t.on_drop = self._on_drop
        services = ((n.set_orientation_control, h.on_set_mode),
                    (n.clear_fault, h.on_clear_fault), (n.send_goal, h.on_send_goal),
                    (n.get_result, h.on_get_result), (n.cancel_goal, h.on_cancel),
                    (n.take_over, h.on_take_over), (n.release, h.on_release))
        self._handles = [t.serve(ep, self._guarded(self.inbox.replies_off_loop(fn)),
                                 with_sender=True, max_bytes=small)
                         for ep, fn in services]
        self._handles += [
            t.subscribe(n.joint_trajectory, self._guarded(h.on_trajectory), with_sender=True,
                        max_bytes=self.cfg.max_trajectory_bytes),
            t.subscribe(n.client_heartbeat, self._guarded(h.on_client_heartbeat),
                        with_sender=True, max_bytes=small),
        ]
        self._stop.clear()
        self.inbox.start_io()
        if self._loop is not None:  # the tool's loop drains the inbox, one command per tick
            self._loop.set_link_work(self.work_once)
            self._loop_drains = True
        else:
            self.inbox.start_worker()
        self._thread = threading.Thread(target=self._run, name="link-server", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop publishing and undeclare the endpoints (pending get_result calls time out)."""
        if self._loop is not None and self._loop_drains:
            self._loop.set_link_work(None)
            self._loop_drains = False
        self._stop.set()
        self.inbox.join()
        if self._thread is not None:
            self._thread.join(timeout=5)
        for h in self._handles:
            h.close()
        self._handles = []

    @property
    def client_alive(self) -> bool:
        """Whether a client was heard from within ``client_timeout``."""
        return self._client_alive

    @property
    def holder(self) -> str | None:
        """The command lease's holder (None: free)."""
        return self.lease.holder

    @property
    def audit(self) -> deque[str]:
        """The lease transitions, JSON lines, newest last (the last 100)."""
        return self.lease.audit

    # ----------------------------------------------------------------- helpers --
    def _guarded(self, fn: Callable) -> Callable:
        """Count malformed payloads and handler failures; never raise into the transport."""
        def wrapped(*args: object) -> None:
            try:
                fn(*args)
            except RefusalError:  # the transport answers it with the reason
                raise
            except cdr.LinkDecodeError as err:
                self._note("decode_errors", "dropped a malformed payload (%s)", err)
            except Exception:
                self.counters.bump("handler_errors")
                _log.exception("link handler failed")
        return wrapped

    def _note(self, key: str, fmt: str, *args: object) -> None:
        self.admission.note(key, fmt, *args)

    def _on_drop(self, name: str, reason: str) -> None:
        self._note("oversized", "dropped a message on %s (%s)", name, reason)

    def _pub(self, ep_name: str, message: object, typename: str) -> None:
        self.transport.publish(getattr(self.names, ep_name), cdr.encode(message, typename))

    def work_once(self) -> None:
        """Run at most one queued ToolAPI call (stops first): :meth:`CommandInbox.work_once`.
        Called once per loop tick; never raises."""
        self.inbox.work_once()

    # ---------------------------------------------------------------- the tick --
    def _progress(self) -> None:
        with self._lock:
            goal = self.goals.active
            ended = self.handlers.settle()
        if isinstance(ended, PrimitiveStatus) and goal is not None:
            self._pub("feedback", m.feedback_msg(goal.goal_id, ended), cdr.FEEDBACK_MESSAGE)
        self.handlers.answer_waiters(ended)

    def _check_client(self, now: float) -> None:
        with self._lock:
            self.lease.expire(now)  # also when nobody commands: telemetry names no stale holder
            last = self.handlers.last_client_rx
        alive = last is not None and now - last < self.cfg.client_timeout
        if self._client_alive and not alive:
            self.counters.bump("link_losses")
            _log.warning("no client heard for %.1f s (policy: %s)", self.cfg.client_timeout,
                         self.cfg.link_loss_policy)
            with self._lock:
                goal = self.goals.active
                if self.cfg.link_loss_policy == "cancel" and goal is not None \
                        and self.api.cancel_primitive():
                    goal.cancel_requested = True
                    goal.status = m.GoalStatus.CANCELING
        self._client_alive = alive

    def tick(self) -> None:
        """One publishing step (the thread calls it at the loop rate; tests may call it)."""
        now, wall = time.monotonic(), time.time()
        self.counters.bump("ticks")
        self._check_client(now)
        self._progress()
        state = self.api.state()
        with self._lock:
            counters = self.counters.snapshot()
            holder = self.holder or ""
        self._pub("joint_states", m.joint_state_msg(state, wall), cdr.JOINT_STATE)
        self._pub("imu", m.imu_msg(state, wall), cdr.IMU)
        self._pub("health", m.health_msg(state, wall, counters, tool_id=self.cfg.tool_id,
                                         lease_holder=holder), cdr.DIAGNOSTIC_ARRAY)
        self._pub("battery", m.battery_msg(state, wall, self.cfg.tool_id), cdr.BATTERY_STATE)
        if now >= self._next_beat:
            self._next_beat = now + self.cfg.heartbeat_period
            self._pub("heartbeat", m.heartbeat_msg(wall, f"{self.cfg.tool_id}/{self.instance}"),
                      cdr.HEADER)
            self.handlers.publish_status()

    def _run(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            try:
                self.tick()
            except Exception:  # a failing snapshot or publish must not end telemetry
                self.counters.bump("handler_errors")
                _log.exception("link tick failed")
            next_t += self.period
            delay = next_t - time.monotonic()
            if delay < 0:  # overrun: re-anchor rather than bursting to catch up
                next_t, delay = time.monotonic(), 0.0
            self._stop.wait(delay)


def serve_forever(api: ToolAPI, config: LinkConfig | None, stop_event: threading.Event,
                  transport: Transport | None = None, *,
                  loop: LinkWorkLoop | None = None) -> ToolServer:
    """Serve ``api`` until ``stop_event`` is set, on ``transport`` or else on a Zenoh session
    (tool role) opened here (LinkOpenError if it cannot be); ``loop`` as for
    :class:`ToolServer`. A transport passed in is left open for its owner to close; one
    opened here is closed.

    Returns the (stopped) server, whose ``counters`` the caller may report.
    """
    cfg = config or LinkConfig()
    owned = transport is None
    if transport is None:
        from articutool.link.zenoh_transport import ZenohTransport
        transport = ZenohTransport(cfg, "tool")
    server = ToolServer(api, transport, cfg, loop=loop)
    server.start()
    try:
        stop_event.wait()
    finally:
        server.stop()
        if owned:
            transport.close()
    return server
