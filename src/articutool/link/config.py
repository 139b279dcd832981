"""Link configuration: Zenoh endpoints, timeouts and the link-loss policy.

Loopback by default: the tool listens on ``tcp/127.0.0.1:7447`` and the client connects there,
with multicast scouting off so nothing leaves the host. For a Pi on the network, have the tool
listen on ``tcp/0.0.0.0:7447`` and the PC connect to ``tcp/<pi address>:7447``. A config file
is TOML or JSON with the field names below at top level (or under a ``[link]`` table)::

    mode = "peer"                      # or "client" (through a zenoh router)
    listen = ["tcp/0.0.0.0:7447"]
    connect = []
    link_loss_policy = "continue"      # what a running primitive does when the PC goes silent
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

__all__ = ["DEFAULT_ENDPOINT", "ConfigError", "LinkConfig", "add_config_args",
           "check_endpoint", "config_from_args", "load_config"]

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"


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
                or not 0 <= self.domain_id <= 232:
            raise ConfigError(f"domain_id must be an integer in [0, 232]; got {self.domain_id!r}")
        for name in ("heartbeat_period", "tool_timeout", "client_timeout", "call_timeout",
                     "reconnect_period"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                    or v <= 0:
                raise ConfigError(f"{name} must be a positive number of seconds; got {v!r}")
        if self.heartbeat_period >= min(self.tool_timeout, self.client_timeout):
            raise ConfigError("heartbeat_period must be shorter than tool_timeout and "
                              f"client_timeout; got {self.heartbeat_period}")
        if self.publish_rate_hz is not None and not (
                isinstance(self.publish_rate_hz, int | float) and 0 < self.publish_rate_hz <= 1000):
            raise ConfigError(f"publish_rate_hz must be in (0, 1000]; got {self.publish_rate_hz!r}")
        if not isinstance(self.namespace, str) or not self.namespace.startswith("/"):
            raise ConfigError(f"namespace must start with '/'; got {self.namespace!r}")

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


def load_config(path: str | Path) -> LinkConfig:
    """Read a link config file: JSON (``.json``) or TOML (anything else), with the common
    reader of the spec and task files (unreadable, non-UTF-8 or malformed: ConfigError)."""
    from articutool.datafile import read_document

    return _from_mapping(read_document(path, "link config", ConfigError), str(path))


def add_config_args(p: argparse.ArgumentParser) -> None:
    """Add ``--link-config``, ``--listen``, ``--connect``, ``--mode`` … to a parser."""
    p.add_argument("--link-config", metavar="FILE", default=None,
                   help="link config TOML/JSON (default: loopback)")
    p.add_argument("--listen", action="append", metavar="ENDPOINT", default=None,
                   help="zenoh endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable)")
    p.add_argument("--connect", action="append", metavar="ENDPOINT", default=None,
                   help="zenoh endpoint to connect to, e.g. tcp/192.168.1.20:7447 (repeatable)")
    p.add_argument("--zenoh-mode", choices=("peer", "client"), default=None,
                   help="zenoh session mode")
    p.add_argument("--domain-id", type=int, default=None, help="ROS domain id (default 0)")
    p.add_argument("--tool-timeout", type=float, default=None, metavar="S",
                   help="seconds of silence before the tool is reported dead")


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
    return cfg.replace(**changes) if changes else cfg
