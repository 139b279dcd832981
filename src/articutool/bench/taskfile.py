"""The Exp. 2a transport task file: a versioned JSON set of (start, goal) tasks (thesis §5.2.1).

The file records the seed, the generator version and short hashes of the spec and the scene
the tasks were made with (:func:`spec_hash`, :func:`scene_hash`); :func:`load_task_set`
validates it and names the field of any error (``tasks[3].start``), :func:`check_task_limits`
refuses a task joint outside the spec's limits, and :func:`save_task_set` writes one task per
line and never overwrites a file. Generation (IK filtering) is :mod:`articutool.bench.tasks`,
which re-exports these names.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from articutool.arm.scene import Scene
from articutool.datafile import format_validation_error, read_document
from articutool.planning.types import TransportTask
from articutool.spec import Spec

__all__ = [
    "FILE_FORMAT",
    "FILE_VERSION",
    "GENERATOR_VERSION",
    "TaskFileError",
    "TaskSet",
    "check_task_limits",
    "default_tasks_path",
    "load_task_set",
    "parse_task_set",
    "save_task_set",
    "scene_hash",
    "spec_hash",
]

FILE_FORMAT = "articutool.transport_tasks"
FILE_VERSION = 1
GENERATOR_VERSION = "1.0"


class TaskFileError(ValueError):
    """A transport task file is unreadable, malformed or of an unknown version."""


# ------------------------------------------------------------------ hashing --
def _digest(obj: Any) -> str:
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def spec_hash(spec: Spec) -> str:
    """Short SHA-256 of the spec sections tasks and plans depend on (canonical JSON).

    Arm, wrist, utensils and collision geometry; filter or controller gains do not change a
    task's validity, so editing them does not flag the task file as stale.
    """
    return _digest(spec.model_dump(mode="json", include={"arm", "wrist", "utensils",
                                                        "collision"}))


def scene_hash(scene: Scene) -> str:
    """Short SHA-256 of the scene's canonical JSON."""
    return _digest(scene.model_dump(mode="json"))


# ------------------------------------------------------------------- file --
Float = Annotated[float, Field(allow_inf_nan=False)]
Joints6 = tuple[Float, Float, Float, Float, Float, Float]
Wrist2 = tuple[Float, Float]


class _StrictModel(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)


class _TaskRecord(_StrictModel):
    task_id: Annotated[int, Field(ge=0, strict=True)]
    start: Joints6
    goal: Joints6
    start_wrist: Wrist2
    goal_wrist: Wrist2
    start_tip: tuple[Float, Float, Float, Float] | None = None  # x, y, z (m), heading (rad)
    goal_tip: tuple[Float, Float, Float, Float] | None = None
    source: str | None = None


class _TaskFile(_StrictModel):
    format: Literal["articutool.transport_tasks"]
    version: int
    generator_version: str
    seed: Annotated[int, Field(ge=0, strict=True)]
    candidates: Annotated[int, Field(ge=0, strict=True)]
    spec_hash: str
    scene_hash: str
    utensil: str
    ik_rejections: dict[str, Annotated[int, Field(ge=0)]] = Field(default_factory=dict)
    tasks: list[_TaskRecord]

    @model_validator(mode="after")
    def _unique_ids(self) -> _TaskFile:
        seen: set[int] = set()
        for i, t in enumerate(self.tasks):
            if t.task_id in seen:
                raise ValueError(f"tasks[{i}].task_id: duplicate task_id {t.task_id}")
            seen.add(t.task_id)
        return self


@dataclass(frozen=True)
class TaskSet:
    """A versioned, IK-filtered set of transport tasks (what the task file holds)."""

    tasks: tuple[TransportTask, ...]
    seed: int
    candidates: int
    spec_hash: str
    scene_hash: str
    utensil: str = "spoon"
    generator_version: str = GENERATOR_VERSION
    ik_rejections: dict[str, int] = field(default_factory=dict)
    extras: tuple[dict[str, Any], ...] = ()  # per task: tip targets and food source

    def to_dict(self) -> dict[str, Any]:
        """The JSON document (``version`` = :data:`FILE_VERSION`)."""
        tasks = []
        for i, t in enumerate(self.tasks):
            rec: dict[str, Any] = {
                "task_id": t.task_id, "start": list(t.start), "goal": list(t.goal),
                "start_wrist": list(t.start_wrist), "goal_wrist": list(t.goal_wrist),
            }
            if i < len(self.extras):
                rec.update(self.extras[i])
            tasks.append(rec)
        return {
            "format": FILE_FORMAT, "version": FILE_VERSION,
            "generator_version": self.generator_version, "seed": self.seed,
            "candidates": self.candidates, "spec_hash": self.spec_hash,
            "scene_hash": self.scene_hash, "utensil": self.utensil,
            "ik_rejections": dict(self.ik_rejections), "tasks": tasks,
        }

    @property
    def sha256(self) -> str:
        """Hash of the task content (ids, joints) — identifies the set in benchmark results."""
        return _digest([[t.task_id, t.start, t.goal, t.start_wrist, t.goal_wrist]
                        for t in self.tasks])


