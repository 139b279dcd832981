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

Who may command (issue 13): on a paired tool (``LinkConfig.requires_pairing``) every command,
trajectory and client heartbeat must carry a paired PC's signature (``articutool.link.auth``);
anything else is refused (services answer ``success=false`` with the reason, topics are
dropped) and counted (``refused_unpaired``). Telemetry is open to any session that reached the
tool (on a paired tool, over mutual TLS, only paired devices reach it).

A paired PC's refusals say why (issue 22): clocks out of sync, a replay, an expired
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

The network cannot slow the loop, and no flood can hold back a stop (issue 22, S1): the
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
congested or dead peer). The tool's loop drains it, one command per tick, when the API
offers ``set_link_work`` (``ToolRuntime``: called once per tick, after the tick); an API
without a loop of its own (a test double) gets a worker thread of this server instead.

Link-loss policy (``LinkConfig.link_loss_policy``) when no client heartbeat or request has
arrived for ``client_timeout`` seconds: ``"continue"`` (default) lets a running primitive
finish; ``"cancel"`` cancels it (motors stop). Continue is the default because primitives are
short, bounded motions inside the wrist's limits that the tool supervises locally: stopping a
twirl or scoop halfway leaves food half-acquired and is no safer than finishing it, and the
PC (which moves the arm) is exactly the party that is gone. Trajectories are finite and run to
their end either way; leveling always continues (it is the point of the decoupling).
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from collections import OrderedDict, deque
from collections.abc import Callable
from functools import partial

from articutool.link import messages as m
from articutool.link.config import LinkConfig
from articutool.link.goals import Goal, GoalTable
from articutool.link.lease import CommandLease
from articutool.link.transport import (
    Endpoint,
    Handle,
    Names,
    RateGate,
    RefusalError,
    Responder,
    Sender,
    Transport,
)
from articutool.tool.api import Mode, PrimitiveStatus, ToolAPI

__all__ = ["ToolServer", "serve_forever"]

_log = logging.getLogger(__name__)
_ZERO_ID = bytes(16)
_KEEP_GOALS = 32  # finished goals remembered for late get_result calls (GoalTable)
_MAX_GATES = 1024  # per-sender rate gates kept (oldest forgotten: a fresh gate is full)
_LOGGED = 10  # log lines per kind of dropped/refused/malformed message, then 1 in _EVERY
_EVERY = 1000


