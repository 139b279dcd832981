"""The viewer's pieces without a browser: recordings of real physics runs, plan samples
checked against the verifier and the arm model, the mesh/collision-name mapping, video export
and ``articutool view``'s bad-input handling (real processes)."""

from __future__ import annotations

import json
import math
import socket
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco")
pytest.importorskip("viser")

from articutool.arm.model import ArmModel
from articutool.sim.recording import Recorder, Recording, RecordingError
from articutool.trajectory import JointTrajectory
from articutool.verify.verifier import verify_trajectory
from articutool.viewer.plan import plan_view
from conftest import free_port, run_cli

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.fixture(scope="module")
def model8(spec):
    return ArmModel(spec, utensil="spoon")


@pytest.fixture(scope="module")
def water_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """A locked-wrist carry of 4 g of water, recorded through the sim CLI: it spills some
    four hundred particles, each checked below."""
    d = tmp_path_factory.mktemp("rec")
    path = d / "water.npz"
    r = run_cli("sim", "--food", "water", "--script", "carry", "--no-level", "--load", "4",
                "--json", "--record", str(path))
    assert r.returncode == 0, r.stderr
    return path, json.loads(r.stdout)


def _deepest_landing(rec: Recording, scene) -> float:
    """How far (m) below a surface a landing particle's centre can be, from the recorded run
    and the contact law MuJoCo applied: a contact exists only once the particle touches, so
    it can enter up to one step's travel v·dt before any force acts; the water-surface law
    (damping ratio 2) then stops it within that step without rebound (measured, physics.toml);
    resting, the contact spring sags by at most g·(τ·ζ)² under the particle's own weight.
    v is the fastest landing the run allows: a fall from the highest point any food reached
    above the ground, starting at the fastest the food moved while on the utensil."""
    import mujoco

    m = mujoco.MjModel.from_xml_string(rec.mjcf)
    ground = m.geom("scene/ground").id
    tau, zeta = m.geom_solref[ground]
    food = next(g for g in range(m.ngeom) if m.geom_priority[g] == 0 and m.geom_bodyid[g] > 0
                and m.body(m.geom_bodyid[g]).name.startswith("food"))
    r = float(m.geom_size[food][0])
    g = -float(m.opt.gravity[2])
    xyz = rec.food_xyz.astype(float)
    placed = rec.food_class >= 0  # a load waits out of the world until it is placed
    height = float(xyz[..., 2][placed].max() - scene.get("ground").xyz[2])
    held = rec.food_class == rec.meta["class_names"].index("utensil")
    on = held[1:] & held[:-1]
    step = np.linalg.norm(np.diff(xyz, axis=0), axis=2) / np.diff(rec.t)[:, None]
    v_launch = float(step[on].max()) if on.any() else 0.0
    v = math.hypot(v_launch, math.sqrt(2.0 * g * height))
    return v * m.opt.timestep + g * (tau * zeta) ** 2 - r


