"""Arm models: the Jaco 2 + Articutool built with Pinocchio; the scene and collision with coal."""

from articutool.arm.model import (
    DOFS,
    TOOL_BASE_FRAME,
    UTENSIL_MOUNT_FRAME,
    ArmModel,
    tip_frame_name,
)
from articutool.arm.scene import Scene, SceneError, default_scene_path

__all__ = [
    "DOFS",
    "TOOL_BASE_FRAME",
    "UTENSIL_MOUNT_FRAME",
    "ArmModel",
    "Scene",
    "SceneError",
    "default_scene_path",
    "tip_frame_name",
]
