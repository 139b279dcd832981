"""The built ``articutool_interfaces`` ROS 2 package and the link's messages are one definition:
ROS 2 decodes the link's bytes of our own types and the other way round,
and the link's RIHS01 type hashes equal those rosidl wrote into the installed package.
The include-path fix of the wheels' CMake exports is checked on copies of the real files.

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
from articutool.tool.api import PrimitiveStatus

_why = "rclpy and the built articutool_interfaces (make; CPython 3.11 on x86_64 only)"
ser = pytest.importorskip("rclpy.serialization", reason=_why)
pytest.importorskip("articutool_interfaces.action", reason=_why)

from articutool_interfaces.action import ExecuteArticutoolPrimitive as A  # noqa: E402
from articutool_interfaces.srv import SetOrientationControl as S  # noqa: E402

GID = bytes(range(16))
CASES: list[tuple[str, Any, Any]] = [
    (f"{cdr.SET_ORIENTATION_CONTROL}_Request", S.Request, m.soc_request(m.Mode.LEVELING, 12.5, -3)),
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
    soc = ser.deserialize_message(cdr.encode(m.soc_request(m.Mode.LEVELING, 12.5, -3.0),
                                           f"{cdr.SET_ORIENTATION_CONTROL}_Request"), S.Request)
    assert (soc.control_mode, soc.pitch_offset, soc.roll_offset) == (S.Request.MODE_LEVELING,
                                                                     12.5, -3.0)


@pytest.mark.parametrize("typename", [cdr.SET_ORIENTATION_CONTROL, cdr.ACTION])
def test_type_hashes_equal_the_built_packages(typename: str) -> None:
    pkg, kind, name = typename.split("/")
    doc = json.loads((Path(sys.prefix) / "share" / pkg / kind / f"{name}.json").read_text())
    for entry in doc["type_hashes"]:
        assert cdr.type_hash(entry["type_name"]) == entry["hash_string"], entry["type_name"]


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
    for rel in ("srv/SetOrientationControl.srv", "action/ExecuteArticutoolPrimitive.action"):
        assert (installed / rel).read_text() == (cdr.IDL_DIR / rel).read_text()
