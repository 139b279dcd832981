"""One real trial of each protocol in the physics world (tiny settings): the records hold
every measured quantity, every gram is accounted for, and the same seed gives the same trial."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("mujoco")

import articutool.cli as cli
from articutool.experiments.analysis import classify
from articutool.experiments.config import ExperimentsConfig
from articutool.experiments.design import conditions, make_trials
from articutool.experiments.runner import run_trial, source_version

CFG = ExperimentsConfig.load()


def _accounted(r: dict) -> float:
    """Every gram held after placing: delivered, shed by a primitive, spilled (in transport
    anything that left the utensil, a container and the air included)."""
    return r["delivered_g"] + r["spilled_g"] + r.get("shed_g", 0.0)


@pytest.mark.slow
def test_capacity_trial_scoops_the_full_bowl_and_weighs_what_the_level_spoon_holds() -> None:
    spec = make_trials("capacity", conditions("capacity", CFG), 1, 0)[0]  # pecans
    r = run_trial(spec).to_log()
    assert r["error"] is None, r.get("traceback")
    assert r["food"] == "pecans" and r["seed"] == 0 and r["completed"]
    assert r["tilt_deg"] < 3.0  # lifted level
    assert r["scoop_g"] > 0.5  # at least a piece
    assert r["scoop_g"] == pytest.approx(r["items_g"], abs=0.1)  # a scale reads the pieces
    assert r["ft_mass_g"] == pytest.approx(r["scoop_g"], abs=0.5)  # the HEX21 agrees
    assert "brim_g" not in r  # a brim test is a liquid's


@pytest.mark.slow
def test_capacity_trial_of_water_also_fills_the_dish_to_the_brim() -> None:
    from articutool.sim.loading import dish_volume_m3
    from articutool.spec import load_spec

    spec = make_trials("capacity", conditions("capacity", CFG), 1, 0)[1]
    r = run_trial(spec).to_log()
    assert r["error"] is None, r.get("traceback")
    assert r["food"] == "water" and r["completed"]
    level_g = dish_volume_m3(load_spec().utensil("soup_spoon")) * 1e6
    assert r["brim_poured_g"] < level_g
    assert 0.8 * r["brim_poured_g"] < r["brim_g"] <= r["brim_poured_g"] + 1e-6


@pytest.mark.slow  # a strict plan and a carry of SPH water: minutes of CPU
def test_exp2b_trial_baseline_water_to_a_goal_accounts_for_every_gram() -> None:
    goals = ["low_near"]
    trials = make_trials("exp2b", conditions("exp2b", CFG, goals=goals), 1, 0, goals=goals)
    spec = next(t for t in trials if t.condition.fields() == {"food": "water", "system": "baseline",
                                                "goal": "low_near"})
    r = run_trial(spec).to_log()
    assert r["error"] is None, r.get("traceback")
    assert r["planner"] == "strict6" and r["tolerance_deg"] == CFG.settings.arm_tolerance_deg
    assert r["completed"] and r["planning_attempts"] >= 1 and r["motion_time_s"] > 0
    assert 0 < r["held_g"] <= CFG.exp2b.load_g["water"] + 1e-6
    assert _accounted(r) == pytest.approx(r["held_g"], abs=1e-3)
    assert r["max_tilt_deg"] < 30.0  # ±20° per axis is at most ~28° from vertical
    json.dumps(r)  # a JSON record


@pytest.mark.parametrize("name", [*CFG.exp2b.systems, *CFG.exp2b.variants])
def test_each_exp2b_systems_food_check_models_the_wrist_it_carries(name: str) -> None:
    # The baseline's arm is the locked spoon's, so its check predicts the locked carry
    # (an arm built without it modelled a leveling wrist under a locked spoon).
    from types import SimpleNamespace

    from articutool.arm.scene import Scene
    from articutool.experiments.units.exp2b import exp2b_arm
    from articutool.feeding.system import System
    from articutool.food.definitions import load_food_definitions
    from articutool.food.loads import food_load
    from articutool.planning.api import plan
    from articutool.planning.types import PlanRequest, TransportTask
    from articutool.spec import load_spec

    spec, scene = load_spec(), Scene.load()
    sset = scene.staging_set
    world = SimpleNamespace(spec=spec, scene=scene, utensil="soup_spoon", q=np.zeros(8))
    goals = {g.name: g.q for g in sset.goals}
    arm = exp2b_arm(world, name, CFG, goals, seed=0)  # type: ignore[arg-type]
    v = CFG.exp2b.variants.get(name)
    system = System.of(v.system if v else name, tolerance_deg=CFG.settings.arm_tolerance_deg)
    assert arm.rigid == (not system.wrist)
    assert (arm.load is not None) == bool(v and v.food_check)
    arm.load = food_load(load_food_definitions()["water"], 7.0)
    req = PlanRequest(planner=system.transport.name, task=TransportTask(
        0, tuple(sset.start), tuple(goals["right"])), timeout_s=10.0, seed=0,
        utensil="soup_spoon", tolerance_deg=system.transport.tolerance_deg)
    traj = plan(req, spec).trajectory
    assert traj is not None
    check = arm.check_food(traj).value
    modelled = {t["wrist"] for t in check.record["tried"] if "wrist" in t} if check.record \
        else set()
    carried = {"leveling", "slosh_free"} if system.wrist else {"locked"}
    assert modelled and modelled <= carried, (name, modelled)
    arm.close()


@pytest.mark.slow
@pytest.mark.parametrize("variant", [n for n, v in CFG.exp2b.variants.items() if v.food_check])
def test_each_exp2b_food_check_models_the_wrist_the_trial_carries(variant: str) -> None:
    # The check predicts the spill of the wrist the transport has: locked for the baseline,
    # leveling (or slosh-free) for the Articutool.
    from articutool.feeding.system import System

    v = CFG.exp2b.variants[variant]
    goals = ["right"]
    trials = make_trials("exp2b", conditions("exp2b", CFG, goals=goals), 1, 0, goals=goals)
    spec = next(t for t in trials if t.condition.system == variant)
    r = run_trial(spec).to_log()
    assert r["error"] is None, r.get("traceback")
    wrists = {c["wrist"] for c in r["food_checks"]}
    assert wrists, "the variant ran no food check"
    carried = ({"leveling", "slosh_free"} if System.of(v.system).wrist else {"locked"})
    assert wrists <= carried, (variant, wrists)


@pytest.mark.slow
def test_exp2c_trial_tilt_primitive_then_transport_and_replay_is_identical() -> None:
    trials = make_trials("exp2c", conditions("exp2c", CFG, load_g={"pecans": 10.0,
                                                                   "water": 15.5}), 1, 0)
    spec = next(t for t in trials if t.condition.food == "water"
                and t.condition.condition == "primitive")
    r = run_trial(spec).to_log()
    assert r["error"] is None, r.get("traceback")
    assert r["primitive"] == "TILT" and r["primitive_ok"]
    assert r["completed"]
    assert _accounted(r) == pytest.approx(r["held_g"], abs=1e-3)
    again = run_trial(spec).to_log()
    for k in ("held_g", "delivered_g", "spilled_g", "shed_g", "after_primitive_g"):
        assert again[k] == r[k]


@pytest.mark.slow
def test_cli_exp2b_one_trial_per_condition_then_report(tmp_path, capsys) -> None:
    out = tmp_path / "res"
    assert cli.main(["experiment", "exp2b", "--trials", "1", "--workers", "1", "--out",
                     str(out), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    # The thesis' foods × systems, and each extra system on its foods (one trial each).
    e = CFG.exp2b
    n = len(e.foods) * len(e.systems) + sum(len(v.foods) for v in e.variants.values())
    assert s["run"]["trials"] == n and (out / "exp2b" / "exp2b.png").exists()
    # Every trial records the code it ran; the summary counts trials per code version.
    assert s["run"]["sources"] == {source_version(): n}
    video = tmp_path / "t3.gif"
    # A fresh process, as a user runs it (MuJoCo picks its GL backend when first imported).
    r = subprocess.run([sys.executable, "-m", "articutool.cli", "experiment", "exp2b",
                        "--trial", "3", "--video", str(video), "--out", str(out)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "reproduces the logged record" in r.stdout
    assert video.stat().st_size > 0
    assert cli.main(["experiment", "report", "--out", str(out)]) == 0
    md = (out / "report.md").read_text()
    assert "Exp. 2b" in md and "1.31" in md and "Honesty rules" in md
    assert f"code: {source_version()} ({n} trials)" in md
    assert "<table>" in (out / "report.html").read_text()


@pytest.mark.slow
def test_exp1_trial_pecans_acquires_and_weighs_at_resting() -> None:
    trials = make_trials("exp1", conditions("exp1", CFG), 1, 0)
    spec = next(t for t in trials
                if t.condition.fields() == {"food": "pecans", "system": "articutool"})
    r = run_trial(spec).to_log()
    assert r["error"] is None, r.get("traceback")
    assert r["stages"] == ["above", "acquire", "resting"] and r["completed"]
    assert r["mass_g"] == pytest.approx(r["masses_end_g"]["utensil"])
    assert r["mass_g"] > 0 and r["spilled_g"] >= 0
    json.dumps(r, allow_nan=False)  # strict JSON: NaN became None


@pytest.mark.slow
def test_exp3_trial_noodles_whole_bite_is_classified_from_its_masses_at_analysis() -> None:
    trials = make_trials("exp3", conditions("exp3", CFG), 1, 0)
    rec = run_trial(trials[0])
    r = rec.to_log()
    assert r["error"] is None, r.get("traceback")
    assert r["stages"] == ["above", "acquire", "shed", "resting", "staging", "present"]
    assert r["completed"] and r["failed_stage"] == "", r
    assert r["planning_attempts_by_goal"]["Staging"] >= 1
    # The class is derived at analysis time, at the report's threshold (our Exp. 1 mean).
    assert r["outcome"] is None
    spilled, d = r["spilled_by_place"], r["delivered_g"]
    assert r["spilled_g"] == pytest.approx(sum(spilled.values()))
    for threshold_g in (0.0, d, 3.0):
        assert classify(rec, threshold_g) == ("user_spill" if spilled["critical"] > 0 else
                                            "table_spill" if spilled["table"] > 0 else
                                            "meaningful_success" if d > threshold_g else
                                            "trivial_success")
    json.dumps(r, allow_nan=False)


def test_a_particle_on_the_table_then_the_floor_is_spilled_once_in_a_record() -> None:
    # Exp. 3 and Exp. 2b/2c read one definition of a spill: net mass changes, not summed
    # events (table + floor for one particle). A locked 40° carry of 8 g of water (seed 0)
    # spills onto the table; water deposits where it lands, so one spilled particle is then
    # moved off the table's edge to the floor (as a drop that ran over the edge).
    import mujoco

    from articutool.experiments.protocols import transport_outcome
    from articutool.sim.scenes import base_tilt_motion, load
    from articutool.sim.world import FeedingWorld
    from conftest import drop_off_the_table

    w = FeedingWorld.make("water", seed=0, load_g=8.0)
    w.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_SLEEP)  # moved by hand below
    load(w, level=False)
    before, n0, start = w.ledger.masses_g(), len(w.ledger.spills), w.ledger.item_classes()
    w.move_arm(base_tilt_motion(w, 40.0))
    w.run(3.0)
    drop_off_the_table(w)
    w.run(0.5)
    events = w.ledger.spills[n0:]
    items = {e.item for e in events}
    assert len(events) > len(items)  # a particle spilled twice: table, then floor
    r = transport_outcome(w, start, n0, before)
    g = w.ledger.item_g
    lost = (start == 1) & (w.ledger.item_classes() != 1)  # left the spoon (1: utensil)
    assert r["spilled_g"] == pytest.approx(g[lost].sum(), abs=1e-3)  # each once
    floor = {e.item for e in events if e.place == "critical" and start[e.item] == 1}
    assert r["spilled_by_place"]["critical"] == pytest.approx(sum(g[k] for k in floor),
                                                              abs=1e-3)


def _dish_centre(model, q_arm, utensil_spec) -> np.ndarray:
    from articutool.food.dish import spoon_dish

    T = model.tip_pose(np.r_[q_arm, 0.0, 0.0])
    return T[:3, 3] - (utensil_spec.tip_z - spoon_dish(utensil_spec)[0]) * T[:3, 2]


def test_the_shedding_pose_is_over_the_scenes_bowl_wherever_the_bowl_is(tmp_path) -> None:
    from articutool.arm.model import ArmModel
    from articutool.arm.scene import Scene, container_floor
    from articutool.meal.bites import shed_configuration
    from articutool.spec import load_spec
    from articutool.tool.kinematics import tilt_from_vertical

    spec = load_spec()
    text = (Path(__file__).parents[1] / "src/articutool/data/scene.toml").read_text()
    moved = tmp_path / "scene.toml"
    assert "xyz = [0.45, -0.45, 0.03]" in text
    moved.write_text(text.replace("xyz = [0.45, -0.45, 0.03]", "xyz = [0.40, -0.38, 0.03]"))
    for scene in (Scene.load(), Scene.load(moved)):
        for utensil in ("spoon", "soup_spoon"):
            q = shed_configuration(spec, scene, utensil)
            model = ArmModel(spec, utensil, 8, scene)
            p = _dish_centre(model, q, spec.utensil(utensil))
            floor = container_floor(scene, "bowl")
            assert np.hypot(*(p[:2] - floor[:2])) < 1e-3  # the dish over the bowl's centre
            assert p[2] - floor[2] == pytest.approx(0.10, abs=1e-3)  # the lift's height
            up = model.tip_pose(np.r_[q, 0.0, 0.0])[:3, 1]
            assert np.degrees(tilt_from_vertical(up)) < 0.1  # level with the wrist at zero
            assert not model.in_collision(np.r_[q, 0.0, 0.0])


@pytest.mark.slow
def test_exp2c_sheds_over_the_bowl_what_falls_is_shed_not_spilled() -> None:
    # Water's closed-loop TILT_UNTIL_LOAD (the shipped open-loop TILT, 0.2 rad, sheds
    # nothing) at the shedding pose, seed 1: particles leave the spoon; they land in the bowl
    # and count as shed. At Resting (over the plate) a TILT poured onto the plate, the table
    # and the floor (an earlier committed run).
    trials = make_trials("exp2c", conditions("exp2c", CFG, load_g={"pecans": 8.48,
                                                                   "water": 15.5}), 2, 0)
    spec = next(t for t in trials if t.condition.food == "water"
                and t.condition.condition == "closed_loop" and t.seed == 1)
    r = run_trial(spec).to_log()
    assert r["error"] is None, r.get("traceback")
    assert r["primitive"] == "TILT_UNTIL_LOAD" and r["primitive_ok"] and r["completed"]
    moved = r["primitive_moved_g"]
    assert moved["container"] > 0  # food left the spoon and landed in the bowl
    assert moved["table"] == 0 and moved["critical"] == 0
    assert r["held_g"] - r["after_primitive_g"] == pytest.approx(moved["container"], abs=1e-3)
    assert r["shed_g"] == pytest.approx(moved["container"], abs=1e-3)
    assert r["spilled_g"] == 0
    assert _accounted(r) == pytest.approx(r["held_g"], abs=1e-3)


def test_food_that_leaves_the_spoon_in_transport_and_lands_in_the_bowl_is_spilled() -> None:
    # Exp. 2b baseline trial 47 lost 0.42 g into a container and scored 0 g spilled. Here a
    # locked spoon of water over the bowl (the shedding pose) tilts 40° on its way: what
    # pours into the bowl is a transport spill, reported apart (place "container").
    from articutool.arm.scene import Scene
    from articutool.experiments.protocols import transport_outcome
    from articutool.meal.bites import shed_configuration
    from articutool.sim.scenes import base_tilt_motion, load
    from articutool.sim.world import FeedingWorld
    from articutool.spec import load_spec

    q = shed_configuration(load_spec(), Scene.load(), "soup_spoon")
    w = FeedingWorld.make("water", seed=0, load_g=8.0, q_arm=q, mouth=False)
    load(w, level=False)
    before, n0, start = w.ledger.masses_g(), len(w.ledger.spills), w.ledger.item_classes()
    w.move_arm(base_tilt_motion(w, 40.0))
    w.run(2.0)
    r = transport_outcome(w, start, n0, before)
    into_bowl = w.ledger.masses_g()["container"] - before["container"]
    assert into_bowl > 0.4  # at least one particle poured into the bowl
    assert r["spilled_by_place"]["container"] == pytest.approx(into_bowl, abs=1e-3)
    assert r["spilled_g"] == pytest.approx(sum(r["spilled_by_place"].values()), abs=1e-3)
    assert r["spilled_g"] + r["delivered_g"] == pytest.approx(before["utensil"], abs=1e-3)


def test_exp2b_has_no_mouth_the_load_at_the_centre_goal_is_weighed_not_eaten() -> None:
    # The centre goal's dish ends inside the scene's 3 cm mouth region: the load used to be
    # eaten on arrival (4 of 20 trials per system). The experimenter weighs the utensil.
    goals = ["centre"]
    trials = make_trials("exp2b", conditions("exp2b", CFG, goals=goals), 1, 0, goals=goals)
    spec = next(t for t in trials if t.condition.food == "pecans"
                and t.condition.system == "articutool")
    r = run_trial(spec).to_log()
    assert r["error"] is None, r.get("traceback")
    assert r["masses_after_g"]["eaten"] == 0.0
    assert r["delivered_g"] == pytest.approx(r["masses_after_g"]["utensil"], abs=1e-4)
    assert r["delivered_g"] > 0 and r["weighed_g"] == pytest.approx(r["delivered_g"], abs=0.1)
    assert _accounted(r) == pytest.approx(r["held_g"], abs=1e-3)


def test_exp2c_closed_loop_target_is_derived_from_the_threshold_above_it() -> None:
    from articutool.experiments.units.exp2c import closed_loop_params, closed_loop_target_g

    assert closed_loop_target_g(8.65, 0.42, 0.09) == pytest.approx(8.65 + 0.42 + 0.27)
    conds = [c.fields() for c in conditions("exp2c", CFG, load_g={"pecans": 8.0,
                                                                  "water": 15.5},
                                            target_g={"water": 9.3})]
    closed = {c["food"]: c for c in conds if c["condition"] == "closed_loop"}
    assert closed["water"]["target_g"] == 9.3 and "target_g" not in closed["pecans"]
    assert "target_g" not in next(c for c in conds if c["condition"] == "control")
    shed = CFG.exp2c.closed_loop["water"]
    params = closed_loop_params(shed.primitive, list(shed.params), 9.3)
    assert params[3] == 9.3 and params[:3] == list(shed.params)[:3]
    pecans = CFG.exp2c.closed_loop["pecans"]
    assert closed_loop_params(pecans.primitive, list(pecans.params), 9.3) == list(pecans.params)


def test_cli_exp2c_without_thresholds_exits_2_naming_them(tmp_path, capsys) -> None:
    (tmp_path / "capacity").mkdir()
    (tmp_path / "capacity" / "summary.json").write_text(json.dumps(
        {"foods": {"pecans": {"capacity_g": {"mean": 7.0}},
                   "water": {"capacity_g": {"mean": 15.0}}}}))
    assert cli.main(["experiment", "exp2c", "--trials", "1", "--workers", "1",
                     "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "--thresholds-g" in err and "closed-loop target" in err
