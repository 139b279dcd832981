"""Link messages: ROS 2 CDR layout, round trips, conversions, and decoder fuzzing."""

from __future__ import annotations

import contextlib
import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from articutool.link import cdr
from articutool.link import messages as m
from articutool.link.transport import Names, key_expr
from articutool.tool.api import Mode, PrimitiveStatus, ToolState
from articutool.trajectory import JointTrajectory

N = Names()
ALL_WIRE_TYPES = [N.set_orientation_control.request_type, N.set_orientation_control.response_type,
                  N.send_goal.request_type, N.send_goal.response_type, N.get_result.request_type,
                  N.get_result.response_type, N.cancel_goal.request_type,
                  N.cancel_goal.response_type, cdr.FEEDBACK_MESSAGE, cdr.GOAL_STATUS_ARRAY,
                  cdr.JOINT_STATE, cdr.IMU, cdr.JOINT_TRAJECTORY, cdr.DIAGNOSTIC_ARRAY,
                  cdr.BATTERY_STATE, cdr.HEADER]


def _state(**kw: object) -> ToolState:
    base = dict(stamp=1.0, mode=Mode.LEVELING, joint_names=("pitch", "roll"),
                position=(0.25, -1.5), velocity=(0.1, -0.2),
                orientation_wxyz=(0.9238795325, 0.0, 0.3826834324, 0.0),
                angular_velocity=(0.01, 0.02, 0.03), linear_acceleration=(0.1, 0.2, 9.8),
                fault="", battery_voltage=11.7, loop_period_mean=0.02, loop_jitter=0.001,
                loop_overruns=3)
    base.update(kw)
    return ToolState(**base)  # type: ignore[arg-type]


def _samples() -> list[tuple[bytes, str]]:
    s = _state()
    traj = JointTrajectory(("pitch", "roll"), np.array([0.0, 0.5, 1.25]),
                           np.array([[0, 0], [0.2, 0.4], [0.3, 1.0]]), np.zeros((3, 2)))
    status = PrimitiveStatus("TWIRL", 42.0, "twirling", (0.1, 2.0), False)
    res = m.PrimitiveResult(True, "done", (0.1, 6.3), m.GoalStatus.SUCCEEDED)
    gid = bytes(range(16))
    out = [
        (m.soc_request(Mode.LEVELING, 10.0, -5.0), N.set_orientation_control.request_type),
        (m.soc_response(False, "busy"), N.set_orientation_control.response_type),
        (m.send_goal_request(gid, "TWIRL", [1.0, 2.5]), N.send_goal.request_type),
        (m.send_goal_response(True, 12.5), N.send_goal.response_type),
        (m.result_msg(res), N.get_result.response_type),
        (m.feedback_msg(gid, status), cdr.FEEDBACK_MESSAGE),
        (m.status_array([(gid, 3.0, m.GoalStatus.EXECUTING)]), cdr.GOAL_STATUS_ARRAY),
        (m.cancel_request(gid), N.cancel_goal.request_type),
        (m.cancel_response(0, [(gid, 3.0)]), N.cancel_goal.response_type),
        (m.joint_state_msg(s, 100.25), cdr.JOINT_STATE),
        (m.imu_msg(s, 100.25), cdr.IMU),
        (m.health_msg(s, 100.25, {"decode_errors": 2}), cdr.DIAGNOSTIC_ARRAY),
        (m.battery_msg(s, 100.25), cdr.BATTERY_STATE),
        (m.trajectory_msg(traj, 5.0), cdr.JOINT_TRAJECTORY),
        (m.heartbeat_msg(7.5, "pc"), cdr.HEADER),
    ]
    return [(cdr.encode(msg, t), t) for msg, t in out]


SAMPLES = _samples()


