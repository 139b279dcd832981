"""Offscreen pictures of the physics world: PNG snapshots and videos (MP4 or GIF).

MuJoCo renders headless through EGL (``MUJOCO_GL=egl``, set by the ``articutool`` package
before any of its modules imports MuJoCo, unless the caller chose a backend). EGL needs the
system's libEGL and a Mesa driver (Debian: ``libegl1``, ``libgl1-mesa-dri``; ``make``
installs them); without them :class:`RenderError` says so.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
from numpy.typing import NDArray

from articutool.sim.world import FeedingWorld

__all__ = ["CAMERAS", "Recorder", "RenderError", "liquid_points", "model_renderer", "render_frame",
           "save_png", "scene_camera", "write_video"]

CAMERAS = ("utensil", "utensil_close", "overview", "bowl", "follow")
# "follow": a free camera aimed at the utensil at a fixed distance and direction in the
# world (from the overview's side, looking down), so the dish's tilt and what it holds stay
# in view wherever the arm carries it. A viewpoint, not a dimension of the scene.
NEAR_M = 0.01  # the near clipping plane: 1 cm, closer than any camera comes to the utensil
FOLLOW_VIEW = {"distance": 0.25, "azimuth": 155.0, "elevation": -30.0}
_HINT = ("offscreen rendering needs EGL: install the system packages libegl1 and "
         "libgl1-mesa-dri (Debian/Ubuntu; `make` does it), or set MUJOCO_GL to a working "
         "backend")


_LIQUID_RGBA = np.array([0.3, 0.5, 0.95, 0.8], dtype=np.float32)  # as the water spheres


class RenderError(RuntimeError):
    """Offscreen rendering is not available, or a file cannot be written."""


def model_renderer(model: mujoco.MjModel, width: int = 640,
                   height: int = 480) -> mujoco.Renderer:
    """An offscreen renderer for ``model`` (:class:`RenderError` when EGL/GL is missing).

    It renders a copy of the model whose near clipping plane is :data:`NEAR_M` away: MuJoCo
    places it at ``znear × extent``, and the extent of a world with parked food (bodies
    waiting far off the table) is ~50 m, which put the plane 0.5 m from the camera and
    clipped every close view."""
    vis = copy.deepcopy(model)
    vis.vis.map.znear = NEAR_M / max(vis.stat.extent, 1e-9)
    try:
        return mujoco.Renderer(vis, height, width)
    except Exception as err:  # EGL/GL missing: MuJoCo raises various types
        raise RenderError(f"{_HINT} ({type(err).__name__}: {err})") from None


def _renderer(world: FeedingWorld, width: int, height: int) -> mujoco.Renderer:
    return model_renderer(world.model, width, height)


def scene_camera(model: mujoco.MjModel, data: mujoco.MjData,
                 camera: str) -> str | mujoco.MjvCamera:
    """What ``Renderer.update_scene`` needs for the camera named ``camera``: a model camera's
    name, or for ``follow`` a free :class:`mujoco.MjvCamera` looking at the utensil body's
    centre of mass in ``data`` from :data:`FOLLOW_VIEW` (placed anew for every frame)."""
    if camera not in CAMERAS:
        raise ValueError(f"camera must be one of {CAMERAS}; got {camera!r}")
    if camera != "follow":
        return camera
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = data.subtree_com[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY,
                                                       "utensil")]
    cam.distance, cam.azimuth, cam.elevation = (FOLLOW_VIEW[k] for k in
                                                ("distance", "azimuth", "elevation"))
    return cam


def liquid_points(world: FeedingWorld) -> list[tuple[NDArray[np.float64], float]]:
    """The liquid MuJoCo does not hold, as (world positions (n, 3), particle radius) groups:
    the container's SPH liquid (:mod:`~articutool.sim.bowl_liquid`) and a load's particles in
    the dish (:mod:`~articutool.sim.liquid_load`; those that left it are MuJoCo's spheres)."""
    out = []
    if world.bowl is not None and world.bowl.grams > 0:
        out.append((world.bowl.positions_world(), world.bowl.r))
    load = world.placement.liquid
    if load is not None and not load.closed and load.liquid.n_particles:
        out.append((load.positions_world()[1], load.settings.particle_radius))
    return out


def _draw_liquid(scene: mujoco.MjvScene, world: FeedingWorld) -> None:
    """Add the world's :func:`liquid_points` to ``scene`` as spheres (as many as it holds)."""
    eye = np.eye(3).ravel()
    for x, r in liquid_points(world):
        size = np.array([r, 0.0, 0.0])
        for xk in x[:max(0, scene.maxgeom - scene.ngeom)]:
            mujoco.mjv_initGeom(scene.geoms[scene.ngeom], int(mujoco.mjtGeom.mjGEOM_SPHERE),
                                size, xk, eye, _LIQUID_RGBA)
            scene.ngeom += 1


def render_frame(world: FeedingWorld, camera: str = "utensil", width: int = 640,
                 height: int = 480, renderer: mujoco.Renderer | None = None) -> NDArray[np.uint8]:
    """One RGB frame (height, width, 3) of the world from a named camera (:data:`CAMERAS`),
    the liquid that is not MuJoCo's drawn as its particles."""
    cam = scene_camera(world.model, world.data, camera)
    r = renderer or _renderer(world, width, height)
    r.update_scene(world.data, camera=cam)
    _draw_liquid(r.scene, world)
    return r.render().copy()


def write_video(frames: list[NDArray[np.uint8]], path: str | Path, fps: float) -> Path:
    """Write RGB frames as a new video file (format by suffix: ``.mp4`` via the ffmpeg
    bundled with imageio-ffmpeg, ``.gif`` via Pillow); returns the path. Nothing at ``path``
    is replaced or written through (:func:`articutool.datafile.publish_new`)."""
    p = Path(path)
    if not frames:
        raise RenderError("no frames were recorded")
    suffix = p.suffix.lower()
    if suffix not in (".gif", ".mp4"):
        raise RenderError(f"video: unknown format {suffix!r}; use .mp4 or .gif")

    def write(tmp: Path) -> None:
        if suffix == ".gif":
            from PIL import Image

            imgs = [Image.fromarray(f) for f in frames]
            imgs[0].save(tmp, save_all=True, append_images=imgs[1:], loop=0,
                         duration=int(1000 / fps))
        else:
            import imageio.v2 as imageio

            with imageio.get_writer(tmp, fps=fps, codec="libx264", macro_block_size=8) as w:
                for f in frames:
                    w.append_data(f)

    return _publish(p, write, "video")


def _publish(p: Path, write: Callable[[Path], None], what: str) -> Path:
    from articutool.datafile import ResultsError, publish_new

    try:
        return publish_new(p, write)
    except (OSError, ResultsError) as err:
        raise RenderError(f"{what}: cannot write {p}: {err}") from None


def save_png(world: FeedingWorld, path: str | Path, camera: str = "utensil") -> Path:
    """Write a new PNG snapshot (never replacing a file or writing through a link); returns
    its path."""
    from PIL import Image

    frame = render_frame(world, camera)
    return _publish(Path(path), lambda tmp: Image.fromarray(frame).save(tmp, format="PNG"),
                    "snapshot")


class Recorder:
    """Records frames at ``fps`` of simulation time while the world runs (``world.on_tick``),
    then writes them with :meth:`save` (``.mp4`` via the ffmpeg bundled with imageio-ffmpeg,
    ``.gif`` via Pillow). ``camera`` is one camera or several, side by side in each frame
    (e.g. ``("overview", "follow")``: the whole path, and what the utensil holds)."""

    def __init__(self, world: FeedingWorld, fps: float = 20.0,
                 camera: str | tuple[str, ...] = "utensil", width: int = 640,
                 height: int = 480) -> None:
        cams = (camera,) if isinstance(camera, str) else tuple(camera)
        if not cams:
            raise ValueError(f"camera must name at least one of {CAMERAS}")
        for c in cams:
            scene_camera(world.model, world.data, c)  # a clear error before the run
        self.world, self.fps, self.cameras = world, float(fps), cams
        self._r = _renderer(world, width, height)
        self.frames: list[NDArray[np.uint8]] = []
        self._next = world.time
        world.on_tick.append(self._grab)

    def _grab(self, world: FeedingWorld) -> None:
        if world.time >= self._next - 1e-9:
            self.frames.append(np.hstack([render_frame(world, c, renderer=self._r)
                                          for c in self.cameras]))
            self._next += 1.0 / self.fps

    def save(self, path: str | Path) -> Path:
        """Write the video (format by suffix: .mp4 or .gif); returns its path."""
        return write_video(self.frames, path, self.fps)
