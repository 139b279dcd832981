"""What the servers of ``articutool ros2`` stand on: the rclpy node a server serves on
(:class:`Side`) and how a callback waits for the tool without holding an executor thread.

A callback that needs the tool hands the link call to a lane (:mod:`articutool.ros2.lanes`) or
a thread of its own and awaits an rclpy ``Future``; the lane or thread triggers the side's
guard condition (``wake``) when the result is set, since setting a future from another thread
does not wake the executor. Callback groups are reentrant: a coroutine callback awaiting a
lane holds a mutually exclusive group (the node's default) until it ends, which would
serialise every request and keep the wake-up guard condition out of the wait set.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from articutool.link.client import LinkError

__all__ = ["BUSY", "Side", "in_thread", "latest_wrist", "outcome", "submit"]

_log = logging.getLogger(__name__)

BUSY = "refused: busy (too many requests waiting for the tool); try again"


@dataclass(frozen=True)
class Side:
    """One rclpy node as its servers use it: the node, its reentrant callback group, the guard
    condition that wakes its executor, and the QoS of every request queue on it."""

    node: Any
    group: Any
    wake: Any
    qos: Any

    @classmethod
    def of(cls, node: Any, qos: Any) -> Side:
        """A reentrant callback group and a wake-up guard condition made on ``node``."""
        from rclpy.callback_groups import ReentrantCallbackGroup
        group = ReentrantCallbackGroup()
        wake = node.create_guard_condition(lambda: None, callback_group=group)
        return cls(node, group, wake, qos)


def submit(lane: Any, fn: Callable[[], Any], wake: Any, counters: dict[str, int]) -> Any:
    """``lane``'s Future for ``fn()``, or None (counted as ``busy``) when the lane is full."""
    future = lane.submit(fn, wake)
    if future is None:
        counters["busy"] += 1
    return future


async def outcome(future: Any, what: str) -> tuple[bool, str]:
    """(success, message) of a link call's Future; never raises into the executor."""
    if future is None:
        return False, BUSY
    try:
        ok, msg = await future
        return bool(ok), str(msg)
    except (ValueError, LinkError) as err:
        return False, str(err)
    except Exception as err:  # never into the executor
        _log.exception("%s failed", what)
        return False, f"internal error: {type(err).__name__}: {err}"


def in_thread(fn: Callable[[], Any], wake: Any, name: str) -> Any:
    """An rclpy Future for ``fn()`` run on a new daemon thread, ``wake`` triggered when set
    (a goal's run lasts as long as its motion, so it has a thread of its own)."""
    from rclpy.task import Future
    future: Future = Future()
    threading.Thread(target=lambda: (future.set_result(fn()), wake.trigger()), name=name,
                     daemon=True).start()
    return future


def latest_wrist(client: Any) -> tuple[float, float] | None:
    """The tool's last joint positions [pitch, roll] (None without a tool or telemetry)."""
    st = client.latest_state() if client is not None else None
    return None if st is None else (float(st.position[0]), float(st.position[1]))