def test_set_orientation_control_request_has_the_ros2_cdr_layout() -> None:
    # CDR: encapsulation 00 01 00 00, uint8, 3 bytes padding to 4, two little-endian float32,
    # 4 bytes padding to 8, then the upstream's quaternion (x, y, z, w float64; identity).
    data = cdr.encode(m.soc_request(Mode.LEVELING, 12.5, -3.0),
                    N.set_orientation_control.request_type)
    assert data == (b"\x00\x01\x00\x00" + b"\x01\x00\x00\x00" + struct.pack("<ff", 12.5, -3.0)
                    + bytes(4) + struct.pack("<dddd", 0.0, 0.0, 0.0, 1.0))


def test_send_goal_layout_is_uuid_then_string_then_float_sequence() -> None:
    gid = bytes(range(16))
    data = cdr.encode(m.send_goal_request(gid, "TWIRL", [1.5]), N.send_goal.request_type)
    body = data[4:]
    assert body[:16] == gid
    assert struct.unpack_from("<I", body, 16)[0] == 6  # "TWIRL\0"
    assert body[20:26] == b"TWIRL\x00"
    # sequence length aligned to 4, then the float32
    assert struct.unpack_from("<If", body, 28) == (1, 1.5)


@pytest.mark.parametrize(("data", "typename"), SAMPLES, ids=[t for _, t in SAMPLES])
def test_every_message_round_trips(data: bytes, typename: str) -> None:
    assert cdr.encode(cdr.decode(data, typename), typename) == data


@pytest.mark.parametrize(("data", "typename"), SAMPLES, ids=[t for _, t in SAMPLES])
def test_every_truncation_is_rejected(data: bytes, typename: str) -> None:
    for k in range(len(data) - 3):  # the last 3 bytes may be alignment padding
        with pytest.raises(cdr.LinkDecodeError):
            cdr.decode(data[:k], typename)


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(ALL_WIRE_TYPES), st.binary(max_size=300))
def test_random_bytes_decode_or_raise_link_decode_error(typename: str, blob: bytes) -> None:
    for data in (blob, b"\x00\x01\x00\x00" + blob):
        try:
            obj = cdr.decode(data, typename)
        except cdr.LinkDecodeError:
            continue
        assert cdr.decode(cdr.encode(obj, typename), typename) is not None


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(SAMPLES), st.data())
def test_bit_flips_decode_or_raise_link_decode_error(sample: tuple[bytes, str],
                                                     data: st.DataObject) -> None:
    raw, typename = sample
    buf = bytearray(raw)
    for _ in range(data.draw(st.integers(1, 4))):
        bit = data.draw(st.integers(0, len(buf) * 8 - 1))
        buf[bit // 8] ^= 1 << (bit % 8)
    with contextlib.suppress(cdr.LinkDecodeError):
        cdr.decode(bytes(buf), typename)


# Bytes from real ROS 2: rclpy 9.1.2 ``serialize_message`` (rmw_fastrtps_cpp typesupport) of a
# JointState (name [pitch, roll], position [0.1, 0.2], velocity [0, 0]) and a JointTrajectory
# (one point at 1 s). The buffer is sized by Fast-CDR's worst-case estimate, so each ends in
# bytes past the message (4 and 8 here), and padding holds whatever memory held (not zeros).
ROS2_JOINT_STATE = bytes.fromhex(
    "0001000000000000000000000100000000dcb40e020000000600000070697463"
    "6800b00e05000000726f6c6c007f0000020000009a9999999999b93f9a999999"
    "9999c93f02000000f8a1b50e0000000000000000000000000000000000000000"
    "2099fb09")
ROS2_JOINT_TRAJECTORY = bytes.fromhex(
    "0001000000000000000000000100000000000100020000000600000070697463"
    "6800742905000000726f6c6c000064090100000002000000000000009a999999"
    "9999b93f9a9999999999c93f02000000a6010000000000000000000000000000"
    "00000000000000000000000001000000000000000000000000000000")


def test_real_ros2_bytes_with_trailing_alignment_padding_are_accepted() -> None:
    js = cdr.decode(ROS2_JOINT_STATE, cdr.JOINT_STATE)
    assert list(js.name) == ["pitch", "roll"] and list(js.position) == [0.1, 0.2]
    traj = m.trajectory_from_msg(cdr.decode(ROS2_JOINT_TRAJECTORY, cdr.JOINT_TRAJECTORY))
    assert traj.joint_names == ("pitch", "roll") and list(traj.times) == [1.0]
    assert traj.positions.tolist() == [[0.1, 0.2]]


def test_trailing_bytes_beyond_padding_and_wrong_header_are_rejected() -> None:
    hb = cdr.encode(m.heartbeat_msg(5.0, "pc"), cdr.HEADER)
    cdr.decode(hb + bytes(7), cdr.HEADER)  # rounding up to 8 is padding
    with pytest.raises(cdr.LinkDecodeError, match="trailing"):
        cdr.decode(hb + hb, cdr.HEADER)  # a second message is not padding
    for raw, t in SAMPLES:
        with pytest.raises(cdr.LinkDecodeError, match="trailing"):
            cdr.decode(raw + bytes(4096), t)
        with pytest.raises(cdr.LinkDecodeError, match="CDR"):
            cdr.decode(b"\x07" + raw[1:], t)


finite = st.floats(-10, 10, allow_nan=False, width=32)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(finite, finite, finite, finite), min_size=1, max_size=8),
       st.lists(st.floats(0.001, 2.0), min_size=8, max_size=8))
