"""Offscreen rendering: close views of a loaded world, and side-by-side videos (the
experiments' replays show what the utensil holds)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from articutool.sim.render import Recorder, model_renderer, scene_camera
from articutool.sim.world import FeedingWorld


@pytest.fixture(scope="module")
def loaded() -> FeedingWorld:
    # 2.5 g of pecans placed on the utensil: the pile's other pieces wait parked far off
    # the table, which makes MuJoCo's model extent ~50 m.
    return FeedingWorld.make("pecans", seed=0, load_g=2.5)


def _utensil_geoms(model: Any) -> set[int]:
    import mujoco

    root = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "utensil")
    bodies = {b for b in range(model.nbody)
              if b == root or _has_ancestor(model, b, root)}
    return {g for g in range(model.ngeom) if int(model.geom_bodyid[g]) in bodies}


def _has_ancestor(model: Any, body: int, root: int) -> bool:
    while body:
        body = int(model.body_parentid[body])
        if body == root:
            return True
    return False


@pytest.mark.parametrize("camera", ["follow", "utensil_close"])
def test_a_close_view_of_a_loaded_world_shows_the_utensil(loaded, camera) -> None:
    import mujoco

    # Before the fix the near clipping plane sat at znear × extent ≈ 0.5 m and clipped
    # every close view of a world with parked food: the utensil never appeared.
    assert loaded.model.stat.extent > 10.0  # the condition this test is about
    r = model_renderer(loaded.model, 160, 120)
    r.enable_segmentation_rendering()
    r.update_scene(loaded.data, camera=scene_camera(loaded.model, loaded.data, camera))
    seg = r.render()
    r.close()
    geoms = seg[..., 0][seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)]
    seen = set(np.unique(geoms).tolist())
    assert seen & _utensil_geoms(loaded.model)


def test_a_recorder_with_two_cameras_puts_them_side_by_side(loaded) -> None:
    rec = Recorder(loaded, fps=50.0, camera=("overview", "follow"), width=96, height=64)
    loaded.run(0.1)
    loaded.on_tick.remove(rec._grab)
    assert rec.frames and all(f.shape == (64, 192, 3) for f in rec.frames)
    left, right = rec.frames[-1][:, :96], rec.frames[-1][:, 96:]
    assert not np.array_equal(left, right)


def test_an_unknown_camera_is_refused_before_the_run(loaded) -> None:
    with pytest.raises(ValueError, match="camera must be one of"):
        Recorder(loaded, camera=("overview", "ceiling"))


def test_rendering_works_whichever_articutool_module_imports_mujoco_first(tmp_path) -> None:
    # CI aborted: an earlier test imported MuJoCo through another module (the viewer, the
    # world) before sim.render could choose EGL, so MuJoCo bound GLFW, which has no display.
    import os
    import subprocess
    import sys

    script = (
        "import articutool.viewer.geometry\n"
        "import mujoco\n"
        "from articutool.sim.render import model_renderer\n"
        "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\".1\"/>"
        "</worldbody></mujoco>')\n"
        "r = model_renderer(m, 32, 24)\n"
        "r.update_scene(mujoco.MjData(m))\n"
        "print(r.render().shape)\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY",
                                                           "PYOPENGL_PLATFORM")}
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "(24, 32, 3)"


def test_a_frame_draws_the_liquid_mujoco_does_not_hold() -> None:
    """The bowl's SPH water is not MuJoCo's: a frame draws it as its particles, in the bowl."""
    from articutool.sim.render import liquid_points, render_frame

    w = FeedingWorld.make("water", seed=0, settle=False)
    try:
        ((x, radius),) = liquid_points(w)
        assert w.bowl is not None and radius == w.bowl.r
        assert len(x) * w.bowl.mass * 1e3 == pytest.approx(w.bowl.grams)
        box = w.bowl.box
        assert np.all(np.hypot(*(x[:, :2] - box.xyz[:2]).T) < box.radius - box.container_wall)
        r = model_renderer(w.model, 160, 120)
        r.update_scene(w.data, camera="bowl")
        bare = r.scene.ngeom
        frame = render_frame(w, "bowl", renderer=r)
        assert r.scene.ngeom == bare + len(x)
        r.update_scene(w.data, camera="bowl")
        assert not np.array_equal(frame, r.render())  # the water is in view
        r.close()
    finally:
        w.close()
