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
import math
import os
import re
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, ValidationError, ValidationInfo, field_validator, model_validator

from articutool.datafile import StrictModel, field_path

__all__ = ["DEFAULT_ENDPOINT", "MAX_DOMAIN_ID", "ConfigError", "LinkConfig", "check_endpoint",
           "check_ros_environment", "config_from_args",
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
_NAMESPACE = r"^/$|^(/[A-Za-z_][A-Za-z0-9_]*)+$"


# zenoh's own settings: '/'-separated names of letters, digits, '_' and '-' (e.g.
# "transport/unicast/max_links"); a value is JSON (tables and lists at most this deep).
_EXTRA_PATH = re.compile(r"^[A-Za-z0-9_-]+(/[A-Za-z0-9_-]+)*$")
_EXTRA_DEPTH = 8


def _check_extra(extra: object) -> dict:
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
    return extra


def _number(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else f"{x:g}"


def _within(default: Any, lo: float, hi: float, what: str, *, above: bool = False) -> Any:
    """A strict field (no bool, string or float-for-int slips through) in [lo, hi], or in
    (lo, hi] when ``above``; ``what`` says what it must be, ``{}`` standing for the range (the
    refusal quotes it)."""
    interval = f"{'(' if above else '['}{_number(lo)}, {_number(hi)}]"
    low = {"gt": lo} if above else {"ge": lo}
    return Field(default, strict=True, le=hi, description=what.format(interval), **low)


def _seconds(default: float, most: float) -> Any:
    """A period in (0, ``most``] s: beyond ``most`` a value is a unit slip (ms written as s)
    or a typo, and 1e308 s overflowed zenoh's retry period in milliseconds."""
    return _within(default, 0, most, "a number of seconds in {}", above=True)


def _given(default: Any, allowed: str) -> Any:
    """A strict field whose refusal says it must be ``allowed``."""
    return Field(default, strict=True, description=allowed)


_ENDPOINTS = f"a list of zenoh endpoints like '{DEFAULT_ENDPOINT}'"
_NAMES = "a list of device names"
_NAME = "a device name"  # refused by check_name, which names the form
_PAIRED_FILE = "a readable file (from articutool pair)"
_TLS = ("tls_root_ca", "tls_certificate", "tls_private_key")


class LinkConfig(StrictModel):
    """Everything the tool server and the PC client need to find each other.

    ``listen``/``connect`` left as None take the role's loopback default (tool listens on
    :data:`DEFAULT_ENDPOINT`, client connects to it). Each field's description says what it
    must be; an invalid value raises :class:`ConfigError` naming the field and that.
    """

    mode: Literal["peer", "client"] = Field("peer", description="'peer' or 'client'")
    listen: tuple[str, ...] | None = Field(None, description=_ENDPOINTS)
    connect: tuple[str, ...] | None = Field(None, description=_ENDPOINTS)
    multicast_scouting: bool = _given(False, "true or false")
    domain_id: int = _within(0, 0, MAX_DOMAIN_ID, "an integer in {}")
    namespace: str = Field("/articutool", strict=True, pattern=_NAMESPACE,
                           description=NAMESPACE_FORM)
    type_hash_in_keys: bool = _given(True, "true or false")
    heartbeat_period: float = _seconds(0.1, 10.0)  # both directions
    # silence after which the client reports the tool dead
    tool_timeout: float = _seconds(1.0, 3600.0)
    # silence after which the tool applies link_loss_policy
    client_timeout: float = _seconds(2.0, 3600.0)
    link_loss_policy: Literal["continue", "cancel"] = Field(
        "continue", description="'continue' or 'cancel'")
    call_timeout: float = _seconds(2.0, 3600.0)  # per service call
    # None: the spec's wrist loop rate
    publish_rate_hz: float | None = _within(None, 0, 1000, "a rate in {} Hz", above=True)
    reconnect_period: float = _seconds(0.2, 60.0)  # between Zenoh connection retries
    extra: dict[str, Any] = Field(default_factory=dict,  # raw zenoh json5 overrides
                                  description="a table of zenoh settings")
    # the tool's identity (key expressions, telemetry)
    tool_id: str = Field("default", description=_NAME)
    # this device; None: the tool_id (tool), a random name (client)
    identity: str | None = Field(None, description=_NAME)
    tls_root_ca: str | None = _given(None, _PAIRED_FILE)  # pairing CA certificate (PEM)
    tls_certificate: str | None = _given(None, _PAIRED_FILE)  # this device's certificate (PEM)
    tls_private_key: str | None = _given(None, _PAIRED_FILE)  # this device's key (PEM, 0600)
    # tool: refuse unsigned commands (None: when paired)
    require_paired: bool | None = _given(None, "true or false")
    # tool: paired identities allowed (None: any of the CA)
    peers: tuple[str, ...] | None = Field(None, description=_NAMES)
    # s: a signed message's timestamp may differ this much
    auth_window: float = _within(30.0, 0, 3600, "in {} seconds", above=True)
    # a JointTrajectory larger than this is dropped
    max_trajectory_bytes: int = _within(1 << 20, 64, 1 << 30, "an integer in {}")
    # a service request or heartbeat larger than this is dropped
    max_request_bytes: int = _within(4096, 64, 1 << 20, "an integer in {}")
    # commands waiting for the loop; excess ones are refused and counted
    inbox_size: int = _within(16, 1, 4096, "an integer in {}")
    # tool: messages/s per sender and endpoint; stops are exempt
    max_rate_hz: float = _within(200.0, 1, 100_000, "in {} messages/s")
    # tool: JSON lines of lease transitions (take-overs…) appended
    audit_log: str | None = _given(None, "a file path")

    def __init__(self, **values: Any) -> None:
        try:
            super().__init__(**values)
        except ValidationError as err:
            raise ConfigError("; ".join(_problems(err))) from None

    @property
    def paired(self) -> bool:
        """Whether this device has pairing material (mutual TLS and signatures)."""
        return self.tls_root_ca is not None

    @property
    def requires_pairing(self) -> bool:
        """Whether the tool refuses commands without a paired device's signature."""
        return self.paired if self.require_paired is None else bool(self.require_paired)

    # A list's items are checked here, so only a list or tuple passes (not a string or set).
    @field_validator("listen", "connect", mode="before")
    @classmethod
    def _endpoints(cls, v: object, info: ValidationInfo) -> object:
        if v is None:
            return v
        if not isinstance(v, list | tuple):
            raise ValueError(f"{info.field_name} must be {_ENDPOINTS}; got {v!r}")
        return tuple(check_endpoint(e, f"{info.field_name}[{i}]") for i, e in enumerate(v))

    @field_validator("peers", mode="before")
    @classmethod
    def _peer_names(cls, v: object) -> object:
        from articutool.link.pairing import check_name

        if v is None:
            return v
        if not isinstance(v, list | tuple):
            raise ValueError(f"peers must be {_NAMES}; got {v!r}")
        return tuple(check_name(p, f"peers[{i}]") for i, p in enumerate(v))

    @field_validator("tool_id", "identity", mode="before")
    @classmethod
    def _name(cls, v: object, info: ValidationInfo) -> object:
        from articutool.link.pairing import check_name

        if v is None and info.field_name == "identity":
            return v
        return check_name(v, str(info.field_name))

    @field_validator("extra", mode="before")
    @classmethod
    def _zenoh_settings(cls, v: object) -> object:
        return _check_extra(v)

    @field_validator(*_TLS)
    @classmethod
    def _readable(cls, v: str | None, info: ValidationInfo) -> str | None:
        if v is not None and not Path(v).is_file():
            raise ValueError(f"{info.field_name} must be {_PAIRED_FILE}; got {v!r}")
        return v

    @model_validator(mode="after")
    def _consistent(self) -> LinkConfig:
        if self.heartbeat_period >= min(self.tool_timeout, self.client_timeout):
            raise ValueError("heartbeat_period must be shorter than tool_timeout and "
                             f"client_timeout; got {self.heartbeat_period}")
        given = [n for n in _TLS if getattr(self, n) is not None]
        if given and len(given) != len(_TLS):
            missing = sorted(set(_TLS) - set(given))
            raise ValueError(f"{missing} must be set too: pairing needs tls_root_ca, "
                             "tls_certificate and tls_private_key (from articutool pair)")
        if self.requires_pairing and not self.paired:
            raise ValueError("require_paired = true needs tls_root_ca, tls_certificate and "
                             "tls_private_key (from articutool pair)")
        return self

    def endpoints(self, role: Literal["tool", "client"]) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(listen, connect) for ``role``, with the loopback defaults filled in."""
        listen = self.listen if self.listen is not None else (
            (DEFAULT_ENDPOINT,) if role == "tool" else ())
        connect = self.connect if self.connect is not None else (
            (DEFAULT_ENDPOINT,) if role == "client" else ())
        return listen, connect

    def replace(self, **changes: Any) -> LinkConfig:
        """A copy with ``changes`` applied (validated)."""
        return LinkConfig(**{**dict(self), **changes})


def _problems(err: ValidationError) -> list[str]:
    """One sentence per problem, naming the field and what it must be (the field's
    description) or, from the checks above, their own sentence."""
    fields = LinkConfig.model_fields
    unknown = [str(e["loc"][0]) for e in err.errors() if e["type"] == "extra_forbidden"]
    out = [f"unknown setting(s) {unknown}; allowed: {sorted(fields)}"] if unknown else []
    for e in err.errors():
        if e["type"] == "extra_forbidden":
            continue
        if e["type"] == "value_error":
            out.append(e["msg"].removeprefix("Value error, "))
        else:
            allowed = fields[str(e["loc"][0])].description
            out.append(f"{field_path(e['loc'])} must be {allowed}; got {e['input']!r}")
    return out


def _from_mapping(data: Any, where: str) -> LinkConfig:
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a table of link settings")
    if "link" in data and isinstance(data["link"], dict):
        data = data["link"]
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