def test_trajectory_conversion_round_trips(rows: list, dts: list[float]) -> None:
    times = np.cumsum(dts[: len(rows)])
    q = np.array([r[:2] for r in rows])
    v = np.array([r[2:] for r in rows])
    traj = JointTrajectory(("pitch", "roll"), times, q, v)
    back = m.trajectory_from_msg(cdr.decode(
        cdr.encode(m.trajectory_msg(traj), cdr.JOINT_TRAJECTORY), cdr.JOINT_TRAJECTORY))
    assert back.joint_names == traj.joint_names
    np.testing.assert_allclose(back.times, traj.times, atol=1e-9)
    np.testing.assert_array_equal(back.positions, traj.positions)
    np.testing.assert_array_equal(back.velocities, traj.velocities)


def test_inconsistent_trajectory_message_is_a_decode_error_naming_the_field() -> None:
    msg = m.trajectory_msg(JointTrajectory(("pitch", "roll"), np.array([0.0, 1.0]),
                                           np.zeros((2, 2)), np.zeros((2, 2))))
    msg.points[1].positions = np.array([1.0])
    with pytest.raises(cdr.LinkDecodeError, match=r"points\[1\].positions"):
        m.trajectory_from_msg(msg)
    msg.points[1].positions = np.array([1.0, 2.0])
    msg.points[1].time_from_start.sec = 0  # not after point 0
    with pytest.raises(cdr.LinkDecodeError, match="increase"):
        m.trajectory_from_msg(msg)


def test_state_survives_the_telemetry_messages() -> None:
    s = _state(fault="motor 1 overload", extra={"temp": 41.5})
    msgs = [cdr.decode(cdr.encode(x, t), t) for x, t in (
        (m.joint_state_msg(s, 1.0), cdr.JOINT_STATE), (m.imu_msg(s, 1.0), cdr.IMU),
        (m.health_msg(s, 1.0, {}), cdr.DIAGNOSTIC_ARRAY),
        (m.battery_msg(s, 1.0), cdr.BATTERY_STATE))]
    back = m.state_from_msgs(*msgs, stamp=s.stamp)
    assert back.mode == s.mode and back.fault == s.fault
    assert back.joint_names == s.joint_names and back.position == s.position
    assert back.velocity == s.velocity and back.loop_overruns == s.loop_overruns
    assert back.extra == {"temp": 41.5}
    np.testing.assert_allclose(back.orientation_wxyz, s.orientation_wxyz)
    assert math.isclose(back.battery_voltage, s.battery_voltage, rel_tol=1e-6)
    assert back.loop_period_mean == s.loop_period_mean and back.loop_jitter == s.loop_jitter
    assert msgs[2].status[0].level == 2  # a fault is an ERROR diagnostic


