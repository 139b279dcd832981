"""The planning scene: named collision primitives in the arm base frame (docs/hardware.md §2).

The packaged default ``articutool/data/scene.toml`` is the seated-user feeding scene (table,
plate, bowl, the user's head and torso, the wheelchair, the ground). ``Scene.load(path)``
reads another file of the same shape. Each object is one primitive with a pose ``xyz`` (m)
plus either ``rpy`` (URDF fixed-axis roll-pitch-yaw, rad) or ``wxyz`` (unit quaternion):

========== ======================== ==========================================
shape      size fields              geometry in the object's frame
========== ======================== ==========================================
box        ``size = [x, y, z]``     centred box, full side lengths
sphere     ``radius``               centred sphere
capsule    ``radius``, ``length``   axis along z, ``length`` between the caps
cylinder   ``radius``, ``length``   axis along z, centred
halfspace  (none)                   solid below the xy-plane (free side is +z)
========== ======================== ==========================================

``utensil_contact = true`` marks objects the utensil is meant to touch (plate, bowl: food
acquisition); the arm and the wrist are still checked against them.
"""

from __future__ import annotations

import functools
import math
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

import coal
import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from articutool.datafile import Finite, Positive, StrictModel, Vec3, read_document
from articutool.rotations import quaternion_to_matrix, rpy_matrix

__all__ = [
    "SCOOP_HEADING",
    "Box",
    "Capsule",
    "Cylinder",
    "Halfspace",
    "Region",
    "Scene",
    "SceneError",
    "SceneObject",
    "Sphere",
    "StagingGoal",
    "StagingSet",
    "container_floor",
    "default_scene_path",
]

# The direction the utensil's tip points while scooping, in the arm base frame of the default
# scene: −y (towards the table's front edge, away from the user), so the wrist stays on the
# arm's side of the bowl. Pointing away from the arm, a level utensil at the bowl is out of the
# Jaco's reach (Pinocchio IK from 23 starts found none). The scripted scenes (sim/scenes.py)
# and the feeding tree both read it here. Not in scene.toml: the experiments' data hash covers
# that file, and adding a field would refuse to resume every recorded run.
SCOOP_HEADING = np.array([0.0, -1.0, 0.0])
SCOOP_HEADING.flags.writeable = False


class SceneError(ValueError):
    """A scene file is missing, malformed or holds an invalid object."""


class _Object(StrictModel):
    name: Annotated[str, Field(min_length=1)]
    xyz: Vec3 = (0.0, 0.0, 0.0)
    rpy: Vec3 | None = None
    wxyz: tuple[Finite, Finite, Finite, Finite] | None = None
    utensil_contact: bool = False
    # Spill accounting in the physics world (articutool.sim): food resting here is back in a
    # container, a non-critical spill (table) or a critical one (the user, wheelchair, floor).
    place: Literal["container", "table", "critical"] | None = None

    @model_validator(mode="after")
    def _one_orientation(self) -> _Object:
        if self.rpy is not None and self.wxyz is not None:
            raise ValueError("give either rpy or wxyz, not both")
        if self.wxyz is not None:
            n = math.sqrt(sum(c * c for c in self.wxyz))
            if abs(n - 1.0) > 1e-3:
                raise ValueError(f"wxyz must be a unit quaternion (norm {n:.4f})")
        return self

    @property
    def rotation(self) -> NDArray[np.float64]:
        """Orientation of the object frame in the arm base frame, (3, 3)."""
        if self.wxyz is not None:
            return quaternion_to_matrix(self.wxyz)
        return rpy_matrix(self.rpy if self.rpy is not None else (0.0, 0.0, 0.0))

    @property
    def pose(self) -> NDArray[np.float64]:
        """Homogeneous pose (4, 4) of the object frame in the arm base frame."""
        T = np.eye(4)
        T[:3, :3] = self.rotation
        T[:3, 3] = self.xyz
        return T

    def geometry(self) -> coal.CollisionGeometry:
        """The coal primitive of this object, in its own frame."""
        raise NotImplementedError  # every concrete shape overrides this


class Box(_Object):
    """Axis-aligned (in its own frame) box with full side lengths ``size``."""

    shape: Literal["box"]
    size: tuple[Positive, Positive, Positive]

    def geometry(self) -> coal.CollisionGeometry:
        return coal.Box(*self.size)


class Sphere(_Object):
    """Sphere of ``radius`` around the object origin."""

    shape: Literal["sphere"]
    radius: Positive

    def geometry(self) -> coal.CollisionGeometry:
        return coal.Sphere(self.radius)


class Capsule(_Object):
    """Capsule along the object's z axis; ``length`` is the cylinder part between the caps."""

    shape: Literal["capsule"]
    radius: Positive
    length: Positive

    def geometry(self) -> coal.CollisionGeometry:
        return coal.Capsule(self.radius, self.length)


class Cylinder(_Object):
    """Cylinder along the object's z axis, centred on the origin.

    ``container_wall``: in the physics world (``articutool.sim``) the cylinder is an open
    container (a bowl) with a floor and a wall this thick; planning treats it as solid.
    """

    shape: Literal["cylinder"]
    radius: Positive
    length: Positive
    container_wall: Positive | None = None

    def geometry(self) -> coal.CollisionGeometry:
        return coal.Cylinder(self.radius, self.length)

    def inner_floor(self) -> NDArray[np.float64]:
        """Centre of the open container's inner floor, in the scene's frame (the arm base);
        ``ValueError`` for a solid cylinder."""
        if self.container_wall is None:
            raise ValueError(f"{self.name}: a solid cylinder (no container_wall) has no inner "
                             "floor")
        return np.array([self.xyz[0], self.xyz[1],
                         self.xyz[2] - self.length / 2 + self.container_wall])


