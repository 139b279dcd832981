"""PC side of the link: ``ArticutoolClient`` (thesis §3.2.2's three command modalities).

The client keeps the latest telemetry, publishes a heartbeat (the tool's link-loss detector
listens to it) and declares the tool *silent* when nothing has arrived from it for
``LinkConfig.tool_timeout`` seconds (default 1 s; the tool publishes at 50 Hz, so that is 50
missed samples). Calls made while the tool is silent raise :class:`ToolSilentError` once their
own time runs out; the Zenoh session keeps reconnecting, and as soon as the tool is heard
again the same client works again — nothing needs re-creating.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
import uuid
from collections.abc import Callable
from typing import Any

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.config import LinkConfig
from articutool.link.transport import (
    Endpoint,
    LinkRefusedError,
    LinkTimeoutError,
    Names,
    Transport,
)
from articutool.tool.api import IDENTITY_XYZW, SERVICE_MODES, Mode, PrimitiveStatus, ToolState
from articutool.trajectory import JointTrajectory

__all__ = ["ArticutoolClient", "LinkError", "ToolConflictError", "ToolRefusedError",
           "ToolSilentError", "check_primitive_request"]

_log = logging.getLogger(__name__)


class LinkError(RuntimeError):
    """The link failed to carry a command (malformed reply, tool restarted mid-goal, …)."""


class ToolRefusedError(LinkError):
    """The tool answered with an error naming why it refused (rate limited, not paired,
    clocks out of sync, a replay …)."""


class ToolSilentError(LinkError):
    """The tool did not answer, and nothing was heard from it within the silence bound."""


class ToolConflictError(LinkError):
    """Two tools answer to the same identity: the client refuses to command either."""


def parse_mode(mode: Mode | str | int) -> Mode:
    """'leveling' / 'disabled' / Mode / 0|1|2 → Mode (the service modes; FULL_ORIENTATION,
    which needs a target, by number or Mode only)."""
    if isinstance(mode, str):
        key = mode.strip().upper()
        if key not in ("LEVELING", "DISABLED"):
            raise ValueError(f"mode must be 'leveling' or 'disabled'; got {mode!r}")
        return Mode[key]
    if mode not in SERVICE_MODES:
        raise ValueError("mode must be DISABLED (0), LEVELING (1) or FULL_ORIENTATION (2); "
                         f"got {mode!r}")
    return Mode(mode)


def _check_size(what: str, size: int, most: int, setting: str) -> None:
    """A message the tool would drop unread for its size (and so never answer) is refused
    before it is sent: ValueError naming the link config setting."""
    if size > most:
        raise ValueError(f"{what}: the message is {size} bytes, more than {setting} = {most} "
                         "(link config) the tool reads: it would drop it unanswered; send "
                         "fewer or shorter values")


def check_primitive_request(cfg: LinkConfig, name: str, params: list[float]) -> None:
    """The goal request of primitive ``name`` with ``params`` fits the tool's
    ``max_request_bytes``: checked before connecting (``client primitive``); ValueError
    otherwise. :meth:`ArticutoolClient.run_primitive` checks every request again."""
    ep = Names(cfg.namespace, cfg.tool_id).send_goal
    payload = cdr.encode(m.send_goal_request(bytes(16), name, [float(p) for p in params]),
                       ep.request_type)
    _check_size(f"primitive {name!r} with {len(params)} parameter(s)", len(payload),
                cfg.max_request_bytes, "max_request_bytes")


class ArticutoolClient:
    """Command and monitor an Articutool over the link.

    ``transport`` defaults to a Zenoh session in the client role built from ``config``.
    """

    def __init__(self, config: LinkConfig | None = None, transport: Transport | None = None,
                 sender: str | None = None) -> None:
        self.cfg = config or LinkConfig()
        self.sender = sender or self.cfg.identity or f"articutool-client-{uuid.uuid4().hex[:8]}"
        if transport is None:
            from articutool.link.zenoh_transport import ZenohTransport
            transport = ZenohTransport(self.cfg, "client", identity=self.sender)
        self.transport = transport
        self.sender = getattr(transport, "identity", None) or self.sender  # a paired CN wins
        self.names = Names(self.cfg.namespace, self.cfg.tool_id)
        self.counters = {"decode_errors": 0, "received": 0, "joint_states": 0,
                         "foreign_heartbeats": 0}
        self._instances: dict[str, float] = {}  # tool instance → last heard (monotonic)
        self._conflict = ""
        self._commanded = False
        self._lock = threading.Lock()
        self._latest: dict[str, Any] = {}
        self._last_rx: float | None = None
        self._js_rx: float = float("nan")
        self._feedback: dict[bytes, tuple[str, Callable[[PrimitiveStatus], None] | None]] = {}
        self._goal: bytes | None = None
        self._stop = threading.Event()
        n = self.names
        self._handles = [self.transport.subscribe(ep, self._receiver(key, ep))
                         for key, ep in (("js", n.joint_states), ("imu", n.imu),
                                         ("health", n.health), ("battery", n.battery),
                                         ("status", n.status))]
        self._handles.append(self.transport.subscribe(n.heartbeat, self._on_tool_heartbeat,
                                                      with_sender=True))
        self._handles.append(self.transport.subscribe(n.feedback, self._on_feedback))
        self._beat = threading.Thread(target=self._heartbeat, name="link-client-beat",
                                      daemon=True)
        self._beat.start()

    # ---------------------------------------------------------------- plumbing --
    def _decode(self, data: bytes, typename: str) -> Any | None:
        try:
            return cdr.decode(data, typename)
        except cdr.LinkDecodeError as err:
            with self._lock:
                self.counters["decode_errors"] += 1
            _log.warning("dropped malformed payload: %s", err)
            return None

    def _receiver(self, key: str, ep: Endpoint) -> Callable[[bytes], None]:
        def on_data(data: bytes) -> None:
            obj = self._decode(data, ep.type)
            if obj is None:
                return
            now = time.monotonic()
            with self._lock:
                self._latest[key] = obj
                self._last_rx = now
                self.counters["received"] += 1
                if key == "js":
                    self.counters["joint_states"] += 1
                    self._js_rx = now
        return on_data

    def _on_tool_heartbeat(self, data: bytes, sender: Any) -> None:
        """Learn the tool instances answering to ``tool_id``; two at once is a conflict."""
        beat = self._decode(data, self.names.heartbeat.type)
        if beat is None:
            return
        tool, _, instance = str(beat.frame_id).partition("/")
        paired = self.cfg.paired and sender is not None
        if tool != self.cfg.tool_id or (paired and not (sender.verified and sender.role == "tool"
                                                        and sender.identity == tool)):
            with self._lock:  # not our tool, or not signed by it: neither alive nor counted
                self.counters["foreign_heartbeats"] += 1
            return
        now = time.monotonic()
        with self._lock:
            self._last_rx = now
            self._instances[instance] = now
            live = sorted(k for k, t in self._instances.items()
                          if now - t < self.cfg.tool_timeout)
            if len(live) > 1 and not self._conflict:
                self._conflict = (f"{len(live)} tools answer to the identity "
                                  f"{self.cfg.tool_id!r} (instances {live}); refusing to "
                                  "command or read either: give each tool its own tool_id")
                _log.error(self._conflict)

    @property
    def conflict(self) -> str:
        """Why this client refuses the tool ('' when exactly one tool answers)."""
        with self._lock:
            return self._conflict

    def _check_conflict(self) -> None:
        c = self.conflict
        if c:
            raise ToolConflictError(c)

    def _on_feedback(self, data: bytes) -> None:
        fb = self._decode(data, self.names.feedback.type)
        if fb is None:
            return
        with self._lock:
            self._last_rx = time.monotonic()
            name, cb = self._feedback.get(m.uuid_bytes(fb.goal_id), ("", None))
        if cb is not None:
            f = fb.feedback
            joints = tuple(float(x) for x in f.current_joint_values)
            try:
                cb(PrimitiveStatus(name=name, percent_complete=float(f.percent_complete),
                                   feedback=str(f.feedback_string),
                                   current_joint_values=joints,  # type: ignore[arg-type]
                                   done=False))
            except Exception:
                _log.exception("feedback callback raised")

    def _heartbeat(self) -> None:
        ep = self.names.client_heartbeat
        while not self._stop.is_set():
            try:
                self.transport.publish(ep, cdr.encode(m.heartbeat_msg(time.time(), self.sender),
                                                    ep.type))
            except Exception:
                _log.exception("heartbeat publish failed")
            self._stop.wait(self.cfg.heartbeat_period)

    def _silence(self) -> str:
        ago = self.last_heard
        return "never heard from the tool" if ago is None else \
            f"last heard from the tool {ago:.1f} s ago"

    def _call(self, ep: Endpoint, request: Any, timeout: float | None = None) -> Any:
        self._check_conflict()
        if ep not in (self.names.get_result, self.names.release):
            self._commanded = True  # may hold the lease: release it on close
        t = self.cfg.call_timeout if timeout is None else timeout
        payload = cdr.encode(request, ep.request_type)
        _check_size(ep.name, len(payload), self.cfg.max_request_bytes, "max_request_bytes")
        try:
            reply = self.transport.call(ep, payload, t)
        except LinkRefusedError as err:
            raise ToolRefusedError(str(err)) from None
        except LinkTimeoutError as err:
            raise ToolSilentError(f"{ep.name}: no reply within {t:g} s ({self._silence()}): "
                                  f"{err}") from None
        obj = self._decode(reply, ep.response_type)
        if obj is None:
            raise LinkError(f"{ep.name}: the tool's reply was malformed")
        return obj

    # ------------------------------------------------------------------ status --
    @property
    def last_heard(self) -> float | None:
        """Seconds since anything arrived from the tool (None if never)."""
        with self._lock:
            last = self._last_rx
        return None if last is None else time.monotonic() - last

    @property
    def tool_alive(self) -> bool:
        """True while the tool was heard within ``tool_timeout``."""
        ago = self.last_heard
        return ago is not None and ago < self.cfg.tool_timeout

    def wait_for_tool(self, timeout: float) -> bool:
        """Block until the tool is heard (True) or ``timeout`` passes (False); then listen
        three heartbeat periods more for a second tool with the same identity
        (ToolConflictError if one answers)."""
        deadline = time.monotonic() + timeout
        while not self.tool_alive:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)
        time.sleep(3 * self.cfg.heartbeat_period)
        self._check_conflict()
        return True

    def has_all_streams(self) -> bool:
        """True once joint states, IMU, health and battery have each been received."""
        with self._lock:
            return all(k in self._latest for k in ("js", "imu", "health", "battery"))

    def lease_holder(self) -> str | None:
        """The command lease's holder per the latest health message ('' none, None unknown)."""
        with self._lock:
            health = self._latest.get("health")
        if health is None:
            return None
        for st in health.status:
            for kv in st.values:
                if kv.key == "lease_holder":
                    return str(kv.value)
        return None

    def latest_tool_time(self) -> float | None:
        """The tool's own stamp (wall-clock seconds) of the latest joint state, or None: how
        far the tool's loop had got when it sent what this client last received."""
        with self._lock:
            js = self._latest.get("js")
        return None if js is None else m.stamp_to_time(js.header.stamp)

    def latest_state(self) -> ToolState | None:
        """The latest telemetry as a ToolState (``stamp`` = local receive time), or None
        (also when two tools answer to one identity: their streams would be mixed)."""
        if self.conflict:
            return None
        with self._lock:
            js = self._latest.get("js")
            parts = (self._latest.get("imu"), self._latest.get("health"),
                     self._latest.get("battery"))
            stamp = self._js_rx
        if js is None:
            return None
        try:
            return m.state_from_msgs(js, *parts, stamp=stamp)
        except cdr.LinkDecodeError:
            with self._lock:
                self.counters["decode_errors"] += 1
            return None

    # ---------------------------------------------------------------- commands --
    def set_mode(self, mode: Mode | str | int, pitch_offset_deg: float = 0.0,
                 roll_offset_deg: float = 0.0,
                 target_xyzw: tuple[float, float, float, float] = IDENTITY_XYZW
                 ) -> tuple[bool, str]:
        """Call ``set_orientation_control``; returns the tool's (success, message).
        ``target_xyzw`` is FULL_ORIENTATION's target, [x, y, z, w] in the robot base.

        Raises ValueError on bad input (nothing is sent) and ToolSilentError without reply.
        """
        req = m.soc_request(parse_mode(mode), float(pitch_offset_deg), float(roll_offset_deg),
                            target_xyzw)
        resp = self._call(self.names.set_orientation_control, req)
        return bool(resp.success), str(resp.message)

    def clear_fault(self) -> tuple[bool, str]:
        """Call ``clear_fault`` (``ToolAPI.clear_fault``: the only request that reboots motors
        after a hardware error, refused while one is still hot); returns (success, message)."""
        resp = self._call(self.names.clear_fault, m.trigger_request())
        return bool(resp.success), str(resp.message)

    def take_over(self) -> tuple[bool, str]:
        """Take the command lease from whoever holds it (audited on the tool)."""
        resp = self._call(self.names.take_over, m.trigger_request())
        return bool(resp.success), str(resp.message)

    def release(self) -> tuple[bool, str]:
        """Give the command lease back (success=false if this client did not hold it)."""
        resp = self._call(self.names.release, m.trigger_request())
        return bool(resp.success), str(resp.message)

    def run_primitive(self, name: str, params: list[float] | tuple[float, ...] = (),
                      feedback_cb: Callable[[PrimitiveStatus], None] | None = None,
                      timeout: float | None = None,
                      goal_id: bytes | None = None) -> m.PrimitiveResult:
        """Run a primitive through the action and wait for its result.

        ``goal_id``: the goal's 16-byte UUID (default random), e.g. a ROS 2 goal's own id
        when ``articutool ros2`` forwards it, so :meth:`cancel` can address it.

        ``feedback_cb(PrimitiveStatus)`` receives feedback (percent, text, joints). On
        ``timeout`` the goal is cancelled and a result with ``success=False`` returned. A
        refusal by the tool is a result with ``success=False`` and the tool's message.
        Raises ToolSilentError when the tool goes silent while the goal runs. If the wait is
        interrupted (KeyboardInterrupt, any exception), the goal is cancelled before the
        exception propagates, so a goal this call started never outlives it unattended.
        """
        if not isinstance(name, str) or not name:
            raise ValueError("primitive name must be a non-empty string")
        params = [float(p) for p in params]
        gid = uuid.uuid4().bytes if goal_id is None else bytes(goal_id)
        if len(gid) != 16:
            raise ValueError(f"goal_id must be 16 bytes; got {len(gid)}")
        with self._lock:
            self._feedback[gid] = (name, feedback_cb)
            self._goal = gid
        try:
            try:
                resp = self._call(self.names.send_goal, m.send_goal_request(gid, name, params))
            except ToolRefusedError as err:  # the reason, where ROS's reply has no text
                return m.PrimitiveResult(False, str(err), (), m.GoalStatus.UNKNOWN)
            if not resp.accepted:
                return m.PrimitiveResult(False, "goal rejected by the tool", (),
                                         m.GoalStatus.UNKNOWN)
            try:
                return self._await_result(gid, timeout)
            except BaseException:
                self._cancel_quietly(gid)
                raise
        finally:
            with self._lock:
                self._feedback.pop(gid, None)
                if self._goal == gid:
                    self._goal = None

    def _await_result(self, gid: bytes, timeout: float | None) -> m.PrimitiveResult:
        ep = self.names.get_result
        deadline = None if timeout is None else time.monotonic() + timeout
        req = cdr.encode(cdr.msg(ep.request_type, goal_id=m.goal_uuid(gid)), ep.request_type)
        while True:
            left = None if deadline is None else deadline - time.monotonic()
            if left is not None and left <= 0:
                self.cancel(gid)
                try:  # the cancelled goal's own result, if it arrives promptly
                    res = self._get_result_once(ep, req, self.cfg.call_timeout)
                    msg = f"timed out after {timeout:g} s; cancelled ({res.message})"
                    return m.PrimitiveResult(False, msg, res.final_joint_values, res.status)
                except LinkTimeoutError:
                    return m.PrimitiveResult(False, f"timed out after {timeout:g} s; "
                                             "cancel requested", (), m.GoalStatus.UNKNOWN)
            poll = self.cfg.tool_timeout if left is None else min(left, self.cfg.tool_timeout)
            t0 = time.monotonic()
            try:
                return self._get_result_once(ep, req, poll)
            except LinkTimeoutError:
                if not self.tool_alive:
                    raise ToolSilentError(f"the tool went silent while running the primitive "
                                          f"({self._silence()})") from None
                # No queryable reachable makes get return at once: don't spin.
                time.sleep(max(0.0, min(0.05, poll - (time.monotonic() - t0))))

    def _get_result_once(self, ep: Endpoint, req: bytes, t: float) -> m.PrimitiveResult:
        try:
            reply = self.transport.call(ep, req, t)
        except LinkRefusedError as err:
            raise LinkError(str(err)) from None
        obj = self._decode(reply, ep.response_type)
        if obj is None:
            raise LinkError(f"{ep.name}: the tool's reply was malformed")
        res = m.result_from_msg(obj)
        if res.status == m.GoalStatus.UNKNOWN:
            raise LinkError("the tool does not know this goal (was it restarted?): "
                            f"{res.message}")
        return res

    def _cancel_quietly(self, gid: bytes) -> None:
        """Cancel ``gid`` on the way out of an interrupted wait; a second Ctrl-C or a silent
        tool must not replace the exception being raised."""
        try:
            if self.cancel(gid):
                _log.info("cancelled goal %s", gid.hex())
        except BaseException:  # best effort while another exception propagates
            _log.warning("could not cancel goal %s", gid.hex())

    def cancel(self, goal_id: bytes | None = None) -> bool:
        """Cancel ``goal_id`` (default: this client's running goal, else every goal).

        True if the tool started cancelling a goal.
        """
        with self._lock:
            gid = goal_id if goal_id is not None else self._goal
        resp = self._call(self.names.cancel_goal, m.cancel_request(gid))
        return int(resp.return_code) == 0 and len(resp.goals_canceling) > 0

    def follow_trajectory(self, trajectory: JointTrajectory,
                          start_at: float | None = None) -> None:
        """Publish a wrist trajectory (joint names [pitch, roll]) for the tool to follow.

        ``start_at``: wall-clock time (``time.time()``) of the trajectory's time 0, sent as
        ``header.stamp`` (e.g. the arm trajectory's start, to run both in step; the PC's and
        the tool's clocks must be synchronised); the tool holds its position until then.
        None starts it on arrival (stamp zero, as in ROS). Fire-and-forget like a ROS topic;
        raises ToolSilentError if the tool is silent (nothing is sent into the void).
        """
        if not isinstance(trajectory, JointTrajectory):
            raise TypeError("trajectory must be an articutool.trajectory.JointTrajectory")
        self._check_conflict()
        if not self.tool_alive:
            raise ToolSilentError(f"not sending the trajectory: {self._silence()}")
        ep = self.names.joint_trajectory
        self._commanded = True
        if start_at is not None and not (math.isfinite(start_at) and start_at > 0):
            raise ValueError(f"start_at must be a wall-clock time > 0; got {start_at!r}")
        stamp = 0.0 if start_at is None else float(start_at)
        payload = cdr.encode(m.trajectory_msg(trajectory, stamp), ep.type)
        _check_size(ep.name, len(payload), self.cfg.max_trajectory_bytes,
                    "max_trajectory_bytes")
        self.transport.publish(ep, payload)

    def close(self) -> None:
        """Release the command lease if this client holds it, stop the heartbeat, undeclare
        everything and close the transport."""
        if self._commanded and self.tool_alive and not self.conflict:
            with contextlib.suppress(LinkError):  # else it expires once this client is silent
                self.release()
        self._stop.set()
        self._beat.join(timeout=2)
        for h in self._handles:
            h.close()
        self.transport.close()

    def __enter__(self) -> ArticutoolClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
