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
by a crash or kill keeps every complete chunk; a normal close (also on Ctrl-C) writes the
summary and index. Every chunk, the data section and the summary carry CRC-32s.

:func:`read_recording` reads a recording back the one way that works for both: in file
order, streaming, every CRC checked. A reader that orders by log time first
(``mcap``'s ``iter_messages`` default) buffers to the end and so yields nothing from a cut
file; one that skips the CRCs accepts flipped bits in a chunk's bytes. A corrupt file
(a CRC mismatch, a record that does not parse, a chunk that does not decompress) is refused
naming where; a cut one (it ends before the footer, without MCAP's closing magic) is read up
to its last complete chunk and said to be cut.
"""

from __future__ import annotations

import os
import stat
import threading
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from articutool.link import cdr
from articutool.link.transport import Endpoint, Handle, Transport

__all__ = ["McapRecorder", "RecordedMessage", "Recording", "RecordingError",
           "RecordingTransport", "read_recording", "ros2msg_definition", "schema_name"]

_SEP = "=" * 80


class RecordingError(ValueError):
    """The recording file cannot be created (it exists, or its folder does not), or read
    (missing, not a regular file, corrupt)."""


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
                              compression=CompressionType.ZSTD, enable_data_crcs=True)
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


_MAGIC = b"\x89MCAP0\r\n"
_FOOTER_BYTES = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, crc
_DATA_END_BYTES = 1 + 8 + 4  # opcode 0x0F, length 4, data section CRC
_DATA_END_HEAD = b"\x0f" + (4).to_bytes(8, "little")
# The largest chunk read back (its uncompressed size is a field of the file: a flipped bit
# must not make the reader allocate gigabytes); ours are 64 KiB.
_MAX_CHUNK_BYTES = 256 << 20


@dataclass(frozen=True)
class RecordedMessage:
    """One recorded message: its topic, schema name, log time (ns) and CDR bytes."""

    topic: str
    schema: str
    log_time_ns: int
    data: bytes


@dataclass
class Recording:
    """What :func:`read_recording` read: the messages in file order, the metadata, and
    whether the file was complete (``cut`` says how far a cut one was read)."""

    messages: list[RecordedMessage] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    complete: bool = False
    cut: str = ""


def read_recording(path: str | Path, topics: Callable[[str], bool] | None = None
                   ) -> Recording:
    """Read the MCAP recording ``path`` in file order (the messages on the topics that
    ``topics`` accepts, default all), checking every CRC the file carries: the chunks', the
    data section's and the summary's. A recording cut before its footer (a crash, ``kill
    -9``) is read up to its last complete chunk, ``complete`` False and ``cut`` saying so;
    anything else that does not read (not a regular file, another format, a CRC mismatch, a
    record or chunk that does not parse) raises :class:`RecordingError` naming the file and
    the byte where it failed."""
    from mcap.exceptions import EndOfFile
    from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    from articutool.datafile import file_kind

    p = Path(path)
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as err:
        raise RecordingError(f"recording {p}: cannot read it: {err.strerror}") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise RecordingError(f"recording {p} is {file_kind(st.st_mode)}; a recording is a "
                             "regular .mcap file")
    with os.fdopen(fd, "rb") as f:
        size = st.st_size
        f.seek(max(0, size - len(_MAGIC)))
        closed = f.read(len(_MAGIC)) == _MAGIC  # a normal close wrote the closing magic
        f.seek(0)
        out = Recording()
        schemas: dict[int, str] = {}
        channels: dict[int, tuple[str, str]] = {}
        footer = None
        reader = StreamReader(f, validate_crcs=True, emit_chunks=True,
                              record_size_limit=max(size, 1))

        def take(rec: Any) -> None:
            if isinstance(rec, Schema):
                schemas[rec.id] = rec.name
            elif isinstance(rec, Channel):
                channels[rec.id] = (rec.topic, schemas.get(rec.schema_id, ""))
            elif isinstance(rec, Message):
                if rec.channel_id not in channels:
                    raise ValueError(f"a message on channel {rec.channel_id}, never declared")
                topic, schema = channels[rec.channel_id]
                if topics is None or topics(topic):
                    out.messages.append(RecordedMessage(topic, schema, rec.log_time,
                                                        bytes(rec.data)))

        try:
            for rec in reader.records:
                if isinstance(rec, Chunk):
                    if rec.uncompressed_size > _MAX_CHUNK_BYTES:
                        raise ValueError(f"a chunk claims {rec.uncompressed_size} bytes")
                    for inner in breakup_chunk(rec, validate_crc=True):
                        take(inner)
                elif isinstance(rec, Metadata):
                    out.metadata[rec.name] = dict(rec.metadata)
                elif isinstance(rec, Footer):
                    footer = rec
                elif not isinstance(rec, DataEnd):
                    take(rec)
        except EndOfFile:
            if closed:  # a finished file that ends early inside: a length field is wrong
                raise RecordingError(f"recording {p} is not a readable MCAP file: corrupt, a "
                                     f"record runs past its end (near byte {f.tell()})"
                                     ) from None
            out.cut = (f"recording {p} was cut (no footer: the recorder was killed or crashed)"
                       f"; read the {len(out.messages)} message(s) of its complete chunks in "
                       "file order")
            return out
        except Exception as err:  # any failure to parse these bytes is corruption
            raise RecordingError(f"recording {p} is not a readable MCAP file: corrupt near "
                                 f"byte {f.tell()} ({type(err).__name__}: {err})") from None
        if footer is None:
            raise RecordingError(f"recording {p} is not a readable MCAP file: no footer")
        # The records no CRC covers: the data section's end (whose CRC a flipped opcode or
        # length would skip) must be where and what it is; the summary and footer must match
        # the footer's CRC.
        start = footer.summary_start or size - len(_MAGIC) - _FOOTER_BYTES
        f.seek(start - _DATA_END_BYTES)
        if f.read(_DATA_END_BYTES)[:9] != _DATA_END_HEAD:
            raise RecordingError(f"recording {p} is not a readable MCAP file: corrupt, its "
                                 f"data section does not end with a DataEnd record at byte "
                                 f"{start - _DATA_END_BYTES}")
        if footer.summary_crc != 0:
            end = size - len(_MAGIC) - 4
            if zlib.crc32(f.read(end - start)) != footer.summary_crc:
                raise RecordingError(f"recording {p} is not a readable MCAP file: corrupt, its "
                                     f"summary (bytes {start}-{end}) does not match its CRC")
    out.complete = True
    return out


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
