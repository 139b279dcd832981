"""``articutool sim`` and ``sim-calibrate``: real runs of the physics world from the CLI."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco")

from articutool.cli import main
from conftest import run_cli


def test_sim_carry_json_accounts_for_a_placed_load_and_its_snapshot_renders_headless(
        tmp_path: Path) -> None:
    # A placed load carried level: the report's accounting adds up, the F/T weighs what is on
    # the spoon, and the last frame renders offscreen in a process of its own.
    from PIL import Image

    png = tmp_path / "s.png"
    r = run_cli("sim", "--food", "pecans", "--load", "2", "--script", "carry", "--json",
                "--seed", "3", "--snapshot", str(png), timeout=900.0)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["total_g"] == pytest.approx(out["on_utensil_g"] + out["in_bowl_g"]
                                           + out["table_g"] + out["critical_g"]
                                           + out["airborne_g"] + out["eaten_g"])
    assert out["on_utensil_g"] > 0
    assert abs(out["ft_mass_g"] - out["on_utensil_g"]) < 0.5
    assert out["tool_fault"] == ""
    img = Image.open(png)
    assert img.size == (640, 480)
    assert len(np.unique(np.asarray(img.convert("L")))) > 20  # a scene, not a blank frame


@pytest.mark.slow  # the spoon in an awake pile of 190 pieces: a minute of CPU
def test_sim_scoop_json_reports_where_the_food_is_and_its_snapshot_renders_headless(
        tmp_path: Path) -> None:
    # The rigid scripted scoop takes 0-2 pecan pieces: seeds 0-4 took 0, 0.92, 0.97, 1.72 and
    # 0 g (the thesis' rigid baseline: 1.32 ± 0.48 g). The report's accounting and the F/T's
    # weighing need a load on the spoon: seed 3's scoop takes two pieces. The same run saves
    # its last frame, rendered offscreen in a process of its own (one scoop for both).
    from PIL import Image

    png = tmp_path / "s.png"
    r = run_cli("sim", "--food", "pecans", "--script", "scoop", "--json", "--seed", "3",
                "--snapshot", str(png), timeout=900.0)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    for key in ("on_utensil_g", "in_bowl_g", "table_g", "critical_g", "spills",
                "realtime_factor"):
        assert key in out
    assert out["total_g"] == pytest.approx(out["on_utensil_g"] + out["in_bowl_g"]
                                           + out["table_g"] + out["critical_g"]
                                           + out["airborne_g"] + out["eaten_g"])
    assert out["on_utensil_g"] > 0  # the scoop acquired something
    assert abs(out["ft_mass_g"] - out["on_utensil_g"]) < 0.5
    assert out["tool_fault"] == ""
    img = Image.open(png)
    assert img.size == (640, 480)
    assert len(np.unique(np.asarray(img.convert("L")))) > 20  # a scene, not a blank frame


@pytest.mark.parametrize("args,field", [
    (["--food", "caviar"], "--food"),
    (["--utensil", "chopsticks"], "--utensil"),
    (["--seed", "-3"], "--seed"),
    (["--video", "out.avi"], "--video"),
])
def test_sim_bad_input_exits_2_naming_the_field(args: list[str], field: str,
                                                tmp_path: Path) -> None:
    r = run_cli("sim", *args)
    assert r.returncode == 2, r.stderr
    assert field in r.stderr and "Traceback" not in r.stderr


def test_sim_never_overwrites_a_file(tmp_path: Path) -> None:
    p = tmp_path / "mine.png"
    p.write_bytes(b"precious")
    r = run_cli("sim", "--snapshot", str(p))
    assert r.returncode == 2 and "exists" in r.stderr
    assert p.read_bytes() == b"precious"


@pytest.mark.slow
def test_sim_video_renders_headless(tmp_path: Path) -> None:
    from PIL import Image

    gif, mp4 = tmp_path / "s.gif", tmp_path / "s.mp4"
    for path in (gif, mp4):
        r = run_cli("sim", "--food", "water", "--script", "tilt", "--video", str(path),
                    timeout=1200.0)  # SPH water and a render: minutes on a loaded host
        assert r.returncode == 0, r.stderr
    with Image.open(gif) as g:
        assert g.n_frames > 100
    assert mp4.stat().st_size > 10_000


@pytest.mark.slow  # three piles of 110 pieces with the no-slip solver: minutes of CPU
def test_sim_calibrate_measures_the_pecan_model(capsys: pytest.CaptureFixture[str]) -> None:
    from articutool.sim.params import PhysicsParams

    assert main(["sim-calibrate", "--food", "pecans", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    # The halves-and-pieces model's mean piece, as drawn from physics.toml's sizes.
    pecans = PhysicsParams.load().food("pecans")
    assert out["piece_mass_g"] == pytest.approx(pecans.piece_mass * 1000.0, abs=1e-3)
    assert out["angle_of_repose_cited_deg"] == pecans.angle_of_repose_deg
    # The verdict is the measured heap against the cited kernels' angle and its tolerance. The
    # shipped model's 28.3° passes, but its heap creeps with 2 no-slip passes (10 hold it and
    # stand at 32.5°): a pass is not asserted (docs/food.md).
    off = abs(out["angle_of_repose_deg"] - out["angle_of_repose_cited_deg"])
    within = off <= out["angle_of_repose_tolerance_deg"]
    assert out["angle_of_repose_within_tolerance"] == ("yes" if within else "no"), out
    assert 5.0 < out["angle_of_repose_deg"] < 60.0
    assert len(out["angle_of_repose_flank_piles_deg"].split(", ")) == 3
    # Static friction holds a resting half on the steel slopes (the creep law).
    assert out["creep_within_law"] == "yes", out["creep_mm"]
    assert out["level_capacity_g"] > 0


@pytest.mark.slow  # a heap of pieces poured and settled under the no-slip solver
def test_a_small_pile_test_pours_a_heap_over_the_plate() -> None:
    from articutool.sim.calibrate import PLATE_RADIUS_M, angle_of_repose_deg
    from articutool.sim.params import PhysicsParams

    params = PhysicsParams.load()
    r = angle_of_repose_deg(params.food("pecans"), params, n=25)
    assert 0 < r["pieces_on_plate"] <= 25
    assert r["angle_deg"] == pytest.approx(
        math.degrees(math.atan2(r["height_mm"] / 1e3, PLATE_RADIUS_M)))
    assert 5.0 < r["angle_deg"] < 60.0


def test_sim_mjcf_writes_the_world_mujoco_reads_back_exactly(tmp_path: Path) -> None:
    # The file is the world's model to the last bit (plus the keyframe 'start'), and its
    # keyframe holds the arm at Resting.
    import mujoco

    from articutool.arm.scene import Scene
    from articutool.sim.params import PhysicsParams
    from articutool.sim.world_spec import build_world_spec
    from articutool.spec import load_spec

    out = tmp_path / "world.xml"
    proc = run_cli("sim", "--food", "water", "--seed", "2", "--mjcf", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "mujoco.viewer" in proc.stdout
    m = mujoco.MjModel.from_xml_path(str(out))
    spec = load_spec()
    ref = build_world_spec(spec, Scene.load(), PhysicsParams.load(), "soup_spoon", "water", 2)
    r = ref.spec.compile()
    for field in ("body_pos", "body_quat", "body_mass", "geom_size", "geom_pos", "geom_quat",
                  "geom_friction", "geom_solref", "geom_priority", "pair_friction",
                  "jnt_range", "actuator_gainprm"):
        assert np.array_equal(getattr(m, field), getattr(r, field)), field
    assert m.opt.timestep == r.opt.timestep and m.nkey == 1 and r.nkey == 0
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, m.key("start").id)
    q = spec.arm.configuration("Resting")
    assert np.array_equal(d.qpos[:6], q)


def test_sim_mjcf_never_overwrites_nor_writes_through_a_link(tmp_path: Path) -> None:
    from conftest import assert_refused

    kept = tmp_path / "mine.xml"
    kept.write_text("<mujoco/>")
    assert_refused(run_cli("sim", "--mjcf", str(kept)), "--mjcf", "exists")
    assert kept.read_text() == "<mujoco/>"
    link = tmp_path / "link.xml"
    link.symlink_to(tmp_path / "elsewhere.xml")  # dangling: writing through it would create it
    assert_refused(run_cli("sim", "--mjcf", str(link)), "--mjcf")
    assert not (tmp_path / "elsewhere.xml").exists()
    assert_refused(run_cli("sim", "--mjcf", str(tmp_path / "world.txt")), "--mjcf", ".xml")
    # A load the utensil cannot hold is refused as `sim` refuses it, and nothing is written.
    assert_refused(run_cli("sim", "--food", "pecans", "--load", "300", "--mjcf",
                           str(tmp_path / "heap.xml")), "--load")
    assert not (tmp_path / "heap.xml").exists()