class Halfspace(_Object):
    """Everything below the object's xy-plane (e.g. the ground); the free side is +z."""

    shape: Literal["halfspace"]

    def geometry(self) -> coal.CollisionGeometry:
        return coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)


SceneObject = Annotated[Box | Sphere | Capsule | Cylinder | Halfspace, Field(discriminator="shape")]


class Region(BaseModel):
    """A named spherical region that is not an obstacle, e.g. the user's mouth: food that
    enters it is taken as eaten in the physics world (``articutool.sim``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: Annotated[str, Field(min_length=1)]
    xyz: Vec3
    radius: Positive


Joints6 = Annotated[list[Finite], Field(min_length=6, max_length=6)]


class StagingGoal(BaseModel):
    """One named Staging goal: arm joint configuration (rad, joints 1..6)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: Annotated[str, Field(min_length=1)]
    q: Joints6
    note: str = ""


class StagingSet(BaseModel):
    """The thesis' Exp. 2b transport set (§5.2.2, Fig. 5.2): a common start and diverse
    Staging goals, all arm joint configurations (rad) at which the locked (rigid) utensil is
    level, so that both the Articutool and the rigid baseline can start and end there."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    start: Joints6
    goals: list[StagingGoal] = Field(min_length=1)

    @model_validator(mode="after")
    def _unique(self) -> StagingSet:
        names = [g.name for g in self.goals]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"duplicate staging goal name(s) {sorted(dup)}")
        return self

    def goal(self, name: str) -> list[float]:
        """The named goal's configuration; unknown names list the known ones."""
        for g in self.goals:
            if g.name == name:
                return list(g.q)
        raise KeyError(f"unknown staging goal {name!r}; known: {[g.name for g in self.goals]}")


@functools.cache
def default_scene_path() -> Path:
    """Path of the scene shipped with the package (looked up once: the planners stat it on
    every plan)."""
    return Path(str(resources.files("articutool") / "data" / "scene.toml"))


def _format_errors(err: ValidationError, raw: Any, source: str) -> str:
    objects = raw.get("objects") if isinstance(raw, dict) else None
    lines = [f"invalid scene {source}:"]
    for e in err.errors():
        loc = list(e["loc"])
        msg = e["msg"].removeprefix("Value error, ")
        where = ".".join(str(p) for p in loc) or "(top level)"
        if len(loc) >= 2 and loc[0] == "objects" and isinstance(loc[1], int):
            i = loc[1]
            item = objects[i] if isinstance(objects, list) and i < len(objects) else None
            name = item.get("name") if isinstance(item, dict) else None
            rest = loc[2:]
            # Drop the discriminator tag pydantic puts in the location of a union member.
            if rest and isinstance(item, dict) and rest[0] == item.get("shape"):
                rest = rest[1:]
            field = ".".join(str(p) for p in rest) or "(object)"
            label = f"object {name!r}" if name else f"object #{i}"
            where = f"{label} (objects[{i}]) field {field}"
        lines.append(f"  {where}: {msg}")
    return "\n".join(lines)


class Scene(BaseModel):
    """A validated set of uniquely named collision objects in the arm base frame."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    version: Annotated[int, Field(ge=1, le=1)] = 1
    frame: str = "j2n6s200_link_base"
    objects: list[SceneObject] = Field(default_factory=list)
    regions: list[Region] = Field(default_factory=list)
    staging_set: StagingSet | None = None

    @model_validator(mode="after")
    def _unique(self) -> Scene:
        seen: set[str] = set()
        for o in [*self.objects, *self.regions]:
            if o.name in seen:
                raise ValueError(f"duplicate object name {o.name!r}")
            seen.add(o.name)
        return self

    @property
    def names(self) -> list[str]:
        """Object names in file order."""
        return [o.name for o in self.objects]

    def region(self, name: str) -> Region:
        """The named region (e.g. ``"mouth"``); unknown names list the known ones."""
        for r in self.regions:
            if r.name == name:
                return r
        raise KeyError(f"unknown scene region {name!r}; known: {[r.name for r in self.regions]}")

    def get(self, name: str) -> _Object:
        """The named object; unknown names list the known ones."""
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(f"unknown scene object {name!r}; known: {self.names}")

    @classmethod
    def from_dict(cls, data: Any, source: str = "<dict>") -> Scene:
        """Validate a scene given as a mapping (e.g. parsed TOML); errors name object and field."""
        try:
            return cls.model_validate(data)
        except ValidationError as err:
            raise SceneError(_format_errors(err, data, source)) from None

    @classmethod
    def load(cls, path: str | Path | None = None) -> Scene:
        """Load and validate a scene file; ``None`` loads the packaged default."""
        p = Path(path) if path is not None else default_scene_path()
        data = read_document(p, "scene", SceneError)
        return cls.from_dict(data, str(p))


def container_floor(scene: Scene, container: str) -> NDArray[np.float64]:
    """Centre of the container's inner floor (arm base frame)."""
    box = scene.get(container)
    if not isinstance(box, Cylinder) or box.container_wall is None:
        raise ValueError(f"container: {container!r} is not an open container of the scene")
    return box.inner_floor()
