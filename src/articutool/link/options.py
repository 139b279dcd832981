"""The link's command-line options (``--link-config``, ``--listen``, ``--connect`` …) that
``articutool tool``, ``client`` and ``ros2`` share. Only argparse: adding them imports no
model, so a command's ``--help`` and a mistyped option stay cheap; the options become a
:class:`articutool.link.config.LinkConfig` in :func:`articutool.link.config.config_from_args`.
"""

from __future__ import annotations

import argparse

from articutool.cli_support import MAX_WAIT_S, seconds

__all__ = ["add_config_args"]


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
    p.add_argument("--tool-timeout", type=seconds(MAX_WAIT_S), default=None, metavar="S",
                   help=f"seconds of silence before the tool is reported dead, in (0, "
                        f"{MAX_WAIT_S:g}]")
    p.add_argument("--tool-id", default=None, metavar="NAME",
                   help="the tool's identity (default: the config's, else 'default')")
