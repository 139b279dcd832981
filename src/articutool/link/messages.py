"""Link message definitions, ROS 2 CDR codecs and conversions to articutool types.

The Articutool interfaces mirror the original ROS 2 package ``articutool_interfaces``
(thesis §3.2.2: a service sets the control mode, an action runs a primitive with feedback,
joint trajectories stream to the wrist). Telemetry uses standard types only:
``sensor_msgs/JointState`` (joint order [pitch, roll]), ``sensor_msgs/Imu`` (filtered
orientation), ``diagnostic_msgs/DiagnosticArray`` (loop health, fault, mode, link counters),
``sensor_msgs/BatteryState`` (motor input voltage) and ``std_msgs/Header`` as a heartbeat.

Payloads are serialised with ``rosbags`` as ROS 2 CDR (:mod:`articutool.link.cdr`: the type
names, the interfaces parsed from the ROS 2 package beside it, ``encode``/``decode``).
Every decoder raises :class:`LinkDecodeError` on malformed input (never
another exception type), so a receiver can count and drop bad payloads. This module is pure.
"""

from __future__ import annotations

import math
import uuid
from dataclasses import dataclass
from typing import Any

import numpy as np

from articutool.link.cdr import (
    ACTION,
    BATTERY_STATE,
    CANCEL_GOAL,
    DIAGNOSTIC_ARRAY,
    FEEDBACK_MESSAGE,
    GET_RESULT,
    GOAL_STATUS_ARRAY,
    HEADER,
    IMU,
    JOINT_STATE,
    JOINT_TRAJECTORY,
    SEND_GOAL,
    SET_ORIENTATION_CONTROL,
    TRIGGER,
    LinkDecodeError,
    msg,
)
from articutool.tool.api import IDENTITY_XYZW, SERVICE_MODES, Mode, PrimitiveStatus, ToolState
from articutool.trajectory import JointTrajectory, TrajectoryError

__all__ = ["GoalStatus", "PrimitiveResult", "goal_uuid", "stamp_to_time", "time_to_stamp"]


class GoalStatus:
    """``action_msgs/msg/GoalStatus`` status constants."""

    UNKNOWN = 0
    ACCEPTED = 1
    EXECUTING = 2
    CANCELING = 3
    SUCCEEDED = 4
    CANCELED = 5
    ABORTED = 6
    TERMINAL = frozenset({4, 5, 6})


@dataclass(frozen=True)
class PrimitiveResult:
    """The action result plus the terminal goal status (a ``GoalStatus`` constant)."""

    success: bool
    message: str
    final_joint_values: tuple[float, ...]
    status: int = GoalStatus.UNKNOWN

    def to_dict(self) -> dict[str, Any]:
        """The JSON form the CLI prints: exactly the action result's fields."""
        return {"success": self.success, "message": self.message,
                "final_joint_values": list(self.final_joint_values)}


# ----------------------------------------------------------------- helpers --
def time_to_stamp(t: float) -> Any:
    """Seconds (float, e.g. ``time.time()``) → ``builtin_interfaces/Time``."""
    sec = math.floor(t)
    nsec = min(round((t - sec) * 1e9), 999_999_999)
    return msg("builtin_interfaces/msg/Time", sec=sec, nanosec=nsec)


def stamp_to_time(stamp: Any) -> float:
    """``builtin_interfaces/Time`` → seconds."""
    return float(stamp.sec) + float(stamp.nanosec) * 1e-9


def header(t: float, frame_id: str = "") -> Any:
    """A ``std_msgs/Header``."""
    return msg(HEADER, stamp=time_to_stamp(t), frame_id=frame_id)


def goal_uuid(goal_id: bytes | None = None) -> Any:
    """A ``unique_identifier_msgs/UUID`` (random when ``goal_id`` is None)."""
    raw = uuid.uuid4().bytes if goal_id is None else bytes(goal_id)
    if len(raw) != 16:
        raise ValueError(f"goal_id must be 16 bytes; got {len(raw)}")
    return msg("unique_identifier_msgs/msg/UUID", uuid=np.frombuffer(raw, dtype=np.uint8).copy())


def uuid_bytes(u: Any) -> bytes:
    """The 16 raw bytes of a ``unique_identifier_msgs/UUID``."""
    return bytes(np.asarray(u.uuid, dtype=np.uint8).tobytes())


def _f32(values: Any) -> Any:
    return np.asarray(list(values), dtype=np.float32)


