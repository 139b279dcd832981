"""The built ``articutool_interfaces`` ROS 2 package and the link's messages are one definition:
ROS 2 decodes the link's bytes of our own types and the other way round, and the link's RIHS01
type hashes equal those rosidl wrote into the installed package. The upstream package's
types (``personalrobotics/articutool_ros2``, field layout kept in
``tests/data/upstream_articutool_interfaces``) hash exactly as ours, so a Jazzy or later
client built from upstream connects to our services. The include-path fix of the wheels'
CMake exports is checked on copies of the real files.

Skipped where rclpy or the built package are unavailable (``make`` builds it on CPython 3.11
x86-64 only).
"""

from __future__ import annotations

import json
import sys
import sysconfig
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from articutool.link import cdr
from articutool.link import messages as m
from articutool.ros2 import build_interfaces as bi
from articutool.tool.api import Mode, PrimitiveStatus

_why = "rclpy and the built articutool_interfaces (make; CPython 3.11 on x86_64 only)"
ser = pytest.importorskip("rclpy.serialization", reason=_why)
pytest.importorskip("articutool_interfaces.action", reason=_why)

from articutool_interfaces.action import ExecuteArticutoolPrimitive as A  # noqa: E402
from articutool_interfaces.srv import SetOrientationControl as S  # noqa: E402

GID = bytes(range(16))
CASES: list[tuple[str, Any, Any]] = [
    (f"{cdr.SET_ORIENTATION_CONTROL}_Request", S.Request, m.soc_request(Mode.LEVELING, 12.5, -3)),
    (f"{cdr.SET_ORIENTATION_CONTROL}_Response", S.Response, m.soc_response(False, "refused: ü")),
    (f"{cdr.SEND_GOAL}_Request", A.Impl.SendGoalService.Request,
     m.send_goal_request(GID, "TWIRL_CW", [1.0, 3.0])),
    (f"{cdr.SEND_GOAL}_Response", A.Impl.SendGoalService.Response,
     m.send_goal_response(True, 1_700_000_000.5)),
    (f"{cdr.GET_RESULT}_Response", A.Impl.GetResultService.Response,
     m.result_msg(m.PrimitiveResult(True, "done", (0.25, 6.28), m.GoalStatus.SUCCEEDED))),
    (cdr.FEEDBACK_MESSAGE, A.Impl.FeedbackMessage,
     m.feedback_msg(GID, PrimitiveStatus("TWIRL_CW", 42.0, "twirl", (0.0, 1.5), False))),
]
IDS = [t.split("/")[-1] for t, _, _ in CASES]


@pytest.mark.parametrize(("typename", "cls", "ours"), CASES, ids=IDS)
def test_both_directions_carry_the_same_message(typename: str, cls: Any, ours: Any) -> None:
    data = cdr.encode(ours, typename)
    theirs = ser.deserialize_message(data, cls)
    back = cdr.decode(ser.serialize_message(theirs), typename)
    assert cdr.encode(back, typename) == data


def test_rclpy_reads_the_fields_we_wrote() -> None:
    req = ser.deserialize_message(
        cdr.encode(m.send_goal_request(GID, "VIBRATE_ROLL", [5.0, 0.1, 2.0]),
                 f"{cdr.SEND_GOAL}_Request"),
        A.Impl.SendGoalService.Request)
    assert req.goal.primitive_name == "VIBRATE_ROLL"
    assert np.allclose(req.goal.parameters, [5.0, 0.1, 2.0])
    assert bytes(req.goal_id.uuid) == GID
    soc = ser.deserialize_message(cdr.encode(m.soc_request(Mode.LEVELING, 12.5, -3.0),
                                           f"{cdr.SET_ORIENTATION_CONTROL}_Request"), S.Request)
    assert (soc.control_mode, soc.pitch_offset, soc.roll_offset) == (S.Request.MODE_LEVELING,
                                                                     12.5, -3.0)
    q = soc.target_orientation_robot_base
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)


UPSTREAM = Path(__file__).resolve().parent / "data" / "upstream_articutool_interfaces"


def test_type_hashes_equal_the_upstream_packages() -> None:
    upstream = cdr.interface_hashes(cdr.package_texts(UPSTREAM))
    ours = cdr.interface_hashes(cdr.package_texts())
    assert sorted(upstream) == sorted(set(ours) - {"articutool_interfaces/srv/VerifyTrajectory"})
    for name, digest in upstream.items():
        assert ours[name] == digest, name


