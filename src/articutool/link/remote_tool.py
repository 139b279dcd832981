"""The tool behind the link as a ``ToolAPI`` (thesis §3.2.2): what lets the feeding tree,
which only knows :class:`~articutool.tool.api.ToolAPI`, drive a tool over the link exactly as
it drives the in-process runtime, faults of the link during a bite included.

Calls never raise for the link: a call the link could not carry is refused with the link's
reason (``(False, why)``), as the tool refuses one. A primitive runs as an action goal on a
thread of this object (``start_primitive`` returns once the goal is sent;
``primitive_status`` polls); the goal is answered by the tool's result, or by the link's
error when the tool went silent while it ran.

Clocks: the client stamps telemetry with its local receive time (``time.monotonic``), and
the link's silence bounds are wall time. :meth:`RemoteTool.state` restamps each snapshot on
the caller's ``clock`` as ``clock() - age``, ``age`` being the wall time since it arrived: the
tree's staleness check then measures the link's real silence. On a simulated clock that
only holds if the world runs no faster than real time (a world running faster would shrink
the wall age of old telemetry less than its clock advanced).
"""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import replace

from articutool.link.client import ArticutoolClient, LinkError
from articutool.tool.api import IDENTITY_XYZW, Mode, PrimitiveStatus, ToolState
from articutool.trajectory import JointTrajectory

__all__ = ["RemoteTool"]

_NOTHING_HEARD = ToolState(stamp=float("-inf"), mode=Mode.DISABLED, joint_names=("", ""),
                           position=(0.0, 0.0), velocity=(0.0, 0.0),
                           orientation_wxyz=(1.0, 0.0, 0.0, 0.0),
                           angular_velocity=(0.0, 0.0, 0.0),
                           linear_acceleration=(0.0, 0.0, 0.0))


class RemoteTool:
    """``ToolAPI`` over an :class:`ArticutoolClient` (see the module doc); ``clock`` is the
    caller's (the tree's) clock."""

    def __init__(self, client: ArticutoolClient, clock: Callable[[], float] = time.monotonic
                 ) -> None:
        self.client, self.clock = client, clock
        self._lock = threading.Lock()
        self._status: PrimitiveStatus | None = None
        self._goal: bytes | None = None
        self._thread: threading.Thread | None = None

    def set_mode(self, mode: Mode, pitch_offset_deg: float = 0.0,
                 roll_offset_deg: float = 0.0,
                 target_xyzw: tuple[float, float, float, float] = IDENTITY_XYZW
                 ) -> tuple[bool, str]:
        """The tool's answer, ``(False, the link's reason)``, or ``(False, why)`` for a mode
        the service does not carry (as the runtime refuses it)."""
        try:
            return self.client.set_mode(mode, pitch_offset_deg, roll_offset_deg, target_xyzw)
        except LinkError as err:
            return False, f"link: {err}"
        except ValueError as err:
            return False, str(err)

    def clear_fault(self) -> tuple[bool, str]:
        """The tool's answer, or ``(False, the link's reason)``."""
        try:
            return self.client.clear_fault()
        except LinkError as err:
            return False, f"link: {err}"

    def start_primitive(self, name: str, parameters: list[float]) -> tuple[bool, str]:
        """Send the goal (its result arrives in :meth:`primitive_status`); refused while
        this object's previous goal is still waiting for its result."""
        with self._lock:
            if self._thread is not None and self._thread.is_alive():
                return False, "refused: a primitive is already running"
            self._goal = gid = uuid.uuid4().bytes
            self._status = PrimitiveStatus(name, 0.0, "goal sent", (0.0, 0.0), done=False)
            self._thread = threading.Thread(target=self._run, args=(gid, name, list(parameters)),
                                            name="remote-primitive", daemon=True)
            self._thread.start()
        return True, "goal sent"

    def _run(self, gid: bytes, name: str, params: list[float]) -> None:
        def feedback(st: PrimitiveStatus) -> None:
            with self._lock:
                if self._goal == gid:
                    self._status = st
        try:
            r = self.client.run_primitive(name, params, feedback, goal_id=gid)
            done = PrimitiveStatus(name, 100.0 if r.success else 0.0, r.message, (0.0, 0.0),
                                   done=True, success=bool(r.success), message=str(r.message),
                                   final_joint_values=tuple(r.final_joint_values))
        except Exception as err:  # the link's answer to the goal: never left unanswered
            done = PrimitiveStatus(name, 0.0, "", (0.0, 0.0), done=True, success=False,
                                   message=f"link: {err}")
        with self._lock:
            if self._goal == gid:
                self._status = done

    def primitive_status(self) -> PrimitiveStatus | None:
        """The latest feedback of this object's goal, or its result once answered."""
        with self._lock:
            return self._status

    def cancel_primitive(self) -> bool:
        """Cancel this object's goal; False if none runs or the link cannot carry it."""
        with self._lock:
            gid = self._goal if self._thread is not None and self._thread.is_alive() else None
        if gid is None:
            return False
        try:
            return self.client.cancel(gid)
        except LinkError:
            return False

    def follow_trajectory(self, trajectory: JointTrajectory, start_delay: float = 0.0
                          ) -> tuple[bool, str]:
        """Publish it (start ``start_delay`` s from now on the wall clock)."""
        try:
            self.client.follow_trajectory(
                trajectory, time.time() + start_delay if start_delay > 0 else None)
        except LinkError as err:
            return False, f"link: {err}"
        except (ValueError, TypeError) as err:
            return False, str(err)
        return True, "sent"

    def state(self) -> ToolState:
        """The latest telemetry, restamped on ``clock`` (see the module doc); stamped
        ``-inf`` (stale) before anything was heard."""
        st = self.client.latest_state()
        if st is None:
            return _NOTHING_HEARD
        return replace(st, stamp=self.clock() - (time.monotonic() - st.stamp))
