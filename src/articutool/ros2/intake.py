"""Services that take every waiting request when the executor calls them once.

rclpy's Python executors take one request per service per wait: each request pays a whole
wait-set rebuild (every entity of the node, Python context managers for each), which on a
loaded 2-core host held ``articutool ros2`` to about 250 requests/s, so a flood of 1 000
calls/s filled the service's DDS queue and DDS dropped the oldest requests unanswered. A
service made by :func:`create_draining_service` answers the request it is called with and,
first, takes up to ``batch`` more from its queue in the same callback: a request answered at
once (a refusal, a bookkeeping answer) is answered there; one that waits for the tool is
handed to the executor as a task that sends its response when it is done. The requests are
answered in the order they arrived; a stop never waits behind a batch (stops have their own
service on their own executor thread, :mod:`articutool.ros2.lanes`).

``start(request, response)`` returns the response, or a coroutine (not yet started) that
returns it.
"""

from __future__ import annotations

import inspect
import logging
from collections.abc import Callable
from typing import Any

__all__ = ["create_draining_service"]

_log = logging.getLogger(__name__)


def create_draining_service(node: Any, srv_type: Any, name: str,
                            start: Callable[[Any, Any], Any], *, qos_profile: Any,
                            callback_group: Any, batch: int = 64) -> Any:
    """An rclpy service on ``node`` answered by ``start`` that drains its queue (module doc)."""
    box: list[Any] = []

    async def finish(srv: Any, header: Any, pending: Any) -> None:
        try:
            srv.send_response(await pending, header)
        except Exception as err:  # the node is being destroyed, or the client is gone
            _log.debug("response not sent: %s", err)

    def drain(srv: Any) -> None:
        executor = node.executor
        if executor is None:  # not spun (a request taken now would have no one to finish it)
            return
        for _ in range(batch):
            try:
                with srv.handle:
                    request, header = srv.handle.service_take_request(srv_type.Request)
            except Exception as err:  # destroyed meanwhile
                _log.debug("no request taken: %s", err)
                return
            if header is None:
                return
            out = start(request, srv_type.Response())
            if inspect.iscoroutine(out):
                executor.create_task(finish, srv, header, out)
            else:
                srv.send_response(out, header)

    async def callback(request: Any, response: Any) -> Any:
        out = start(request, response)  # the oldest request: started first
        drain(box[0])
        if inspect.iscoroutine(out):
            out = await out
        return out

    box.append(node.create_service(srv_type, name, callback, qos_profile=qos_profile,
                                   callback_group=callback_group))
    return box[0]
