"""The bounded channel between the tool's loop process and its link process (thesis §3.2).

``articutool tool`` runs the 50 Hz loop in one process and the network link in another
(``onboard.py``, ``onboard_link.py``), so nothing the network does can take the loop's CPU,
its interpreter lock or its scheduler share. They talk over one Unix stream socket pair, in
length-prefixed frames (4 bytes big-endian, then a pickle: both ends are this program, and the
socket pair is never reachable from outside the two processes).

Loop side, :class:`LoopChannel`: its :meth:`~LoopChannel.work_once` runs once per tick, after
the tick (``ToolRuntime.set_link_work``). It never blocks: it reads what has arrived (at most
``_READ_PER_TICK`` bytes), runs at most ``_CALLS_PER_TICK`` ToolAPI calls, and queues one
*report* — the state snapshot, the primitive status and the answers to the calls it ran — that
it sends as far as the socket takes it. While a report is still going out, no new one is
made and the answers wait for the next: a stalled link process costs the loop one failed
``send`` per tick, never a wait, and no answer is ever dropped.

Link side, :class:`LoopProxy`: a :class:`~articutool.tool.api.ToolAPI` for the link server.
``state()`` and ``primitive_status()`` return the latest report (no round trip); a command is
sent with a deadline (``CALL_S``) and the caller waits for its answer. The loop refuses a
call whose deadline has passed without running it and says so, so a caller told "not run"
has not moved the wrist behind its back (with no answer at all, ``_GRACE_S`` later, the
caller is told it may have run). Reports are read in order by one thread, which updates the state
before it wakes a caller, so an answer is never older than the state seen after it.

Trajectories are validated in the link process (:meth:`LoopProxy.prevalidate_trajectory`,
the checks whose cost grows with the trajectory, with the spec the loop runs) and the loop
only checks the start against the present joints, as when both ran in one process.
"""

from __future__ import annotations

import contextlib
import logging
import pickle
import socket
import struct
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import replace
from typing import Any

from articutool.spec import Spec
from articutool.tool.api import IDENTITY_XYZW, Mode, PrimitiveStatus, ToolState
from articutool.tool.following import TrajectoryFollower
from articutool.trajectory import JointTrajectory

__all__ = ["CALL_S", "ChannelClosedError", "FrameReader", "LoopChannel", "LoopProxy", "send_frame"]

log = logging.getLogger(__name__)

CALL_S = 2.0  # s a command may wait for the loop before the loop refuses to run it
_GRACE_S = 1.0  # s the proxy waits past a deadline for the loop's answer (refused or run)
_MAX_FRAME = 64 << 20  # bytes; a trajectory within the link's 1 MiB CDR limit is ~0.7 MB
_READ_PER_TICK = 1 << 20  # bytes the loop reads per tick
_CALLS_PER_TICK = 4  # ToolAPI calls the loop runs per tick (the link sends one or two)
_HEADER = struct.Struct(">I")
_CALLS = ("set_mode", "clear_fault", "start_primitive", "cancel_primitive",
          "follow_trajectory")


class ChannelClosedError(ConnectionError):
    """The other process closed the channel (it ended) or sent something unreadable."""


def _frame(message: object) -> bytes:
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    if len(data) > _MAX_FRAME:
        raise ValueError(f"a channel message of {len(data)} bytes (at most {_MAX_FRAME})")
    return _HEADER.pack(len(data)) + data


def send_frame(sock: socket.socket, message: object) -> None:
    """Send one message on a blocking socket (the link side, and the start-up handshake)."""
    sock.sendall(_frame(message))


class FrameReader:
    """Frames from a stream socket; keeps a partial frame between reads."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self._buf = bytearray()

    def _pop(self) -> object | None:
        if len(self._buf) < _HEADER.size:
            return None
        (n,) = _HEADER.unpack_from(self._buf)
        if n > _MAX_FRAME:
            raise ChannelClosedError(f"a channel frame of {n} bytes (at most {_MAX_FRAME})")
        if len(self._buf) < _HEADER.size + n:
            return None
        data = bytes(self._buf[_HEADER.size:_HEADER.size + n])
        del self._buf[:_HEADER.size + n]
        try:
            return pickle.loads(data)
        except Exception as err:
            raise ChannelClosedError(
                f"an unreadable channel frame ({type(err).__name__})") from None

    def read(self, timeout: float | None = None) -> object:
        """The next message, waiting at most ``timeout`` s (None: until it comes); raises
        TimeoutError, or ChannelClosedError at the end of the stream."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            msg = self._pop()
            if msg is not None:
                return msg
            if deadline is not None:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError("no message on the channel")
                self.sock.settimeout(left)
            else:
                self.sock.settimeout(None)
            try:
                chunk = self.sock.recv(1 << 16)
            except TimeoutError:
                raise TimeoutError("no message on the channel") from None
            except OSError as err:
                raise ChannelClosedError(str(err)) from None
            if not chunk:
                raise ChannelClosedError("the other process closed the channel")
            self._buf += chunk

    def poll(self, budget: int) -> list[object]:
        """The messages complete after reading at most ``budget`` bytes without waiting
        (the socket must be non-blocking); ChannelClosedError at the end of the stream."""
        got = 0
        while got < budget:
            try:
                chunk = self.sock.recv(min(1 << 16, budget - got))
            except (BlockingIOError, InterruptedError):
                break
            except OSError as err:
                raise ChannelClosedError(str(err)) from None
            if not chunk:  # what it sent last can no longer be answered
                raise ChannelClosedError("the link process closed the channel")
            self._buf += chunk
            got += len(chunk)
        out = []
        while (msg := self._pop()) is not None:
            out.append(msg)
        return out


