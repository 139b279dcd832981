"""The ROS 2 environment variables rcl reads at start, checked before it reads them.

rcl refuses a bad ``ROS_DOMAIN_ID`` with an exception from deep inside ``rclpy.init`` and an
unknown ``RMW_IMPLEMENTATION`` by ending the whole process (exit code 102, no message the
user can act on). :func:`check_ros_environment` says instead, naming the variable and what
it may be: ``ROS_DOMAIN_ID`` an integer in [0, 232] (the range DDS can map to UDP ports),
``RMW_IMPLEMENTATION`` one of the middleware implementations installed (the ament index's
``rmw_typesupport`` resources under ``AMENT_PREFIX_PATH`` and this environment's prefix).
Unset or empty, each takes rcl's default.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path

__all__ = ["MAX_DOMAIN_ID", "check_ros_environment", "installed_rmw_implementations"]

MAX_DOMAIN_ID = 232


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