# ------------------------------------------------------------- service/action --
def soc_request(mode: Mode, pitch_offset_deg: float, roll_offset_deg: float,
                target_xyzw: tuple[float, float, float, float] = IDENTITY_XYZW) -> Any:
    """``SetOrientationControl`` request: DISABLED, LEVELING (offsets in degrees) or
    FULL_ORIENTATION (``target_orientation_robot_base`` = ``target_xyzw``, [x, y, z, w])."""
    if mode not in SERVICE_MODES:
        raise ValueError("control_mode must be DISABLED (0), LEVELING (1) or FULL_ORIENTATION "
                         f"(2); got {mode!r}")
    for name, v in (("pitch_offset", pitch_offset_deg), ("roll_offset", roll_offset_deg)):
        if not math.isfinite(v):
            raise ValueError(f"{name} must be a finite number of degrees; got {v}")
    x, y, z, w = (float(v) for v in target_xyzw)
    if not all(math.isfinite(v) for v in (x, y, z, w)):
        raise ValueError(f"target_orientation_robot_base must be finite; got {target_xyzw}")
    return msg(f"{SET_ORIENTATION_CONTROL}_Request", control_mode=int(mode),
               pitch_offset=float(pitch_offset_deg), roll_offset=float(roll_offset_deg),
               target_orientation_robot_base=msg("geometry_msgs/msg/Quaternion", x=x, y=y,
                                                 z=z, w=w))


def soc_response(success: bool, message: str) -> Any:
    """``SetOrientationControl`` response."""
    return msg(f"{SET_ORIENTATION_CONTROL}_Response", success=bool(success), message=message)


def trigger_request() -> Any:
    """``std_srvs/Trigger`` request (no fields)."""
    return msg(f"{TRIGGER}_Request", structure_needs_at_least_one_member=0)


def trigger_response(success: bool, message: str) -> Any:
    """``std_srvs/Trigger`` response."""
    return msg(f"{TRIGGER}_Response", success=bool(success), message=message)


def send_goal_request(goal_id: bytes, name: str, parameters: list[float]) -> Any:
    """Action ``SendGoal`` request."""
    goal = msg(f"{ACTION}_Goal", primitive_name=name, parameters=_f32(parameters))
    return msg(f"{SEND_GOAL}_Request", goal_id=goal_uuid(goal_id), goal=goal)


def send_goal_response(accepted: bool, t: float) -> Any:
    """Action ``SendGoal`` response."""
    return msg(f"{SEND_GOAL}_Response", accepted=bool(accepted), stamp=time_to_stamp(t))


def result_msg(result: PrimitiveResult) -> Any:
    """Action ``GetResult`` response for ``result``."""
    r = msg(f"{ACTION}_Result", success=result.success, message=result.message,
            final_joint_values=_f32(result.final_joint_values))
    return msg(f"{GET_RESULT}_Response", status=int(result.status), result=r)


def result_from_msg(m: Any) -> PrimitiveResult:
    """``GetResult`` response → PrimitiveResult."""
    r = m.result
    return PrimitiveResult(bool(r.success), str(r.message),
                           tuple(float(x) for x in r.final_joint_values), int(m.status))


def feedback_msg(goal_id: bytes, status: PrimitiveStatus) -> Any:
    """Action feedback message from a PrimitiveStatus."""
    fb = msg(f"{ACTION}_Feedback", feedback_string=status.feedback,
             percent_complete=float(status.percent_complete),
             current_joint_values=_f32(status.current_joint_values))
    return msg(FEEDBACK_MESSAGE, goal_id=goal_uuid(goal_id), feedback=fb)


def status_array(goals: list[tuple[bytes, float, int]]) -> Any:
    """``GoalStatusArray`` from (goal_id, accept time, status) triples."""
    items = [msg("action_msgs/msg/GoalStatus",
                 goal_info=msg("action_msgs/msg/GoalInfo", goal_id=goal_uuid(g),
                               stamp=time_to_stamp(t)), status=int(s))
             for g, t, s in goals]
    return msg(GOAL_STATUS_ARRAY, status_list=items)


def cancel_request(goal_id: bytes | None) -> Any:
    """``CancelGoal`` request; ``None`` cancels all goals (zero id, zero stamp)."""
    info = msg("action_msgs/msg/GoalInfo", goal_id=goal_uuid(goal_id or bytes(16)),
               stamp=time_to_stamp(0.0))
    return msg(f"{CANCEL_GOAL}_Request", goal_info=info)


