"""Recordings of the physics world: what :class:`Recorder` writes and :class:`Recording` reads.

Attach a recorder to any :class:`~articutool.sim.world.FeedingWorld` run (a scripted scene, a
bite, an experiment trial), then save it::

    from articutool.sim.recording import Recorder
    rec = Recorder(world)           # samples every tool tick (world.on_tick) at rate_hz
    ...                             # run the world: scripts, trees, primitives
    rec.save("run.npz")             # never overwrites: RecordingError if the file exists

The file is one compressed NumPy archive (``numpy.savez_compressed``, no pickled objects,
readable with ``numpy.load(path)`` alone). T frames, I food items, P food points:

============== ================ ==========================================================
key            shape / dtype    content
============== ================ ==========================================================
``meta``       0-d str          JSON: ``format`` = "articutool-recording", ``version`` = 1,
                                food, utensil, seed, load (placed load?), rate_hz, spec_version,
                                ``joint_names`` (the 8 of ``q``), ``modes`` (tool mode names
                                by value), ``class_names`` (food classes by code),
                                ``food_kind`` ("pieces" | "strands" | "none"),
                                ``strand_vertices`` (points per strand), ``point_radius`` (m),
                                ``food_rgba``, ``spills`` (below), ``extra`` (caller's dict)
``mjcf``       0-d str          the world's MJCF: the exact model that was recorded
``t``          (T,) float64     simulation time (s)
``q``          (T, 8) float64   arm joints 1..6, wrist pitch, roll: ground truth (rad)
``qpos``       (T, nq) float32  MuJoCo ``qpos`` (arm, wrist, food joints): replays the scene
``food_xyz``   (T, P, 3) f32    food points in the world frame (m): piece centres, or every
                                strand's capsule origins, strand after strand
``food_class`` (T, I) int8      where each item is (``class_names`` code; −1 = not placed)
``tool_mode``  (T,) int8        the tool's mode (``modes``)
``tool_q``     (T, 2) float32   the tool's own wrist joint reading [pitch, roll] (rad)
``tilt_deg``   (T,) float32     true tilt of the utensil's up vector from vertical (°)
``base_tilt_deg`` (T,) float32  tilt of the tool base F0 (°)
============== ================ ==========================================================

Each spill (``meta.spills``) is the world's :class:`~articutool.sim.accounting.SpillEvent`
(``t``, ``mass_g``, ``place``, ``where``, ``item``; ``t`` is when the item first touched the
spill place) plus ``counted_t``, the tick at which the accounting counted it (a frame is
recorded at that tick, so its ``food_class`` is the class the accounting decided from), and
``xyz``, where that item was then.
"""

from __future__ import annotations

import json
import math
import zipfile
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from articutool.datafile import file_kind, parse_json

if TYPE_CHECKING:
    from articutool.sim.world import FeedingWorld

__all__ = ["FORMAT", "VERSION", "Recorder", "Recording", "RecordingError"]

FORMAT = "articutool-recording"
VERSION = 1
_ARRAYS = ("t", "q", "qpos", "food_xyz", "food_class", "tool_mode", "tool_q", "tilt_deg",
           "base_tilt_deg")


class RecordingError(ValueError):
    """A recording cannot be written (file exists, bad name) or read (missing, malformed)."""


def _food_point_ids(world: FeedingWorld) -> tuple[str, NDArray[np.int64], list[tuple[int, int]]]:
    """Kind of food, body ids of pieces, (first body id, count) of strands: a strand's
    capsule bodies are consecutive (a nested chain), their origins its points."""
    m, lay = world.model, world.layout
    if lay.food_strands:
        spans = [(int(m.body(f"{name}/0").id), lay.strand_segments)
                 for name in lay.food_strands]
        return "strands", np.zeros(0, dtype=np.int64), spans
    ids = np.array([m.body(b).id for b in lay.food_bodies], dtype=np.int64)
    return ("pieces" if ids.size else "none"), ids, []