class LoopChannel:
    """The loop's end (module doc): ``work_once`` once per tick; never blocks, never raises.

    ``runtime`` is the :class:`~articutool.tool.runtime.ToolRuntime` whose loop calls it;
    ``extra`` is merged into every reported state's ``extra`` (e.g. the loop's priority);
    ``on_lost(reason)`` is called once, on the loop's thread, when the link process is gone.
    """

    def __init__(self, reader: FrameReader, runtime: Any, *,
                 extra: dict[str, float] | None = None,
                 on_lost: Callable[[str], None] | None = None) -> None:
        self.reader = reader
        self.sock = reader.sock
        self.rt = runtime
        self.extra = dict(extra or {})
        self.on_lost = on_lost
        self.lost = ""
        self._calls: deque[tuple[int, str, tuple, float]] = deque()
        self._answers: list[tuple[int, object]] = []
        self._out = b""
        self.reports = 0
        self.stalled_sends = 0

    def start(self) -> None:
        """Switch the socket to non-blocking (after the start-up handshake)."""
        self.sock.setblocking(False)

    def report(self) -> tuple:
        """The report message: state (with ``extra``), primitive status, answers so far."""
        state = self.rt.state()
        if self.extra:
            state = replace(state, extra={**state.extra, **self.extra})
        answers, self._answers = self._answers, []
        return ("report", state, self.rt.primitive_status(), answers)

    def work_once(self) -> None:
        """Read, run at most ``_CALLS_PER_TICK`` calls, report. Never raises."""
        if self.lost:
            return
        try:
            for msg in self.reader.poll(_READ_PER_TICK):
                if not (isinstance(msg, tuple) and len(msg) == 5 and msg[0] == "call"
                        and msg[2] in _CALLS):
                    raise ChannelClosedError(f"an unexpected channel message {str(msg)[:80]}")
                self._calls.append(msg[1:])
            for _ in range(min(_CALLS_PER_TICK, len(self._calls))):
                self._run(*self._calls.popleft())
            if not self._out:
                self._out = _frame(self.report())
                self.reports += 1
            try:
                sent = self.sock.send(self._out)
                self._out = self._out[sent:]
            except (BlockingIOError, InterruptedError):
                self.stalled_sends += 1
        except (ChannelClosedError, OSError) as err:
            self._lose(str(err) or type(err).__name__)
        except Exception as err:  # never into the loop
            log.exception("link channel failed")
            self._lose(f"{type(err).__name__}: {err}")

    def _run(self, cid: int, name: str, args: tuple, deadline: float) -> None:
        if time.monotonic() > deadline:
            self._answers.append((cid, ("expired", None)))
            return
        try:
            if name == "follow_trajectory":
                traj, delay, prechecked = args
                try:
                    if prechecked:  # the link process ran prevalidate_trajectory, our spec
                        traj = self.rt.adopt_prevalidated(traj)
                    result: object = self.rt.follow_trajectory(traj, delay)
                except (ValueError, TypeError) as err:  # TrajectoryError is a ValueError
                    result = (False, f"trajectory refused: {err}")
            else:
                result = getattr(self.rt, name)(*args)
            self._answers.append((cid, ("ok", result)))
        except Exception as err:
            log.exception("ToolAPI call %s from the link failed", name)
            self._answers.append((cid, ("error", f"{type(err).__name__}: {err}")))

    def _lose(self, reason: str) -> None:
        self.lost = reason
        if self.on_lost is not None:
            self.on_lost(reason)


class _Pending:
    __slots__ = ("event", "result")

    def __init__(self) -> None:
        self.event = threading.Event()
        self.result: tuple[str, object] | None = None


