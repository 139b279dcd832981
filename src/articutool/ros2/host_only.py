"""Host-only ``articutool ros2``: DDS on loopback and shared memory, and a check that it is.

``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` only stops a participant from *searching* beyond
this host: with it, rmw_fastrtps adds a UDPv4 transport open on every interface (sockets on
0.0.0.0 and on each interface's address), so a participant on another host that names this
host as a static peer discovers the node and calls its services. So, unless the user opens
the graph, the node applies a Fast DDS profile of its own before rmw initialises:

- no builtin transports; a UDPv4 transport whose interface allow-list is 127.0.0.1 (up to 32
  participants probed per initial peer, as rmw's localhost setting does) and shared memory;
- discovery metatraffic on a unicast 127.0.0.1 locator and no multicast locator; initial
  peers 127.0.0.1 and the user's IPv4 loopback ``ROS_STATIC_PEERS``; with
  ``ROS_AUTOMATIC_DISCOVERY_RANGE=OFF`` no initial peers and one participant (rmw's meaning);
- ``ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT`` in the node's own environment, so rmw adds
  no transport of its own, and ``SKIP_DEFAULT_XML_FILE=1`` so no ``DEFAULT_FASTDDS_PROFILES.xml``
  in the working directory is read beside it.

The profile goes to a new private directory (mode 0700, the file created exclusively, never
through a link). Once the participant exists, :func:`exposed_sockets` lists every IP socket
of the process (``/proc/self/net`` and ``/proc/self/fd``) that is bound to anything but a
loopback address; the node refuses to run if there is one.
"""

from __future__ import annotations

import ipaddress
import os
import shutil
import socket
import struct
import tempfile
from collections.abc import Iterable, MutableMapping
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import escape

__all__ = ["BoundSocket", "HostOnlyProfile", "apply_profile", "exposed", "exposed_sockets",
           "process_sockets", "profile_xml"]

PROFILE_NAME = "articutool_host_only"
# Variables that would change the transports behind the profile's back in this process.
_OVERRIDDEN = ("FASTDDS_BUILTIN_TRANSPORTS",)


def _loopback_ipv4(peers: Iterable[str]) -> list[str]:
    """The IPv4 loopback addresses among ``ROS_STATIC_PEERS`` entries, 127.0.0.1 first."""
    out = ["127.0.0.1"]
    for raw in peers:
        host = raw.strip()
        host = "127.0.0.1" if host == "localhost" else host
        try:
            ip = ipaddress.ip_address(host)
        except ValueError:
            continue
        if ip.version == 4 and ip.is_loopback and str(ip) not in out:
            out.append(str(ip))
    return out


def profile_xml(peers: Iterable[str] = (), discovery: bool = True) -> str:
    """The Fast DDS XML profile: loopback UDPv4 and shared memory only, unicast discovery on
    127.0.0.1 (``discovery`` False: no initial peers and no participant but this one)."""
    initial = "".join(f"<locator><udpv4><address>{escape(a)}</address></udpv4></locator>"
                      for a in _loopback_ipv4(peers)) if discovery else ""
    alone = ("" if discovery else
             "<allocation><total_participants><initial>1</initial><maximum>1</maximum>"
             "<increment>0</increment></total_participants></allocation>")
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns="http://www.eprosima.com">
  <profiles>
    <transport_descriptors>
      <transport_descriptor>
        <transport_id>{PROFILE_NAME}_udp</transport_id>
        <type>UDPv4</type>
        <maxInitialPeersRange>32</maxInitialPeersRange>
        <interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>
      </transport_descriptor>
      <transport_descriptor>
        <transport_id>{PROFILE_NAME}_shm</transport_id>
        <type>SHM</type>
      </transport_descriptor>
    </transport_descriptors>
    <participant profile_name="{PROFILE_NAME}" is_default_profile="true">
      <rtps>
        <useBuiltinTransports>false</useBuiltinTransports>
        <userTransports>
          <transport_id>{PROFILE_NAME}_udp</transport_id>
          <transport_id>{PROFILE_NAME}_shm</transport_id>
        </userTransports>
        <builtin>
          <metatrafficUnicastLocatorList>
            <locator><udpv4><address>127.0.0.1</address></udpv4></locator>
          </metatrafficUnicastLocatorList>
          <initialPeersList>{initial}</initialPeersList>
        </builtin>{alone}
      </rtps>
    </participant>
  </profiles>
