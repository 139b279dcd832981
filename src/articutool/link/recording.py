"""MCAP recordings of ROS 2 CDR messages (``--record FILE.mcap``), and a link that records.

:class:`McapRecorder` writes messages as ROS 2 CDR into an MCAP file with the ``ros2`` profile
and every schema embedded as ``ros2msg`` text (the concatenated definition rosbag2 writes), so
Foxglove, ``ros2 bag`` (rosbag2_storage_mcap) and ``mcap_ros2`` read it without a ROS install.
:class:`RecordingTransport` wraps a link :class:`~articutool.link.transport.Transport` and records
every payload it carries, as the bytes that went over the link: topics under their ROS 2
names, service requests and replies under ``<service>/request`` and ``<service>/response``
(``pkg/srv/Name_Request`` / ``_Response``; the action's sub-services likewise).

Never overwrites: the file is created exclusively (:class:`RecordingError` if it exists).
Messages are written in zstd chunks of ``chunk_bytes`` (default 64 KiB, about a second of the
tool's telemetry), each handed to the OS as it completes (the file is flushed after every
message; messages themselves wait in the chunk being built), so a recording cut
by a crash or kill is readable with a streaming reader (``mcap.reader.NonSeekingReader``) up
to its last complete chunk; a normal close (also on Ctrl-C) writes the summary and index.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from articutool.link import cdr
from articutool.link.transport import Endpoint, Handle, Transport

__all__ = ["McapRecorder", "RecordingError", "RecordingTransport", "ros2msg_definition",
           "schema_name"]

_SEP = "=" * 80


class RecordingError(ValueError):
    """The recording file cannot be created (it exists, or its folder does not)."""


def _field_type(node: tuple[Any, Any]) -> tuple[str, list[str]]:
    """A rosbags field type as .msg text, and the message types it refers to."""
    kind, desc = int(node[0]), node[1]
    if kind == 1:  # BASE: (name, string bound)
        name, bound = desc
        return (f"{name}<={bound}" if bound else name), []
    if kind == 2:  # NAME: pkg/kind/Name, written pkg/Name as in .msg files
        return _nested_name(desc), [desc]
    sub, n = desc  # 3 ARRAY (fixed n) or 4 SEQUENCE (bound n, 0 = unbounded)
    text, deps = _field_type(sub)
    if kind == 3:
        return f"{text}[{n}]", deps
    return (f"{text}[<={n}]" if n else f"{text}[]"), deps


_SUFFIXES = ("_Request", "_Response", "_Goal", "_Result", "_Feedback")


def schema_name(typename: str) -> str:
    """The MCAP schema name of ``pkg/kind/Name``: itself when the ``.msg`` grammar
    (rosidl_adapter: ``[A-Z][A-Za-z0-9]*`` plus one generated suffix such as ``_Request``)
    accepts ``Name``, which covers every type but the action protocol's own
    (``X_SendGoal_Request``, ``X_GetResult_Response``, ``X_FeedbackMessage``): those keep
    their suffix and drop the other underscores (``XSendGoal_Request``), since readers such
    as ``mcap_ros2`` reject them otherwise. CDR carries no type names: the bytes decode the
    same."""
    pkg, kind, name = typename.split("/")
    suffix = next((x for x in _SUFFIXES if name.endswith(x)), "")
    stem = name[:len(name) - len(suffix)]
    if "_" in stem:
        name = stem.replace("_", "") + suffix
    return f"{pkg}/{kind}/{name}"


def _nested_name(typename: str) -> str:
    """A used type's name in ``ros2msg`` text: ``pkg/Name`` (see :func:`schema_name`)."""
    pkg, _, name = schema_name(typename).split("/")
    return f"{pkg}/{name}"


def ros2msg_definition(typename: str) -> str:
    """The ``ros2msg`` schema of ``typename`` (any type in :func:`messages.typestore`, also
    service and action parts): its fields, then each type it uses after a ``MSG: pkg/Name``
    header, separated by ``=`` lines, as rosbag2 writes it into MCAP."""
    ts = cdr.typestore()
    parts, seen, todo = [], {typename}, [typename]
    while todo:
        t = todo.pop(0)
        consts, fields = ts.fielddefs[t]
        lines = [f"{ctype} {cname}={value}" for cname, ctype, value in consts]
        for fname, node in fields:
            text, deps = _field_type(node)
            lines.append(f"{text} {fname}")
            for d in deps:
                if d not in seen:
                    seen.add(d)
                    todo.append(d)
        body = "\n".join(lines) + "\n"
        if t != typename:
            body = f"{_SEP}\nMSG: {_nested_name(t)}\n{body}"
        parts.append(body)
    return "".join(parts)