# ------------------------------------------------------------------ recordings --
def test_sim_record_holds_the_runs_spills_where_they_landed(water_run, spec) -> None:
    path, report = water_run
    rec = Recording.load(path)
    assert report["spills"], "the locked carry of water is expected to spill"
    assert [(s["t"], s["item"], s["place"]) for s in rec.spills] == \
        [(s["t"], s["item"], s["place"]) for s in report["spills"]]
    from articutool.arm.scene import Scene

    scene = Scene.load()
    sink = _deepest_landing(rec, scene)
    for s in rec.spills:
        o = scene.get(s["where"])
        local = o.rotation.T @ (np.asarray(s["xyz"]) - np.asarray(o.xyz))
        # Where the item was when it counted as spilled: on (or just above) that object —
        # an item may be counted as it lands, still inside the surface by as much as the
        # contact lets it sink; on an unbounded ground plane (a halfspace) that is any point
        # just above the plane.
        if o.shape == "halfspace":
            assert -sink <= local[2] <= 0.05, (s["where"], local, sink)
        else:
            assert np.linalg.norm(local) < 1.0, (s["where"], s["place"], local)
        if s["where"] == "table":
            half = np.asarray(o.size) / 2
            assert np.all(np.abs(local[:2]) <= half[:2] + 0.01)
            assert half[2] - sink <= local[2] <= half[2] + 0.03, (local, sink)
    # The accounting and the recording agree on every trajectory: the frame recorded at the
    # tick a spill was counted classifies the item at that place or worse, and every frame
    # from its first touch until then shows it on spill places or in the air (a bounce
    # pauses the count; back on the utensil or in a container would have restarted it), for
    # at least the dwell time. Later it may roll on, off the table or into the plate.
    from articutool.sim.params import PhysicsParams

    names = rec.meta["class_names"]
    dwell = PhysicsParams.load().world.spill_dwell_s
    period = 1.0 / spec.wrist.loop_rate_hz  # the accounting step: its first tick counts too
    for s in rec.spills:
        worse = {"table": {"table", "critical"}, "critical": {"critical"}}[s["place"]]
        (counted,) = np.flatnonzero(np.abs(rec.t - s["counted_t"]) < 1e-9)[-1:]
        assert names[rec.food_class[counted, s["item"]]] in worse, s
        assert s["counted_t"] - s["t"] >= dwell - period - 1e-3, s
        stay = (rec.t >= s["t"] - 1e-3) & (rec.t <= s["counted_t"] + 1e-9)
        assert {names[c] for c in rec.food_class[stay, s["item"]]} <= worse | {"airborne"}, s
    assert rec.q.shape == (len(rec), 8) and rec.meta["joint_names"][6:] == \
        list(spec.wrist.joint_names)
    assert rec.meta["extra"] == {"script": "carry", "level": False, "load_g": 4.0}
    assert set(np.unique(rec.tool_mode)) <= {int(k) for k in rec.meta["modes"]}
    # Telemetry: the carry tilts the locked utensil ~40° at the end (as the CLI reported).
    assert rec.tilt_deg[-1] == pytest.approx(report["final_tilt_deg"], abs=1.0)


def test_recorder_samples_the_world_and_never_overwrites(tmp_path: Path, spec) -> None:
    from articutool.sim.world import FeedingWorld
    from articutool.trajectory import smooth_joint_motion

    world = FeedingWorld.make(None, "spoon", settle=False)
    rec = Recorder(world, rate_hz=10.0)
    q0 = world.arm_q
    q1 = q0 + np.array([0.2, 0.0, 0.0, 0.0, 0.0, 0.0])
    world.follow_arm(smooth_joint_motion(q0, q1, spec.arm.max_velocity,
                                         spec.arm.joint_names, duration=1.0), settle_s=0.0)
    path = rec.save(tmp_path / "arm.npz")
    r = Recording.load(path)
    assert r.t[-1] - r.t[0] == pytest.approx(1.0, abs=0.1)
    assert np.allclose(np.diff(r.t), 0.1, atol=1e-6)  # 10 Hz of simulated time
    assert np.allclose(r.q[-1], world.q, atol=1e-9)
    assert r.q[-1, 0] - r.q[0, 0] == pytest.approx(0.2, abs=0.01)  # the arm moved
    assert r.food_xyz.shape == (len(r), 0, 3) and r.meta["food_kind"] == "none"
    before = path.read_bytes()
    with pytest.raises(RecordingError, match="exists"):
        rec.save(path)
    assert path.read_bytes() == before
    with pytest.raises(RecordingError, match=r"\.npz"):
        rec.save(tmp_path / "arm.json")
    with pytest.raises(ValueError, match="rate_hz"):
        Recorder(world, rate_hz=1000.0)