def test_the_hash_comparison_sees_a_missing_field() -> None:
    """Without the quaternion upstream keeps (our package's earlier layout) the service
    hash differs: the comparison above can fail."""
    texts = cdr.package_texts(UPSTREAM)
    rel = "srv/SetOrientationControl.srv"
    texts[rel] = texts[rel].replace("geometry_msgs/Quaternion target_orientation_robot_base\n",
                                    "")
    changed = cdr.interface_hashes(texts)
    assert changed[cdr.SET_ORIENTATION_CONTROL] != cdr.type_hash(cdr.SET_ORIENTATION_CONTROL)
    assert changed[cdr.ACTION] == cdr.type_hash(cdr.ACTION)


def test_the_full_orientation_constant_changes_no_hash() -> None:
    """ADA checks SetOrientationControl.Request.MODE_FULL_ORIENTATION (2), which upstream
    removed: ours defines it, upstream's current text lacks it, and the RIHS01 hash of the
    service, its request and response is the same either way (constants are not hashed)."""
    ours = cdr.package_texts()
    rel = "srv/SetOrientationControl.srv"
    assert "uint8 MODE_FULL_ORIENTATION=2" in ours[rel]
    upstream = cdr.package_texts(UPSTREAM)
    assert "MODE_FULL_ORIENTATION" not in upstream[rel]
    a, b = cdr.interface_hashes(ours), cdr.interface_hashes(upstream)
    name = cdr.SET_ORIENTATION_CONTROL  # its hash covers the request and response types
    assert a[name] == b[name] == cdr.type_hash(name)
    without = dict(ours, **{rel: ours[rel].replace("uint8 MODE_FULL_ORIENTATION=2\n", "")})
    assert cdr.interface_hashes(without)[name] == a[name]
    from articutool_interfaces.srv import SetOrientationControl
    assert SetOrientationControl.Request.MODE_FULL_ORIENTATION == 2  # the built package has it


INSTALLED = sorted((Path(sys.prefix) / "share" / "articutool_interfaces").glob("*/*.json"))


@pytest.mark.parametrize("path", INSTALLED, ids=[p.stem for p in INSTALLED])
def test_type_hashes_equal_the_built_packages(path: Path) -> None:
    doc = json.loads(path.read_text())
    for entry in doc["type_hashes"]:
        assert cdr.type_hash(entry["type_name"]) == entry["hash_string"], entry["type_name"]


def test_every_interface_is_built() -> None:
    assert {p.stem for p in INSTALLED} == {Path(r).stem for r in cdr.package_texts()}


def test_the_export_path_fix_is_idempotent(tmp_path: Path) -> None:
    files = sorted(Path(sys.prefix).glob("share/*/cmake/*__rosidl_generator_pyExport.cmake"))
    assert files, "no ROS 2 export files installed"
    src = files[0]
    dst = tmp_path / src.relative_to(sys.prefix)
    dst.parent.mkdir(parents=True)
    # as the wheel ships it: the wheel builder's include paths
    text = src.read_text()
    text = text.replace(sysconfig.get_paths()["include"],
                        "/opt/python/cp311-cp311/include/python3.11")
    text = text.replace(np.get_include(),
                        "/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include")
    dst.write_text(text)
    assert "/opt/python" in dst.read_text()
    assert bi.fix_export_paths(tmp_path) == [dst]
    fixed = dst.read_text()
    assert "/opt/python" not in fixed
    assert f'"{sysconfig.get_paths()["include"]};{np.get_include()}"' in fixed
    assert bi.fix_export_paths(tmp_path) == []  # second run: nothing to do
    assert dst.read_text() == fixed


def test_the_package_builds_from_the_same_files_the_link_parses() -> None:
    installed = Path(sys.prefix) / "share" / "articutool_interfaces"
    for rel, text in cdr.package_texts().items():
        assert (installed / rel).read_text() == text


PEER_JSON = sorted(p for pkg in ("control_msgs", "controller_manager_msgs")
                   for p in (Path(sys.prefix) / "share" / pkg).glob("*/*.json"))


@pytest.mark.parametrize("path", PEER_JSON, ids=[p.stem for p in PEER_JSON])
def test_the_trajectory_path_types_hash_as_rosidl_built_them(path: Path) -> None:
    """control_msgs/FollowJointTrajectory and controller_manager_msgs/SwitchController,
    built from the field layouts in ros2/peer_interfaces: our texts hash as rosidl does."""
    from articutool.ros2.build_interfaces import PEERS
    pkg = path.parts[-3]
    ours = cdr.interface_hashes(cdr.package_texts(PEERS / pkg), pkg)
    top = json.loads(path.read_text())["type_hashes"][0]
    assert ours[top["type_name"]] == top["hash_string"]