def cancel_response(return_code: int, goals: list[tuple[bytes, float]]) -> Any:
    """``CancelGoal`` response."""
    infos = [msg("action_msgs/msg/GoalInfo", goal_id=goal_uuid(g), stamp=time_to_stamp(t))
             for g, t in goals]
    return msg(f"{CANCEL_GOAL}_Response", return_code=int(return_code), goals_canceling=infos)


# ----------------------------------------------------------------- telemetry --
def joint_state_msg(state: ToolState, t: float) -> Any:
    """``sensor_msgs/JointState`` ([pitch, roll]; effort left empty)."""
    return msg(JOINT_STATE, header=header(t, "articutool"), name=list(state.joint_names),
               position=np.asarray(state.position, dtype=np.float64),
               velocity=np.asarray(state.velocity, dtype=np.float64),
               effort=np.zeros(0, dtype=np.float64))


def imu_msg(state: ToolState, t: float, frame_id: str = "atool_imu_frame") -> Any:
    """``sensor_msgs/Imu`` carrying the filtered orientation (covariances unknown → 0)."""
    w, x, y, z = state.orientation_wxyz
    return msg(IMU, header=header(t, frame_id),
               orientation=msg("geometry_msgs/msg/Quaternion", x=x, y=y, z=z, w=w),
               orientation_covariance=np.zeros(9),
               angular_velocity=msg("geometry_msgs/msg/Vector3", x=state.angular_velocity[0],
                                    y=state.angular_velocity[1], z=state.angular_velocity[2]),
               angular_velocity_covariance=np.zeros(9),
               linear_acceleration=msg("geometry_msgs/msg/Vector3",
                                       x=state.linear_acceleration[0],
                                       y=state.linear_acceleration[1],
                                       z=state.linear_acceleration[2]),
               linear_acceleration_covariance=np.zeros(9))


HEALTH_NAME = "articutool: control loop"


def health_msg(state: ToolState, t: float, link_counters: dict[str, int],
               tool_id: str = "articutool", lease_holder: str = "") -> Any:
    """``DiagnosticArray`` with one status: OK, WARN while leveling is stalled, or ERROR with
    the fault as message; ``hardware_id`` is the tool's identity, ``lease_holder`` the
    commanding client."""
    values = {"mode": state.mode.name, "lease_holder": lease_holder,
              "loop_period_mean": repr(state.loop_period_mean),
              "loop_jitter": repr(state.loop_jitter), "loop_overruns": str(state.loop_overruns),
              "fault": state.fault}
    values.update({k: repr(v) for k, v in state.extra.items()})
    values.update({f"link_{k}": str(v) for k, v in link_counters.items()})
    kvs = [msg("diagnostic_msgs/msg/KeyValue", key=k, value=v) for k, v in values.items()]
    stalled = state.extra.get("leveling_stalled", 0.0) == 1.0
    level = 2 if state.fault else 1 if stalled else 0  # DiagnosticStatus.ERROR / WARN / OK
    text = state.fault or ("leveling stalled short of level" if stalled else "OK")
    st = msg("diagnostic_msgs/msg/DiagnosticStatus", level=level, name=HEALTH_NAME,
             message=text, hardware_id=tool_id, values=kvs)
    return msg(DIAGNOSTIC_ARRAY, header=header(t), status=[st])


def battery_msg(state: ToolState, t: float, tool_id: str = "articutool") -> Any:
    """``sensor_msgs/BatteryState`` with the motors' input voltage (other fields unknown);
    ``serial_number`` is the tool's identity."""
    nan = float("nan")
    return msg(BATTERY_STATE, header=header(t), voltage=state.battery_voltage,
               temperature=nan, current=nan, charge=nan, capacity=nan, design_capacity=nan,
               percentage=nan, power_supply_status=0, power_supply_health=0,
               power_supply_technology=0, present=math.isfinite(state.battery_voltage),
               cell_voltage=np.zeros(0, dtype=np.float32),
               cell_temperature=np.zeros(0, dtype=np.float32), location="articutool",
               serial_number=tool_id)


def _fl(s: str) -> float:
    try:
        return float(s)
    except ValueError:
        return float("nan")