@pytest.mark.parametrize("content,match", [
    (None, "does not exist"),
    (b"not a zip file", "not a readable .npz"),
    ("npz-missing", "lacks the arrays"),
    ("npz-bad-meta", "meta.format"),
])
def test_bad_recordings_are_refused_naming_the_problem(tmp_path: Path, content, match) -> None:
    p = tmp_path / "r.npz"
    if content == "npz-missing":
        np.savez_compressed(p, t=np.zeros(3))
    elif content == "npz-bad-meta":
        arrays = {k: np.zeros(1) for k in ("mjcf", "t", "q", "qpos", "food_xyz", "food_class",
                                           "tool_mode", "tool_q", "tilt_deg", "base_tilt_deg")}
        np.savez_compressed(p, meta=np.array(json.dumps({"format": "other"})), **arrays)
    elif content is not None:
        p.write_bytes(content)
    with pytest.raises(RecordingError, match=match):
        Recording.load(p)
    r = run_cli("view", "--recording", str(p), "--duration", "1")
    assert r.returncode == 2, r.stderr
    assert "--recording" in r.stderr and match.split()[0] in r.stderr
    assert "Traceback" not in r.stderr


def test_export_renders_every_recorded_state_without_a_browser(water_run, tmp_path) -> None:
    import imageio.v3 as iio

    path, _ = water_run
    rec = Recording.load(path)
    out = tmp_path / "water.gif"
    r = run_cli("view", "--recording", str(path), "--export", str(out), "--fps", "2",
                "--camera", "overview")
    assert r.returncode == 0, r.stderr
    frames = iio.imread(out, index=None)
    expected = len(np.arange(rec.t[0], rec.t[-1] + 1e-9, 1 / 2))
    assert frames.shape[0] == expected
    assert frames.std(axis=0).max() > 0  # the arm moved between frames
    again = run_cli("view", "--recording", str(path), "--export", str(out))
    assert again.returncode == 2 and "exists" in again.stderr


# ------------------------------------------------------------------------ plans --
def test_plan_margin_is_the_verifiers(spec, model8) -> None:
    traj = JointTrajectory.load(EXAMPLES / "transport_feasible.json")
    v = plan_view(traj, model8, spec)
    rep = verify_trajectory(traj, model8, spec)
    assert v.verified is True and v.failure_xyz is None
    assert v.margin is not None
    assert np.nanmin(v.margin) == pytest.approx(rep.velocity_margin, abs=1e-9)
    # The wrist levels the utensil along the whole plan (tilt from the arm model's FK).
    assert np.max(v.tilt_deg) < 1.0
    k = v.t.size // 2
    assert np.allclose(v.tip[k], model8.tip_pose(v.q[k])[:3, 3])


def test_plan_marks_the_first_failing_waypoint(spec, model8) -> None:
    traj = JointTrajectory.load(EXAMPLES / "transport_flip.json")
    v = plan_view(traj, model8, spec)
    rep = verify_trajectory(traj, model8, spec)
    assert v.verified is False and v.reason == rep.reason != "ok"
    assert v.failure_index == rep.first_failure_index
    assert v.failure_time == rep.first_failure_time
    after = v.t > rep.first_failure_time + 0.05
    assert after.any() and np.isnan(v.margin[after]).all()
    assert np.isfinite(v.margin[v.t < rep.first_failure_time]).all()
    k = v.sample_at(rep.first_failure_time)
    assert np.allclose(v.failure_xyz, v.tip[k])


def test_locked_and_eight_joint_plans(spec, model8) -> None:
    traj = JointTrajectory.load(EXAMPLES / "transport_feasible.json")
    locked = plan_view(traj, model8, spec, wrist="locked")
    assert locked.margin is None and locked.verified is None
    assert np.all(locked.q[:, 6:] == 0.0)
    assert locked.tilt_deg.max() > 5.0  # a rigid spoon does not stay level here
    names = (*spec.arm.joint_names, *spec.wrist.joint_names)
    q8 = np.concatenate([traj.positions, np.full((len(traj), 2), 0.3)], axis=1)
    v8 = plan_view(JointTrajectory(names, traj.times, q8, np.zeros_like(q8)), model8, spec)
    assert np.allclose(v8.q[:, 6:], 0.3)
    with pytest.raises(ValueError, match="joint_names"):
        plan_view(JointTrajectory(("a", "b"), [0.0, 1.0], np.zeros((2, 2)),
                                  np.zeros((2, 2))), model8, spec)


