"""``articutool/stop`` (``std_srvs/Trigger``): DISABLED on the tool, which aborts any primitive
or trajectory, on the safety node.

Every stop — this service, a DISABLED on ``SetOrientationControl``, a cancelled
``FollowJointTrajectory`` — goes through the one :class:`~articutool.ros2.lanes.StopLane` this
server owns: one thread, and stops that wait share the next one to run, so no number of them
fills it. The service's queue is shared with no other request and is served by the safety
node's own executor thread, so no flood of other calls holds a stop back.
"""

from __future__ import annotations

from typing import Any

from articutool.ros2.lanes import StopLane
from articutool.ros2.serving import Side, outcome
from articutool.tool.api import Mode

__all__ = ["StopServer"]


class StopServer:
    """The stop service on ``side`` (the safety node) and :attr:`lane`, the stop lane every
    stop of ``client``'s tool goes through (each one counted in ``counters['stops']``)."""

    def __init__(self, client: Any, side: Side, name: str, counters: dict[str, int]) -> None:
        from std_srvs.srv import Trigger

        self._client, self._side, self._counters = client, side, counters
        self.lane = StopLane(self._stop_tool)
        side.node.create_service(Trigger, name, self._on_stop, qos_profile=side.qos,
                                 callback_group=side.group)

    def close(self) -> None:
        self.lane.close()

    def _stop_tool(self) -> tuple[bool, str]:
        self._counters["stops"] += 1
        return self._client.set_mode(Mode.DISABLED)

    async def _on_stop(self, _request: Any, response: Any) -> Any:
        future = self.lane.submit(self._side.wake)
        response.success, response.message = await outcome(future, "stop")
        return response