class LoopProxy:
    """The link process's ToolAPI: the loop's reports and its answers (module doc)."""

    def __init__(self, reader: FrameReader, spec: Spec) -> None:
        self.reader = reader
        self.sock = reader.sock
        self.spec = spec
        self._follower = TrajectoryFollower(spec)
        self._send_lock = threading.Lock()
        self._lock = threading.Lock()
        self._pending: dict[int, _Pending] = {}
        self._next = 0
        self._state: ToolState | None = None
        self._status: PrimitiveStatus | None = None
        self.first_report = threading.Event()
        self.closed = threading.Event()
        self.reason = ""
        self._thread = threading.Thread(target=self._read, name="loop-reports", daemon=True)
        self._thread.start()

    # -- the reader --
    def _read(self) -> None:
        try:
            while True:
                msg = self.reader.read()
                if not (isinstance(msg, tuple) and msg and msg[0] == "report"):
                    raise ChannelClosedError(f"an unexpected channel message {str(msg)[:80]}")
                _, state, status, answers = msg
                with self._lock:
                    self._state, self._status = state, status
                    waiters = [(self._pending.pop(cid, None), res) for cid, res in answers]
                self.first_report.set()
                for pending, res in waiters:
                    if pending is not None:
                        pending.result = res
                        pending.event.set()
        except (ChannelClosedError, OSError) as err:
            self.reason = str(err)
        finally:
            self.closed.set()
            self.first_report.set()
            with self._lock:
                waiters = list(self._pending.values())
                self._pending.clear()
            for pending in waiters:
                pending.event.set()

    def send(self, message: object) -> None:
        """Send one message to the loop process (thread-safe, blocking)."""
        with self._send_lock:
            send_frame(self.sock, message)

    def _call(self, name: str, *args: object) -> tuple[str, object]:
        """(kind, value): ("ok", result), ("error", text), or ("expired", "timeout" or "gone",
        None): refused for its deadline, no answer in time, the loop process ended."""
        if self.closed.is_set():
            return "gone", None
        pending = _Pending()
        deadline = time.monotonic() + CALL_S
        with self._lock:
            cid = self._next = self._next + 1
            self._pending[cid] = pending
        try:
            self.send(("call", cid, name, args, deadline))
        except OSError:
            return "gone", None
        if not pending.event.wait(CALL_S + _GRACE_S) or pending.result is None:
            with self._lock:
                self._pending.pop(cid, None)
            return ("gone", None) if self.closed.is_set() else ("timeout", None)
        return pending.result

    def _command(self, name: str, *args: object) -> tuple[bool, str]:
        kind, value = self._call(name, *args)
        if kind == "ok":
            ok, msg = value  # type: ignore[misc]
            return bool(ok), str(msg)
        if kind == "error":
            return False, f"tool error: {value}"
        if kind == "expired":
            return False, (f"refused: the tool's loop did not take the command within "
                           f"{CALL_S:g} s (not run)")
        if kind == "timeout":  # its answer is late: it may have run just before its deadline
            return False, (f"no answer from the tool's loop within {CALL_S + _GRACE_S:g} s; "
                           "the command may have run: read the tool's state")
        return False, "refused: the tool's loop process has ended"

    # -- ToolAPI --
    def set_mode(self, mode: Mode | int, pitch_offset_deg: float = 0.0,
                 roll_offset_deg: float = 0.0,
                 target_xyzw: tuple[float, float, float, float] = IDENTITY_XYZW
                 ) -> tuple[bool, str]:
        """The loop's ``set_mode``."""
        return self._command("set_mode", mode, pitch_offset_deg, roll_offset_deg,
                             tuple(target_xyzw))

    def clear_fault(self) -> tuple[bool, str]:
        """The loop's ``clear_fault``."""
        return self._command("clear_fault")

    def start_primitive(self, name: str, parameters: list[float]) -> tuple[bool, str]:
        """The loop's ``start_primitive``."""
        return self._command("start_primitive", name, list(parameters))

    def cancel_primitive(self) -> bool:
        """The loop's ``cancel_primitive``; False if it did not answer."""
        kind, value = self._call("cancel_primitive")
        return bool(value) if kind == "ok" else False

    def follow_trajectory(self, trajectory: JointTrajectory,
                          start_delay: float = 0.0) -> tuple[bool, str]:
        """The loop's ``follow_trajectory``; a trajectory :meth:`prevalidate_trajectory`
        returned is only checked against the present joints there."""
        checked = self._follower.is_prechecked(trajectory)
        return self._command("follow_trajectory", trajectory, start_delay, checked)

    def prevalidate_trajectory(self, trajectory: JointTrajectory) -> JointTrajectory:
        """The state-independent checks, here in the link process (see
        :meth:`~articutool.tool.runtime.ToolRuntime.prevalidate_trajectory`)."""
        return self._follower.prevalidate(trajectory)

    def primitive_status(self) -> PrimitiveStatus | None:
        """From the latest report."""
        with self._lock:
            return self._status

    def state(self) -> ToolState:
        """The latest report's state (the loop's snapshot after its last tick and calls)."""
        with self._lock:
            state = self._state
        if state is None:
            raise RuntimeError("no report from the tool's loop yet")
        return state

    def close(self) -> None:
        """Close the channel (the loop process sees the link process end)."""
        with contextlib.suppress(OSError):
            self.sock.shutdown(socket.SHUT_RDWR)
        self.sock.close()
        self._thread.join(timeout=2.0)