</dds>
"""


@dataclass
class HostOnlyProfile:
    """The profile file written for this process; :meth:`remove` deletes it."""

    path: Path

    def remove(self) -> None:
        """Delete the private directory (Fast DDS has read the file by then)."""
        shutil.rmtree(self.path.parent, ignore_errors=True)


def apply_profile(env: MutableMapping[str, str]) -> HostOnlyProfile:
    """Write the profile to a new private directory and point ``env`` (the node's own
    ``os.environ``, before rclpy initialises) at it. The discovery range it keeps is the
    one :func:`articutool.ros2.exposure.discovery_scope` accepted (LOCALHOST or OFF)."""
    rng = env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").strip().upper()
    peers = env.get("ROS_STATIC_PEERS", "").split(";")
    folder = Path(tempfile.mkdtemp(prefix="articutool-dds-"))  # 0700, new: no one else's
    path = folder / "host_only.xml"
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0),
                 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(profile_xml(peers, discovery=rng != "OFF"))
    env["FASTDDS_DEFAULT_PROFILES_FILE"] = str(path)
    env["SKIP_DEFAULT_XML_FILE"] = "1"
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SYSTEM_DEFAULT"  # rmw adds no transport
    for name in _OVERRIDDEN:
        env.pop(name, None)
    return HostOnlyProfile(path)


@dataclass(frozen=True)
class BoundSocket:
    """One IP socket of a process: ``proto`` (udp, udp6, tcp, tcp6), local address, port."""

    proto: str
    address: str
    port: int

    def __str__(self) -> str:
        host = f"[{self.address}]" if ":" in self.address else self.address
        return f"{self.proto} {host}:{self.port}"


def _address(hexaddr: str) -> str:
    raw = bytes.fromhex(hexaddr)
    if len(raw) == 4:
        return socket.inet_ntop(socket.AF_INET, struct.pack("<I", int(hexaddr, 16)))
    words = struct.unpack(">4I", raw)  # four host-order (little-endian) 32-bit words
    return socket.inet_ntop(socket.AF_INET6, struct.pack("<4I", *words))


def process_sockets(pid: int | str = "self") -> list[BoundSocket]:
    """Every UDP and TCP socket (IPv4 and IPv6) the process ``pid`` holds, from
    ``/proc/<pid>/fd`` and its network namespace's ``/proc/<pid>/net`` tables (Linux)."""
    inodes = set()
    fd_dir = f"/proc/{pid}/fd"
    for fd in os.listdir(fd_dir):
        try:
            target = os.readlink(f"{fd_dir}/{fd}")
        except OSError:  # closed meanwhile
            continue
        if target.startswith("socket:["):
            inodes.add(int(target[8:-1]))
    out = []
    for proto in ("udp", "udp6", "tcp", "tcp6"):
        try:
            lines = Path(f"/proc/{pid}/net/{proto}").read_text().splitlines()[1:]
        except OSError:  # no IPv6 in this kernel
            continue
        for line in lines:
            f = line.split()
            if len(f) > 9 and int(f[9]) in inodes:
                host, port = f[1].rsplit(":", 1)
                out.append(BoundSocket(proto, _address(host), int(port, 16)))
    return out


def exposed(sockets: Iterable[BoundSocket]) -> list[BoundSocket]:
    """The sockets bound to anything but a loopback address (0.0.0.0 and :: included)."""
    return [s for s in sockets if not ipaddress.ip_address(s.address).is_loopback]


def exposed_sockets() -> list[BoundSocket]:
    """This process's sockets that another host could reach (see :func:`exposed`)."""
    return exposed(process_sockets())