def test_colliding_pairs_are_the_models_and_every_body_has_a_mesh(spec, model8) -> None:
    from articutool.arm.scene import Scene
    from articutool.viewer.app import _matches
    from articutool.viewer.geometry import geom_meshes, model_for_view

    q0 = np.concatenate([spec.arm.configuration("AbovePlate"), [0.0, 0.0]])
    rng = np.random.default_rng(0)
    hit = None
    for _ in range(500):
        q = q0.copy()
        q[1:3] += rng.uniform(-0.8, 0.8, 2)
        if model8.colliding_pairs(q):
            hit = q
            break
    assert hit is not None
    names = spec.arm.joint_names + list(spec.wrist.joint_names)
    traj = JointTrajectory(tuple(names), [0.0, 1.0], [q0, hit], np.zeros((2, 8)))
    v = plan_view(traj, model8, spec)
    assert v.collisions[-1] == model8.colliding_pairs(hit)
    assert v.colliding_samples.size and v.colliding_samples[-1] == v.t.size - 1
    # Every collision body the arm model can report is drawn by some mesh of the viewer.
    model, root = model_for_view(spec, Scene.load(), "spoon")
    meshes = geom_meshes(model, root)
    bodies = {b for pair in model8.collision_pairs for b in pair}
    for b in bodies:
        assert any(_matches(b, m) for m in meshes), b
    robot = {m.name for m in meshes if m.robot}
    assert {"atool_body", "atool_distal"} <= robot and any(n.startswith("utensil/")
                                                           for n in robot)
    assert not any(m.robot for m in meshes if m.name.startswith("scene/"))


# -------------------------------------------------------------------- CLI input --
def _busy_port() -> tuple[socket.socket, int]:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen()
    return s, s.getsockname()[1]


@pytest.mark.parametrize("args,field", [
    (["--plan", "no/such/file.json"], "cannot read"),
    (["--plan", "BADJSON"], "not valid JSON"),
    (["--plan", "WRONGJOINTS"], "joint_names"),
    (["--port", "70000"], "--port"),
    (["--plan-task", "99999"], "--plan-task"),
    (["--export", "x.mp4"], "--export needs --recording"),
    (["--plan", "a.json", "--plan-task", "1"], "at most one"),
    (["--utensil", "chopsticks"], "--utensil"),
])
def test_view_bad_input_exits_2(tmp_path: Path, args: list[str], field: str) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    wrong = tmp_path / "wrong.json"
    JointTrajectory(("a", "b"), [0.0, 1.0], np.zeros((2, 2)), np.zeros((2, 2))).save(wrong)
    args = [str(bad) if a == "BADJSON" else str(wrong) if a == "WRONGJOINTS" else a
            for a in args]
    r = run_cli("view", *args, "--duration", "1")
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert field in r.stderr and "Traceback" not in r.stderr
    assert "viewer: http" not in r.stdout  # no server was started


def test_view_refuses_a_port_in_use() -> None:
    s, port = _busy_port()
    try:
        r = run_cli("view", "--port", str(port), "--duration", "1")
    finally:
        s.close()
    assert r.returncode == 2 and "--port" in r.stderr and "in use" in r.stderr


def test_view_plans_a_benchmark_task_then_serves_it() -> None:
    r = run_cli("view", "--plan-task", "0", "--system", "strict8", "--timeout", "20",
                "--duration", "1", "--port", str(free_port()))
    assert r.returncode == 0, r.stderr
    assert "planning task 0 with strict8" in r.stdout
    assert "8-joint trajectory" in r.stdout and "viewer: http://127.0.0.1:" in r.stdout


