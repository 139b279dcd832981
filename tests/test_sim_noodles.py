"""Noodles as capsule chains: the model, its stability, the fork's twirl option."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from articutool.sim.params import PhysicsParams  # noqa: E402
from articutool.sim.scenes import max_twirl_turns  # noqa: E402
from articutool.sim.world import FeedingWorld  # noqa: E402
from articutool.spec import load_spec  # noqa: E402

_RESETS = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
           mujoco.mjtWarning.mjWARN_BADQACC)


def test_noodle_world_builds_as_jointed_chains() -> None:
    from articutool.sim.build import WorldConfig, build_parts

    food = PhysicsParams.load().food("noodles")
    parts = build_parts(WorldConfig("noodles", seed=5000))  # the model alone: no step
    m = parts.model
    n = len(parts.layout.food_strands)
    assert n == round(food.fill_g / 1000 / food.piece_mass)
    assert m.nflex == 0 and m.opt.noslip_iterations == food.noslip_iterations
    # Every strand is `segments` bodies: a free root and ball joints whose spring is E·I/ds.
    balls = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL]
    assert len(balls) == n * (food.segments - 1)
    ei = food.young * math.pi * food.strand_radius**4 / 4
    ds = food.strand_length / food.segments
    assert m.jnt_stiffness[balls] == pytest.approx(ei / ds)
    # MuJoCo reserves the arena the world's spec asks for (the thesis bowl's test below reads
    # the spec alone).
    assert m.narena == parts.layout.spec.memory > 0


@pytest.mark.slow  # the laid nest falls and settles: a minute of CPU
def test_the_noodle_world_stays_stable() -> None:
    food = PhysicsParams.load().food("noodles")
    w = FeedingWorld.make("noodles", seed=5000)
    m, d = w.model, w.data
    n = len(w.layout.food_strands)
    w.run(1.0)  # the heap settles for 1 s more with the tool running
    assert np.isfinite(d.qpos).all()
    assert all(d.warning[int(k)].number == 0 for k in _RESETS)
    g = w.ledger.masses_g()
    assert g["container"] == pytest.approx(n * food.piece_mass * 1000)
    # The heap stays a heap round the bowl's centre (nothing thrown out by stored energy).
    bowl = w.scene.get("bowl")
    xy = np.array([d.xpos[m.body(f"{s}/{i}").id][:2] for s in w.layout.food_strands
                   for i in range(food.segments)])
    assert np.max(np.linalg.norm(xy - np.asarray(bowl.xyz[:2]), axis=1)) < bowl.radius


def test_a_strand_collides_with_itself_but_not_across_a_joint() -> None:
    from articutool.sim.build import WorldConfig, build_parts

    # the model alone: no step of the laid nest
    m = build_parts(WorldConfig("noodles", seed=5000)).model
    a, b, c = (m.geom(f"strand0/{i}").id for i in (0, 1, 5))
    assert m.geom_contype[a] & m.geom_conaffinity[c]  # a wrap can rest on its own strand
    assert m.body_parentid[m.geom_bodyid[b]] == m.geom_bodyid[a]  # neighbours: parent-child
    assert not m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT


def test_the_thesis_bowl_reserves_the_arena_its_settling_heap_was_measured_to_use() -> None:
    """MuJoCo aborts a step whose contacts outgrow its arena (the 125 g nest overflowed 256 MB
    while it fell); the arena reserved for 125 g holds twice what the laid bowl's fall used
    (studies/noodle_cost.py --settle-s, its JSON committed). The world's spec is built, not
    compiled (11 CPU s for this bowl): the compiled nest above reserves what its spec asks."""
    import json
    from pathlib import Path

    from articutool.arm.scene import Scene
    from articutool.sim.world_spec import build_world_spec

    trace = json.loads((Path(__file__).resolve().parents[1] / "studies" / "results" /
                        "noodle_settle_125g.json").read_text())
    params = _noodle_params(fill_g=125.0)
    layout = build_world_spec(load_spec(), Scene.load(), params, "fork", "noodles", seed=6000)
    assert trace["fill_g"] == 125.0 and trace["strands"] == len(layout.food_strands) == 63
    assert layout.spec.memory >= 2 * trace["arena_max_used_mb"] * 2**20


@pytest.mark.parametrize("args", [["--twirl-turns", "5"], ["--twirl-turns", "-1"],
                                  ["--twirl-turns", "nan"], ["--twirl-turns", "two"],
                                  ["--utensil", "spoon", "--twirl-turns", "1"]])
def test_twirl_turns_bad_input_exits_2_naming_the_field(args: list[str]) -> None:
    r = subprocess.run([sys.executable, "-m", "articutool", "sim", "--food", "noodles",
                        "--script", "scoop", *args], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2, r.stderr
    assert "--twirl-turns" in r.stderr and "Traceback" not in r.stderr


def test_twirl_turns_range_is_the_cable_budget() -> None:
    hi = max_twirl_turns(load_spec())
    assert hi < load_spec().wrist.roll_turn_budget
    r = subprocess.run([sys.executable, "-m", "articutool", "sim", "--food", "noodles",
                        "--twirl-turns", f"{hi + 0.01}"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2 and f"[0, {hi:g}]" in r.stderr


@pytest.mark.slow  # the laid nest stepped while it falls
def test_a_noodle_recording_holds_every_capsule_where_the_world_has_it(tmp_path) -> None:
    from articutool.sim.recording import Recorder, Recording

    w = FeedingWorld.make("noodles", seed=5000, settle=False)
    rec = Recorder(w)
    w.run(0.1)
    rec.save(tmp_path / "n.npz")
    r = Recording.load(tmp_path / "n.npz")
    segs = PhysicsParams.load().food("noodles").segments
    assert r.meta["food_kind"] == "strands"
    assert r.meta["strand_vertices"] == [segs] * len(w.layout.food_strands)
    last = r.food_xyz[-1].reshape(len(w.layout.food_strands), segs, 3)
    # Strand 3's points are its capsules' origins, in order along the chain (the last frame
    # is up to one recording period old: within 1 mm of now, far less than a segment).
    ids = [w.model.body(f"strand3/{i}").id for i in range(segs)]
    assert np.allclose(last[3], w.data.xpos[ids], atol=1e-3)
    assert r.point_class(len(r) - 1).size == segs * len(w.layout.food_strands)


@pytest.mark.slow
def test_the_forks_acquisition_twirls_through_the_tool_runtime_and_lifts_strands() -> None:
    from articutool.sim.accounting import UTENSIL
    from articutool.sim.scenes import skewer

    w = FeedingWorld.make("noodles", seed=5000)  # a study seed (studies/noodle_twirl.py)
    turns = max_twirl_turns(w.spec)
    roll: list[float] = []
    w.on_tick.append(lambda world: roll.append(float(world.wrist_q[1])))
    skewer(w, level=True, twirl_turns=turns)
    # The tool's own TWIRL_CW turned the roll joint (the script only asked), without a fault.
    assert max(roll) >= 2 * math.pi * turns - 0.1
    assert w.tool.fault == ""
    assert all(w.data.warning[int(k)].number == 0 for k in _RESETS)
    # Every strand is somewhere: on the fork, in the bowl or fallen (what the fork lifts is the
    # twirl study's measurement, studies/noodle_twirl.py, not an assertion).
    g = w.ledger.masses_g()
    n_on = int(np.sum(w.ledger.item_classes() == UTENSIL))
    assert g["utensil"] == pytest.approx(n_on * w.layout.piece_mass * 1000)
    assert sum(g.values()) == pytest.approx(len(w.layout.food_strands) * w.layout.piece_mass
                                            * 1000)


def _study_module():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "studies" / "noodle_twirl.py"
    spec = importlib.util.spec_from_file_location("noodle_twirl", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_study_never_counts_a_run_mujoco_reset(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # MuJoCo writes MUJOCO_LOG.TXT on a warning
    study = _study_module()
    def run(seed: int, turns: float, g: float, reset: bool = False) -> dict:
        return {"seed": seed, "twirl_turns": turns, "lifted_g": g, "ft_mass_g": g + 0.5,
                "reset": reset, "realtime_factor": 0.3}

    runs = ([run(s, 2.0, g) for s, g in ((0, 4.0), (1, 5.0), (2, 6.0))]
            + [run(3, 2.0, 99.0, reset=True), run(3, 0.0, 0.0)]
            + [run(s, 0.0, g) for s, g in ((0, 0.0), (1, 1.0), (2, 0.0))])
    s = study.summarise(runs, 2.0)
    assert (s["twirl"]["runs"], s["twirl"]["reset"], s["twirl"]["n"]) == (4, 1, 3)
    assert s["twirl"]["mean_g"] == pytest.approx(5.0)  # the reset run's 99 g is not in it
    assert s["twirl"]["ft_mean_g"] == pytest.approx(5.5)
    assert s["mann_whitney_u"]["p_one_sided"] < 0.1  # all twirl runs above all still ones
    assert s["paired_wilcoxon"]["pairs"] == 3  # seed 3's still run has no kept twirl pair
    # A real reset is what the study detects: MuJoCo's counter after an unstable step.
    m = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body><freejoint/><geom size="0.1"/></body></worldbody></mujoco>')
    d = mujoco.MjData(m)
    d.qvel[0] = math.nan
    mujoco.mj_step(m, d)
    assert "mjWARN_BADQVEL" in study.warnings_of(d)


def _noodle_params(**food: float) -> PhysicsParams:
    d = PhysicsParams.load().model_dump()
    d["foods"]["noodles"].update(food)
    return PhysicsParams.from_dict(d)


def test_starch_tack_without_a_gap_is_refused_naming_the_field() -> None:
    from articutool.sim.params import PhysicsError

    # MuJoCo's contact adhesion acts only across a gap: without one it would silently do nothing.
    with pytest.raises(PhysicsError, match="adhesion_gap"):
        _noodle_params(stickiness_pa=650.0, adhesion_gap=0.0)


def test_tack_is_the_force_of_fork_and_strand_contacts() -> None:
    food = PhysicsParams.load().food("noodles")
    assert food.stickiness_pa > 0  # the shipped strands stick
    w = FeedingWorld.make("noodles", seed=5100, settle=False)
    m = w.model
    tine, s0, s1 = (m.geom(n).id for n in ("utensil/tine0", "strand0/3", "strand1/7"))
    # A fork-strand contact takes the fork's adhesion alone (the higher priority decides, as
    # for every food-partner law): a strand lying on it; two strands' contact sums theirs
    # (equal priorities): the film's law averaged over a settled nest's contact angles.
    assert m.geom_priority[tine] > m.geom_priority[s0] == m.geom_priority[s1]
    assert m.geom_adhesion[tine] == pytest.approx(food.tack_per_contact, rel=1e-5)
    assert m.geom_adhesion[s0] + m.geom_adhesion[s1] == pytest.approx(
        food.tack_per_strand_contact, rel=1e-5)
    # Each carries half the gap: MuJoCo sums a pair's.
    assert m.geom_gap[[tine, s0, s1]] == pytest.approx([food.adhesion_gap / 2] * 3)
    # The settled nest's crossings pull: an adhesive passive force acts on the strands,
    # where a friction-only nest has none.
    w.run(0.3, tick=False)
    assert np.abs(w.data.qfrc_adhesion).max() > 0
    plain = FeedingWorld.make("noodles", seed=5100, settle=False,
                               params=_noodle_params(stickiness_pa=0.0))
    plain.run(0.3, tick=False)
    assert np.abs(plain.data.qfrc_adhesion).max() == 0


@pytest.mark.parametrize("lower", ["strand", "fork"])
def test_a_sticky_pair_pulls_across_the_adhesion_gap_and_no_further(lower: str) -> None:
    # MuJoCo sums the two geoms' gaps (whatever their priorities): the pair's range is the
    # food's adhesion_gap, not twice it.
    from articutool.sim.food_strands import set_fork_strand, set_strand_geom

    food = PhysicsParams.load().food("noodles")
    r, gap = food.strand_radius, food.adhesion_gap
    set_lower = set_strand_geom if lower == "strand" else set_fork_strand
    for sep, pulls in ((0.9 * gap, True), (1.1 * gap, False)):
        s = mujoco.MjSpec()
        s.option.gravity = [0.0, 0.0, 0.0]
        set_lower(s.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[r, 0, 0],
                                       fromto=[0.0, -0.005, 0.0, 0.0, 0.005, 0.0]), food)
        b = s.worldbody.add_body(pos=[0.0, 0.0, 2 * r + sep])
        b.add_freejoint()
        set_strand_geom(b.add_geom(type=mujoco.mjtGeom.mjGEOM_CAPSULE, size=[r, 0, 0],
                                   fromto=[-0.005, 0.0, 0.0, 0.005, 0.0, 0.0]), food)
        m = s.compile()
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        assert (np.abs(d.qfrc_adhesion).max() > 0) == pulls, (lower, sep)


def test_a_twirl_before_insertion_frees_roll_budget_for_the_twirl_inside() -> None:
    from articutool.sim.scenes import skewer

    class TwirledError(Exception):
        pass

    def stop(name: str) -> None:
        if name == "twirled":
            raise TwirledError

    w = FeedingWorld.make(None, "fork", seed=1)  # the bowl without food: the fork's motion only
    roll: list[float] = []
    w.on_tick.append(lambda world: roll.append(float(world.wrist_q[1])))
    hi = max_twirl_turns(w.spec)
    with pytest.raises(TwirledError):
        skewer(w, twirl_turns=hi + 2.0, prewind_turns=2.0, on_phase=stop)
    # The tool's own TWIRL_CCW turned 2 turns back first, then TWIRL_CW 4.9 turns forward:
    # more than the cable budget allows from zero, never past it.
    assert min(roll) == pytest.approx(-2 * 2 * math.pi, abs=0.1)
    assert max(roll) == pytest.approx(2 * math.pi * hi, abs=0.1)
    assert max(roll) - min(roll) > 2 * math.pi * w.spec.wrist.roll_turn_budget
    assert w.tool.fault == ""


def test_the_lever_table_shows_every_run_and_never_counts_a_reset_one(tmp_path,
                                                                     monkeypatch) -> None:
    import importlib
    import json
    from pathlib import Path

    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "studies"))
    levers = importlib.import_module("noodle_levers")

    def run(seed: int, turns: float, g: float, reset: bool = False) -> dict:
        return {"seed": seed, "twirl_turns": turns, "lifted_g": g, "ft_mass_g": g,
                "strands_touching": {"in": 7, "twirled": 2, "lifted": round(g)},
                "reset": reset, "warnings": {"mjWARN_BADQACC": 1} if reset else {},
                "realtime_factor": 0.25}

    base = {"what": "shipped", "still_from": None, "twirl_turns": 2.9,
            "runs": [run(5100, 2.9, 4.0), run(5100, 0.0, 8.0),
                     run(5101, 2.9, 99.0, reset=True), run(5101, 0.0, 1.0)]}
    more = {"what": "more turns", "still_from": "baseline", "twirl_turns": 4.9,
            "runs": [run(5100, 4.9, 9.0), run(5101, 4.9, 3.0)]}
    (tmp_path / "baseline.json").write_text(json.dumps(base))
    (tmp_path / "more_turns.json").write_text(json.dumps(more))
    rows = levers.table(tmp_path).splitlines()[2:]
    # One row per variant and seed, twirl and still side by side, a mean where two pairs count.
    assert [r.split("|")[2].strip() for r in rows] == ["5100", "5101", "5100", "5101", "mean"]
    assert rows[0].startswith("| baseline: shipped | 5100 | 4.00 (7 / 2 / 4) | 8.00 (7 / 8) ")
    # The reset run is listed and flagged, but no difference is taken from it.
    assert "99.00 (reset: not counted)" in rows[1] and "| – | 1 (BADQACC) |" in rows[1]
    # A motion-only lever is compared with the baseline's still fork on the same seeds.
    assert "| 1.00 (7 / 1) (baseline) | +2.00 |" in rows[3]
    assert "| +1.50 (2 of 2 seeds more) |" in rows[4]