class McapRecorder:
    """Write ROS 2 CDR messages to a new MCAP file; thread-safe; ``close()`` finishes it."""

    def __init__(self, path: str | Path, chunk_bytes: int = 64 * 1024) -> None:
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        try:
            self._file = open(self.path, "xb")  # noqa: SIM115 (closed in close())
        except FileExistsError:
            raise RecordingError(f"{self.path} exists; refusing to overwrite it") from None
        except OSError as err:
            raise RecordingError(f"cannot create {self.path}: {err.strerror}") from None
        self._writer = Writer(self._file, chunk_size=chunk_bytes,
                              compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="articutool")
        self._lock = threading.Lock()
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str]] = {}
        self._seq: dict[int, int] = {}
        self.count = 0
        self.closed = False

    def _channel(self, topic: str, typename: str) -> int:
        ch = self._channels.get(topic)
        if ch is not None:
            if ch[1] != typename:
                raise ValueError(f"{topic} carries {ch[1]}, not {typename}")
            return ch[0]
        sid = self._schemas.get(typename)
        if sid is None:
            sid = self._writer.register_schema(
                name=schema_name(typename), encoding="ros2msg",
                data=ros2msg_definition(typename).encode())
            self._schemas[typename] = sid
        cid = self._writer.register_channel(topic=topic, message_encoding="cdr", schema_id=sid)
        self._channels[topic] = (cid, typename)
        return cid

    def write(self, topic: str, typename: str, data: bytes, t: float | None = None) -> None:
        """Record CDR bytes ``data`` of ``typename`` on ``topic`` at ``t`` (s; default now).
        Silently ignored after ``close()`` (late transport callbacks)."""
        ns = time.time_ns() if t is None else round(t * 1e9)
        with self._lock:
            if self.closed:
                return
            cid = self._channel(topic, typename)
            seq = self._seq.get(cid, 0)
            self._seq[cid] = seq + 1
            self._writer.add_message(channel_id=cid, log_time=ns, publish_time=ns,
                                     data=bytes(data), sequence=seq)
            self._file.flush()  # a chunk the writer just completed goes to the OS now
            self.count += 1

    def write_msg(self, topic: str, typename: str, message: Any, t: float | None = None) -> None:
        """Record a message object (encoded with :func:`messages.encode`)."""
        self.write(topic, typename, cdr.encode(message, typename), t)

    def metadata(self, name: str, values: dict[str, str]) -> None:
        """An MCAP metadata record (e.g. the run's food, system and seed)."""
        with self._lock:
            if not self.closed:
                self._writer.add_metadata(name=name, data={k: str(v) for k, v in
                                                           values.items()})
                self._file.flush()

    def close(self) -> None:
        """Write the summary and close the file (idempotent)."""
        with self._lock:
            if self.closed:
                return
            self.closed = True
            try:
                self._writer.finish()
            finally:
                self._file.close()

    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class RecordingTransport(Transport):
    """A link transport that records every payload it carries (see the module docstring).

    Everything else (attributes such as ``cfg`` and ``identity``, the drop hook) is the
    wrapped transport's. A payload is recorded before it is handed on, as it was carried,
    whether or not the receiver then accepts it.
    """

    def __init__(self, inner: Transport, recorder: McapRecorder) -> None:
        self.inner = inner
        self.recorder = recorder

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    @property  # type: ignore[override]
    def on_drop(self) -> Callable[[str, str], None] | None:
        return self.inner.on_drop

    @on_drop.setter
    def on_drop(self, hook: Callable[[str, str], None] | None) -> None:
        self.inner.on_drop = hook

    def _rec(self, topic: str, typename: str, data: bytes) -> None:
        try:
            self.recorder.write(topic, typename, data)
        except Exception:  # a full disk must not take the link down
            import logging
            logging.getLogger(__name__).exception("recording %s failed", topic)

    def publish(self, ep: Endpoint, payload: bytes) -> None:
        self._rec(ep.name, ep.type, payload)
        self.inner.publish(ep, payload)

    def subscribe(self, ep: Endpoint, callback: Callable[..., None], with_sender: bool = False,
                  max_bytes: int | None = None) -> Handle:
        def on_data(payload: bytes, *sender: Any) -> None:
            self._rec(ep.name, ep.type, payload)
            callback(payload, *sender)
        return self.inner.subscribe(ep, on_data, with_sender, max_bytes)

    def serve(self, ep: Endpoint, handler: Callable[..., None], with_sender: bool = False,
              max_bytes: int | None = None) -> Handle:
        def on_request(request: bytes, respond: Callable[[bytes], None], *sender: Any) -> None:
            self._rec(f"{ep.name}/request", ep.request_type, request)

            def reply(data: bytes) -> None:
                self._rec(f"{ep.name}/response", ep.response_type, data)
                respond(data)
            handler(request, reply, *sender)
        return self.inner.serve(ep, on_request, with_sender, max_bytes)

    def call(self, ep: Endpoint, payload: bytes, timeout: float) -> bytes:
        self._rec(f"{ep.name}/request", ep.request_type, payload)
        reply = self.inner.call(ep, payload, timeout)
        self._rec(f"{ep.name}/response", ep.response_type, reply)
        return reply

    def close(self) -> None:
        self.inner.close()
