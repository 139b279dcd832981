"""The upstream Articutool's ros2_control controllers, as ``articutool ros2`` emulates them for
``switch_controller`` and ``list_controllers`` (``controller_manager_msgs``, Humble layout).

The wrist picks its control law per command (a trajectory enters TRAJECTORY, a primitive
PRIMITIVE, a mode DISABLED, LEVELING or FULL_ORIENTATION), so a switch changes no behaviour;
what it changes is the answer ``list_controllers`` gives, as a controller manager's would:
:class:`ControllerBook` keeps each emulated controller's state, starting as the upstream
launch leaves them (every controller spawned, so active), and applies a switch with
ros2_control's strictness: BEST_EFFORT skips unknown names and controllers already in the
asked state, STRICT refuses the whole switch for any of them and changes nothing. Pure.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["BEST_EFFORT", "CONTROLLERS", "STRICT", "ControllerBook", "Emulated"]

BEST_EFFORT, STRICT = 1, 2  # controller_manager_msgs/srv/SwitchController strictness


@dataclass(frozen=True)
class Emulated:
    """One upstream controller (``articutool_moveit/config/controllers.yaml``): its type and
    the interfaces it commands and reads, per joint."""

    name: str
    type: str
    command: str  # command interface ('' for a broadcaster)
    state: tuple[str, ...]  # state interfaces it requires


CONTROLLERS = (
    Emulated("velocity_controller", "velocity_controllers/JointGroupVelocityController",
             "velocity", ()),
    Emulated("joint_trajectory_controller",
             "joint_trajectory_controller/JointTrajectoryController", "position",
             ("position",)),
    Emulated("joint_state_broadcaster", "joint_state_broadcaster/JointStateBroadcaster", "",
             ("position", "velocity", "effort")),
)


class ControllerBook:
    """Each emulated controller's ros2_control state ('active' or 'inactive')."""

    def __init__(self, joint_names: tuple[str, str]) -> None:
        self.joints = tuple(joint_names)
        self.known = {c.name: c for c in CONTROLLERS}
        self.state = {c.name: "active" for c in CONTROLLERS}

    def switch(self, activate: list[str], deactivate: list[str], strictness: int
               ) -> tuple[bool, str]:
        """Apply a switch as ros2_control does; (ok, what happened)."""
        problems = [f"unknown controller {n!r}" for n in [*activate, *deactivate]
                    if n not in self.known]
        problems += [f"{n} is already active" for n in activate
                     if self.state.get(n) == "active"]
        problems += [f"{n} is already inactive" for n in deactivate
                     if self.state.get(n) == "inactive"]
        if problems and strictness == STRICT:
            return False, f"STRICT switch refused: {'; '.join(problems)}; nothing changed"
        for n in deactivate:
            if n in self.known:
                self.state[n] = "inactive"
        for n in activate:
            if n in self.known:
                self.state[n] = "active"
        note = f" (skipped: {'; '.join(problems)})" if problems else ""
        return True, ("switched (bookkeeping only: the wrist picks its control law per "
                      f"command){note}")

    def listed(self) -> list[dict[str, object]]:
        """``ControllerState`` fields of every emulated controller, as list_controllers
        answers: an active controller claims its command interfaces."""
        out = []
        for c in CONTROLLERS:
            command = [f"{j}/{c.command}" for j in self.joints] if c.command else []
            active = self.state[c.name] == "active"
            out.append({
                "name": c.name, "state": self.state[c.name], "type": c.type,
                "claimed_interfaces": command if active else [],
                "required_command_interfaces": command,
                "required_state_interfaces": [f"{j}/{s}" for j in self.joints
                                              for s in c.state],
                "is_chainable": False, "is_chained": False, "reference_interfaces": [],
            })
        return out
