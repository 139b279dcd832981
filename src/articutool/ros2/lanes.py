"""Where ``articutool ros2`` runs the link calls its ROS 2 callbacks make: never on an executor
thread, and stops never behind anything else.

rclpy calls a service or action callback on an executor thread; a callback that waits for the
tool (a link round trip, up to the call timeout) holds that thread, and under a flood of calls
every thread waits while new requests, stops among them, pile up in DDS queues and are
dropped. So callbacks are coroutines that hand the call to a lane and ``await`` its result:

- :class:`WorkLane`: a few threads and a bounded queue for ordinary requests; when it is
  full a request is answered at once ("busy"), so a flood is refused, not queued;
- :class:`StopLane`: one thread that only stops the wrist; stop requests that arrive while
  one waits to run share it (every stop is the same stop), so no number of them can fill it.

An awaited result is an rclpy ``Future``; setting it from a lane thread does not wake the
executor, so each waiter names a guard condition of its node that the lane triggers.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable
from typing import Any

__all__ = ["StopLane", "WorkLane"]

_log = logging.getLogger(__name__)


def _settle(future: Any, wake: Any, fn: Callable[[], Any]) -> None:
    try:
        future.set_result(fn())
    except BaseException as err:  # the awaiting coroutine re-raises it
        future.set_exception(err)
    try:
        wake.trigger()
    except Exception as err:  # the node is being destroyed
        _log.debug("wake not delivered: %s", err)


class WorkLane:
    """``threads`` threads running submitted calls, at most ``capacity`` waiting."""

    def __init__(self, name: str, threads: int = 2, capacity: int = 16) -> None:
        self._q: queue.Queue[tuple[Any, Any, Callable[[], Any]] | None] = queue.Queue(capacity)
        self._threads = [threading.Thread(target=self._run, name=f"{name}-{i}", daemon=True)
                         for i in range(threads)]
        for t in self._threads:
            t.start()

    def submit(self, fn: Callable[[], Any], wake: Any) -> Any | None:
        """An rclpy Future for ``fn()``'s result, or None when the lane is full."""
        from rclpy.task import Future
        future: Future = Future()
        try:
            self._q.put_nowait((future, wake, fn))
        except queue.Full:
            return None
        return future

    def _run(self) -> None:
        while True:
            item = self._q.get()
            if item is None:
                return
            _settle(*item)

    def close(self) -> None:
        """Let the threads end once the waiting calls are done."""
        for _ in self._threads:
            self._q.put(None)


class StopLane:
    """One thread running ``stop()``; waiters that arrive before a stop starts share it."""

    def __init__(self, stop: Callable[[], Any]) -> None:
        self._stop = stop
        self._cv = threading.Condition()
        self._waiters: list[tuple[Any, Any]] = []
        self._closed = False
        self.runs = 0
        self._thread = threading.Thread(target=self._run, name="ros2-stop", daemon=True)
        self._thread.start()

    def submit(self, wake: Any) -> Any:
        """An rclpy Future for the result of the next stop to start (never None)."""
        from rclpy.task import Future
        future: Future = Future()
        with self._cv:
            self._waiters.append((future, wake))
            self._cv.notify()
        return future

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._waiters and not self._closed:
                    self._cv.wait()
                if self._closed and not self._waiters:
                    return
                waiters, self._waiters = self._waiters, []
            self.runs += 1
            try:
                result: Any = self._stop()
                error = None
            except BaseException as err:
                result, error = None, err
            for future, wake in waiters:
                _settle(future, wake, (lambda e=error, r=result: _raise_or(e, r)))

    def close(self) -> None:
        """End the thread once the waiting stops have run."""
        with self._cv:
            self._closed = True
            self._cv.notify()


def _raise_or(error: BaseException | None, result: Any) -> Any:
    if error is not None:
        raise error
    return result