class Recorder:
    """Records a :class:`~articutool.sim.world.FeedingWorld` run (see the module doc).

    Args:
        world: the world to record; the recorder appends itself to ``world.on_tick``.
        rate_hz: frames per simulated second (at most the tool's loop rate; every k-th tick).
        extra: free-form JSON-serialisable facts stored in ``meta.extra`` (e.g. the script).
    """

    def __init__(self, world: FeedingWorld, rate_hz: float = 25.0,
                 extra: dict[str, Any] | None = None) -> None:
        loop = world.spec.wrist.loop_rate_hz
        if not (math.isfinite(rate_hz) and 0 < rate_hz <= loop):
            raise ValueError(f"rate_hz must be in (0, {loop:g}] Hz (the tool's loop rate); "
                             f"got {rate_hz}")
        self.world = world
        self._every = max(1, round(loop / rate_hz))
        self.rate_hz = loop / self._every
        self.extra = dict(extra or {})
        json.dumps(self.extra)  # fail now, not at save time
        self._kind, self._bodies, self._spans = _food_point_ids(world)
        self._ticks = 0
        self._frames: dict[str, list[Any]] = {k: [] for k in _ARRAYS}
        self._spills: list[dict[str, Any]] = []
        self._seen_spills = len(world.ledger.spills)
        self._grab(world)
        world.on_tick.append(self._on_tick)

    def __len__(self) -> int:
        return len(self._frames["t"])

    def _on_tick(self, world: FeedingWorld) -> None:
        self._ticks += 1
        new = len(world.ledger.spills) > self._seen_spills
        if new or self._ticks % self._every == 0:
            self._grab(world)

    def _food_xyz(self) -> NDArray[np.float32]:
        d = self.world.data
        if self._kind == "strands":
            return np.concatenate([d.xpos[a:a + n] for a, n in self._spans]
                                  ).astype(np.float32)
        return d.xpos[self._bodies].astype(np.float32)

    def _grab(self, world: FeedingWorld) -> None:
        f = self._frames
        state = world.tool.state()
        xyz = self._food_xyz()
        f["t"].append(world.time)
        f["q"].append(world.q)
        f["qpos"].append(world.data.qpos.astype(np.float32))
        f["food_xyz"].append(xyz)
        f["food_class"].append(world.ledger.item_classes().astype(np.int8))
        f["tool_mode"].append(int(state.mode))
        f["tool_q"].append(np.asarray(state.position, dtype=np.float32))
        f["tilt_deg"].append(world.tilt_deg())
        f["base_tilt_deg"].append(world.tool_base_tilt_deg())
        for s in world.ledger.spills[self._seen_spills:]:
            d = asdict(s)
            d["counted_t"] = world.time
            d["xyz"] = self._item_xyz(xyz, s.item).tolist()
            self._spills.append(d)
        self._seen_spills = len(world.ledger.spills)

    def _item_xyz(self, xyz: NDArray[np.float32], item: int) -> NDArray[np.float64]:
        if self._kind == "strands":
            a = sum(n for _, n in self._spans[:item])
            return xyz[a:a + self._spans[item][1]].astype(float).mean(axis=0)
        return xyz[item].astype(float)

    def meta(self) -> dict[str, Any]:
        """The JSON header this recording will carry."""
        from articutool.sim import accounting as acc
        from articutool.tool.api import Mode

        w = self.world
        rgba = {"pieces": "0.55 0.33 0.15 1", "strands": "0.95 0.85 0.45 1"}
        rgba_food = rgba.get(self._kind, "0 0 0 1")
        if w.food and self._kind == "pieces" and w.model.ngeom:
            rgba_food = " ".join(f"{c:.3g}" for c in
                                 w.model.geom_rgba[w.model.geom(w.layout.food_bodies[0]).id])
        return {
            "format": FORMAT, "version": VERSION, "food": w.food, "utensil": w.utensil,
            "seed": w.seed, "load": w.load_g is not None, "rate_hz": self.rate_hz,
            "spec_version": w.spec.version,
            "joint_names": [*w.layout.arm_joints, *w.layout.wrist_joints],
            "modes": {int(m): m.name for m in Mode},
            "class_names": list(acc.CLASS_NAMES),
            "food_kind": self._kind,
            "strand_vertices": [n for _, n in self._spans],
            "point_radius": (w.layout.piece_size / 2 if w.layout.piece_size
                             else float(w.params.food(w.food).strand_radius)
                             if self._kind == "strands" else 0.0),
            "food_rgba": [float(c) for c in rgba_food.split()],
            "spills": self._spills,
            "extra": self.extra,
        }

    def save(self, path: str | Path) -> Path:
        """Write the recording to ``path`` (must end in ``.npz``; never overwritten: an
        existing file raises :class:`RecordingError`). Returns the path."""
        p = Path(path)
        if p.suffix.lower() != ".npz":
            raise RecordingError(f"recording file {p} must end in .npz")
        if not p.parent.is_dir():
            raise RecordingError(f"recording file {p}: folder {p.parent} does not exist")
        f = self._frames
        n_items = len(f["food_class"][0])
        arrays = {
            "meta": np.array(json.dumps(self.meta())),
            "mjcf": np.array(self.world.layout.xml),
            "t": np.asarray(f["t"], dtype=np.float64),
            "q": np.asarray(f["q"], dtype=np.float64).reshape(-1, 8),
            "qpos": np.asarray(f["qpos"], dtype=np.float32),
            "food_xyz": np.asarray(f["food_xyz"], dtype=np.float32).reshape(len(self), -1, 3),
            "food_class": np.asarray(f["food_class"], dtype=np.int8).reshape(len(self), n_items),
            "tool_mode": np.asarray(f["tool_mode"], dtype=np.int8),
            "tool_q": np.asarray(f["tool_q"], dtype=np.float32).reshape(-1, 2),
            "tilt_deg": np.asarray(f["tilt_deg"], dtype=np.float32),
            "base_tilt_deg": np.asarray(f["base_tilt_deg"], dtype=np.float32),
        }
        try:
            with open(p, "xb") as fh:
                np.savez_compressed(fh, **arrays)
        except FileExistsError:
            raise RecordingError(f"recording file {p} exists; choose a new file (nothing is "
                                 "overwritten)") from None
        except OSError as err:
            raise RecordingError(f"cannot write recording {p}: {err.strerror}") from None
        return p


