"""The link's wire format: ROS 2 type names, the Articutool interfaces and CDR (thesis §3.2.2).

The Articutool's own types are defined once, in the ROS 2 interface package shipped beside this
module (``articutool_interfaces``: ``SetOrientationControl``, ``TriggerCalibration``,
``ImuCalibrationStatus``, ``ExecuteArticutoolPrimitive`` and ``VerifyTrajectory``, thesis
Listings 3.1-3.2): this module parses those files into a ``rosbags`` type store with the
action protocol's and the standard types, and ``make`` builds the same files into a real ROS 2
package (:mod:`articutool.ros2.build_interfaces`). Payloads are ROS 2 CDR, including the 4-byte
encapsulation header, i.e. the bytes a ROS 2 node puts on the wire; :func:`decode` raises
:class:`LinkDecodeError` on malformed input (never another exception type). Pure (its only I/O
is reading its own interface files once, at import). :mod:`articutool.link.messages` builds
and converts the messages and re-exports these names.
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path
from typing import Any

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

__all__ = [
    "ACTION",
    "BATTERY_STATE",
    "CANCEL_GOAL",
    "DIAGNOSTIC_ARRAY",
    "FEEDBACK_MESSAGE",
    "GET_RESULT",
    "GOAL_STATUS_ARRAY",
    "HEADER",
    "IDL_DIR",
    "IMU",
    "IMU_CALIBRATION_STATUS",
    "JOINT_STATE",
    "JOINT_TRAJECTORY",
    "PKG",
    "SEND_GOAL",
    "SET_ORIENTATION_CONTROL",
    "TRIGGER",
    "TRIGGER_CALIBRATION",
    "VERIFY_TRAJECTORY",
    "LinkDecodeError",
    "dds_type_name",
    "decode",
    "encode",
    "interface_hashes",
    "msg",
    "package_texts",
    "register_interfaces",
    "type_hash",
    "typestore",
]

PKG = "articutool_interfaces"
SET_ORIENTATION_CONTROL = f"{PKG}/srv/SetOrientationControl"
TRIGGER_CALIBRATION = f"{PKG}/srv/TriggerCalibration"
IMU_CALIBRATION_STATUS = f"{PKG}/msg/ImuCalibrationStatus"
VERIFY_TRAJECTORY = f"{PKG}/srv/VerifyTrajectory"
ACTION = f"{PKG}/action/ExecuteArticutoolPrimitive"
SEND_GOAL = f"{ACTION}_SendGoal"
GET_RESULT = f"{ACTION}_GetResult"
FEEDBACK_MESSAGE = f"{ACTION}_FeedbackMessage"
CANCEL_GOAL = "action_msgs/srv/CancelGoal"
TRIGGER = "std_srvs/srv/Trigger"
GOAL_STATUS_ARRAY = "action_msgs/msg/GoalStatusArray"
JOINT_STATE = "sensor_msgs/msg/JointState"
IMU = "sensor_msgs/msg/Imu"
JOINT_TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
BATTERY_STATE = "sensor_msgs/msg/BatteryState"
HEADER = "std_msgs/msg/Header"

IDL_DIR = Path(__file__).resolve().parent / PKG  # the ROS 2 package's source


def _sections(text: str, parts: tuple[str, ...], where: str) -> dict[str, str]:
    """The ``---``-separated sections of an interface text as {type name: .msg text}."""
    sections = re.split(r"^---[ \t]*$", text, flags=re.MULTILINE)
    if len(sections) != len(parts):
        raise RuntimeError(f"{where}: expected {len(parts)} sections separated by '---'; "
                           f"found {len(sections)}")
    return {name: body.strip("\n") + "\n" for name, body in zip(parts, sections, strict=True)}


def package_texts(root: Path = IDL_DIR) -> dict[str, str]:
    """Every ``msg/*.msg``, ``srv/*.srv`` and ``action/*.action`` of a package folder, as
    {relative path: text}."""
    return {f"{kind}/{f.name}": f.read_text(encoding="utf-8")
            for kind in ("msg", "srv", "action")
            for f in sorted((root / kind).glob(f"*.{kind}"))}


# std_srvs/srv/Trigger; an empty ROS 2 request carries the IDL generator's placeholder byte.
_SRV_TRIGGER = {
    "Trigger_Request": "uint8 structure_needs_at_least_one_member\n",
    "Trigger_Response": "bool success\nstring message\n",
}
# action_msgs/srv/CancelGoal is not in rosbags' stores (it only holds messages).
_CANCEL = {
    "CancelGoal_Request": "action_msgs/GoalInfo goal_info\n",
    "CancelGoal_Response": (
        "int8 ERROR_NONE=0\nint8 ERROR_REJECTED=1\nint8 ERROR_UNKNOWN_GOAL_ID=2\n"
        "int8 ERROR_GOAL_TERMINATED=3\nint8 return_code\naction_msgs/GoalInfo[] goals_canceling\n"),
}


class LinkDecodeError(ValueError):
    """A payload is not a valid CDR encoding of the expected message type."""


def _rename(obj: Any, mapping: dict[str, str]) -> Any:
    """Rewrite type-name strings inside rosbags field definitions."""
    if isinstance(obj, str):
        return mapping.get(obj, obj)
    if isinstance(obj, tuple):
        return tuple(_rename(o, mapping) for o in obj)
    if isinstance(obj, list):
        return [_rename(o, mapping) for o in obj]
    return obj


def _parse(pkg: str, kind: str, defs: dict[str, str], also: tuple[str, ...] = ()) -> dict[str, Any]:
    """Parse .msg texts registered as ``pkg/kind/Name`` (rosbags assumes ``pkg/msg/Name``).

    ``also`` names further ``pkg/kind`` types the texts refer to by their short name.
    """
    out: dict[str, Any] = {}
    for name, text in defs.items():
        out.update(get_types_from_msg(text, f"{pkg}/msg/{name}"))
    mapping = {f"{pkg}/msg/{n}": f"{pkg}/{kind}/{n}" for n in (*defs, *also)}
    return {mapping.get(k, k): _rename(v, mapping) for k, v in out.items()}


def _srv_description(pkg: str, kind: str, base: str) -> dict[str, Any]:
    """REP 2011 service description structs, used only for the service's RIHS01 type hash."""
    defs = {
        f"{base}_Event": (f"service_msgs/ServiceEventInfo info\n{base}_Request[<=1] request\n"
                          f"{base}_Response[<=1] response\n"),
        base: (f"{base}_Request request_message\n{base}_Response response_message\n"
               f"{base}_Event event_message\n"),
    }
    return _parse(pkg, kind, defs, also=(f"{base}_Request", f"{base}_Response"))


_SEI = "service_msgs/msg/ServiceEventInfo"


def _empty_placeholder(defs: dict[str, str]) -> dict[str, str]:
    """A section without fields gets the placeholder byte rosidl gives an empty structure
    (``TriggerCalibration``'s request), as for ``std_srvs/Trigger``."""
    return {k: (v if re.search(r"^\s*[A-Za-z]", v, flags=re.MULTILINE)
                else "uint8 structure_needs_at_least_one_member\n") for k, v in defs.items()}


def register_interfaces(ts: Any, pkg: str, texts: dict[str, str]) -> list[str]:
    """Register a package's interfaces ({``msg|srv|action/Name.ext``: text}) in ``ts`` as
    rosidl generates them: messages; a service's request, response and REP 2011 description;
    an action's goal, result, feedback, its SendGoal/GetResult services, feedback message and
    description. Returns the top-level type names (``pkg/kind/Name``)."""
    out = []
    for rel, text in texts.items():
        kind, fname = rel.split("/")
        name = fname.rsplit(".", 1)[0]
        if kind == "msg":
            ts.register(_parse(pkg, "msg", _sections(text, (name,), rel)))
        elif kind == "srv":
            defs = _sections(text, (f"{name}_Request", f"{name}_Response"), rel)
            ts.register(_parse(pkg, "srv", _empty_placeholder(defs)))
            ts.register(_srv_description(pkg, "srv", name))
        else:
            parts = ("Goal", "Result", "Feedback")
            defs = _sections(text, tuple(f"{name}_{p}" for p in parts), rel)
            defs.update({
                f"{name}_SendGoal_Request": (
                    f"unique_identifier_msgs/UUID goal_id\n{name}_Goal goal\n"),
                f"{name}_SendGoal_Response": "bool accepted\nbuiltin_interfaces/Time stamp\n",
                f"{name}_GetResult_Request": "unique_identifier_msgs/UUID goal_id\n",
                f"{name}_GetResult_Response": f"int8 status\n{name}_Result result\n",
                f"{name}_FeedbackMessage": (
                    f"unique_identifier_msgs/UUID goal_id\n{name}_Feedback feedback\n"),
            })
            ts.register(_parse(pkg, "action", _empty_placeholder(defs)))
            for sub in ("SendGoal", "GetResult"):
                ts.register(_srv_description(pkg, "action", f"{name}_{sub}"))
            subs = ("Goal", "Result", "Feedback", "SendGoal", "GetResult", "FeedbackMessage")
            fields = "".join(f"{name}_{p} {f}\n" for p, f in zip(subs, (
                "goal", "result", "feedback", "send_goal_service", "get_result_service",
                "feedback_message"), strict=True))
            ts.register(_parse(pkg, "action", {name: fields},
                               also=tuple(f"{name}_{p}" for p in subs)))
        out.append(f"{pkg}/{kind}/{name}")
    return out


def _base_store() -> Any:
    """rosbags' ROS 2 (Jazzy) store, with ServiceEventInfo as rosidl describes it."""
    ts = get_typestore(Stores.ROS2_JAZZY)
    # rosidl maps a .msg ``char`` to uint8, and ROS 2's type descriptions (hence every
    # service's RIHS01 hash) say uint8[16] for ServiceEventInfo.client_gid; rosbags keeps
    # ``char``, which gives other hashes (found against rclpy's installed descriptions).
    # Same wire size; nothing here serialises ServiceEventInfo.
    consts, fields = ts.fielddefs[_SEI]
    ts.fielddefs[_SEI] = (consts, [
        (n, (t[0], ((t[1][0][0], ("uint8", 0)), t[1][1])) if n == "client_gid" else t)
        for n, t in fields])
    return ts


@lru_cache(maxsize=1)
def typestore() -> Any:
    """The ROS 2 (Jazzy) type store with the Articutool and action protocol types."""
    ts = _base_store()
    register_interfaces(ts, PKG, package_texts())
    ts.register(_parse("action_msgs", "srv", _CANCEL))
    if f"{TRIGGER}_Request" not in ts.fielddefs:
        ts.register(_parse("std_srvs", "srv", _SRV_TRIGGER))
        ts.register(_srv_description("std_srvs", "srv", "Trigger"))
    ts.register(_srv_description("action_msgs", "srv", "CancelGoal"))
    return ts


def interface_hashes(texts: dict[str, str], pkg: str = PKG) -> dict[str, str]:
    """RIHS01 hashes of a package's interfaces computed from their texts alone
    ({``srv/X.srv``: text, …}), e.g. another release of ``articutool_interfaces``."""
    ts = _base_store()
    return {name: str(ts.hash_rihs01(name)) for name in register_interfaces(ts, pkg, texts)}


def type_hash(typename: str) -> str:
    """RIHS01 type hash (REP 2011) of a message, service or action type, via rosbags."""
    return str(typestore().hash_rihs01(typename))


def dds_type_name(typename: str) -> str:
    """``pkg/msg/Name`` → ``pkg::msg::dds_::Name_`` (the type name rmw_zenoh puts in keys)."""
    pkg, kind, name = typename.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def msg(typename: str, **fields: Any) -> Any:
    """Build a message instance of ``typename``."""
    return typestore().types[typename](**fields)


def encode(message: Any, typename: str) -> bytes:
    """Serialise ``message`` as little-endian ROS 2 CDR (with encapsulation header)."""
    return bytes(typestore().serialize_cdr(message, typename))


_ALIGN = {"bool": 1, "byte": 1, "char": 1, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2,
          "int32": 4, "uint32": 4, "float32": 4, "int64": 8, "uint64": 8, "float64": 8,
          "string": 4, "wstring": 4}  # strings start with an aligned uint32 length
_FINAL_PAD = 7  # a serializer may round the whole message up to the largest alignment (8)


def _padding_bound(value: Any, node: tuple[Any, Any]) -> int:
    """Most alignment padding (bytes) CDR can put in ``value`` of rosbags field type ``node``:
    ``align - 1`` before every aligned item, once per primitive array (it is contiguous)."""
    kind, desc = int(node[0]), node[1]
    if kind == 1:  # BASE: (type name, string bound)
        return _ALIGN.get(desc[0], 8) - 1
    if kind == 2:  # NAME: a nested message
        _, fields = typestore().fielddefs[desc]
        return sum(_padding_bound(getattr(value, f), t) for f, t in fields)
    sub, _ = desc  # ARRAY or SEQUENCE of sub
    head = 3 if kind == 4 else 0  # a sequence's uint32 length
    if int(sub[0]) == 1 and sub[1][0] not in ("string", "wstring"):
        return head + _ALIGN.get(sub[1][0], 8) - 1
    return head + sum(_padding_bound(v, sub) for v in value)


def decode(data: bytes | bytearray | memoryview, typename: str) -> Any:
    """Deserialise ROS 2 CDR bytes as ``typename``; raise LinkDecodeError when malformed.

    Checks the encapsulation header (plain CDR, either endianness) and wraps every decoder
    failure (bad lengths, bad UTF-8, short buffers) in LinkDecodeError. Bytes after the
    message are accepted only as alignment padding: at most the padding the message's own
    fields could need (:func:`_padding_bound`) plus the final rounding to 8. ROS 2's
    ``rmw_serialize`` (Fast-CDR typesupport) sizes its buffer by the serialised-size
    estimate, which assumes worst-case padding, so its messages end in such bytes (8 per
    ``JointTrajectoryPoint``; with whatever the buffer held: padding contents are
    unspecified in CDR and are not checked here or inside the message). Anything longer
    (another message appended, a truncated length) is an error.
    """
    raw = bytes(data)
    if len(raw) < 4 or raw[0] != 0 or raw[1] not in (0, 1):
        raise LinkDecodeError(
            f"{typename}: not a CDR payload (need a 4-byte header 00 00|01 ..; got "
            f"{raw[:4].hex() or 'nothing'})")
    try:
        ts = typestore()
        md = ts.get_msgdef(typename)
        fn = md.deserialize_cdr_le if raw[1] == 1 else md.deserialize_cdr_be
        obj, pos = fn(raw[4:], 0, md.cls, ts)
    except Exception as err:  # rosbags raises assorted errors on garbage: normalise them
        raise LinkDecodeError(f"{typename}: malformed CDR payload ({len(raw)} bytes): "
                              f"{type(err).__name__}: {err}") from None
    extra = len(raw) - 4 - pos
    if extra > _FINAL_PAD:  # only then is the (linear) walk over the message needed
        bound = _FINAL_PAD + _padding_bound(obj, (2, typename))
        if extra > bound:
            raise LinkDecodeError(
                f"{typename}: payload has {len(raw)} bytes but the message ends at byte "
                f"{pos + 4}: {extra} trailing bytes, more than the {bound} of alignment "
                "padding it can have")
    return obj
