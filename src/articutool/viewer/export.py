"""A recording to a video file without a browser (papers, CI artefacts).

The recorded MJCF is compiled again and every output frame sets the recorded ``qpos`` (the
robot and every food body, as they were) and renders it offscreen with MuJoCo through EGL
(:mod:`articutool.sim.render`, the same cameras as ``articutool sim --video``). Nothing is
simulated again: the pictures are the recorded states, not a re-run.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from articutool.sim.recording import Recording, RecordingError

MAX_FPS = 120.0  # frames/s of an exported video

__all__ = ["MAX_FPS", "export_video"]


def export_video(rec: Recording, path: str | Path, camera: str = "overview",
                 fps: float | None = None, width: int = 640, height: int = 480) -> Path:
    """Render ``rec`` to ``path`` (``.mp4`` or ``.gif``; never overwritten).

    ``fps`` defaults to the recording's rate; frames are the recorded states nearest each
    output time. Raises :class:`RecordingError` for a bad path or camera and
    :class:`~articutool.sim.render.RenderError` when rendering is unavailable.
    """
    import mujoco

    from articutool.sim.render import CAMERAS, model_renderer, scene_camera, write_video

    p = Path(path)
    if p.suffix.lower() not in (".mp4", ".gif"):
        raise RecordingError(f"video file {p} must end in .mp4 or .gif")
    if p.exists():
        raise RecordingError(f"video file {p} exists; choose a new file (nothing is "
                             "overwritten)")
    if not p.parent.is_dir():
        raise RecordingError(f"video file {p}: folder {p.parent} does not exist")
    if camera not in CAMERAS:
        raise RecordingError(f"camera must be one of {list(CAMERAS)}; got {camera!r}")
    rate = float(rec.meta.get("rate_hz", 25.0))
    fps = rate if fps is None else float(fps)
    if not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
        raise RecordingError(f"fps must be in (0, {MAX_FPS:g}]; got {fps}")
    model = mujoco.MjModel.from_xml_string(rec.mjcf)
    if rec.qpos.shape[1] != model.nq:
        raise RecordingError(f"recording: qpos has {rec.qpos.shape[1]} values per frame; its "
                             f"model has nq = {model.nq}")
    data = mujoco.MjData(model)
    renderer = model_renderer(model, width, height)
    times = np.arange(rec.t[0], rec.t[-1] + 1e-9, 1.0 / fps)
    frames = []
    for t in times:
        data.qpos[:] = rec.qpos[rec.frame_at(float(t))]
        mujoco.mj_forward(model, data)
        renderer.update_scene(data, camera=scene_camera(model, data, camera))
        frames.append(renderer.render().copy())
    renderer.close()
    return write_video(frames, p, fps)
