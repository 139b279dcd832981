"""The link's command handlers: one per service and topic the tool serves (thesis §3.2.2,
§4.5).

Each handler admits the sender (``link/admission.py``: pairing, per-sender rate), decodes and
validates the request, checks the command lease (``link/lease.py``), then queues the ToolAPI
call in the command inbox (``link/inbox.py``) for the tool's loop; stops (DISABLED, a cancel)
pass the rate limit and the lease and are never refused for room. The action's goals live in
the goal table (``link/goals.py``); a refused primitive is accepted then aborted, so the
client can read why (ROS 2's SendGoal reply has no text). A stop supersedes the motion
queued before it (``link/inbox.py``): a mode request it discards is refused, a primitive goal
is accepted then aborted (a cancel of that goal: accepted then CANCELED), a trajectory is
dropped and counted.

:class:`CommandHandlers` is an object ``ToolServer`` (``link/server.py``) owns and builds with
the parts the handlers need: the API, the transport and names, and the server's counters,
lease, goal table, admission, inbox and lock (held around the lease and goals). The server
owns the endpoints and the publishing loop; it reads :attr:`CommandHandlers.last_client_rx`
for the link-loss policy and, on its ticks, calls :meth:`~CommandHandlers.settle`,
:meth:`~CommandHandlers.answer_waiters` and :meth:`~CommandHandlers.publish_status`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.admission import Admission
from articutool.link.auth import Sender
from articutool.link.counters import LinkCounters
from articutool.link.goals import Goal, GoalTable
from articutool.link.inbox import SUPERSEDED, CommandInbox
from articutool.link.lease import CommandLease
from articutool.link.transport import Endpoint, Names, RefusalError, Responder, Transport
from articutool.tool.api import (
    SERVICE_MODES,
    Mode,
    PrimitiveStatus,
    ToolAPI,
    TrajectoryPrevalidation,
)

__all__ = ["CommandHandlers"]

_log = logging.getLogger(__name__)
_ZERO_ID = bytes(16)


class CommandHandlers:
    """The service and topic handlers a ``ToolServer`` serves and the goal results they
    answer."""

    def __init__(self, api: ToolAPI, transport: Transport, names: Names, *,
                 counters: LinkCounters, lease: CommandLease, goals: GoalTable,
                 admission: Admission, inbox: CommandInbox, lock: threading.RLock) -> None:
        self.api = api
        self.transport = transport
        self.names = names
        self.counters = counters
        self.lease = lease
        self.goals = goals
        self.admission = admission
        self.inbox = inbox
        self._lock = lock
        # an API with the state-independent trajectory checks runs them in the link thread
        self._prevalidate = (api.prevalidate_trajectory
                             if isinstance(api, TrajectoryPrevalidation) else None)
        self.last_client_rx: float | None = None  # monotonic; read under the lock

    def _client_seen(self, who: str) -> None:
        """``who`` was heard. While a client holds the lease only it counts for the link-loss
        policy: observers chatting on must not hide that the commanding PC went silent."""
        with self._lock:
            if self.lease.holder is None or self.lease.holder == who:
                self.last_client_rx = time.monotonic()

    def _lease(self, who: str, stop: bool = False) -> str:
        """'' if ``who`` may command now, else the refusal naming the holder (counted);
        see :meth:`CommandLease.acquire`."""
        now = time.monotonic()
        with self._lock:
            refusal = self.lease.acquire(who, now, stop)
            if refusal:
                self.counters.bump("refused_lease")
            return refusal

    def _refuse(self, respond: Responder, ep: Endpoint, msg: str) -> None:
        """Answer a refused service call with success=false and ``msg``."""
        t = ep.response_type
        if ep.type == cdr.SET_ORIENTATION_CONTROL:
            respond(cdr.encode(m.soc_response(False, msg), t))
        elif ep.type == cdr.TRIGGER:
            respond(cdr.encode(m.trigger_response(False, msg), t))
        elif ep.type == cdr.SEND_GOAL:  # ROS 2's SendGoal reply has no text: not accepted
            respond(cdr.encode(m.send_goal_response(False, time.time()), t))
        elif ep.type == cdr.CANCEL_GOAL:
            R = cdr.typestore().types[t]
            respond(cdr.encode(m.cancel_response(R.ERROR_REJECTED, []), t))

    def _ask(self, fn: Callable[..., tuple[bool, str]], *args: object) -> tuple[bool, str]:
        """Call a ToolAPI command; an exception becomes a refusal the client can read."""
        try:
            ok, msg = fn(*args)
            return bool(ok), str(msg)
        except Exception as err:
            self.counters.bump("handler_errors")
            _log.exception("ToolAPI call failed")
            return False, f"tool error: {type(err).__name__}: {err}"

    def _joints_now(self) -> tuple[float, ...]:
        try:
            return tuple(self.api.state().position)
        except Exception:
            return ()

    # ---------------------------------------------------------------- handlers --
    def on_set_mode(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.set_orientation_control
        since = self.inbox.epoch  # a DISABLED queued from now on supersedes this request
        who, refusal = self.admission.admit(sender, "set_orientation_control")
        if who is None:
            return self._refuse(respond, ep, refusal)
        req = cdr.decode(data, ep.request_type)
        stop = req.control_mode == Mode.DISABLED
        if not stop:
            self.admission.rate_limit(ep, sender)
        self._client_seen(who)
        refusal = self._lease(who, stop=stop)
        if refusal:
            return self._refuse(respond, ep, refusal)
        if req.control_mode not in SERVICE_MODES:
            return self._refuse(respond, ep, (
                f"control_mode must be {Mode.DISABLED.value} (DISABLED), "
                f"{Mode.LEVELING.value} (LEVELING) or {Mode.FULL_ORIENTATION.value} "
                f"(FULL_ORIENTATION); got {req.control_mode}"))
        pitch, roll = float(req.pitch_offset), float(req.roll_offset)
        t = req.target_orientation_robot_base
        target = (float(t.x), float(t.y), float(t.z), float(t.w))

        def run() -> tuple[bool, str]:
            if req.control_mode == Mode.FULL_ORIENTATION:
                return self._ask(self.api.set_mode, Mode.FULL_ORIENTATION, 0.0, 0.0, target)
            return self._ask(self.api.set_mode, Mode(req.control_mode), pitch, roll)

        def answer(result: object) -> None:
            respond(cdr.encode(m.soc_response(*result), ep.response_type))  # type: ignore[misc]
        if stop:  # every DISABLED is the same stop: waiting ones are run once
            return self.inbox.submit_stop("disable", run, answer, supersede=True)
        if not self.inbox.submit(lambda: answer(run()),
                                 discard=lambda _: answer((False, f"refused: {SUPERSEDED}")),
                                 since=since):
            self._refuse(respond, ep, "refused: the tool's command inbox is full")
        return None

    def on_clear_fault(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.clear_fault
        who, refusal = self.admission.admit(sender, "clear_fault")
        if who is None:
            return self._refuse(respond, ep, refusal)
        self.admission.rate_limit(ep, sender)
        cdr.decode(data, ep.request_type)
        self._client_seen(who)
        refusal = self._lease(who)
        if refusal:
            return self._refuse(respond, ep, refusal)

        def work() -> None:
            ok, msg = self._ask(self.api.clear_fault)
            respond(cdr.encode(m.trigger_response(ok, msg), ep.response_type))
        if not self.inbox.submit(work):
            self._refuse(respond, ep, "refused: the tool's command inbox is full")
        return None

    def on_take_over(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.take_over
        who, refusal = self.admission.admit(sender, "take_over")
        if who is None:
            return self._refuse(respond, ep, refusal)
        self.admission.rate_limit(ep, sender)
        cdr.decode(data, ep.request_type)
        self._client_seen(who)
        with self._lock:
            before = self.lease.take_over(who, time.monotonic())
            if before not in (None, who):
                self.counters.bump("lease_takeovers")
        _log.warning("AUDIT take-over: %s took the command lease from %s", who,
                     before or "nobody")
        self.lease.record("take_over", who, before)
        respond(cdr.encode(m.trigger_response(True, f"{who} holds the command lease (was: "
                                                  f"{before or 'nobody'})"), ep.response_type))
        return None

    def on_release(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.release
        who, refusal = self.admission.admit(sender, "release")
        if who is None:
            return self._refuse(respond, ep, refusal)
        self.admission.rate_limit(ep, sender)
        cdr.decode(data, ep.request_type)
        with self._lock:
            mine = self.lease.release(who)
        if mine:
            _log.info("command lease released by %s", who)
            self.lease.record("lease_released", who, None)
        respond(cdr.encode(m.trigger_response(mine, "released" if mine else
                                            f"not held by {who} (holder: {self.lease.holder})"),
                         ep.response_type))
        return None

    def on_send_goal(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.send_goal
        since = self.inbox.epoch
        who, refusal = self.admission.admit(sender, "send_goal")
        if who is None:  # SendGoal's reply has no text: an error reply names the reason
            raise RefusalError(refusal)
        self.admission.rate_limit(ep, sender)
        req = cdr.decode(data, ep.request_type)
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
            respond(cdr.encode(m.send_goal_response(True, now), ep.response_type))
            return None

        def work() -> None:
            self._start_goal(gid, name, params, respond)
        if not self.inbox.submit(work, key=("goal", gid), discard=lambda cancelled:
                                 self._discard_goal(gid, name, respond, cancelled), since=since):
            raise RefusalError("the tool's command inbox is full")
        return None

    def _start_goal(self, gid: bytes, name: str, params: list[float],
                    respond: Responder) -> None:
        now = time.time()
        ep = self.names.send_goal
        with self._lock:
            if gid in self.goals:  # a resent goal id is a protocol error: reject it
                respond(cdr.encode(m.send_goal_response(False, now), ep.response_type))
                return
            ended = self.settle()  # the running goal may have ended since the last tick
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
        self.answer_waiters(ended)
        respond(cdr.encode(m.send_goal_response(True, now), ep.response_type))
        self.publish_status()

    def _discard_goal(self, gid: bytes, name: str, respond: Responder, cancelled: bool) -> None:
        """Answer a queued goal a stop discarded before it started: accepted, then CANCELED
        (a cancel of this goal) or ABORTED (superseded by a DISABLED)."""
        now = time.time()
        ep = self.names.send_goal
        status = m.GoalStatus.CANCELED if cancelled else m.GoalStatus.ABORTED
        msg = "cancelled before it started" if cancelled else SUPERSEDED
        with self._lock:
            fresh = gid not in self.goals
            if fresh:  # a resent goal id stays a protocol error (see _start_goal)
                self.goals.remember(Goal(gid, name, now, status, result=m.PrimitiveResult(
                    False, msg, self._joints_now(), status)))
        respond(cdr.encode(m.send_goal_response(fresh, now), ep.response_type))
        self.publish_status()

    def on_get_result(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.get_result  # read-only: open to all, within each sender's rate
        self.admission.rate_limit(ep, sender)
        req = cdr.decode(data, ep.request_type)
        gid = m.uuid_bytes(req.goal_id)
        with self._lock:
            goal = self.goals.get(gid)
            if goal is not None and goal.result is None:
                goal.waiters.append(respond)  # long poll: answered when the goal ends
                return
            result = goal.result if goal is not None else m.PrimitiveResult(
                False, "unknown goal id", (), m.GoalStatus.UNKNOWN)
        respond(cdr.encode(m.result_msg(result), ep.response_type))

    def on_cancel(self, data: bytes, respond: Responder, sender: Sender) -> None:
        ep = self.names.cancel_goal
        who, refusal = self.admission.admit(sender, "cancel_goal")
        if who is None:  # CancelGoal's reply has no text: an error reply names the reason
            raise RefusalError(refusal)
        req = cdr.decode(data, ep.request_type)  # a stop: no rate limit, never refused for room
        self._client_seen(who)
        self._lease(who, stop=True)  # a stop: accepted from any admitted client
        gid = m.uuid_bytes(req.goal_info.goal_id)
        R = cdr.typestore().types[ep.response_type]

        # A queued start of the goal (any goal, for the zero id) is discarded, never run.
        dropped = self.inbox.discard(lambda k: isinstance(k, tuple) and k[0] == "goal" and (
            gid == _ZERO_ID or k[1] == gid))
        with self._lock:
            cancelled = [(g.goal_id, g.accepted_at) for k in dropped
                         if (g := self.goals.get(k[1])) is not None]  # type: ignore[index]

        def answer(result: object) -> None:
            code, canceling = result  # type: ignore[misc]
            if cancelled:  # a queued start it discarded is a goal it cancelled
                code, canceling = R.ERROR_NONE, cancelled + canceling
            respond(cdr.encode(m.cancel_response(code, canceling), ep.response_type))
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
            self.publish_status()
            return out
        self.inbox.submit_stop(("cancel", goal.goal_id), run, answer)
        return None

    def on_trajectory(self, data: bytes, sender: Sender) -> None:
        ep = self.names.joint_trajectory
        since = self.inbox.epoch  # decoding a large trajectory takes long: a stop may overtake
        who, _ = self.admission.admit(sender, "a trajectory")
        if who is None or not self.admission.within_rate(ep, sender):
            return
        message = cdr.decode(data, ep.type)  # in the link thread
        traj = m.trajectory_from_msg(message)
        if self._prevalidate is not None:  # the length-dependent checks here, not in the tick
            try:
                traj = self._prevalidate(traj)
            except (ValueError, TypeError) as err:  # TrajectoryError is a ValueError
                self.counters.bump("rejected_trajectories")
                _log.warning("trajectory from %s refused: %s", who, err)
                return
        self._client_seen(who)
        refusal = self._lease(who)
        if refusal:
            self.counters.bump("rejected_trajectories")
            _log.warning("trajectory from %s %s", who, refusal)
            return
        # As ROS trajectory controllers: time 0 is header.stamp (wall clock, so the PC's and
        # the tool's clocks must agree), or arrival when the stamp is zero.
        stamp = m.stamp_to_time(message.header.stamp)

        def work() -> None:
            delay = stamp - time.time() if stamp > 0 else 0.0
            ok, msg = self._ask(self.api.follow_trajectory, traj, delay)
            if not ok:
                self.counters.bump("rejected_trajectories")
                _log.warning("trajectory refused: %s", msg)

        def discard(_: bool) -> None:  # a topic: nobody to answer; counted and logged
            self.counters.bump("rejected_trajectories")
            _log.warning("trajectory from %s dropped: %s", who, SUPERSEDED)
        if not self.inbox.submit(work, discard=discard, since=since):
            self.counters.bump("rejected_trajectories")

    def on_client_heartbeat(self, data: bytes, sender: Sender) -> None:
        ep = self.names.client_heartbeat
        who, _ = self.admission.admit(sender, "a client heartbeat")
        if who is None or not self.admission.within_rate(ep, sender):  # a forged heartbeat keeps
            return  # neither a lease nor the link alive
        cdr.decode(data, ep.type)
        self._client_seen(who)
        with self._lock:
            self.lease.renew(who, time.monotonic())

    def settle(self) -> tuple[list[Responder], m.PrimitiveResult] | PrimitiveStatus | None:
        """The active goal's progress (lock held): see :meth:`GoalTable.settle`; the waiters
        of a goal that ended are answered outside the lock by :meth:`answer_waiters`."""
        return self.goals.settle(self.api.primitive_status)

    def answer_waiters(self, ended: object) -> None:
        """Answer the get_result waiters of a goal :meth:`settle` found ended."""
        if not isinstance(ended, tuple):
            return
        waiters, result = ended
        payload = cdr.encode(m.result_msg(result), self.names.get_result.response_type)
        for respond in waiters:
            respond(payload)
        self.publish_status()

    def publish_status(self) -> None:
        """Publish the action's goal statuses (from the ``link-io`` thread)."""
        with self._lock:
            goals = self.goals.statuses()
        payload = cdr.encode(m.status_array(goals), cdr.GOAL_STATUS_ARRAY)
        self.inbox.off_loop(lambda: self.transport.publish(self.names.status, payload))