@dataclass(frozen=True)
class Recording:
    """A recording read back and validated (:meth:`load`); arrays as in the module doc."""

    meta: dict[str, Any]
    mjcf: str
    t: NDArray[np.float64]
    q: NDArray[np.float64]
    qpos: NDArray[np.float32]
    food_xyz: NDArray[np.float32]
    food_class: NDArray[np.int8]
    tool_mode: NDArray[np.int8]
    tool_q: NDArray[np.float32]
    tilt_deg: NDArray[np.float32]
    base_tilt_deg: NDArray[np.float32]

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def spills(self) -> list[dict[str, Any]]:
        """Spill events (``t``, ``mass_g``, ``place``, ``where``, ``item``, ``counted_t``,
        ``xyz``)."""
        return list(self.meta["spills"])

    def point_class(self, frame: int) -> NDArray[np.int8]:
        """Class of every food point at ``frame`` (a strand's vertices share its class)."""
        c = self.food_class[frame]
        if self.meta["food_kind"] == "strands":
            return np.repeat(c, self.meta["strand_vertices"])
        return c

    def frame_at(self, t: float) -> int:
        """Index of the last frame at or before ``t`` (the first frame before the start)."""
        return int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self) - 1))

    @classmethod
    def load(cls, path: str | Path) -> Recording:
        """Read and validate a recording; :class:`RecordingError` names what is wrong."""
        p = Path(path)
        if not p.is_file():
            what = ("does not exist" if not p.exists() else
                    f"is {file_kind(p.stat().st_mode)} (a regular .npz file is needed)")
            raise RecordingError(f"recording {p} {what}")
        try:
            with np.load(p, allow_pickle=False) as z:
                missing = [k for k in ("meta", "mjcf", *_ARRAYS) if k not in z.files]
                if missing:
                    raise RecordingError(f"recording {p} lacks the arrays {missing}; is it "
                                         "an articutool recording?")
                data = {k: z[k] for k in ("meta", "mjcf", *_ARRAYS)}
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
            if isinstance(err, RecordingError):
                raise
            raise RecordingError(f"recording {p} is not a readable .npz archive "
                                 f"({type(err).__name__}: {err})") from None
        meta = parse_json(str(data["meta"]), f"recording {p}: meta", RecordingError)
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            raise RecordingError(f"recording {p}: meta.format must be {FORMAT!r}")
        if meta.get("version") != VERSION:
            raise RecordingError(f"recording {p}: meta.version must be {VERSION}; got "
                                 f"{meta.get('version')!r}")
        for key in ("food_kind", "strand_vertices", "spills", "modes", "class_names",
                    "point_radius", "food_rgba"):
            if key not in meta:
                raise RecordingError(f"recording {p}: meta.{key} is missing")
        t = data["t"]
        n = t.shape[0] if t.ndim == 1 else -1
        if n < 1:
            raise RecordingError(f"recording {p}: t must be a non-empty 1-D array; got shape "
                                 f"{t.shape}")
        if not np.isfinite(t).all() or (np.diff(t) < 0).any():
            raise RecordingError(f"recording {p}: t must be finite and non-decreasing")
        shapes = {"q": (n, 8), "tool_q": (n, 2), "tool_mode": (n,), "tilt_deg": (n,),
                  "base_tilt_deg": (n,)}
        for k, shape in shapes.items():
            if data[k].shape != shape:
                raise RecordingError(f"recording {p}: {k} must have shape {shape}; got "
                                     f"{data[k].shape}")
        for k in ("qpos", "food_xyz", "food_class"):
            if data[k].shape[:1] != (n,):
                raise RecordingError(f"recording {p}: {k} must have {n} frames; got shape "
                                     f"{data[k].shape}")
        if data["food_xyz"].ndim != 3 or data["food_xyz"].shape[2] != 3:
            raise RecordingError(f"recording {p}: food_xyz must have shape (T, P, 3); got "
                                 f"{data['food_xyz'].shape}")
        pts = (sum(meta["strand_vertices"]) if meta["food_kind"] == "strands"
               else data["food_class"].shape[1])
        if data["food_xyz"].shape[1] != pts:
            raise RecordingError(f"recording {p}: food_xyz holds {data['food_xyz'].shape[1]} "
                                 f"points per frame; meta says {pts}")
        for k in ("q", "qpos"):
            if not np.isfinite(data[k]).all():
                raise RecordingError(f"recording {p}: {k} holds NaN or inf")
        return cls(meta=meta, mjcf=str(data["mjcf"]),
                   **{k: data[k] for k in _ARRAYS})
