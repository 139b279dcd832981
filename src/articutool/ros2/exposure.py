"""Who can reach ``articutool ros2`` on the DDS graph: the check that keeps the wrist off the
network unless the user opens it.

Plain DDS has no authentication: any participant that discovers the node can call its
services and so command the wrist (the link's pairing and signatures protect only the link
behind it). The ROS 2 wheels the node runs on carry no DDS-Security plugins (measured:
``studies/ros2_dds_security.py``), so discovery is the only lock. Since ROS 2 Iron the
default discovery range is the whole subnet. :func:`discovery_scope` reads the environment
rcl reads and says whether discovery stays on this host; the node starts only then, or when
its own ``--allow-remote-ros-clients`` flag says the user wants the graph open (a variable in
the shell is not that consent: it applies to every ROS 2 process started there).

Pure: reads only the mapping it is given.
"""

from __future__ import annotations

import ipaddress
from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["ALLOW_FLAG", "Scope", "discovery_scope"]

ALLOW_FLAG = "--allow-remote-ros-clients"
_HOST_RANGES = ("LOCALHOST", "OFF")
# Variables that can widen discovery behind the range's back (a Fast DDS XML profile can
# add peers and transports; this check cannot read what it allows).
_PROFILE_VARS = ("FASTDDS_DEFAULT_PROFILES_FILE", "FASTRTPS_DEFAULT_PROFILES_FILE",
                 "FASTDDS_ENVIRONMENT_FILE", "ROS_DISCOVERY_SERVER")


@dataclass(frozen=True)
class Scope:
    """``host_only`` when discovery cannot leave this host; ``why`` says what was read."""

    host_only: bool
    why: str


def _loopback(peer: str) -> bool:
    host = peer.strip().rsplit(":", 1)[0] if peer.count(":") == 1 else peer.strip()
    host = host.strip("[]")
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def discovery_scope(env: Mapping[str, str]) -> Scope:
    """Whether the ROS 2 process started with ``env`` discovers only on this host.

    Host-only: ``ROS_AUTOMATIC_DISCOVERY_RANGE`` is ``LOCALHOST`` or ``OFF``, every
    ``ROS_STATIC_PEERS`` entry (``;``-separated) is a loopback address, and no DDS profile
    or discovery server variable is set. ``ROS_LOCALHOST_ONLY`` is not read by this ROS 2
    (rcl 10 replaced it with the range) and does not count.
    """
    rng = env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper()
    if rng not in _HOST_RANGES:
        shown = f"is {rng!r}" if rng else "is not set (ROS 2's default: the whole subnet)"
        hint = (" (ROS_LOCALHOST_ONLY=1 is not read by this ROS 2)"
                if env.get("ROS_LOCALHOST_ONLY", "").strip() == "1" else "")
        return Scope(False, f"ROS_AUTOMATIC_DISCOVERY_RANGE {shown}{hint}")
    peers = [p for p in env.get("ROS_STATIC_PEERS", "").split(";") if p.strip()]
    remote = [p.strip() for p in peers if not _loopback(p)]
    if remote and rng == "LOCALHOST":
        return Scope(False, f"ROS_STATIC_PEERS names hosts other than this one: {remote}")
    profiles = [v for v in _PROFILE_VARS if env.get(v, "").strip()]
    if profiles:
        return Scope(False, f"{', '.join(profiles)} is set: a DDS profile or discovery server "
                            "can reach other hosts, which this check cannot rule out")
    return Scope(True, f"ROS_AUTOMATIC_DISCOVERY_RANGE={rng}")
