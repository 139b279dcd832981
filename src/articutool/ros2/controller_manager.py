"""The upstream Articutool's controller manager as ADA and MoveIt call it:
``articutool/controller_manager/switch_controller`` and ``…/list_controllers``
(``controller_manager_msgs``, Humble layout), answered from a
:class:`~articutool.ros2.controllers.ControllerBook`.

The wrist picks its control law per command (a trajectory, a primitive, a mode), so a switch
changes only what ``list_controllers`` answers, with ros2_control's strictness. Bookkeeping
only: no link call, answered at once, the services drain their queues
(:mod:`articutool.ros2.intake`).
"""

from __future__ import annotations

from typing import Any

from articutool.ros2.controllers import ControllerBook
from articutool.ros2.intake import create_draining_service
from articutool.ros2.serving import Side

__all__ = ["ControllerManagerServer"]


class ControllerManagerServer:
    """``switch_controller`` and ``list_controllers`` on ``side`` (the main node) for the
    emulated controllers of the wrist's ``joint_names``."""

    def __init__(self, side: Side, names: dict[str, str], joint_names: tuple[str, str]) -> None:
        from controller_manager_msgs.srv import ListControllers, SwitchController

        self._book = ControllerBook(joint_names)
        create_draining_service(side.node, SwitchController, names["switch_controller"],
                                self._on_switch_controller, qos_profile=side.qos,
                                callback_group=side.group)
        create_draining_service(side.node, ListControllers, names["list_controllers"],
                                self._on_list_controllers, qos_profile=side.qos,
                                callback_group=side.group)

    def _on_switch_controller(self, request: Any, response: Any) -> Any:
        activate = [str(c) for c in (*request.activate_controllers,
                                     *getattr(request, "start_controllers", []))]
        deactivate = [str(c) for c in (*request.deactivate_controllers,
                                       *getattr(request, "stop_controllers", []))]
        response.ok, text = self._book.switch(activate, deactivate, int(request.strictness))
        if hasattr(response, "message"):
            response.message = text
        return response

    def _on_list_controllers(self, _request: Any, response: Any) -> Any:
        from controller_manager_msgs.msg import ControllerState
        response.controller = [ControllerState(**c) for c in self._book.listed()]
        return response
