"""MCAP recordings: ROS 2 CDR messages with embedded ``ros2msg`` schemas,
read back with the standard readers (``mcap``'s reader and the ``mcap_ros2`` decoder).

The tool and the client are real processes (``articutool tool --record``, ``articutool client
--record``); a recording cut by SIGKILL is read with mcap's streaming reader up to its last
complete chunk; nothing overwrites an existing file.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, make_reader
from mcap_ros2.decoder import DecoderFactory

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.recording import McapRecorder, RecordingError, schema_name
from articutool.tool.api import Mode, PrimitiveStatus, ToolState
from articutool.trajectory import JointTrajectory
from conftest import free_port, wait_until

SRC = Path(__file__).resolve().parent.parent / "src"
ENV = dict(os.environ, PYTHONPATH=str(SRC))


def _state() -> ToolState:
    return ToolState(stamp=1.0, mode=Mode.LEVELING, joint_names=("atool_pitch", "atool_roll"),
                     position=(0.1, -0.25), velocity=(0.5, 0.0),
                     orientation_wxyz=(0.9, 0.1, -0.2, 0.3), angular_velocity=(0.01, 0.02, 0.03),
                     linear_acceleration=(0.1, 0.2, 9.81), battery_voltage=11.9,
                     loop_period_mean=0.02, loop_jitter=0.0004, loop_overruns=1, fault="",
                     extra={})


def _read(path: Path) -> list[tuple[str, str, Any]]:
    """(topic, schema name, decoded message) of every message, via the summary (a whole
    file) with mcap_ros2's decoder."""
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        return [(ch.topic, sch.name, dec) for sch, ch, _, dec in reader.iter_decoded_messages()]


T = 1_700_000_000.5
GID = bytes(range(16))
ALL: list[tuple[str, Any]] = [
    (cdr.JOINT_STATE, m.joint_state_msg(_state(), T)),
    (cdr.IMU, m.imu_msg(_state(), T)),
    (cdr.DIAGNOSTIC_ARRAY, m.health_msg(_state(), T, {"decode_errors": 2}, "wrist_1", "pc_1")),
    (cdr.BATTERY_STATE, m.battery_msg(_state(), T)),
    (cdr.HEADER, m.heartbeat_msg(T, "pc_1")),
    (cdr.JOINT_TRAJECTORY, m.trajectory_msg(JointTrajectory(
        ("atool_pitch", "atool_roll"), np.array([0.0, 1.5]), np.array([[0, 0], [0.3, 0.1]]),
        np.zeros((2, 2))), T)),
    (cdr.GOAL_STATUS_ARRAY, m.status_array([(GID, T, m.GoalStatus.EXECUTING)])),
    (cdr.FEEDBACK_MESSAGE, m.feedback_msg(GID, PrimitiveStatus("TWIRL_CW", 40.0, "twirl",
                                                             (0.0, 2.5), False))),
    (f"{cdr.SET_ORIENTATION_CONTROL}_Request", m.soc_request(Mode.LEVELING, 10.0, -5.0)),
    (f"{cdr.SET_ORIENTATION_CONTROL}_Response", m.soc_response(False, "refused")),
    (f"{cdr.SEND_GOAL}_Request", m.send_goal_request(GID, "TWIRL_CW", [1.0, 3.0])),
    (f"{cdr.SEND_GOAL}_Response", m.send_goal_response(True, T)),
    (f"{cdr.GET_RESULT}_Request", cdr.msg(f"{cdr.GET_RESULT}_Request", goal_id=m.goal_uuid(GID))),
    (f"{cdr.GET_RESULT}_Response", m.result_msg(m.PrimitiveResult(True, "done", (0.0, 6.28), 4))),
    (f"{cdr.CANCEL_GOAL}_Request", m.cancel_request(GID)),
    (f"{cdr.CANCEL_GOAL}_Response", m.cancel_response(0, [(GID, T)])),
    (f"{cdr.TRIGGER}_Request", m.trigger_request()),
    (f"{cdr.TRIGGER}_Response", m.trigger_response(False, "no fault to clear")),
]


