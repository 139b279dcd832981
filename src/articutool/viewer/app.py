"""The viewer's web page (viser): the scene, the robot, plans and replayed runs.

:class:`ViewerApp` fills a :class:`viser.ViserServer` with

* the scene and the robot from the feeding world's model (:mod:`articutool.viewer.geometry`),
  posed at a named configuration of the spec (a dropdown);
* a **plan** (:func:`show_plan`): a time slider and play button moving the robot, the tip's
  path coloured by the verifier's velocity margin or by the tilt from vertical (green = good,
  red = bad), the first failing waypoint as a red sphere labelled with the verifier's reason,
  and the colliding bodies at the current sample drawn red and listed;
* a **replay** of a recording (:func:`show_replay`): the world at each recorded frame, food
  points coloured by where they are (utensil, container, table, critical, airborne), spill
  markers appearing where and when food landed, and the tool's telemetry (tilt, wrist
  angles, mode) as plots beside the 3-D view.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np
import viser
import viser.uplot
from numpy.typing import NDArray

from articutool.sim.accounting import SpillEvent, spilled_by_place
from articutool.sim.recording import Recording
from articutool.viewer.geometry import GeomMesh, Poser, geom_meshes
from articutool.viewer.plan import PlanView

__all__ = ["CLASS_COLORS", "ViewerApp", "ramp_colors"]

# Food point colours by accounting class (airborne, utensil, container, table, critical, eaten).
CLASS_COLORS = np.array([[230, 160, 30], [40, 170, 60], [150, 110, 70], [240, 120, 20],
                         [220, 30, 30], [0, 0, 0]], dtype=np.uint8)
_UNPLACED = np.array([160, 160, 160], dtype=np.uint8)
_HIGHLIGHT = (230, 20, 20)
_X: dict[str, Any] = {"x": {"time": False}}  # plot x axes are seconds, not dates
_SPILL_FIELDS = ("t", "mass_g", "place", "where", "item")


def ramp_colors(values: NDArray[np.float64], good: float, bad: float) -> NDArray[np.uint8]:
    """Green (at ``good``) → yellow → red (at ``bad``) per value; NaN is grey. (N,) → (N, 3)."""
    v = np.asarray(values, dtype=float)
    s = np.clip(np.nan_to_num((v - good) / (bad - good)), 0.0, 1.0)
    rgb = np.stack([np.clip(2 * s, 0, 1), np.clip(2 * (1 - s), 0, 1), np.zeros_like(s)], -1)
    out = (rgb * 220 + 20).astype(np.uint8)
    out[~np.isfinite(v)] = (150, 150, 150)
    return out


def _rgb(rgba: Sequence[float]) -> tuple[int, int, int]:
    return (int(rgba[0] * 255), int(rgba[1] * 255), int(rgba[2] * 255))


def _matches(body: str, mesh: GeomMesh) -> bool:
    """Does a collision body of the Pinocchio model (``ArmModel``) name this MJCF geom?"""
    if body.startswith("utensil_"):
        return mesh.name.startswith("utensil/")
    return mesh.name == body or mesh.name.startswith(body + "/")


class _Player:
    """A time slider with a play button that advances it in real time."""

    def __init__(self, server: viser.ViserServer, t0: float, t1: float,
                 on_time: Callable[[float], None], start: float | None = None) -> None:
        step = max((t1 - t0) / 1000.0, 1e-3)
        first = float(np.clip(t0 if start is None else start, t0, t1))
        self.slider = server.gui.add_slider("time (s)", min=float(t0), max=float(t1),
                                            step=float(step), initial_value=first)
        self.play = server.gui.add_checkbox("play", initial_value=False)
        self.speed = server.gui.add_slider("speed (×)", min=0.1, max=4.0, step=0.1,
                                           initial_value=1.0)
        self._t0, self._t1 = float(t0), float(t1)
        self._stop = threading.Event()
        self.slider.on_update(lambda _: on_time(float(self.slider.value)))
        self._thread = threading.Thread(target=self._run, name="viewer-player", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        last = time.monotonic()
        while not self._stop.wait(0.05):
            now = time.monotonic()
            if self.play.value:
                t = float(self.slider.value) + (now - last) * float(self.speed.value)
                self.slider.value = self._t0 if t > self._t1 else t
            last = now

    def close(self) -> None:
        """Stop the play thread."""
        self._stop.set()
        self._thread.join(timeout=1.0)


class ViewerApp:
    """The 3-D scene of one viser server (see the module doc).

    Args:
        server: the viser server to draw into.
        model: the feeding world's compiled MuJoCo model (with or without food).
        robot_root: the robot's root body (the arm base frame).
        joint_names: the robot's 8 joints, in the order configurations are given.
        configurations: named 8-joint configurations for the dropdown (first is shown).
    """

    def __init__(self, server: viser.ViserServer, model: Any, robot_root: str,
                 joint_names: Sequence[str], configurations: dict[str, NDArray[np.float64]]
                 ) -> None:
        self.server = server
        self.poser = Poser(model, list(joint_names))
        self.meshes = geom_meshes(model, robot_root)
        self._closers: list[Callable[[], None]] = []
        server.gui.configure_theme(show_share_button=False, control_width="large")
        server.scene.set_up_direction("+z")
        server.initial_camera.position = (1.45, -0.5, 1.05)
        server.initial_camera.look_at = (0.3, 0.1, 0.35)
        self.handles: dict[int, viser.MeshHandle] = {}
        self._robot_ids = np.array([m.geom_id for m in self.meshes if m.robot], dtype=np.int64)
        self.show_robot = server.gui.add_checkbox("show robot", initial_value=True)
        self.show_robot.on_update(lambda _: self._robot_visible(bool(self.show_robot.value)))
        mujoco.mj_kinematics(model, self.poser.data)  # the scene's geoms at their poses
        pos, quat = self.poser.poses([m.geom_id for m in self.meshes])
        for k, m in enumerate(self.meshes):
            opacity = None if m.rgba[3] >= 0.99 else float(m.rgba[3])
            node = f"/robot/{m.name}" if m.robot else f"/scene/{m.name}"
            self.handles[m.geom_id] = server.scene.add_mesh_simple(
                node, m.vertices, m.faces, color=_rgb(m.rgba), opacity=opacity,
                position=pos[k], wxyz=quat[k])
            if m.plane:  # a 10 cm grid on the ground, for scale
                server.scene.add_grid(f"/grid/{m.name}", width=2.0, height=2.0, cell_size=0.1,
                                      plane="xy", position=pos[k] + (0.0, 0.0, 0.001),
                                      wxyz=quat[k])
        self.configurations = dict(configurations)
        if self.configurations:
            names = list(self.configurations)
            self.config = server.gui.add_dropdown("configuration", names, initial_value=names[0])
            self.config.on_update(lambda _: self.pose(self.configurations[self.config.value]))
            self.pose(self.configurations[names[0]])

    # ----------------------------------------------------------------- robot --
    def _robot_visible(self, on: bool) -> None:
        for g in self._robot_ids:
            self.handles[int(g)].visible = on

    def _update_robot(self, highlight: Sequence[str] = ()) -> None:
        pos, quat = self.poser.poses(self._robot_ids)
        with self.server.atomic():
            for k, g in enumerate(self._robot_ids):
                h = self.handles[int(g)]
                h.position, h.wxyz = pos[k], quat[k]
            for m in self.meshes:
                hit = any(_matches(b, m) for b in highlight)
                want = _HIGHLIGHT if hit else _rgb(m.rgba)
                if tuple(self.handles[m.geom_id].color) != want:
                    self.handles[m.geom_id].color = want

    def pose(self, q: NDArray[np.float64], highlight: Sequence[str] = ()) -> None:
        """Show the robot at the 8-joint configuration ``q``; ``highlight`` draws those
        collision bodies red (``ArmModel`` names: links, ``utensil_…``, ``scene/…``)."""
        self.poser.set_q(q)
        self._update_robot(highlight)

    def close(self) -> None:
        """Stop background threads (the server is stopped by its owner)."""
        for c in self._closers:
            c()

    # ------------------------------------------------------------------ plans --
    def show_plan(self, view: PlanView, color_by: str = "auto",
                  start: float | None = None) -> None:
        """Add a plan: slider, tip path, failure marker, collision highlight (module doc)."""
        s = self.server
        by = ("margin" if view.margin is not None else "tilt") if color_by == "auto" else color_by
        if by == "margin" and view.margin is None:
            raise ValueError("color_by='margin' needs a verified (leveling) plan")
        if by == "margin":
            assert view.margin is not None
            colors = ramp_colors(view.margin, good=1.0, bad=0.0)
            legend = "velocity margin: green 100 % → red 0 % (grey: after the failure)"
        else:
            colors = ramp_colors(view.tilt_deg, good=0.0, bad=30.0)
            legend = "tilt from vertical: green 0° → red ≥ 30°"
        seg = np.stack([view.tip[:-1], view.tip[1:]], axis=1)
        col = np.stack([colors[:-1], colors[1:]], axis=1)
        s.scene.add_line_segments("/plan/tip_path", seg, col, thickness=0.006)
        bad = view.colliding_samples
        if bad.size:
            s.scene.add_point_cloud("/plan/collisions", view.tip[bad],
                                    np.tile(np.array(_HIGHLIGHT, dtype=np.uint8), (bad.size, 1)),
                                    point_size=0.015, point_shape="circle")
        if view.failure_xyz is not None:
            s.scene.add_icosphere("/plan/failure", radius=0.02, color=_HIGHLIGHT,
                                  position=tuple(view.failure_xyz))
            s.scene.add_label("/plan/failure/label",
                              f"first failure: {view.reason} (t = {view.failure_time:.2f} s, "
                              f"waypoint {view.failure_index})", position=(0.0, 0.0, 0.04))
        lines = [f"**{view.title}**", *[f"- {x}" for x in view.summary], f"- path: {legend}"]
        if view.verified is False:
            lines.append(f"- **first failing waypoint {view.failure_index}** "
                         f"(t = {view.failure_time:.3f} s): `{view.reason}`")
        s.gui.add_markdown("\n".join(lines))
        status = s.gui.add_markdown("")

        def at(t: float) -> None:
            k = view.sample_at(t)
            pairs = view.collisions[k]
            self.pose(view.q[k], highlight=[b for p in pairs for b in p])
            m = ("" if view.margin is None else f", margin {view.margin[k]:.1%}"
                 if np.isfinite(view.margin[k]) else ", past the first failure (not leveled)")
            status.content = (f"t = {view.t[k]:.2f} s: tilt {view.tilt_deg[k]:.1f}°{m}; "
                              + ("colliding: " + ", ".join(f"{a} × {b}" for a, b in pairs)
                                 if pairs else "no collision"))

        player = _Player(s, float(view.t[0]), float(view.t[-1]), at, start)
        self._closers.append(player.close)
        at(float(player.slider.value))

    # ----------------------------------------------------------------- replay --
    def show_replay(self, rec: Recording, start: float | None = None) -> None:
        """Add a recorded run: world per frame, food points, spills, telemetry plots."""
        s = self.server
        meta = rec.meta
        radius = max(float(meta["point_radius"]), 0.002)
        food = None
        if rec.food_xyz.shape[1]:
            food = s.scene.add_point_cloud("/replay/food", rec.food_xyz[0],
                                           self._food_colors(rec, 0), point_size=2 * radius,
                                           point_shape="circle")
        spill_nodes = []
        places: dict[str, Any] = {}  # one label per object food landed on, at its first spill
        for i, sp in enumerate(rec.spills):
            c = (220, 30, 30) if sp["place"] == "critical" else (240, 140, 20)
            h = s.scene.add_icosphere(f"/replay/spill{i}", radius=max(radius, 0.006), color=c,
                                      position=tuple(sp["xyz"]), visible=False)
            spill_nodes.append((float(sp["t"]), h))
            key = f"{sp['where']} ({sp['place']})"
            if key not in places:
                places[key] = s.scene.add_label(f"/replay/spill_label{len(places)}", key,
                                                position=tuple(np.add(sp["xyz"], (0, 0, 0.03))),
                                                visible=False)
        modes = {int(k): v for k, v in meta["modes"].items()}
        n_sp = len(rec.spills)
        # Spilled grams as everywhere: each item once, at its worst place (sim.accounting).
        spilled = sum(spilled_by_place([SpillEvent(**{k: sp[k] for k in _SPILL_FIELDS})
                                        for sp in rec.spills]).values())
        s.gui.add_markdown(
            f"**replay**: {meta.get('food') or 'no food'} on the {meta['utensil']}, seed "
            f"{meta['seed']}, {len(rec)} frames over {rec.t[-1] - rec.t[0]:.1f} s "
            f"({meta['rate_hz']:g} Hz); {n_sp} spill event(s), {spilled:.2f} g"
            + "".join(f"; {k} {v}" for k, v in (meta.get("extra") or {}).items())
            + "\n\nfood: green utensil · brown container · orange table · red critical · "
              "amber airborne")
        t = rec.t.astype(np.float64)
        s.gui.add_uplot(
            (t, rec.tilt_deg.astype(np.float64), rec.base_tilt_deg.astype(np.float64)),
            (viser.uplot.Series(label="t (s)"),
             viser.uplot.Series(label="utensil tilt (°)", stroke="red", width=2),
             viser.uplot.Series(label="tool base tilt (°)", stroke="gray", width=1)),
            title="tilt from vertical", aspect=2.0, scales=_X)
        s.gui.add_uplot(
            (t, np.degrees(rec.tool_q[:, 0]).astype(np.float64),
             np.degrees(rec.tool_q[:, 1]).astype(np.float64)),
            (viser.uplot.Series(label="t (s)"),
             viser.uplot.Series(label="pitch (°)", stroke="blue", width=2),
             viser.uplot.Series(label="roll (°)", stroke="green", width=2)),
            title="wrist joints (tool's encoders)", aspect=2.0, scales=_X)
        s.gui.add_uplot(
            (t, rec.tool_mode.astype(np.float64)),
            (viser.uplot.Series(label="t (s)"),
             viser.uplot.Series(label="mode", stroke="purple", width=2)),
            title="tool mode: " + ", ".join(f"{k} {v}" for k, v in sorted(modes.items())),
            aspect=3.0, scales=_X)
        status = s.gui.add_markdown("")

        def at(tt: float) -> None:
            k = rec.frame_at(tt)
            self.poser.set_qpos(rec.qpos[k])
            self._update_robot()
            with s.atomic():
                if food is not None:
                    food.points = rec.food_xyz[k]
                    food.colors = self._food_colors(rec, k)
                for ts, h in spill_nodes:
                    h.visible = ts <= rec.t[k] + 1e-9
                for key, lab in places.items():
                    so_far = [sp for sp in rec.spills if sp["t"] <= rec.t[k] + 1e-9
                              and f"{sp['where']} ({sp['place']})" == key]
                    lab.visible = bool(so_far)
                    if so_far:
                        lab.text = (f"spill on {key}: {len(so_far)} event(s), "
                                    f"{sum(x['mass_g'] for x in so_far):.2f} g since "
                                    f"{so_far[0]['t']:.2f} s")
            status.content = (f"t = {rec.t[k]:.2f} s: mode "
                              f"{modes.get(int(rec.tool_mode[k]), rec.tool_mode[k])}, "
                              f"tilt {rec.tilt_deg[k]:.1f}°, pitch "
                              f"{np.degrees(rec.tool_q[k, 0]):.1f}°, roll "
                              f"{np.degrees(rec.tool_q[k, 1]):.1f}°")

        player = _Player(s, float(rec.t[0]), float(rec.t[-1]), at, start)
        self._closers.append(player.close)
        at(float(player.slider.value))

    @staticmethod
    def _food_colors(rec: Recording, k: int) -> NDArray[np.uint8]:
        c = rec.point_class(k).astype(np.int64)
        out = CLASS_COLORS[np.clip(c, 0, len(CLASS_COLORS) - 1)].copy()
        out[c < 0] = _UNPLACED
        return out