def state_from_msgs(js: Any, imu: Any | None, health: Any | None, battery: Any | None,
                    stamp: float) -> ToolState:
    """Rebuild a ToolState (``stamp`` = local receive time) from the telemetry messages.

    Raises LinkDecodeError when the joint state does not hold exactly two joints.
    """
    if len(js.name) != 2 or len(js.position) != 2:
        raise LinkDecodeError(f"{JOINT_STATE}: expected 2 joints [pitch, roll]; got {js.name}")
    vel = tuple(float(v) for v in js.velocity) if len(js.velocity) == 2 else (0.0, 0.0)
    quat, gyro, acc = (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    if imu is not None:
        o, g, a = imu.orientation, imu.angular_velocity, imu.linear_acceleration
        quat, gyro, acc = (o.w, o.x, o.y, o.z), (g.x, g.y, g.z), (a.x, a.y, a.z)
    kv: dict[str, str] = {}
    if health is not None:
        for st in health.status:
            if st.name == HEALTH_NAME:
                kv = {k.key: k.value for k in st.values}
    mode = Mode.__members__.get(kv.get("mode", ""), Mode.DISABLED)
    known = {"mode", "loop_period_mean", "loop_jitter", "loop_overruns", "fault",
             "lease_holder"}
    extra = {k: _fl(v) for k, v in kv.items() if k not in known}
    return ToolState(
        stamp=stamp, mode=mode, joint_names=(str(js.name[0]), str(js.name[1])),
        position=(float(js.position[0]), float(js.position[1])), velocity=vel,
        orientation_wxyz=tuple(float(v) for v in quat),  # type: ignore[arg-type]
        angular_velocity=tuple(float(v) for v in gyro),  # type: ignore[arg-type]
        linear_acceleration=tuple(float(v) for v in acc),  # type: ignore[arg-type]
        fault=kv.get("fault", ""),
        battery_voltage=float(battery.voltage) if battery is not None else float("nan"),
        loop_period_mean=_fl(kv.get("loop_period_mean", "nan")),
        loop_jitter=_fl(kv.get("loop_jitter", "nan")),
        loop_overruns=int(_fl(kv.get("loop_overruns", "0")) or 0), extra=extra)


# -------------------------------------------------------------- trajectories --
def trajectory_msg(traj: JointTrajectory, t: float = 0.0) -> Any:
    """articutool JointTrajectory → ``trajectory_msgs/JointTrajectory``."""
    pts = []
    for ti, q, v in zip(traj.times, traj.positions, traj.velocities, strict=True):
        sec = math.floor(ti)
        nsec = min(round((ti - sec) * 1e9), 999_999_999)
        pts.append(msg("trajectory_msgs/msg/JointTrajectoryPoint",
                       # contiguous: the CDR serialiser views the buffer (a wrist part sliced
                       # out of a longer path is strided)
                       positions=np.ascontiguousarray(q, dtype=np.float64),
                       velocities=np.ascontiguousarray(v, dtype=np.float64),
                       accelerations=np.zeros(0), effort=np.zeros(0),
                       time_from_start=msg("builtin_interfaces/msg/Duration", sec=int(sec),
                                           nanosec=nsec)))
    return msg(JOINT_TRAJECTORY, header=header(t), joint_names=list(traj.joint_names),
               points=pts)


def trajectory_from_msg(m: Any) -> JointTrajectory:
    """``trajectory_msgs/JointTrajectory`` → articutool JointTrajectory.

    Missing velocities (an empty array, allowed by ROS) become zeros. Raises
    LinkDecodeError when the message is inconsistent (TrajectoryError names the field).
    """
    try:
        n = len(m.joint_names)
        times, pos, vel = [], [], []
        for i, p in enumerate(m.points):
            times.append(float(p.time_from_start.sec) + float(p.time_from_start.nanosec) * 1e-9)
            if len(p.positions) != n:
                raise TrajectoryError(f"points[{i}].positions must have {n} values")
            pos.append(np.asarray(p.positions, dtype=float))
            v = np.asarray(p.velocities, dtype=float)
            if v.size == 0:
                v = np.zeros(n)
            if v.size != n:
                raise TrajectoryError(f"points[{i}].velocities must have {n} values or none")
            vel.append(v)
        if not times:
            raise TrajectoryError("points must be a non-empty list")
        return JointTrajectory(tuple(str(s) for s in m.joint_names), np.array(times),
                               np.array(pos), np.array(vel))
    except TrajectoryError as err:
        raise LinkDecodeError(f"{JOINT_TRAJECTORY}: {err}") from None


def heartbeat_msg(t: float, sender: str) -> Any:
    """Heartbeat: a ``std_msgs/Header`` whose frame_id names the sender."""
    return header(t, sender)