def test_every_link_type_decodes_with_the_standard_reader(tmp_path: Path) -> None:
    path = tmp_path / "all.mcap"
    with McapRecorder(path) as rec:
        for i, (typename, message) in enumerate(ALL):
            rec.write_msg(f"/t{i}", typename, message, T + i)
    got = _read(path)
    assert [(t, s) for t, s, _ in got] == [(f"/t{i}", schema_name(tn))
                                           for i, (tn, _) in enumerate(ALL)]
    by_topic = {t: d for t, _, d in got}
    js = by_topic["/t0"]
    assert list(js.name) == ["atool_pitch", "atool_roll"]
    assert list(js.position) == [0.1, -0.25] and js.header.stamp.sec == int(T)
    fb = by_topic["/t7"]
    assert fb.feedback.feedback_string == "twirl" and fb.feedback.percent_complete == 40.0
    assert bytes(fb.goal_id.uuid) == GID
    goal = by_topic["/t10"]
    assert goal.goal.primitive_name == "TWIRL_CW" and list(goal.goal.parameters) == [1.0, 3.0]
    assert by_topic["/t8"].control_mode == 1 and by_topic["/t8"].roll_offset == -5.0
    health = by_topic["/t2"].status[0]
    assert health.hardware_id == "wrist_1"
    assert {kv.key: kv.value for kv in health.values}["lease_holder"] == "pc_1"


def test_a_recording_never_overwrites(tmp_path: Path) -> None:
    path = tmp_path / "mine.mcap"
    path.write_bytes(b"the user's file")
    with pytest.raises(RecordingError, match="exists"):
        McapRecorder(path)
    assert path.read_bytes() == b"the user's file"
    for args in (["tool", "--duration", "1", "--record", str(path)],
                 ["client", "--record", str(path), "state"]):
        p = subprocess.run([sys.executable, "-m", "articutool", *args], env=ENV,
                           capture_output=True, text=True, timeout=60)
        assert p.returncode == 2, p.stderr
        assert "--record" in p.stderr and "exists" in p.stderr
    assert path.read_bytes() == b"the user's file"


