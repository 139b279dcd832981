"""The tool's command surface: what the runtime offers and what the link serves.

``ToolRuntime`` (``articutool.tool.runtime``) implements ``ToolAPI``; the network link
(``articutool.link``) serves any ``ToolAPI`` so link tests can use a small fake. All methods
are thread-safe and return promptly: motion happens in the runtime's own 50 Hz loop.
Joint order everywhere is [pitch, roll]; angles in radians unless a name says ``_deg``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Protocol, runtime_checkable

from articutool.trajectory import JointTrajectory

__all__ = ["ABORTED_BY_MODE_CHANGE", "IDENTITY_XYZW", "SERVICE_MODES", "LinkWorkLoop", "Mode",
           "PrimitiveStatus", "ToolAPI",
           "ToolState", "TrajectoryPrevalidation"]

# How a primitive's result message starts when a mode change (a DISABLED from any client)
# aborted it, followed by the mode's name: a caller that did not ask for it was stopped.
ABORTED_BY_MODE_CHANGE = "aborted by mode change to "


class Mode(IntEnum):
    """Control modes; DISABLED, LEVELING and FULL_ORIENTATION are the ``SetOrientationControl``
    constants (``MODE_DISABLED``, ``MODE_LEVELING``, ``MODE_FULL_ORIENTATION``)."""

    DISABLED = 0
    LEVELING = 1
    FULL_ORIENTATION = 2
    PRIMITIVE = 3
    TRAJECTORY = 4


#: The identity quaternion [x, y, z, w]: ``target_orientation_robot_base`` when unused.
IDENTITY_XYZW = (0.0, 0.0, 0.0, 1.0)

#: The modes ``SetOrientationControl`` (``set_mode``) enters.
SERVICE_MODES = (Mode.DISABLED, Mode.LEVELING, Mode.FULL_ORIENTATION)


@dataclass(frozen=True)
class PrimitiveStatus:
    """Progress of the current (or last) primitive, as the action's feedback and result."""

    name: str
    percent_complete: float  # 0..100
    feedback: str
    current_joint_values: tuple[float, float]
    done: bool
    success: bool = False  # meaningful once done
    message: str = ""  # meaningful once done
    final_joint_values: tuple[float, ...] = ()  # meaningful once done


@dataclass(frozen=True)
class ToolState:
    """A snapshot of the tool for telemetry (published at the loop rate)."""

    stamp: float  # monotonic seconds
    mode: Mode
    joint_names: tuple[str, str]
    position: tuple[float, float]
    velocity: tuple[float, float]
    orientation_wxyz: tuple[float, float, float, float]  # filtered IMU, sensor in world
    angular_velocity: tuple[float, float, float]  # rad/s, sensor frame, bias-corrected
    linear_acceleration: tuple[float, float, float]  # m/s², sensor frame
    fault: str = ""  # empty when healthy; otherwise why the motors were stopped
    battery_voltage: float = float("nan")  # V, from the motors' input voltage
    loop_period_mean: float = float("nan")  # s
    loop_jitter: float = float("nan")  # s, standard deviation of the period
    loop_overruns: int = 0
    extra: dict[str, float] = field(default_factory=dict)


class ToolAPI(Protocol):
    """What the PC can ask of the tool (thesis §3.2.2: service, action, trajectories)."""

    def set_mode(
        self, mode: Mode, pitch_offset_deg: float = 0.0, roll_offset_deg: float = 0.0,
        target_xyzw: tuple[float, float, float, float] = IDENTITY_XYZW,
    ) -> tuple[bool, str]:
        """Switch mode (DISABLED, LEVELING with offsets, or FULL_ORIENTATION holding the
        utensil at ``target_xyzw``, [x, y, z, w] in a gravity-aligned robot base); aborts a
        running primitive."""
        ...

    def clear_fault(self) -> tuple[bool, str]:
        """Explicitly clear the fault (the only request that reboots faulted motors, and only
        once the cause is gone, e.g. an overheated motor has cooled); the mode stays DISABLED."""
        ...

    def start_primitive(self, name: str, parameters: list[float]) -> tuple[bool, str]:
        """Start a primitive; refused while leveling, while another runs, or on bad input."""
        ...

    def primitive_status(self) -> PrimitiveStatus | None:
        """Progress of the running primitive, or the result of the last one (None if never)."""
        ...

    def cancel_primitive(self) -> bool:
        """Cancel the running primitive (motors stop); False if none was running."""
        ...

    def follow_trajectory(
        self, trajectory: JointTrajectory, start_delay: float = 0.0
    ) -> tuple[bool, str]:
        """Enter TRAJECTORY mode and follow a wrist trajectory (joint names [pitch, roll]).

        ``start_delay`` (s) starts it that long after the call (a ``header.stamp`` in the
        future: ``stamp − now``), holding the present position until then; ≤ 0 starts now.
        """
        ...

    def state(self) -> ToolState:
        """The latest state snapshot."""
        ...


@runtime_checkable
class TrajectoryPrevalidation(Protocol):
    """A ``ToolAPI`` that also offers the trajectory checks that do not depend on the wrist's
    state (``ToolRuntime``, ``LoopProxy``): the link server runs them in its own thread, so
    the loop's tick only checks a trajectory against the present joints."""

    def prevalidate_trajectory(self, trajectory: JointTrajectory) -> JointTrajectory:
        """``trajectory`` checked (ValueError naming the limit), ready to follow."""
        ...


class LinkWorkLoop(Protocol):
    """A tool loop that runs a link's queued work once per tick, after the tick
    (``ToolRuntime.run``): a link server given one hands it its ``work_once``."""

    def set_link_work(self, work: Callable[[], None] | None) -> None:
        """Have the loop call ``work()`` once per tick; None detaches it."""
        ...