def test_bad_request_values_are_refused_before_sending() -> None:
    with pytest.raises(ValueError, match="control_mode"):
        m.soc_request(Mode.PRIMITIVE, 0, 0)
    with pytest.raises(ValueError, match="pitch_offset"):
        m.soc_request(Mode.LEVELING, float("nan"), 0)
    with pytest.raises(ValueError, match="target_orientation_robot_base"):
        m.soc_request(Mode.FULL_ORIENTATION, 0, 0, (math.nan, 0.0, 0.0, 1.0))


def test_full_orientation_carries_its_target_as_the_wire_mode_2() -> None:
    req = m.soc_request(Mode.FULL_ORIENTATION, 0, 0, (0.1, 0.2, 0.3, 0.9))
    back = cdr.decode(cdr.encode(req, f"{cdr.SET_ORIENTATION_CONTROL}_Request"),
                      f"{cdr.SET_ORIENTATION_CONTROL}_Request")
    t = back.target_orientation_robot_base
    assert back.control_mode == 2 and (t.x, t.y, t.z, t.w) == (0.1, 0.2, 0.3, 0.9)


def test_key_expressions_follow_rmw_zenoh() -> None:
    k = key_expr(3, N.joint_states)
    domain, *name, dds, h = k.split("/")
    assert domain == "3" and name == ["articutool", "default", "joint_states"]  # tool identity
    assert dds == "sensor_msgs::msg::dds_::JointState_"
    assert h.startswith("RIHS01_") and len(h) == 7 + 64
    assert N.send_goal.name == "/articutool/default/execute_primitive/_action/send_goal"
    assert Names(tool_id="wrist-7").joint_states.name == "/articutool/wrist-7/joint_states"
    assert key_expr(0, N.cancel_goal).split("/")[-2] == "action_msgs::srv::dds_::CancelGoal_"
    assert key_expr(0, N.imu, with_hash=False).endswith("/*")
    # distinct interfaces have distinct hashes
    assert len({cdr.type_hash(t) for t in (cdr.SET_ORIENTATION_CONTROL, cdr.SEND_GOAL,
                                         cdr.GET_RESULT, cdr.ACTION)}) == 4


@pytest.mark.parametrize(("extra", "fault", "level", "text"), [
    ({"leveling_stalled": 0.0}, "", 0, "OK"),
    ({"leveling_stalled": 1.0, "leveling_target_pitch": -1.4, "leveling_target_roll": 3.0},
     "", 1, "leveling stalled short of level"),
    ({"leveling_stalled": 1.0}, "IMU stale", 2, "IMU stale"),
])
def test_health_warns_while_leveling_is_stalled(extra, fault, level, text) -> None:
    """A stalled leveling is no fault but is never silent: WARN, and the target on the wire."""
    msg = m.health_msg(_state(extra=extra, fault=fault), 1.0, {})
    back = cdr.decode(cdr.encode(msg, cdr.DIAGNOSTIC_ARRAY), cdr.DIAGNOSTIC_ARRAY)
    (st,) = back.status
    assert (st.level, st.message) == (level, text)
    state = m.state_from_msgs(m.joint_state_msg(_state(), 1.0), None, back, None, 2.0)
    assert state.extra == pytest.approx(extra)


def test_a_wrist_part_sliced_from_a_longer_path_encodes() -> None:
    # The feeding tree sends the wrist's part of a longer path, whose rows can be strided
    # (a transposed joint-major array); the CDR serialiser needs contiguous rows (it
    # crashed `meal --record` on a sweep).
    times = np.array([0.0, 0.5, 1.0])
    q8 = np.arange(24, dtype=np.float64).reshape(8, 3).T / 10  # rows strided
    wrist = JointTrajectory(("pitch", "roll"), times, q8[:, 6:], np.zeros((8, 3)).T[:, 6:])
    assert not wrist.positions[0].flags["C_CONTIGUOUS"]
    data = cdr.encode(m.trajectory_msg(wrist), cdr.JOINT_TRAJECTORY)
    back = m.trajectory_from_msg(cdr.decode(data, cdr.JOINT_TRAJECTORY))
    assert np.allclose(back.positions, q8[:, 6:8])