def default_tasks_path() -> Path:
    """The packaged benchmark set (``articutool/data/transport_tasks_v1.json``)."""
    return Path(str(resources.files("articutool") / "data" / "transport_tasks_v1.json"))


def parse_task_set(data: Any, source: str = "<dict>") -> TaskSet:
    """Validate a parsed task document; errors name the field (e.g. ``tasks[3].start``)."""
    if isinstance(data, dict) and "version" in data and data["version"] != FILE_VERSION:
        raise TaskFileError(f"invalid tasks file {source}:\n  version: unsupported "
                            f"{data['version']!r}; this articutool reads version {FILE_VERSION}")
    try:
        doc = _TaskFile.model_validate(data)
    except ValidationError as err:
        raise TaskFileError(format_validation_error(err, f"invalid tasks file {source}:")) from None
    tasks = tuple(TransportTask(t.task_id, tuple(t.start), tuple(t.goal), tuple(t.start_wrist),
                                tuple(t.goal_wrist)) for t in doc.tasks)
    extras = tuple(t.model_dump(include={"start_tip", "goal_tip", "source"}, exclude_none=True)
                   for t in doc.tasks)
    return TaskSet(tasks=tasks, seed=doc.seed, candidates=doc.candidates,
                   spec_hash=doc.spec_hash, scene_hash=doc.scene_hash, utensil=doc.utensil,
                   generator_version=doc.generator_version,
                   ik_rejections=dict(doc.ik_rejections), extras=extras)


def load_task_set(path: str | Path | None = None) -> TaskSet:
    """Read and validate a task file; ``None`` loads the packaged default."""
    p = Path(path) if path is not None else default_tasks_path()
    data = read_document(p, "tasks file", TaskFileError)
    return parse_task_set(data, str(p))


def check_task_limits(task_set: TaskSet, spec: Spec) -> None:
    """Raise :class:`TaskFileError` naming the first task joint outside the spec's limits.

    Such a task is bad input, not a planning problem: no trial may count it as a failure.
    """
    arm = [(j.name, j.lower, j.upper) for j in spec.arm.joints]
    wrist = [(n, lo, hi) for n, (lo, hi) in zip(spec.wrist.joint_names, spec.wrist.limits,
                                                strict=True)]
    for i, t in enumerate(task_set.tasks):
        for field_name, joints in (("start", arm), ("goal", arm), ("start_wrist", wrist),
                                   ("goal_wrist", wrist)):
            for j, (x, (name, lo, hi)) in enumerate(zip(getattr(t, field_name), joints,
                                                        strict=True)):
                if not lo <= x <= hi:
                    raise TaskFileError(
                        f"tasks[{i}].{field_name}[{j}] (task_id {t.task_id}) = {x:.4f} rad is "
                        f"outside the limits [{lo:.4f}, {hi:.4f}] rad of {name}")


def save_task_set(task_set: TaskSet, path: str | Path) -> None:
    """Write ``task_set`` as JSON; refuses to overwrite an existing file."""
    p = Path(path)
    doc = task_set.to_dict()
    tasks = doc.pop("tasks")
    # Header fields one per line, then one task per line: readable and diff-friendly.
    lines = ["{", *(f" {json.dumps(k)}: {json.dumps(v)}," for k, v in doc.items()), ' "tasks": [']
    lines += [f"  {json.dumps(t)}," for t in tasks]
    if tasks:
        lines[-1] = lines[-1][:-1]
    lines += [" ]", "}", ""]
    try:
        with p.open("x", encoding="utf-8") as f:
            f.write("\n".join(lines))
    except FileExistsError:
        raise TaskFileError(f"{p} exists; refusing to overwrite it") from None
    except OSError as err:
        raise TaskFileError(f"cannot write tasks file {p}: {err.strerror}") from None
