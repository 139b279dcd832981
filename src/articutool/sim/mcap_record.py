"""MCAP recordings of the physics world (``articutool meal --record FILE.mcap``, experiment
trials): what the link would carry, plus the world's ground truth, as ROS 2 CDR messages.

In simulation the feeding tree calls the tool's API in-process (no link), so the recorder
writes, under the link's names (``/articutool/<tool_id>/…``, :class:`~articutool.link.
transport.Names`), the messages the link carries for the same traffic: every tool tick the
telemetry (``joint_states``, ``imu/data``, ``health``, ``battery``); every command as its
service request and response (``set_orientation_control``, ``clear_fault``), a primitive as
the action's ``send_goal`` request/response, ``feedback`` every tick while it runs and the
``get_result`` response when it ends (cancels as ``cancel_goal``); wrist trajectories on
``joint_trajectory``. The world adds ``/arm/joint_states`` (the Jaco's six joints, every
tick), ``/sim/food`` (mass per place, 10 Hz, and every spill so far) and ``/feeding/tree``
(every behaviour's status whenever one changes). All as ``diagnostic_msgs`` /
``sensor_msgs``, so standard tools plot them. Stamps and log times are the wall-clock start
plus simulated time.
"""

from __future__ import annotations

import time
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import py_trees

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.recording import McapRecorder
from articutool.link.transport import Names
from articutool.tool.api import Mode, PrimitiveStatus, ToolState

__all__ = ["WorldMcapRecorder"]

# DiagnosticStatus level: a FAILURE is often expected (a guard that finds nothing wrong): WARN.
_LEVEL = {py_trees.common.Status.FAILURE: 1, py_trees.common.Status.INVALID: 3}


class _RecordingTool:
    """The tool API as the tree sees it, recording each call as its link messages."""

    def __init__(self, api: Any, owner: WorldMcapRecorder) -> None:
        self._api, self._o = api, owner

    def __getattr__(self, name: str) -> Any:
        return getattr(self._api, name)

    def set_mode(self, mode: Mode, pitch_offset_deg: float = 0.0,
                 roll_offset_deg: float = 0.0) -> tuple[bool, str]:
        o, ep = self._o, self._o.names.set_orientation_control
        wire = mode in (Mode.DISABLED, Mode.LEVELING)  # the only modes the service has
        if wire:
            o.write(f"{ep.name}/request", ep.request_type,
                    m.soc_request(mode, pitch_offset_deg, roll_offset_deg))
        ok, msg = self._api.set_mode(mode, pitch_offset_deg, roll_offset_deg)
        if wire:
            o.write(f"{ep.name}/response", ep.response_type, m.soc_response(ok, msg))
        return ok, msg

    def clear_fault(self) -> tuple[bool, str]:
        o, ep = self._o, self._o.names.clear_fault
        o.write(f"{ep.name}/request", ep.request_type, m.trigger_request())
        ok, msg = self._api.clear_fault()
        o.write(f"{ep.name}/response", ep.response_type, m.trigger_response(ok, msg))
        return ok, msg

    def start_primitive(self, name: str, parameters: list[float]) -> tuple[bool, str]:
        o, n = self._o, self._o.names
        gid = uuid.uuid4().bytes
        o.write(f"{n.send_goal.name}/request", n.send_goal.request_type,
                m.send_goal_request(gid, name, list(parameters)))
        ok, msg = self._api.start_primitive(name, parameters)
        o.write(f"{n.send_goal.name}/response", n.send_goal.response_type,
                m.send_goal_response(True, o.stamp()))  # the link accepts, then reports
        if ok:
            o.goal = gid
        else:
            o.result(gid, m.PrimitiveResult(False, msg, (), m.GoalStatus.ABORTED))
        return ok, msg

    def cancel_primitive(self) -> bool:
        o, ep = self._o, self._o.names.cancel_goal
        gid = o.goal
        o.write(f"{ep.name}/request", ep.request_type, m.cancel_request(gid))
        started = self._api.cancel_primitive()
        if started:
            o.cancelled = gid
        goals = [(gid, o.stamp())] if started and gid is not None else []
        o.write(f"{ep.name}/response", ep.response_type,
                m.cancel_response(0 if goals else 1, goals))
        return started

    def follow_trajectory(self, trajectory: Any, *args: Any, **kw: Any) -> Any:
        o, ep = self._o, self._o.names.joint_trajectory
        out = self._api.follow_trajectory(trajectory, *args, **kw)
        o.write(ep.name, ep.type, m.trajectory_msg(trajectory, o.stamp()))
        return out