@pytest.mark.parametrize(("args", "says"), [
    (["--record", "run.bag"], ".mcap"),
    (["--no-serve", "--record", "run.mcap"], "--serve"),
    (["--record", "no/such/folder/run.mcap"], "folder"),
])
def test_tool_record_bad_input_exits_2(tmp_path: Path, args: list[str], says: str) -> None:
    p = subprocess.run([sys.executable, "-m", "articutool", "tool", "--duration", "1", *args],
                       env=ENV, capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert p.returncode == 2, p.stderr
    assert "--record" in p.stderr and says in p.stderr and "Traceback" not in p.stderr
    assert list(tmp_path.iterdir()) == []


def _tool(tmp_path: Path, port: int, *extra: str) -> subprocess.Popen[str]:
    """``articutool tool`` in a session of its own: its loop process and the link process it
    starts (which writes the recording) can be killed together, as a power cut would."""
    return subprocess.Popen([sys.executable, "-m", "articutool", "tool", "--no-level",
                             "--listen", f"tcp/127.0.0.1:{port}", *extra], env=ENV,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _kill_if_running(tool: subprocess.Popen[str]) -> None:
    """A tool a failed test leaves running is killed with its link process (its session)."""
    if tool.poll() is None:
        os.killpg(tool.pid, signal.SIGKILL)
        tool.wait(10)


def _wait_for(path: Path, size: int, timeout: float) -> None:
    assert wait_until(lambda: path.exists() and path.stat().st_size >= size, timeout, 0.1), \
        f"{path} did not reach {size} bytes"


def test_a_killed_tools_recording_is_readable_to_its_last_chunk(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    tool = _tool(tmp_path, free_port(), "--record", str(path))
    try:
        _wait_for(path, 60_000, 60)  # a few complete chunks (each about a second)
    finally:
        os.killpg(tool.pid, signal.SIGKILL)  # both processes: the recorder gets no chance
        tool.wait(10)
    with path.open("rb") as f, pytest.raises(McapError):  # no summary: the file was cut
        make_reader(f).get_summary()
    counts: Counter[str] = Counter()
    decode = DecoderFactory()
    with path.open("rb") as f:
        try:  # in file order: every complete chunk's messages, then the cut
            for sch, ch, msg in NonSeekingReader(f).iter_messages(log_time_order=False):
                dec = decode.decoder_for(ch.message_encoding, sch)(msg.data)
                counts[ch.topic.rsplit("/", 1)[-1]] += 1
                if ch.topic.endswith("joint_states"):
                    assert len(dec.position) == 2
        except (McapError, EOFError):
            pass
    assert counts["joint_states"] >= 10 and counts["battery"] >= 10
    from articutool.link.recording import read_recording

    got = read_recording(path)  # our reader: the same messages, and says the file was cut
    assert not got.complete and "was cut" in got.cut
    assert len(got.messages) == sum(counts.values())


def test_ctrl_c_closes_the_tools_recording(tmp_path: Path) -> None:
    path = tmp_path / "tool.mcap"
    tool = _tool(tmp_path, free_port(), "--record", str(path))
    try:
        _wait_for(path, 60_000, 60)  # a few complete chunks (each about a second)
        tool.send_signal(signal.SIGINT)
        _, err = tool.communicate(timeout=30)
    finally:
        _kill_if_running(tool)
    assert tool.returncode == 0, err
    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    got = _read(path)
    assert len(got) == summary.statistics.message_count > 0
    topics = {t.rsplit("/articutool/default/", 1)[-1] for t, _, _ in got}
    assert {"joint_states", "imu/data", "health", "battery", "heartbeat"} <= topics


def test_the_clients_recording_holds_its_goal(tmp_path: Path) -> None:
    port = free_port()
    tool = _tool(tmp_path, port)
    path = tmp_path / "client.mcap"
    try:
        p = subprocess.run([sys.executable, "-m", "articutool", "client", "--connect",
                            f"tcp/127.0.0.1:{port}", "--wait", "30", "--record", str(path),
                            "primitive", "TWIRL_CW", "0.25", "3", "--json"], env=ENV,
                           capture_output=True, text=True, timeout=120)
    finally:
        tool.send_signal(signal.SIGINT)
        try:
            tool.wait(30)
        finally:
            _kill_if_running(tool)
    assert p.returncode == 0, p.stderr
    got = _read(path)
    by: dict[str, list[Any]] = {}
    for topic, _, dec in got:
        by.setdefault(topic.split("/articutool/default/", 1)[-1], []).append(dec)
    (goal,) = by["execute_primitive/_action/send_goal/request"]
    assert goal.goal.primitive_name == "TWIRL_CW" and list(goal.goal.parameters) == [0.25, 3.0]
    (accepted,) = by["execute_primitive/_action/send_goal/response"]
    assert accepted.accepted
    fbs = [f for f in by["execute_primitive/_action/feedback"]
           if bytes(f.goal_id.uuid) == bytes(goal.goal_id.uuid)]
    assert len(fbs) >= 3
    results = by["execute_primitive/_action/get_result/response"]
    assert results[-1].status == m.GoalStatus.SUCCEEDED and results[-1].result.success
    assert len(by["joint_states"]) >= 5


@pytest.mark.slow
def test_a_recorded_simulated_bite_opens_with_the_standard_reader(tmp_path: Path) -> None:
    """``articutool meal --record``: the bite's own record (--json) agrees with the file."""
    import json

    path = tmp_path / "bite.mcap"
    p = subprocess.run([sys.executable, "-m", "articutool", "meal", "--food", "pecans",
                        "--bites", "1", "--json", "--record", str(path)], env=ENV,
                       capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, p.stderr[-2000:]
    bite = json.loads(p.stdout)["bites"][0]
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        (meta,) = list(reader.iter_metadata())
        got = [(ch.topic, dec) for _, ch, _, dec in reader.iter_decoded_messages()]
    assert meta.metadata["food"] == "pecans" and meta.metadata["strategy"] == bite["strategy"]
    by: dict[str, list[Any]] = {}
    for topic, dec in got:
        by.setdefault(topic.replace("/articutool/default/", "tool:"), []).append(dec)
    # telemetry at the tool's 50 Hz through the whole simulated bite
    n = len(by["tool:joint_states"])
    assert n == len(by["tool:imu/data"]) == len(by["tool:health"]) == len(by["/arm/joint_states"])
    assert abs(n - 50 * bite["sim_time_s"]) <= 0.02 * n
    arm = by["/arm/joint_states"][-1]
    assert list(arm.name) == [f"j2n6s200_joint_{i}" for i in range(1, 7)]
    # the food accounting's last word is the bite's delivered mass
    last = {kv.key: float(kv.value) for kv in by["/sim/food"][-1].status[0].values}
    assert last["eaten_g"] == pytest.approx(bite["delivered_g"])
    assert last["table_g"] + last["critical_g"] == pytest.approx(bite["spilled_g"])
    # the tree's status: each stage's behaviour reached SUCCESS in a completed bite
    done = {s.name.rsplit(" / ", 1)[-1] for arr in by["/feeding/tree"] for s in arr.status
            if s.message == "SUCCESS"}
    assert any(name.startswith("present at Staging") for name in done), sorted(done)[:20]
    # the commands as the link carries them: leveling on, a primitive with feedback, a result
    modes = [r.control_mode for r in by["tool:set_orientation_control/request"]]
    assert 1 in modes and 0 in modes
    assert all(r.success for r in by["tool:set_orientation_control/response"])
    goals = by["tool:execute_primitive/_action/send_goal/request"]
    results = by["tool:execute_primitive/_action/get_result/response"]
    assert len(goals) == len(results) >= 1
    assert len(by["tool:execute_primitive/_action/feedback"]) > 5
    assert bite["completed"]
    assert all(r.status == m.GoalStatus.SUCCEEDED and r.result.success for r in results)


@pytest.mark.slow
def test_an_experiment_trial_recording_agrees_with_its_record(tmp_path: Path) -> None:
    import json

    path = tmp_path / "capacity.mcap"
    base = [sys.executable, "-m", "articutool", "experiment", "capacity", "--trials", "1",
            "--out", str(tmp_path / "out")]
    p = subprocess.run([*base, "--trial", "0", "--json", "--record", str(path)], env=ENV,
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    rec = json.loads(p.stdout)["record"]
    got = _read(path)
    food = [d for t, _, d in got if t == "/sim/food"]
    on_spoon = {kv.key: float(kv.value) for kv in food[-1].status[0].values}["utensil_g"]
    assert on_spoon == pytest.approx(rec["items_g"], abs=1e-3)  # the trial's own measure
    assert sum(t.endswith("/joint_states") for t, _, _ in got) > 100
    for args, says in ((["--record", str(path), "--trial", "0"], "exists"),
                       (["--record", str(tmp_path / "new.mcap")], "--trial")):
        p = subprocess.run([*base, *args], env=ENV, capture_output=True, text=True, timeout=60)
        assert p.returncode == 2 and "--record" in p.stderr and says in p.stderr, p.stderr
    assert not (tmp_path / "new.mcap").exists()


def test_an_experiment_trials_recording_holds_its_feeding_tree(tmp_path: Path) -> None:
    """``experiment … --trial K --record``: the protocol's own tree is on ``/feeding/tree``
    (the recorder's visitor passed down, as ``meal`` does), and the recorded replay has the
    outcome of the trial logged without a recorder. Exp. 2b, pecans, baseline: a few s."""
    import json

    pytest.importorskip("mujoco")
    from articutool.experiments.config import ExperimentsConfig
    from articutool.experiments.design import conditions, make_trials
    from articutool.experiments.runner import log_path, run_trial

    trials = make_trials("exp2b", conditions("exp2b", ExperimentsConfig.load(),
                                             goals=["centre"]), 1, 0, goals=["centre"])
    spec = next(t for t in trials if t.condition.fields() == {
        "food": "pecans", "system": "baseline", "goal": "centre"})
    logged = run_trial(spec).to_log()  # as a run logs it: no recorder
    assert logged["error"] is None, logged.get("traceback")
    out = tmp_path / "out"
    log = log_path(out, "exp2b")
    log.parent.mkdir(parents=True)
    log.write_text(json.dumps(logged) + "\n", encoding="utf-8")
    path = tmp_path / "exp2b.mcap"
    p = subprocess.run([sys.executable, "-m", "articutool", "experiment", "exp2b", "--trials",
                        "1", "--out", str(out), "--trial", str(spec.trial), "--json",
                        "--record", str(path)], env=ENV, capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    replay = json.loads(p.stdout)
    rec = replay["record"]
    for k in ("completed", "held_g", "delivered_g", "spilled_g", "masses_after_g"):
        assert rec[k] == logged[k], (k, replay["replay"])
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        (meta,) = list(reader.iter_metadata())
        got = [(ch.topic, sch.name, dec) for sch, ch, _, dec in reader.iter_decoded_messages()]
    assert meta.metadata["experiment"] == "exp2b"
    tree = [(s, d) for t, s, d in got if t == "/feeding/tree"]
    assert len(tree) >= 2 and {s for s, _ in tree} == {cdr.DIAGNOSTIC_ARRAY}
    status = [{st.name: st.message for st in d.status} for _, d in tree]
    assert status[0]["bite"] == "RUNNING"
    assert status[-1]["bite"] == ("SUCCESS" if rec["completed"] else "FAILURE")
    assert rec["completed"] and status[-1]["bite / tool DISABLED (then DISABLED) / move to "
                                           "centre / Execute to centre"] == "SUCCESS"
    stamps = [d.header.stamp.sec + d.header.stamp.nanosec * 1e-9 for _, d in tree]
    assert stamps == sorted(stamps)
    # every recording in simulation: the arm's joints and the food accounting as well
    topics = Counter(t for t, _, _ in got)
    assert topics["/arm/joint_states"] > 100 and topics["/sim/food"] > 10


def _joint_states(names: list[str], t: float, q: list[float]) -> Any:
    return cdr.msg(cdr.JOINT_STATE, header=m.header(t), name=names,
                 position=np.asarray(q, dtype=np.float64), velocity=np.zeros(0),
                 effort=np.zeros(0))


def test_view_replays_an_mcap_recordings_joint_states(tmp_path: Path) -> None:
    from articutool.sim.recording import RecordingError
    from articutool.spec import load_spec
    from articutool.viewer.mcap_replay import load_mcap_motion

    spec = load_spec()
    arm, wrist = list(spec.arm.joint_names), list(spec.wrist.joint_names)
    t = T + np.arange(0.0, 2.0, 0.02)
    q_arm = np.stack([0.1 * j + 0.05 * np.sin(t - T + j) for j in range(6)], axis=1)
    q_wrist = np.stack([0.2 * np.sin(t - T), 0.5 * (t - T)], axis=1)
    path = tmp_path / "run.mcap"
    with McapRecorder(path) as rec:
        for k, tk in enumerate(t):
            rec.write_msg("/articutool/wrist_1/joint_states", cdr.JOINT_STATE,
                          _joint_states(wrist, tk, list(q_wrist[k])), tk)
            rec.write_msg("/arm/joint_states", cdr.JOINT_STATE,
                          _joint_states(arm, tk + 0.001, list(q_arm[k])), tk + 0.001)
            rec.write_msg("/articutool/wrist_1/health", cdr.DIAGNOSTIC_ARRAY,
                          m.health_msg(_state(), tk, {}), tk)
    motion = load_mcap_motion(path, spec)
    assert motion.joint_names == (*arm, *wrist)
    assert motion.times[0] == 0.0 and motion.times[-1] == pytest.approx(t[-1] - t[0])
    assert np.allclose(motion.positions[:, 6:], q_wrist)
    assert np.allclose(motion.positions[1:-1, :6], q_arm[1:-1], atol=2e-4)  # 1 ms apart
    # a tool-only recording: the arm rests at Resting
    tool_only = tmp_path / "tool.mcap"
    with McapRecorder(tool_only) as rec:
        for k, tk in enumerate(t[:10]):
            rec.write_msg("/articutool/default/joint_states", cdr.JOINT_STATE,
                          _joint_states(wrist, tk, list(q_wrist[k])), tk)
    rest = load_mcap_motion(tool_only, spec).positions[:, :6]
    assert np.allclose(rest, spec.arm.configuration("Resting"))
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file")
    with pytest.raises(RecordingError, match="not a readable MCAP"):
        load_mcap_motion(junk, spec)
    view = [sys.executable, "-m", "articutool", "view", "--recording"]
    p = subprocess.run([*view, str(path), "--duration", "1", "--port", str(free_port())],
                       env=ENV, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "8-joint trajectory" in p.stdout and "viewer: http://" in p.stdout
    for args, says in (([str(junk)], "not a readable MCAP"),
                       ([str(path), "--export", str(tmp_path / "v.mp4")], ".npz")):
        p = subprocess.run([*view, *args, "--duration", "1"], env=ENV, capture_output=True,
                           text=True, timeout=120)
        assert p.returncode == 2 and says in p.stderr and "Traceback" not in p.stderr, p.stderr


_text = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00"),
                max_size=20)
_f64 = st.floats(allow_nan=False, width=64)
_f32 = st.floats(allow_nan=False, width=32)


@settings(max_examples=40, deadline=None)
@given(names=st.lists(_text, max_size=4), data=st.data(), fb=_text,
       pct=_f32, joints=st.lists(_f32, max_size=5), prim=_text,
       params=st.lists(_f32, max_size=6))
def test_recorded_messages_decode_to_what_was_written(names: list[str], data: Any, fb: str,
                                                      pct: float, joints: list[float],
                                                      prim: str, params: list[float]) -> None:
    """Any field contents survive our schema text + mcap_ros2's decoder (strings, arrays)."""
    pos = data.draw(st.lists(_f64, min_size=len(names), max_size=len(names)))
    js = cdr.msg(cdr.JOINT_STATE, header=m.header(T, "f"), name=names,
               position=np.asarray(pos, dtype=np.float64), velocity=np.zeros(0),
               effort=np.zeros(0))
    fbm = m.feedback_msg(GID, PrimitiveStatus(prim, pct, fb, tuple(joints), False))  # type: ignore[arg-type]
    goal = m.send_goal_request(GID, prim, params)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "p.mcap"
        with McapRecorder(path) as rec:
            rec.write_msg("/js", cdr.JOINT_STATE, js, T)
            rec.write_msg("/fb", cdr.FEEDBACK_MESSAGE, fbm, T)
            rec.write_msg("/goal", f"{cdr.SEND_GOAL}_Request", goal, T)
        got = {t: dec for t, _, dec in _read(path)}
    assert list(got["/js"].name) == names and list(got["/js"].position) == pos
    f = got["/fb"].feedback
    assert (f.feedback_string, f.percent_complete) == (fb, pct)
    assert list(f.current_joint_values) == joints
    g = got["/goal"].goal
    assert g.primitive_name == prim and list(g.parameters) == params


# ------------------------------------------------- corrupt and cut recordings --
def _wrist_recording(path: Path, n: int = 300, close: bool = True) -> bytes:
    """A recording of ``n`` wrist joint states in 2 KiB chunks; its bytes on disk (with
    ``close=False``: as a recorder killed now leaves them, every completed chunk flushed)."""
    from articutool.spec import load_spec

    wrist = list(load_spec().wrist.joint_names)
    rec = McapRecorder(path, chunk_bytes=2048)
    for k in range(n):
        t = T + 0.02 * k
        rec.write_msg("/articutool/default/joint_states", cdr.JOINT_STATE,
                      _joint_states(wrist, t, [0.1 * np.sin(0.02 * k), 0.01 * k]), t)
    data = path.read_bytes()
    rec.close()
    return path.read_bytes() if close else data


def test_every_flipped_bit_is_refused_naming_the_file(tmp_path: Path) -> None:
    from articutool.link.recording import read_recording

    good = _wrist_recording(tmp_path / "good.mcap")
    assert read_recording(tmp_path / "good.mcap").complete
    rng = np.random.default_rng(0)
    offsets = sorted({0, len(good) - 1, *rng.integers(0, len(good), 60).tolist()})
    for off in offsets:
        for bit in (0, 5):
            bad = bytearray(good)
            bad[off] ^= 1 << bit
            p = tmp_path / f"flip-{off}-{bit}.mcap"
            p.write_bytes(bytes(bad))
            with pytest.raises(RecordingError, match=str(p)):
                read_recording(p)
    # Through the viewer: exit 2 naming the file, never a decompressor's traceback.
    chunk = good.index(b"zstd") + 40  # inside the first chunk's compressed bytes
    _view_refuses(good, chunk, 4, tmp_path / "chunk.mcap")


def _view_refuses(good: bytes, off: int, bit: int, p: Path) -> None:
    """``good`` with bit ``bit`` of byte ``off`` flipped, written to ``p``: ``articutool view``
    refuses it with exit 2 naming it, without a traceback."""
    bad = bytearray(good)
    bad[off] ^= 1 << bit
    p.write_bytes(bytes(bad))
    r = subprocess.run([sys.executable, "-m", "articutool", "view", "--recording", str(p),
                        "--duration", "1", "--port", str(free_port())], env=ENV,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert str(p) in r.stderr and "not a readable MCAP file: corrupt" in r.stderr


def _records(data: bytes) -> list[tuple[str, int, int]]:
    """Every record of an MCAP file as ``mcap``'s stream reader finds it: (kind, start, end)."""
    import io

    from mcap.stream_reader import StreamReader

    f = io.BytesIO(data)
    out, start = [], 8
    for rec in StreamReader(f, emit_chunks=True).records:
        out.append((type(rec).__name__, start, f.tell()))
        start = f.tell()
    return out


def test_every_bit_outside_the_chunks_data_is_checked(tmp_path: Path) -> None:
    """Each bit of the magic at both ends, every record's opcode and length, the DataEnd,
    the summary offsets and the footer, and of every 23rd byte of the other records (header,
    chunks, message indexes, schemas, channels, statistics, chunk indexes), flipped alone:
    every damaged file is refused naming it (RecordingError, never another exception).
    Every bit of every byte was checked once (33 352 flips of a 4 169-byte file, all refused,
    60 CPU s)."""
    from articutool.link.recording import read_recording

    good = _wrist_recording(tmp_path / "good.mcap", n=60)
    whole = read_recording(tmp_path / "good.mcap")
    assert whole.complete and len(whole.messages) == 60
    recs = _records(good)
    kinds = Counter(k for k, _, _ in recs)
    assert kinds["Chunk"] >= 3 and kinds["DataEnd"] == kinds["Footer"] == 1
    assert {"Schema", "Channel", "Statistics", "ChunkIndex", "SummaryOffset"} <= set(kinds)
    offsets = {*range(8), *range(len(good) - 8, len(good))}  # the magic at both ends
    for kind, start, end in recs:  # every opcode and length; the small records whole
        whole_record = kind in ("DataEnd", "SummaryOffset", "Footer")
        offsets |= {*range(start, start + 9), *range(start + 9, end, 1 if whole_record else 23)}
    p = tmp_path / "bad.mcap"
    for off in sorted(offsets):
        for bit in range(8):
            bad = bytearray(good)
            bad[off] ^= 1 << bit
            p.write_bytes(bytes(bad))
            with pytest.raises(RecordingError, match=r"bad\.mcap"):
                read_recording(p)
    assert len(offsets) > 0.1 * len(good)


@pytest.mark.parametrize("where", ["summary_start", "message_index_length", "data_end_length"])
def test_a_flip_that_moved_the_reader_is_refused_by_view(where, tmp_path: Path) -> None:
    """Flips that once passed: the footer's summary offset (the reader sought before the
    file: a traceback), a message index's length (the reader skipped the last chunk and the
    data section's end, and replayed the rest), the DataEnd's length (read all the same)."""
    good = _wrist_recording(tmp_path / "good.mcap", n=60)
    recs = _records(good)
    footer = next(s for k, s, _ in recs if k == "Footer")
    last_index = [s for k, s, _ in recs if k == "MessageIndex"][-2]
    data_end = next(s for k, s, _ in recs if k == "DataEnd")
    off, bit = {"summary_start": (footer + 9 + 7, 7),
                "message_index_length": (last_index + 3, 1),
                "data_end_length": (data_end + 1, 2)}[where]
    _view_refuses(good, off, bit, tmp_path / "bad.mcap")


def test_a_cut_recording_is_read_to_its_last_chunk_and_said_to_be_cut(tmp_path: Path) -> None:
    from articutool.link.recording import read_recording

    cut = tmp_path / "cut.mcap"
    cut.write_bytes(_wrist_recording(tmp_path / "whole.mcap", close=False))
    whole = read_recording(tmp_path / "whole.mcap")
    got = read_recording(cut)
    assert not got.complete and "was cut" in got.cut
    assert 100 < len(got.messages) < len(whole.messages) == 300
    assert got.messages == whole.messages[:len(got.messages)]  # file order, nothing invented
    # What mcap's reader gives by default (log-time order, so it reads to the end): nothing.
    with cut.open("rb") as f, pytest.raises(McapError):
        list(NonSeekingReader(f).iter_messages())
    r = subprocess.run([sys.executable, "-m", "articutool", "view", "--recording", str(cut),
                        "--duration", "1", "--port", str(free_port())], env=ENV,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "note:" in r.stderr and "was cut" in r.stderr and "viewer: http://" in r.stdout


@pytest.mark.parametrize("kind", ["fifo", "folder"])
def test_a_recording_that_is_not_a_regular_file_is_refused_without_waiting(kind,
                                                                           tmp_path: Path):
    p = tmp_path / "r.mcap"
    if kind == "fifo":
        os.mkfifo(p)
    else:
        p.mkdir()
    r = subprocess.run([sys.executable, "-m", "articutool", "view", "--recording", str(p),
                        "--duration", "1", "--port", str(free_port())], env=ENV,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert str(p) in r.stderr
