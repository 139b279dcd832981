"""``SetOrientationControl`` on ADA's name and on the upstream node's, and our ``clear_fault``:
the tool's mode commands, forwarded over the link.

Offsets are read in radians by default, what ADA's ``CallSetOrientationControl`` sends
(``math.radians`` of its inputs), or in degrees as the upstream ``.srv`` says with
``offset_units="degrees"``; the link carries degrees. MODE_FULL_ORIENTATION (2) forwards
``target_orientation_robot_base``; the other modes ignore it. Every DISABLED is a stop (the
stop lane). A request the tool would refuse whatever its state (bad numbers, offsets outside
the connected tool's reported joint limits) is refused here with the tool's own message,
without a lane or a link round trip; the others run on a bounded work lane, and a full lane
answers "busy" at once. The services drain their queues (:mod:`articutool.ros2.intake`).
"""

from __future__ import annotations

import math
import time
from typing import Any

from articutool.link import messages as m
from articutool.link.client import parse_mode
from articutool.ros2.admission import mode_refusal
from articutool.ros2.intake import create_draining_service
from articutool.ros2.lanes import StopLane, WorkLane
from articutool.ros2.serving import Side, outcome, submit
from articutool.tool.api import Mode
from articutool.tool.telemetry import reported_limits

__all__ = ["OrientationControlServer"]

_LIMITS_TTL = 1.0  # s between reads of the connected tool's reported joint limits


class OrientationControlServer:
    """The mode services on ``side`` (the main node) for ``client``'s tool; DISABLED goes to
    ``stops``, the rest to a work lane of its own."""

    def __init__(self, client: Any, side: Side, names: dict[str, str], offset_units: str,
                 stops: StopLane, counters: dict[str, int]) -> None:
        from articutool_interfaces.srv import SetOrientationControl
        from std_srvs.srv import Trigger

        self._client, self._side, self._stops, self._counters = client, side, stops, counters
        self._scale = (180.0 / math.pi) if offset_units == "radians" else 1.0
        self._work = WorkLane("ros2-work", threads=2, capacity=16)
        self._limits, self._limits_at = None, -math.inf
        for key in ("set_orientation_control", "set_orientation_control_mode"):
            create_draining_service(side.node, SetOrientationControl, names[key],
                                    self._start_set_mode, qos_profile=side.qos,
                                    callback_group=side.group)
        create_draining_service(side.node, Trigger, names["clear_fault"],
                                self._start_clear_fault, qos_profile=side.qos,
                                callback_group=side.group)

    def close(self) -> None:
        self._work.close()

    def _start_set_mode(self, request: Any, response: Any) -> Any:
        """The response when the node answers at once (a refusal, a busy lane), else the
        coroutine that awaits the tool (:mod:`articutool.ros2.intake`)."""
        mode = int(request.control_mode)
        pitch = float(request.pitch_offset) * self._scale
        roll = float(request.roll_offset) * self._scale
        client = self._client
        t = request.target_orientation_robot_base
        target = (float(t.x), float(t.y), float(t.z), float(t.w))
        try:  # refused here, as the link client would, without waiting for a lane
            m.soc_request(parse_mode(mode), pitch, roll, target)
        except ValueError as err:
            response.success, response.message = False, str(err)
            return response
        # as the connected tool would (its reported limits): no link round trip
        refusal = mode_refusal(mode, pitch, roll, self._tool_limits())
        if refusal is not None:
            response.success, response.message = False, refusal
            return response
        if mode == Mode.DISABLED:  # every DISABLED is a stop
            future = self._stops.submit(self._side.wake)
        else:
            future = submit(self._work, lambda: client.set_mode(mode, pitch, roll, target),
                            self._side.wake, self._counters)
        return _finish(future, response, "set_orientation_control")

    def _tool_limits(self) -> Any:
        """The connected tool's joint limits as it reports them, read at most every
        ``_LIMITS_TTL`` s (a state is rebuilt from telemetry on each read)."""
        now = time.monotonic()
        if now - self._limits_at > _LIMITS_TTL:
            self._limits, self._limits_at = reported_limits(self._client.latest_state()), now
        return self._limits

    def _start_clear_fault(self, _request: Any, response: Any) -> Any:
        future = submit(self._work, self._client.clear_fault, self._side.wake, self._counters)
        return _finish(future, response, "clear_fault")


async def _finish(future: Any, response: Any, what: str) -> Any:
    response.success, response.message = await outcome(future, what)
    return response
