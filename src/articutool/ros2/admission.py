"""Refusals ``articutool ros2`` answers itself, before a request takes a lane, a thread or a
link round trip: the tool's own checks of the request alone, so the message is the tool's.

Under a flood of bad calls each one forwarded costs a signed link round trip (and, for a
goal, a thread and a goal slot) only for the tool to refuse it; these checks refuse them at
once. Only checks that depend on nothing but the request and the connected tool's own
limits are made here (the tool still checks its state: faults, a running primitive,
leveling, its joints). The limits are the ones that tool reports in its telemetry
(:func:`~articutool.tool.telemetry.reported_limits`), never the packaged spec: a tool built
from another spec file has other limits, and a request within them must reach it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from articutool.tool.api import Mode
from articutool.tool.modes import check_offsets
from articutool.tool.primitives import PrimitiveError, get_primitive

__all__ = ["mode_refusal", "primitive_refusal"]


def mode_refusal(mode: int, pitch_deg: float, roll_deg: float,
                 limits: NDArray[np.float64] | None) -> str | None:
    """Why the connected tool, whose joint limits (rad) are ``limits``, would refuse
    LEVELING with these offsets (degrees), or None; None also when its limits are not known
    (``limits`` None: the tool checks)."""
    if mode != Mode.LEVELING or limits is None:
        return None
    try:
        check_offsets(pitch_deg, roll_deg, limits)
    except ValueError as err:
        return str(err)
    return None


def primitive_refusal(name: str) -> str | None:
    """Why the tool would refuse a primitive of this name whatever its state, or None."""
    try:
        get_primitive(str(name))
    except PrimitiveError as err:
        return str(err)
    return None