class WorldMcapRecorder:
    """Record a :class:`~articutool.sim.world.FeedingWorld` run into a new MCAP file.

    Install before the run (it wraps ``world.tool`` and adds a tick hook), add
    :attr:`tree_visitor` to the behaviour tree's visitors, and :meth:`close` at the end (also
    on Ctrl-C: the file is then complete). ``metadata`` goes into an MCAP metadata record.
    """

    def __init__(self, world: Any, path: str | Path, *, tool_id: str = "default",
                 metadata: dict[str, Any] | None = None, food_period_s: float = 0.1) -> None:
        self.rec = McapRecorder(path)
        self.world = world
        self.names = Names(tool_id=tool_id)
        self.tool_id = tool_id
        self.t0 = time.time()
        self.goal: bytes | None = None
        self.cancelled: bytes | None = None
        self._api = world.tool
        self._food_period = food_period_s
        self._next_food = 0.0
        self._spills = 0
        if metadata:
            self.rec.metadata("articutool", {k: str(v) for k, v in metadata.items()})
        world.tool = _RecordingTool(self._api, self)
        world.on_tick.append(self._on_tick)
        self.tree_visitor = _TreeStatus(self)

    def stamp(self) -> float:
        """Wall-clock start + simulated time (s)."""
        return self.t0 + float(self.world.time)

    def write(self, topic: str, typename: str, message: Any) -> None:
        """Record ``message`` now (simulated time)."""
        t = self.stamp()
        self.rec.write_msg(topic, typename, message, t)

    def result(self, gid: bytes, res: m.PrimitiveResult) -> None:
        """A goal's end: its ``get_result`` response and the action status."""
        n = self.names
        self.write(f"{n.get_result.name}/response", n.get_result.response_type,
                   m.result_msg(res))
        self.write(n.status.name, n.status.type, m.status_array([(gid, self.stamp(),
                                                                 res.status)]))

    def _on_tick(self, world: Any) -> None:
        t, n = self.stamp(), self.names
        st: ToolState = self._api.state()
        for ep, msg in ((n.joint_states, m.joint_state_msg(st, t)), (n.imu, m.imu_msg(st, t)),
                        (n.health, m.health_msg(st, t, {}, self.tool_id)),
                        (n.battery, m.battery_msg(st, t, self.tool_id))):
            self.rec.write_msg(ep.name, ep.type, msg, t)
        arm = cdr.msg(cdr.JOINT_STATE, header=m.header(t, "j2n6s200_link_base"),
                    name=list(world.layout.arm_joints),
                    position=np.asarray(world.arm_q, dtype=np.float64),
                    velocity=np.zeros(0), effort=np.zeros(0))
        self.rec.write_msg("/arm/joint_states", cdr.JOINT_STATE, arm, t)
        if self.goal is not None:
            self._goal_tick(self._api.primitive_status())
        if world.time >= self._next_food or len(world.ledger.spills) != self._spills:
            self._next_food = world.time + self._food_period
            self._food(world, t)

    def _goal_tick(self, ps: PrimitiveStatus | None) -> None:
        gid, n = self.goal, self.names
        if ps is None or gid is None:
            return
        if not ps.done:
            self.write(n.feedback.name, n.feedback.type, m.feedback_msg(gid, ps))
            return
        self.goal = None
        cancelled = not ps.success and self.cancelled == gid
        status = (m.GoalStatus.SUCCEEDED if ps.success else
                  m.GoalStatus.CANCELED if cancelled else m.GoalStatus.ABORTED)
        self.result(gid, m.PrimitiveResult(ps.success, ps.message, ps.final_joint_values,
                                           status))

    def _food(self, world: Any, t: float) -> None:
        kv = [cdr.msg("diagnostic_msgs/msg/KeyValue", key=f"{k}_g", value=repr(v))
              for k, v in world.ledger.masses_g().items()]
        sts = [cdr.msg("diagnostic_msgs/msg/DiagnosticStatus", level=0, name="food: mass per place",
                     message=world.food, hardware_id="sim", values=kv)]
        for s in world.ledger.spills:
            sts.append(cdr.msg("diagnostic_msgs/msg/DiagnosticStatus", level=1,
                             name=f"food: spill of item {s.item}", message=s.place,
                             hardware_id="sim", values=[
                                 cdr.msg("diagnostic_msgs/msg/KeyValue", key=k, value=str(v))
                                 for k, v in (("t", s.t), ("mass_g", s.mass_g),
                                              ("where", s.where))]))
        self._spills = len(world.ledger.spills)
        self.rec.write_msg("/sim/food", cdr.DIAGNOSTIC_ARRAY,
                           cdr.msg(cdr.DIAGNOSTIC_ARRAY, header=m.header(t), status=sts), t)

    def close(self) -> None:
        """Restore the world's tool API, stop recording and finish the file."""
        if self.world.tool is not self._api:
            self.world.tool = self._api
        if self._on_tick in self.world.on_tick:
            self.world.on_tick.remove(self._on_tick)
        self.rec.close()


class _TreeStatus(py_trees.visitors.VisitorBase):
    """Records every visited behaviour's status on ``/feeding/tree`` when any changed, with
    its feedback message (why a guard stopped the bite, why a step failed) as the value
    ``feedback`` when it has one."""

    def __init__(self, owner: WorldMcapRecorder) -> None:
        super().__init__(full=False)
        self.o = owner
        self.now: dict[str, tuple[str, str]] = {}
        self.last: dict[str, tuple[str, str]] = {}

    def initialise(self) -> None:
        self.now = {}

    def run(self, behaviour: py_trees.behaviour.Behaviour) -> None:
        path, node = [behaviour.name], behaviour.parent
        while node is not None:
            path.append(node.name)
            node = node.parent
        self.now[" / ".join(reversed(path))] = (behaviour.status.name,
                                                str(behaviour.feedback_message or ""))

    def finalise(self) -> None:
        if self.now == self.last or self.o.rec.closed:
            return
        self.last = dict(self.now)
        sts = [cdr.msg("diagnostic_msgs/msg/DiagnosticStatus",
                      level=_LEVEL.get(py_trees.common.Status[s], 0), name=name, message=s,
                      hardware_id="feeding tree",
                      values=[cdr.msg("diagnostic_msgs/msg/KeyValue", key="feedback", value=fb)]
                      if fb else [])
               for name, (s, fb) in self.now.items()]
        t = self.o.stamp()
        self.o.rec.write_msg("/feeding/tree", cdr.DIAGNOSTIC_ARRAY,
                             cdr.msg(cdr.DIAGNOSTIC_ARRAY, header=m.header(t), status=sts), t)