class ToolServer:
    """Serve ``api`` on ``transport``; :meth:`start` spawns the publishing thread."""

    def __init__(self, api: ToolAPI, transport: Transport, config: LinkConfig | None = None,
                 rate_hz: float | None = None) -> None:
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
        self.counters: dict[str, int] = {"decode_errors": 0, "handler_errors": 0,
                                         "rejected_trajectories": 0, "link_losses": 0,
                                         "ticks": 0, "refused_unpaired": 0, "refused_lease": 0,
                                         "lease_takeovers": 0, "oversized": 0, "rate_limited": 0,
                                         "dropped_excess": 0, "commands": 0}
        self.lease = CommandLease(self.cfg.client_timeout, self.cfg.tool_id,
                                  self.cfg.audit_log)
        self._inbox: deque[Callable[[], None]] = deque()
        # Stops waiting for the loop, by what they do: (run, answers); see _submit_stop.
        self._stops: OrderedDict[object, tuple[Callable[[], object],
                                                list[Callable[[object], None]]]] = OrderedDict()
        self._gates: OrderedDict[tuple[str, str], RateGate] = OrderedDict()
        self._loop_drains = False
        self._worker: threading.Thread | None = None
        self._wake = threading.Condition()
        # Network I/O never runs on the thread that executes commands (the tool's loop): a
        # reply or publish may block on a congested or dead peer. It goes to link-io.
        self._exec_ident: int | None = None
        self._io: deque[Callable[[], None]] = deque()
        self._io_wake = threading.Condition()
        self._io_thread: threading.Thread | None = None
        self._lock = threading.RLock()
        self.goals = GoalTable(_KEEP_GOALS)
        self._last_client_rx: float | None = None
        self._client_alive = False
        self._handles: list[Handle] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._next_beat = 0.0

    # --------------------------------------------------------------- lifecycle --
    def start(self) -> None:
        """Declare the endpoints and start publishing."""
        n, t, small = self.names, self.transport, self.cfg.max_request_bytes
        t.on_drop = self._on_drop
        services = ((n.set_orientation_control, self._on_set_mode),
                    (n.clear_fault, self._on_clear_fault), (n.send_goal, self._on_send_goal),
                    (n.get_result, self._on_get_result), (n.cancel_goal, self._on_cancel),
                    (n.take_over, self._on_take_over), (n.release, self._on_release))
        self._handles = [t.serve(ep, self._guarded(self._replies_off_loop(fn)),
                                 with_sender=True, max_bytes=small)
                         for ep, fn in services]
        self._handles += [
            t.subscribe(n.joint_trajectory, self._guarded(self._on_trajectory), with_sender=True,
                        max_bytes=self.cfg.max_trajectory_bytes),
            t.subscribe(n.client_heartbeat, self._guarded(self._on_client_heartbeat),
                        with_sender=True, max_bytes=small),
        ]
        hook = getattr(self.api, "set_link_work", None)
        self._stop.clear()
        self._io_thread = threading.Thread(target=self._run_io, name="link-io", daemon=True)
        self._io_thread.start()
        if callable(hook):  # the tool's loop drains the inbox, one command per tick
            hook(self.work_once)
            self._loop_drains = True
        else:
            self._worker = threading.Thread(target=self._drain, name="link-worker", daemon=True)
            self._worker.start()
        self._thread = threading.Thread(target=self._run, name="link-server", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop publishing and undeclare the endpoints (pending get_result calls time out)."""
        if self._loop_drains:
            self.api.set_link_work(None)  # type: ignore[attr-defined]
            self._loop_drains = False
        self._stop.set()
        with self._wake:
            self._wake.notify_all()
        if self._worker is not None:
            self._worker.join(timeout=5)
            self._worker = None
        if self._io_thread is not None:
            self._io_thread.join(timeout=5)
            self._io_thread = None
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
            except m.LinkDecodeError as err:
                self._note("decode_errors", "dropped a malformed payload (%s)", err)
            except Exception:
                with self._lock:
                    self.counters["handler_errors"] += 1
                _log.exception("link handler failed")
        return wrapped

    def _client_seen(self, who: str) -> None:
        """``who`` was heard. While a client holds the lease only it counts for the link-loss
        policy: observers chatting on must not hide that the commanding PC went silent."""
        with self._lock:
            if self.holder is None or self.holder == who:
                self._last_client_rx = time.monotonic()

    def _note(self, key: str, fmt: str, *args: object) -> None:
        """Count one dropped, refused or malformed message under ``key`` and log it: the
        first few of each kind, then one in _EVERY with the count (a flood must not flood
        the log: issue 22)."""
        with self._lock:
            self.counters[key] += 1
            n = self.counters[key]
        if n <= _LOGGED or n % _EVERY == 0:
            _log.warning(fmt + "; %d %s so far", *args, n, key)

    def _on_drop(self, name: str, reason: str) -> None:
        self._note("oversized", "dropped a message on %s (%s)", name, reason)

    def _admit(self, sender: Sender, what: str) -> tuple[str | None, str]:
        """(the client's identity, '') if it may command, else (None, the refusal naming
        the real reason: a paired PC whose clock is off is told so); counted, logged."""
        if self.cfg.requires_pairing and not (sender.verified and sender.role == "pc"):
            why = sender.refused or (f"{sender.identity!r} is not a PC" if sender.verified
                                     else "not a paired PC: not signed")
            self._note("refused_unpaired", "refused %s (%s)", what, why)
            return None, f"refused: {why}"
        return sender.identity or "anonymous", ""

    def _sender_key(self, sender: Sender) -> str:
        """Whose rate limit a message counts against: the verified identity; on a paired
        tool every unverified sender shares one (a claimed name proves nothing)."""
        if sender.verified or not self.cfg.requires_pairing:
            return sender.identity or "anonymous"
        return "(unverified)"

    def _within_rate(self, ep: Endpoint, sender: Sender) -> bool:
        """Take one of the sender's ``max_rate_hz`` tokens on ``ep``; False (counted) if it
        has none left. One sender's flood never uses another's."""
        k = (ep.name, self._sender_key(sender))
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
        self._note("rate_limited", "dropped a message on %s (rate, from %s)", ep.name, k[1])
        return False

    def _rate_limit(self, ep: Endpoint, sender: Sender) -> None:
        """Raise RefusalError (an immediate error reply) when the sender is over its rate."""
        if not self._within_rate(ep, sender):
            raise RefusalError(f"rate limited: more than {self.cfg.max_rate_hz:g} requests/s from "
                          f"{self._sender_key(sender)} on {ep.name}")

    def _lease(self, who: str, stop: bool = False) -> str:
        """'' if ``who`` may command now, else the refusal naming the holder (counted);
        see :meth:`CommandLease.acquire`."""
        now = time.monotonic()
        with self._lock:
            refusal = self.lease.acquire(who, now, stop)
            if refusal:
                self.counters["refused_lease"] += 1
            return refusal

    def _submit(self, work: Callable[[], None]) -> bool:
        """Queue a ToolAPI call for the loop; False (counted) when the inbox is full."""
        with self._lock:
            if len(self._inbox) >= self.cfg.inbox_size:
                self.counters["dropped_excess"] += 1
                return False
            self._inbox.append(work)
        with self._wake:
            self._wake.notify()
        return True

    def _submit_stop(self, key: object, run: Callable[[], object],
                     answer: Callable[[object], None]) -> None:
        """Queue a stop for the loop, never refused: a stop equal to one waiting (same
        ``key``) joins it, the loop runs it once and every caller gets ``answer(result)``.
        Stops are idempotent, so this is the same as running each; and however many
        arrive, the stops waiting stay as few as their kinds."""
        with self._lock:
            waiting = self._stops.get(key)
            if waiting is None:
                self._stops[key] = (run, [answer])
            else:
                waiting[1].append(answer)
        with self._wake:
            self._wake.notify()

    def _drain(self) -> None:
        """Worker thread (APIs without a loop): run queued commands one at a time."""
        while not self._stop.is_set():
            with self._lock:
                pending = bool(self._stops or self._inbox)
            if not pending:
                with self._wake:
                    self._wake.wait(0.05)
                continue
            self.work_once()

    def work_once(self) -> None:
        """Run at most one queued ToolAPI call (stops first). Called once per loop tick; never
        raises."""
        with self._lock:
            if self._stops:
                _, (run, answers) = self._stops.popitem(last=False)
                work: Callable[[], None] | None = partial(self._run_stop, run, answers)
            else:
                work = self._inbox.popleft() if self._inbox else None
        if work is None:
            return
        self._exec_ident = threading.get_ident()
        try:
            work()
            with self._lock:
                self.counters["commands"] += 1
        except Exception:
            with self._lock:
                self.counters["handler_errors"] += 1
            _log.exception("link command failed")

    @staticmethod
    def _run_stop(run: Callable[[], object], answers: list[Callable[[object], None]]) -> None:
        result = run()
        for answer in answers:
            answer(result)

    def _off_loop(self, io: Callable[[], None]) -> None:
        """Run network I/O now, unless on the command-executing thread: then on link-io."""
        if threading.get_ident() != self._exec_ident:
            io()
            return
        with self._io_wake:
            self._io.append(io)
            self._io_wake.notify()

    def _replies_off_loop(self, fn: Callable[..., None]) -> Callable[..., None]:
        """A service handler whose ``respond`` never sends from the command thread."""
        def handler(data: bytes, respond: Responder, sender: Sender) -> None:
            fn(data, lambda reply: self._off_loop(lambda: respond(reply)), sender)
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
                with self._lock:
                    self.counters["handler_errors"] += 1
                _log.exception("link reply/publish failed")

    def _refuse(self, respond: Responder, ep: Endpoint, msg: str) -> None:
        """Answer a refused service call with success=false and ``msg``."""
        t = ep.response_type
        if ep.type == m.SET_ORIENTATION_CONTROL:
            respond(m.encode(m.soc_response(False, msg), t))
        elif ep.type == m.TRIGGER:
            respond(m.encode(m.trigger_response(False, msg), t))
        elif ep.type == m.SEND_GOAL:  # ROS 2's SendGoal reply has no text: not accepted
            respond(m.encode(m.send_goal_response(False, time.time()), t))
        elif ep.type == m.CANCEL_GOAL:
            R = m.typestore().types[t]
            respond(m.encode(m.cancel_response(R.ERROR_REJECTED, []), t))

    def _pub(self, ep_name: str, message: object, typename: str) -> None:
        self.transport.publish(getattr(self.names, ep_name), m.encode(message, typename))

    def _ask(self, fn: Callable[..., tuple[bool, str]], *args: object) -> tuple[bool, str]:
        """Call a ToolAPI command; an exception becomes a refusal the client can read."""
        try:
            ok, msg = fn(*args)
            return bool(ok), str(msg)
        except Exception as err:
            with self._lock:
                self.counters["handler_errors"] += 1
            _log.exception("ToolAPI call failed")
            return False, f"tool error: {type(err).__name__}: {err}"

    def _joints_now(self) -> tuple[float, ...]:
        try:
            return tuple(self.api.state().position)
        except Exception:
            return ()

    # ---------------------------------------------------------------- handlers --
    def _on_set_mode(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.set_orientation_control
        who, refusal = self._admit(sender, "set_orientation_control")
        if who is None:
            return self._refuse(respond, ep, refusal)
        req = m.decode(data, ep.request_type)
        stop = req.control_mode == Mode.DISABLED
        if not stop:
            self._rate_limit(ep, sender)
        self._client_seen(who)
        refusal = self._lease(who, stop=stop)
        if refusal:
            return self._refuse(respond, ep, refusal)
        if req.control_mode not in (Mode.DISABLED, Mode.LEVELING):
            return self._refuse(respond, ep, (
                f"control_mode must be {Mode.DISABLED.value} (DISABLED) or "
                f"{Mode.LEVELING.value} (LEVELING); got {req.control_mode}"))
        pitch, roll = float(req.pitch_offset), float(req.roll_offset)

        def run() -> tuple[bool, str]:
            return self._ask(self.api.set_mode, Mode(req.control_mode), pitch, roll)

        def answer(result: object) -> None:
            respond(m.encode(m.soc_response(*result), ep.response_type))  # type: ignore[misc]
        if stop:  # every DISABLED is the same stop: waiting ones are run once
            return self._submit_stop("disable", run, answer)
        if not self._submit(lambda: answer(run())):
            self._refuse(respond, ep, "refused: the tool's command inbox is full")
        return None

    def _on_clear_fault(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.clear_fault
        who, refusal = self._admit(sender, "clear_fault")
        if who is None:
            return self._refuse(respond, ep, refusal)
        self._rate_limit(ep, sender)
        m.decode(data, ep.request_type)
        self._client_seen(who)
        refusal = self._lease(who)
        if refusal:
            return self._refuse(respond, ep, refusal)

        def work() -> None:
            ok, msg = self._ask(self.api.clear_fault)
            respond(m.encode(m.trigger_response(ok, msg), ep.response_type))
        if not self._submit(work):
            self._refuse(respond, ep, "refused: the tool's command inbox is full")
        return None

    def _on_take_over(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.take_over
        who, refusal = self._admit(sender, "take_over")
        if who is None:
            return self._refuse(respond, ep, refusal)
        self._rate_limit(ep, sender)
        m.decode(data, ep.request_type)
        self._client_seen(who)
        with self._lock:
            before = self.lease.take_over(who, time.monotonic())
            if before not in (None, who):
                self.counters["lease_takeovers"] += 1
        _log.warning("AUDIT take-over: %s took the command lease from %s", who,
                     before or "nobody")
        self.lease.record("take_over", who, before)
        respond(m.encode(m.trigger_response(True, f"{who} holds the command lease (was: "
                                                  f"{before or 'nobody'})"), ep.response_type))
        return None

    def _on_release(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.release
        who, refusal = self._admit(sender, "release")
        if who is None:
            return self._refuse(respond, ep, refusal)
        self._rate_limit(ep, sender)
        m.decode(data, ep.request_type)
        with self._lock:
            mine = self.lease.release(who)
        if mine:
            _log.info("command lease released by %s", who)
            self.lease.record("lease_released", who, None)
        respond(m.encode(m.trigger_response(mine, "released" if mine else
                                            f"not held by {who} (holder: {self.holder})"),
                         ep.response_type))
        return None

    def _on_send_goal(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.send_goal
        who, refusal = self._admit(sender, "send_goal")
        if who is None:  # SendGoal's reply has no text: an error reply names the reason
            raise RefusalError(refusal)
        self._rate_limit(ep, sender)
        req = m.decode(data, ep.request_type)
        self._client_seen(who)
        refusal = self._lease(who)
        gid = m.uuid_bytes(req.goal_id)
        name = str(req.goal.primitive_name)
        params = [float(x) for x in req.goal.parameters]
        if refusal:  # accepted then aborted, so the client can read why (see the docstring)
            now = time.time()
            with self._lock:
                if gid in self.goals:
                    return self._refuse(respond, ep, "")
                self.goals.remember(Goal(gid, name, now, m.GoalStatus.ABORTED, result=(
                    m.PrimitiveResult(False, refusal, self._joints_now(),
                                      m.GoalStatus.ABORTED))))
            respond(m.encode(m.send_goal_response(True, now), ep.response_type))
            return None

        def work() -> None:
            self._start_goal(gid, name, params, respond)
        if not self._submit(work):
            raise RefusalError("the tool's command inbox is full")
        return None

    def _start_goal(self, gid: bytes, name: str, params: list[float],
                    respond: Responder) -> None:
        now = time.time()
        ep = self.names.send_goal
        with self._lock:
            if gid in self.goals:  # a resent goal id is a protocol error: reject it
                respond(m.encode(m.send_goal_response(False, now), ep.response_type))
                return
            ended = self._settle()  # the running goal may have ended since the last tick
            running = self.goals.active
            if running is not None:  # ours still runs: starting now could hide its result
                ok, msg = False, (f"busy: primitive {running.name} is running (goal "
                                  f"{running.goal_id.hex()})")
            else:
                ok, msg = self._ask(self.api.start_primitive, name, params)
            goal = Goal(gid, name, now, m.GoalStatus.EXECUTING if ok else m.GoalStatus.ABORTED)
            if ok:
                self.goals.active = goal
            else:
                goal.result = m.PrimitiveResult(False, msg, self._joints_now(),
                                                m.GoalStatus.ABORTED)
            self.goals.remember(goal)
        self._answer(ended)
        respond(m.encode(m.send_goal_response(True, now), ep.response_type))
        self._publish_status()

    def _on_get_result(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.get_result  # read-only: open to all, within each sender's rate
        self._rate_limit(ep, sender)
        req = m.decode(data, ep.request_type)
        gid = m.uuid_bytes(req.goal_id)
        with self._lock:
            goal = self.goals.get(gid)
            if goal is not None and goal.result is None:
                goal.waiters.append(respond)  # long poll: answered when the goal ends
                return
            result = goal.result if goal is not None else m.PrimitiveResult(
                False, "unknown goal id", (), m.GoalStatus.UNKNOWN)
        respond(m.encode(m.result_msg(result), ep.response_type))

    def _on_cancel(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.cancel_goal
        who, refusal = self._admit(sender, "cancel_goal")
        if who is None:  # CancelGoal's reply has no text: an error reply names the reason
            raise RefusalError(refusal)
        req = m.decode(data, ep.request_type)  # a stop: no rate limit, never refused for room
        self._client_seen(who)
        self._lease(who, stop=True)  # a stop: accepted from any admitted client
        gid = m.uuid_bytes(req.goal_info.goal_id)
        R = m.typestore().types[ep.response_type]

        def answer(result: object) -> None:
            respond(m.encode(m.cancel_response(*result), ep.response_type))  # type: ignore[misc]
        with self._lock:
            goal = self.goals.active if gid == _ZERO_ID else self.goals.get(gid)
            if goal is None:
                now: tuple[int, list] | None = (R.ERROR_NONE if gid == _ZERO_ID else
                                                R.ERROR_UNKNOWN_GOAL_ID, [])
            elif goal.result is not None:
                now = (R.ERROR_GOAL_TERMINATED, [])
            else:
                now = None
        if now is not None:  # nothing to stop: answered here, without the loop
            return answer(now)

        def run() -> tuple[int, list]:
            with self._lock:
                if goal.result is not None or self.goals.active is not goal:
                    out: tuple[int, list] = (R.ERROR_GOAL_TERMINATED, [])
                elif self.api.cancel_primitive():
                    goal.cancel_requested = True
                    goal.status = m.GoalStatus.CANCELING
                    out = (R.ERROR_NONE, [(goal.goal_id, goal.accepted_at)])
                else:  # finished in between: the next tick reports its result
                    out = (R.ERROR_GOAL_TERMINATED, [])
            self._publish_status()
            return out
        self._submit_stop(("cancel", goal.goal_id), run, answer)
        return None

    def _on_trajectory(self, data: bytes, sender: Sender) -> None:
        ep = self.names.joint_trajectory
        who, _ = self._admit(sender, "a trajectory")
        if who is None or not self._within_rate(ep, sender):
            return
        message = m.decode(data, ep.type)  # in the link thread
        traj = m.trajectory_from_msg(message)
        pre = getattr(self.api, "prevalidate_trajectory", None)
        if callable(pre):  # the length-dependent checks here, not in the loop's tick
            try:
                traj = pre(traj)
            except (ValueError, TypeError) as err:  # TrajectoryError is a ValueError
                with self._lock:
                    self.counters["rejected_trajectories"] += 1
                _log.warning("trajectory from %s refused: %s", who, err)
                return
        self._client_seen(who)
        refusal = self._lease(who)
        if refusal:
            with self._lock:
                self.counters["rejected_trajectories"] += 1
            _log.warning("trajectory from %s %s", who, refusal)
            return
        # As ROS trajectory controllers: time 0 is header.stamp (wall clock, so the PC's and
        # the tool's clocks must agree), or arrival when the stamp is zero.
        stamp = m.stamp_to_time(message.header.stamp)

        def work() -> None:
            delay = stamp - time.time() if stamp > 0 else 0.0
            ok, msg = self._ask(self.api.follow_trajectory, traj, delay)
            if not ok:
                with self._lock:
                    self.counters["rejected_trajectories"] += 1
                _log.warning("trajectory refused: %s", msg)
        if not self._submit(work):
            with self._lock:
                self.counters["rejected_trajectories"] += 1

    def _on_client_heartbeat(self, data: bytes, sender: Sender) -> None:
        ep = self.names.client_heartbeat
        who, _ = self._admit(sender, "a client heartbeat")
        if who is None or not self._within_rate(ep, sender):  # a forged heartbeat keeps
            return  # neither a lease nor the link alive
        m.decode(data, ep.type)
        self._client_seen(who)
        with self._lock:
            self.lease.renew(who, time.monotonic())

    # ---------------------------------------------------------------- the tick --
    def _settle(self) -> tuple[list[Responder], m.PrimitiveResult] | PrimitiveStatus | None:
        """The active goal's progress (lock held): see :meth:`GoalTable.settle`; the waiters
        of a goal that ended are answered outside the lock by :meth:`_answer`."""
        return self.goals.settle(self.api.primitive_status)

    def _answer(self, ended: object) -> None:
        """Answer the get_result waiters of a goal :meth:`_settle` found ended."""
        if not isinstance(ended, tuple):
            return
        waiters, result = ended
        payload = m.encode(m.result_msg(result), self.names.get_result.response_type)
        for respond in waiters:
            respond(payload)
        self._publish_status()

    def _progress(self) -> None:
        with self._lock:
            goal = self.goals.active
            ended = self._settle()
        if isinstance(ended, PrimitiveStatus) and goal is not None:
            self._pub("feedback", m.feedback_msg(goal.goal_id, ended), m.FEEDBACK_MESSAGE)
        self._answer(ended)

    def _check_client(self, now: float) -> None:
        with self._lock:
            self.lease.expire(now)  # also when nobody commands: telemetry names no stale holder
            last = self._last_client_rx
        alive = last is not None and now - last < self.cfg.client_timeout
        if self._client_alive and not alive:
            self.counters["link_losses"] += 1
            _log.warning("no client heard for %.1f s (policy: %s)", self.cfg.client_timeout,
                         self.cfg.link_loss_policy)
            with self._lock:
                goal = self.goals.active
                if self.cfg.link_loss_policy == "cancel" and goal is not None \
                        and self.api.cancel_primitive():
                    goal.cancel_requested = True
                    goal.status = m.GoalStatus.CANCELING
        self._client_alive = alive

    def _publish_status(self) -> None:
        with self._lock:
            goals = self.goals.statuses()
        payload = m.encode(m.status_array(goals), m.GOAL_STATUS_ARRAY)
        self._off_loop(lambda: self.transport.publish(self.names.status, payload))

    def tick(self) -> None:
        """One publishing step (the thread calls it at the loop rate; tests may call it)."""
        now, wall = time.monotonic(), time.time()
        self.counters["ticks"] += 1
        self._check_client(now)
        self._progress()
        state = self.api.state()
        with self._lock:
            counters = dict(self.counters)
            holder = self.holder or ""
        self._pub("joint_states", m.joint_state_msg(state, wall), m.JOINT_STATE)
        self._pub("imu", m.imu_msg(state, wall), m.IMU)
        self._pub("health", m.health_msg(state, wall, counters, tool_id=self.cfg.tool_id,
                                         lease_holder=holder), m.DIAGNOSTIC_ARRAY)
        self._pub("battery", m.battery_msg(state, wall, self.cfg.tool_id), m.BATTERY_STATE)
        if now >= self._next_beat:
            self._next_beat = now + self.cfg.heartbeat_period
            self._pub("heartbeat", m.heartbeat_msg(wall, f"{self.cfg.tool_id}/{self.instance}"),
                      m.HEADER)
            self._publish_status()

    def _run(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            try:
                self.tick()
            except Exception:  # a failing snapshot or publish must not end telemetry
                with self._lock:
                    self.counters["handler_errors"] += 1
                _log.exception("link tick failed")
            next_t += self.period
            delay = next_t - time.monotonic()
            if delay < 0:  # overrun: re-anchor rather than bursting to catch up
                next_t, delay = time.monotonic(), 0.0
            self._stop.wait(delay)


def serve_forever(api: ToolAPI, config: LinkConfig | None, stop_event: threading.Event,
                  transport: Transport | None = None) -> ToolServer:
    """Serve ``api`` until ``stop_event`` is set, on ``transport`` or else on a Zenoh session
    (tool role) opened here (LinkOpenError if it cannot be). A transport passed in is left
    open for its owner to close; one opened here is closed.

    Returns the (stopped) server, whose ``counters`` the caller may report.
    """
    cfg = config or LinkConfig()
    owned = transport is None
    if transport is None:
        from articutool.link.zenoh_transport import ZenohTransport
        transport = ZenohTransport(cfg, "tool")
    server = ToolServer(api, transport, cfg)
    server.start()
    try:
        stop_event.wait()
    finally:
        server.stop()
        if owned:
            transport.close()
    return server
