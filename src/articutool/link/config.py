"""Link configuration: Zenoh endpoints, timeouts and the link-loss policy.

Loopback by default: the tool listens on ``tcp/127.0.0.1:7447`` and the client connects there,
with multicast scouting off so nothing leaves the host. For a Pi on the network, pair first
(``articutool pair``): the tool listens on ``tls/0.0.0.0:7447`` with mutual TLS and the PC
connects to ``tls/<pi address>:7447``; a plain endpoint on a network address without pairing
is refused (:func:`articutool.link.zenoh_transport.exposure`; ``articutool tool
--insecure-listen`` overrides).
A config file is TOML or JSON with the field names below at top level (or under a ``[link]``
table)::

    mode = "peer"                      # or "client" (through a zenoh router)
    listen = ["tls/0.0.0.0:7447"]
    connect = []
    link_loss_policy = "continue"      # what a running primitive does when the PC goes silent
    tool_id = "wrist-1"                # the tool's identity: in every key and in telemetry
    identity = "pc-1"                  # this device's name (the certificate's CN when paired)
    tls_root_ca = "ca.pem"             # paired (``articutool pair`` writes these): mutual TLS,
    tls_certificate = "cert.pem"       #   signed commands, and a tool that refuses any
    tls_private_key = "key.pem"        #   command not signed by a paired device

Relative paths in a config file are relative to the file. Size limits (bytes) per message
kind: ``max_trajectory_bytes`` (JointTrajectory), ``max_request_bytes`` (service requests and
heartbeats); larger messages are dropped before decoding and counted.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import re
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

__all__ = ["DEFAULT_ENDPOINT", "MAX_DOMAIN_ID", "ConfigError", "LinkConfig", "add_config_args",
           "check_endpoint", "check_ros_environment", "config_from_args",
           "installed_rmw_implementations", "load_config"]

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
MAX_DOMAIN_ID = 232  # the largest ROS domain id DDS can map to UDP ports


class ConfigError(ValueError):
    """A link configuration value is invalid (the message names the field)."""


# Zenoh locators: <protocol>/<address>[?metadata][#config]. IP protocols take host:port.
_IP_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws")
_ENDPOINT_FORM = (f"'<protocol>/<host>:<port>' with protocol one of {', '.join(_IP_PROTOCOLS)} "
                  f"and port in [0, 65535] (e.g. '{DEFAULT_ENDPOINT}'), or "
                  "'unixsock-stream/<path>'")


def check_endpoint(endpoint: object, field_name: str) -> str:
    """Check the syntax of one zenoh endpoint; ConfigError names ``field_name`` and the form.

    Whether the address can be used (free, on this host) is only known when the session
    opens: that failure is :class:`~articutool.link.transport.LinkOpenError`.
    """
    bad = ConfigError(f"{field_name} must be a zenoh endpoint {_ENDPOINT_FORM}; "
                      f"got {endpoint!r}")
    if not isinstance(endpoint, str):
        raise bad
    proto, sep, rest = endpoint.partition("/")
    address = rest.split("?", 1)[0].split("#", 1)[0]
    if not sep or not address:
        raise bad
    if proto == "unixsock-stream":
        return endpoint
    if proto not in _IP_PROTOCOLS:
        raise bad
    host, colon, port = address.rpartition(":")
    if not colon or not host or not port.isdigit() or int(port) > 65535:
        raise bad
    return endpoint


# A ROS namespace: every name is a literal key-expression chunk, so no Zenoh wildcard
# ('*', '**', '$*') or empty chunk can make the tool's names match another tool's.
NAMESPACE_FORM = ("'/' or '/'-separated names of letters, digits and '_' (each starting with a "
                  "letter or '_'), e.g. '/articutool'")
_NAMESPACE = re.compile(r"^/$|^(/[A-Za-z_][A-Za-z0-9_]*)+$")


# The longest each period may be (s): beyond these a value is a unit slip (ms written as s)
# or a typo, and 1e308 s overflowed zenoh's retry period in milliseconds.
_PERIODS_S = {"heartbeat_period": 10.0, "tool_timeout": 3600.0, "client_timeout": 3600.0,
              "call_timeout": 3600.0, "reconnect_period": 60.0}
# zenoh's own settings: '/'-separated names of letters, digits, '_' and '-' (e.g.
# "transport/unicast/max_links"); a value is JSON (tables and lists at most this deep).
_EXTRA_PATH = re.compile(r"^[A-Za-z0-9_-]+(/[A-Za-z0-9_-]+)*$")
_EXTRA_DEPTH = 8


def _check_extra(extra: object) -> None:
    """``extra``: a table of zenoh config paths to JSON values (checked here for shape;
    zenoh says whether it accepts each when the session opens)."""
    if not isinstance(extra, dict):
        raise ConfigError("extra must be a table of zenoh settings (path = value, e.g. "
                          f"\"transport/unicast/max_links\" = 2); got {extra!r}")

    def check(path: str, v: object, depth: int) -> None:
        if depth > _EXTRA_DEPTH:
            raise ConfigError(f"extra[{path!r}] is nested deeper than {_EXTRA_DEPTH} levels")
        if isinstance(v, float) and not math.isfinite(v):
            raise ConfigError(f"extra[{path!r}] must be finite; got {v!r}")
        if isinstance(v, dict):
            for k, x in v.items():
                if not isinstance(k, str):
                    raise ConfigError(f"extra[{path!r}] keys must be strings; got {k!r}")
                check(path, x, depth + 1)
        elif isinstance(v, list | tuple):
            for x in v:
                check(path, x, depth + 1)
        elif not (v is None or isinstance(v, str | bool | int | float)):
            raise ConfigError(f"extra[{path!r}] must be a JSON value; got {v!r}")

    for path, v in extra.items():
        if not isinstance(path, str) or not _EXTRA_PATH.match(path):
            raise ConfigError(f"extra: {path!r} is not a zenoh config path ('/'-separated "
                              "names of letters, digits, '_' and '-')")
        check(path, v, 1)


@dataclass(frozen=True)
class LinkConfig:
    """Everything the tool server and the PC client need to find each other.

    ``listen``/``connect`` left as None take the role's loopback default (tool listens on
    :data:`DEFAULT_ENDPOINT`, client connects to it).
    """

    mode: Literal["peer", "client"] = "peer"
    listen: tuple[str, ...] | None = None
    connect: tuple[str, ...] | None = None
    multicast_scouting: bool = False
    domain_id: int = 0
    namespace: str = "/articutool"
    type_hash_in_keys: bool = True
    heartbeat_period: float = 0.1  # s, both directions
    tool_timeout: float = 1.0  # s of silence after which the client reports the tool dead
    client_timeout: float = 2.0  # s of silence after which the tool applies link_loss_policy
    link_loss_policy: Literal["continue", "cancel"] = "continue"
    call_timeout: float = 2.0  # s per service call
    publish_rate_hz: float | None = None  # None: the spec's wrist loop rate
    reconnect_period: float = 0.2  # s between Zenoh connection retries
    extra: dict[str, Any] = field(default_factory=dict)  # raw zenoh json5 overrides
    tool_id: str = "default"  # the tool's identity (key expressions, telemetry)
    identity: str | None = None  # this device; None: the tool_id (tool), a random name (client)
    tls_root_ca: str | None = None  # pairing CA certificate (PEM)
    tls_certificate: str | None = None  # this device's certificate (PEM)
    tls_private_key: str | None = None  # this device's key (PEM, mode 0600)
    require_paired: bool | None = None  # tool: refuse unsigned commands (None: when paired)
    peers: tuple[str, ...] | None = None  # tool: paired identities allowed (None: any of the CA)
    auth_window: float = 30.0  # s: a signed message's timestamp may differ this much
    max_trajectory_bytes: int = 1 << 20  # a JointTrajectory larger than this is dropped
    max_request_bytes: int = 4096  # a service request or heartbeat larger than this is dropped
    inbox_size: int = 16  # commands waiting for the loop; excess ones are refused and counted
    max_rate_hz: float = 200.0  # tool: messages/s per sender and endpoint; stops are exempt
    audit_log: str | None = None  # tool: JSON lines of lease transitions (take-overs…) appended

    @property
    def paired(self) -> bool:
        """Whether this device has pairing material (mutual TLS and signatures)."""
        return self.tls_root_ca is not None

    @property
    def requires_pairing(self) -> bool:
        """Whether the tool refuses commands without a paired device's signature."""
        return self.paired if self.require_paired is None else bool(self.require_paired)

    def __post_init__(self) -> None:
        if self.mode not in ("peer", "client"):
            raise ConfigError(f"mode must be 'peer' or 'client'; got {self.mode!r}")
        if self.link_loss_policy not in ("continue", "cancel"):
            raise ConfigError("link_loss_policy must be 'continue' or 'cancel'; "
                              f"got {self.link_loss_policy!r}")
        for name in ("listen", "connect"):
            v = getattr(self, name)
            if v is None:
                continue
            if isinstance(v, str) or not isinstance(v, list | tuple):
                raise ConfigError(f"{name} must be a list of zenoh endpoints like "
                                  f"'{DEFAULT_ENDPOINT}'; got {v!r}")
            for i, e in enumerate(v):
                check_endpoint(e, f"{name}[{i}]")
            object.__setattr__(self, name, tuple(v))
        if isinstance(self.domain_id, bool) or not isinstance(self.domain_id, int) \
                or not 0 <= self.domain_id <= MAX_DOMAIN_ID:
            raise ConfigError(f"domain_id must be an integer in [0, {MAX_DOMAIN_ID}]; got "
                              f"{self.domain_id!r}")
        for name in ("multicast_scouting", "type_hash_in_keys"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} must be true or false; got {getattr(self, name)!r}")
        for name, most in _PERIODS_S.items():
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v <= most:
                raise ConfigError(f"{name} must be a number of seconds in (0, {most:g}]; "
                                  f"got {v!r}")
        if self.heartbeat_period >= min(self.tool_timeout, self.client_timeout):
            raise ConfigError("heartbeat_period must be shorter than tool_timeout and "
                              f"client_timeout; got {self.heartbeat_period}")
        if self.publish_rate_hz is not None and (
                isinstance(self.publish_rate_hz, bool)
                or not isinstance(self.publish_rate_hz, int | float)
                or not 0 < self.publish_rate_hz <= 1000):
            raise ConfigError(f"publish_rate_hz must be in (0, 1000]; got {self.publish_rate_hz!r}")
        _check_extra(self.extra)
        if not isinstance(self.namespace, str) or not _NAMESPACE.match(self.namespace):
            raise ConfigError(f"namespace must be {NAMESPACE_FORM}; got {self.namespace!r}")
        from articutool.link.pairing import NAME_FORM, check_name
        for name in ("tool_id", "identity"):
            v = getattr(self, name)
            if v is not None:
                try:
                    check_name(v, name)
                except ValueError:
                    raise ConfigError(f"{name} must be {NAME_FORM}; got {v!r}") from None
        tls = {n: getattr(self, n) for n in ("tls_root_ca", "tls_certificate", "tls_private_key")}
        given = [n for n, v in tls.items() if v is not None]
        if given and len(given) != 3:
            missing = sorted(set(tls) - set(given))
            raise ConfigError(f"{missing} must be set too: pairing needs tls_root_ca, "
                              "tls_certificate and tls_private_key (from articutool pair)")
        for n in given:
            if not isinstance(tls[n], str) or not Path(tls[n]).is_file():
                raise ConfigError(f"{n} must be a readable file (from articutool pair); "
                                  f"got {tls[n]!r}")
        if self.peers is not None:
            if isinstance(self.peers, str) or not isinstance(self.peers, list | tuple):
                raise ConfigError(f"peers must be a list of device names; got {self.peers!r}")
            for i, p in enumerate(self.peers):
                try:
                    check_name(p, f"peers[{i}]")
                except ValueError as err:
                    raise ConfigError(str(err)) from None
            object.__setattr__(self, "peers", tuple(self.peers))
        if self.require_paired not in (None, True, False):
            raise ConfigError(f"require_paired must be true or false; got {self.require_paired!r}")
        if self.requires_pairing and not self.paired:
            raise ConfigError("require_paired = true needs tls_root_ca, tls_certificate and "
                              "tls_private_key (from articutool pair)")
        if self.audit_log is not None and not isinstance(self.audit_log, str):
            raise ConfigError(f"audit_log must be a file path; got {self.audit_log!r}")
        v = self.max_rate_hz
        if isinstance(v, bool) or not isinstance(v, int | float) or not 1 <= v <= 100_000:
            raise ConfigError(f"max_rate_hz must be in [1, 100000] messages/s; got {v!r}")
        v = self.auth_window
        if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v <= 3600:
            raise ConfigError(f"auth_window must be in (0, 3600] seconds; got {v!r}")
        for name, lo, hi in (("max_trajectory_bytes", 64, 1 << 30),
                             ("max_request_bytes", 64, 1 << 20), ("inbox_size", 1, 4096)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise ConfigError(f"{name} must be an integer in [{lo}, {hi}]; got {v!r}")

    def endpoints(self, role: Literal["tool", "client"]) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(listen, connect) for ``role``, with the loopback defaults filled in."""
        listen = self.listen if self.listen is not None else (
            (DEFAULT_ENDPOINT,) if role == "tool" else ())
        connect = self.connect if self.connect is not None else (
            (DEFAULT_ENDPOINT,) if role == "client" else ())
        return listen, connect

    def replace(self, **changes: Any) -> LinkConfig:
        """A copy with ``changes`` applied (validated)."""
        return dataclasses.replace(self, **changes)


def _from_mapping(data: Any, where: str) -> LinkConfig:
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a table of link settings")
    if "link" in data and isinstance(data["link"], dict):
        data = data["link"]
    names = {f.name for f in dataclasses.fields(LinkConfig)}
    unknown = sorted(set(data) - names)
    if unknown:
        raise ConfigError(f"{where}: unknown setting(s) {unknown}; allowed: {sorted(names)}")
    try:
        return LinkConfig(**data)
    except ConfigError as err:
        raise ConfigError(f"{where}: {err}") from None


_PATHS = ("tls_root_ca", "tls_certificate", "tls_private_key", "audit_log")


def load_config(path: str | Path) -> LinkConfig:
    """Read a link config file: JSON (``.json``) or TOML (anything else), with the common
    reader of the spec and task files (unreadable, non-UTF-8 or malformed: ConfigError).
    The ``tls_*`` paths are relative to the file."""
    from articutool.datafile import read_document

    data = read_document(path, "link config", ConfigError)
    table = data.get("link") if isinstance(data, dict) and isinstance(data.get("link"),
                                                                       dict) else data
    if isinstance(table, dict):
        base = Path(path).resolve().parent
        for k in _PATHS:
            if isinstance(table.get(k), str):
                table[k] = str(base / table[k])
    return _from_mapping(data, str(path))


def add_config_args(p: argparse.ArgumentParser) -> None:
    """Add ``--link-config``, ``--listen``, ``--connect``, ``--mode`` … to a parser."""
    p.add_argument("--link-config", metavar="FILE", default=None,
                   help="link config TOML/JSON (default: loopback)")
    p.add_argument("--listen", action="append", metavar="ENDPOINT", default=None,
                   help="zenoh endpoint to listen on, e.g. tls/0.0.0.0:7447 (repeatable)")
    p.add_argument("--connect", action="append", metavar="ENDPOINT", default=None,
                   help="zenoh endpoint to connect to, e.g. tcp/192.168.1.20:7447 (repeatable)")
    p.add_argument("--zenoh-mode", choices=("peer", "client"), default=None,
                   help="zenoh session mode")
    p.add_argument("--domain-id", type=int, default=None, help="ROS domain id (default 0)")
    p.add_argument("--tool-timeout", type=float, default=None, metavar="S",
                   help="seconds of silence before the tool is reported dead")
    p.add_argument("--tool-id", default=None, metavar="NAME",
                   help="the tool's identity (default: the config's, else 'default')")


def config_from_args(args: argparse.Namespace) -> LinkConfig:
    """A LinkConfig from ``--link-config`` plus the flags overriding it."""
    cfg = load_config(args.link_config) if args.link_config else LinkConfig()
    changes: dict[str, Any] = {}
    if args.listen:
        changes["listen"] = tuple(args.listen)
    if args.connect:
        changes["connect"] = tuple(args.connect)
    if args.zenoh_mode:
        changes["mode"] = args.zenoh_mode
    if args.domain_id is not None:
        changes["domain_id"] = args.domain_id
    if args.tool_timeout is not None:
        changes["tool_timeout"] = args.tool_timeout
    if getattr(args, "tool_id", None) is not None:
        changes["tool_id"] = args.tool_id
    return cfg.replace(**changes) if changes else cfg


# ------------------------------------------------------ the ROS 2 environment --
# rcl refuses a bad ``ROS_DOMAIN_ID`` with an exception from deep inside ``rclpy.init`` and an
# unknown ``RMW_IMPLEMENTATION`` by ending the whole process (exit code 102, no message the
# user can act on); ``articutool ros2`` checks both first. Unset or empty, each takes rcl's
# default.
def installed_rmw_implementations(prefixes: Iterable[str | Path] | None = None
                                  ) -> tuple[str, ...]:
    """The RMW implementations the ament index lists under ``prefixes`` (default: the
    ``AMENT_PREFIX_PATH`` entries and ``sys.prefix``), sorted; ``rmw_implementation`` (the
    loader, not a middleware) is left out."""
    if prefixes is None:
        prefixes = [*filter(None, os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)),
                    sys.prefix]
    found: set[str] = set()
    for prefix in prefixes:
        index = Path(prefix) / "share" / "ament_index" / "resource_index" / "rmw_typesupport"
        try:
            found.update(p.name for p in index.iterdir())
        except OSError:
            continue
    found.discard("rmw_implementation")
    return tuple(sorted(found))


def check_ros_environment(env: Mapping[str, str],
                          rmw_installed: Iterable[str] | None = None) -> None:
    """Raise ``ValueError`` naming the variable when ``ROS_DOMAIN_ID`` or
    ``RMW_IMPLEMENTATION`` in ``env`` would make rcl fail or end the process."""
    domain = env.get("ROS_DOMAIN_ID", "")
    if domain and not (domain.isascii() and domain.isdigit()
                       and int(domain) <= MAX_DOMAIN_ID):
        raise ValueError(f"ROS_DOMAIN_ID must be an integer in [0, {MAX_DOMAIN_ID}] (or unset "
                         f"for 0); got {domain!r}")
    rmw = env.get("RMW_IMPLEMENTATION", "")
    if rmw:
        known = tuple(rmw_installed) if rmw_installed is not None else \
            installed_rmw_implementations()
        if rmw not in known:
            raise ValueError(f"RMW_IMPLEMENTATION must name an installed middleware "
                             f"({', '.join(known) or 'none found'}) or be unset; got {rmw!r}")
