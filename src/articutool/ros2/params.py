"""The ROS 2 parameters of ``articutool ros2``: declared, typed, with ranges, read-only once
the node runs (they configure how it starts).

Each parameter's default is what the command line and the link config say, so
``--ros-args -p name:=value`` (or a launch file's parameters) overrides a flag, and ``ros2
param get /articutool_ros2 NAME`` reads the value in force. A value of the wrong type or out
of range is bad input: :class:`ParamError` names the parameter and what it allows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

__all__ = ["PARAMS", "Param", "ParamError", "declare_all", "unknown_overrides"]


class ParamError(ValueError):
    """A parameter given a value the node cannot use; the message names it."""


@dataclass(frozen=True)
class Param:
    """One parameter: name, type ('string', 'double', 'string_array', 'bool'), description and,
    for numbers, the allowed closed range; ``choices`` for strings."""

    name: str
    type: str
    description: str
    low: float = -math.inf
    high: float = math.inf
    choices: tuple[str, ...] = ()


PARAMS = (
    Param("tool_id", "string", "the tool's identity on the link (default: the link config's)"),
    Param("link_config", "string", "link config TOML/JSON of the paired PC ('' = flags only)"),
    Param("namespace", "string",
          "prefix of every ROS 2 name ('' = the upstream Articutool names exactly)"),
    Param("wait_s", "double", "seconds to wait for the tool to be heard at start", 0.0, 3600.0),
    Param("call_timeout_s", "double", "seconds a command may wait for the tool's reply",
          0.05, 60.0),
    Param("tool_timeout_s", "double", "seconds of silence before the tool counts as gone",
          0.05, 60.0),
    Param("joint_names", "string_array",
          "ROS 2 names of the wrist joints [pitch, roll] in joint states and trajectories"),
    Param("offset_units", "string", "unit of SetOrientationControl's offsets on the wire "
          "(radians: what ADA's CallSetOrientationControl sends; degrees: the upstream .srv)",
          choices=("degrees", "radians")),
    Param("republish_joint_states", "bool",
          "also publish the wrist's joint states on joint_states (upstream's republisher)"),
    Param("utensil", "string", "utensil VerifyTrajectory assumes when a request names none"),
)


def declare_all(node: Any, defaults: dict[str, Any]) -> dict[str, Any]:
    """Declare :data:`PARAMS` on ``node`` with ``defaults``; return the values in force
    (overrides from ``--ros-args -p`` applied). Raises ParamError naming a parameter whose
    override has the wrong type or lies outside its range or choices."""
    from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, ParameterType
    from rclpy.exceptions import (
        InvalidParameterTypeException,
        InvalidParameterValueException,
    )

    kinds = {"string": ParameterType.PARAMETER_STRING,
             "double": ParameterType.PARAMETER_DOUBLE,
             "string_array": ParameterType.PARAMETER_STRING_ARRAY,
             "bool": ParameterType.PARAMETER_BOOL}
    _integers_as_doubles(node)
    out: dict[str, Any] = {}
    for p in PARAMS:
        desc = ParameterDescriptor(name=p.name, type=kinds[p.type], read_only=True,
                                   description=p.description
                                   + (f" (one of {list(p.choices)})" if p.choices else ""))
        if p.type == "double":
            desc.floating_point_range = [FloatingPointRange(from_value=p.low, to_value=p.high,
                                                            step=0.0)]
        allowed = (f"a number in [{p.low:g}, {p.high:g}]" if p.type == "double"
                   else "a list of 2 strings" if p.type == "string_array"
                   else "true or false" if p.type == "bool"
                   else f"one of {list(p.choices)}" if p.choices else "a string")
        try:
            value = node.declare_parameter(p.name, defaults[p.name], desc).value
        except (InvalidParameterTypeException, InvalidParameterValueException, TypeError) as err:
            raise ParamError(f"parameter {p.name} must be {allowed}: {err}") from None
        if p.choices and value not in p.choices:
            raise ParamError(f"parameter {p.name} must be one of {list(p.choices)}; "
                             f"got {value!r}")
        if p.type == "string_array":
            value = tuple(str(v) for v in value)
            if len(value) != 2 or not all(value) or value[0] == value[1]:
                raise ParamError(f"parameter {p.name} must be {allowed} (two different "
                                 f"non-empty names); got {list(value)}")
        out[p.name] = value
    return out


def _integers_as_doubles(node: Any) -> None:
    """``-p wait_s:=5`` means 5.0: rclpy would refuse an integer for a double parameter."""
    from rclpy.parameter import Parameter

    overrides = getattr(node, "_parameter_overrides", None)
    if not isinstance(overrides, dict):
        return
    for p in PARAMS:
        given = overrides.get(p.name)
        if p.type == "double" and given is not None \
                and given.type_ == Parameter.Type.INTEGER:
            overrides[p.name] = Parameter(p.name, Parameter.Type.DOUBLE, float(given.value))


def unknown_overrides(node: Any) -> list[str]:
    """Names given with ``--ros-args -p`` that are not parameters of the node (typos)."""
    known = {p.name for p in PARAMS} | {"use_sim_time", "start_type_description_service"}
    given = getattr(node, "_parameter_overrides", {}) or {}
    return sorted(n for n in given if n not in known)
