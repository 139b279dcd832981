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
file; one that skips the CRCs accepts flipped bits in a chunk's bytes, and one that reads
only the records accepts a changed length that skips a chunk. So the whole file is checked:
the magic at both ends, every record's length, the chunks' and the data section's CRCs
(``mcap``'s stream reader), one DataEnd where the footer puts the summary, the summary and
its offsets as the footer names them, the summary read from the footer by ``mcap``'s seeking
reader matching the chunks, message indexes, schemas, channels and counts read, and the
summary CRC. A corrupt file is refused naming what is wrong and where; a cut one (it ends
before the footer, without MCAP's closing magic) is read up to its last complete chunk and
said to be cut.
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
    from mcap.records import (
        Attachment,
        Channel,
        Chunk,
        DataEnd,
        Footer,
        Message,
        MessageIndex,
        Metadata,
        Schema,
        SummaryOffset,
    )
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
        layout: list[tuple[Any, int, int]] = []  # every record: (what, start, end)
        kept = (DataEnd, Footer, MessageIndex, SummaryOffset)  # small: kept whole
        counted = _Counted()

        def take(rec: Any) -> None:
            if isinstance(rec, Schema):
                schemas[rec.id] = rec.name
                counted.declared(rec)
            elif isinstance(rec, Channel):
                channels[rec.id] = (rec.topic, schemas.get(rec.schema_id, ""))
                counted.declared(rec)
            elif isinstance(rec, Message):
                if rec.channel_id not in channels:
                    raise ValueError(f"a message on channel {rec.channel_id}, never declared")
                counted.message(rec)
                topic, schema = channels[rec.channel_id]
                if topics is None or topics(topic):
                    out.messages.append(RecordedMessage(topic, schema, rec.log_time,
                                                        bytes(rec.data)))

        try:
            for rec in reader.records:
                start = layout[-1][2] if layout else len(_MAGIC)
                layout.append((rec if isinstance(rec, kept) else type(rec), start, f.tell()))
                if isinstance(rec, Chunk):
                    counted.chunks.append((rec.message_start_time, rec.message_end_time,
                                           rec.compression, len(rec.data),
                                           rec.uncompressed_size))
                    if rec.uncompressed_size > _MAX_CHUNK_BYTES:
                        raise ValueError(f"a chunk claims {rec.uncompressed_size} bytes")
                    for inner in breakup_chunk(rec, validate_crc=True):
                        take(inner)
                elif isinstance(rec, Metadata):
                    out.metadata[rec.name] = dict(rec.metadata)
                    counted.metadata += 1
                elif isinstance(rec, DataEnd):
                    counted.ended = True
                elif isinstance(rec, Attachment):
                    counted.attachments += 1
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
        try:
            _check_whole(f, size, layout, footer, counted)
        except ValueError as err:
            raise RecordingError(f"recording {p} is not a readable MCAP file: corrupt, {err}"
                                 ) from None
        except Exception as err:  # the summary, read from the footer, does not parse
            raise RecordingError(f"recording {p} is not a readable MCAP file: corrupt, its "
                                 f"summary does not read from its footer ({type(err).__name__}"
                                 f": {err})") from None
    out.complete = True
    return out


@dataclass
class _Counted:
    """What the data section holds, counted as it is read: messages per channel, and the
    earliest and latest log time."""

    per_channel: dict[int, int] = field(default_factory=dict)
    first_ns: int | None = None
    last_ns: int | None = None
    schemas: dict[int, Any] = field(default_factory=dict)  # the data section's, whole
    channels: dict[int, Any] = field(default_factory=dict)
    # each chunk's start and end time, compression, compressed and uncompressed size
    chunks: list[tuple[int, int, str, int, int]] = field(default_factory=list)
    metadata: int = 0
    attachments: int = 0
    ended: bool = False  # past the data section (the summary repeats schemas and channels)

    def declared(self, rec: Any) -> None:
        if not self.ended:
            (self.schemas if hasattr(rec, "encoding") else self.channels)[rec.id] = rec

    def message(self, rec: Any) -> None:
        self.per_channel[rec.channel_id] = self.per_channel.get(rec.channel_id, 0) + 1
        t = int(rec.log_time)
        self.first_ns = t if self.first_ns is None else min(self.first_ns, t)
        self.last_ns = t if self.last_ns is None else max(self.last_ns, t)


def _check_whole(f: Any, size: int, layout: list[tuple[Any, int, int]], footer: Any,
                 counted: _Counted) -> None:
    """A whole recording's structure beyond what the records' own CRCs cover (``ValueError``
    saying what is wrong): the file ends at its closing magic; every record's length field
    is the length read; one DataEnd (whose CRC the
    stream reader checked) ends the data section where the footer's ``summary_start`` says the
    summary begins; the summary holds only summary records, the summary offsets start where
    the footer says and each names a run of records of its kind; the summary as ``mcap``'s
    seeking reader reads it from the footer (:meth:`mcap.reader.SeekingReader.get_summary`)
    indexes exactly the chunks read, with their message indexes, and counts the messages,
    channels and schemas read; and the summary and footer match the footer's CRC."""
    from mcap.opcode import Opcode
    from mcap.reader import SeekingReader
    from mcap.records import (
        AttachmentIndex,
        Channel,
        Chunk,
        ChunkIndex,
        DataEnd,
        Footer,
        MessageIndex,
        MetadataIndex,
        Schema,
        Statistics,
        SummaryOffset,
    )

    def kind(rec: Any) -> type:
        return rec if isinstance(rec, type) else type(rec)

    if f.tell() != size:
        raise ValueError(f"{size - f.tell()} bytes follow its closing magic")
    for rec, start, end in layout:  # a record read past or short of its length field
        f.seek(start + 1)
        length = int.from_bytes(f.read(8), "little")
        if start + 9 + length != end:
            raise ValueError(f"the {kind(rec).__name__} record at byte {start} says it is "
                             f"{length} bytes long; it is {end - start - 9}")
    ends = [k for k, (rec, _, _) in enumerate(layout) if kind(rec) is DataEnd]
    if len(ends) != 1:
        raise ValueError(f"its data section ends {len(ends)} times (a DataEnd record is "
                         "missing or repeated: a length field was changed)")
    data_end = layout[ends[0]][2]
    summary = layout[ends[0] + 1:-1]
    foot_start = layout[-1][1]
    if kind(layout[-1][0]) is not Footer or foot_start != size - len(_MAGIC) - _FOOTER_BYTES:
        raise ValueError("its footer is not where the file ends")
    if footer.summary_start not in (0, data_end) or (footer.summary_start == 0
                                                      and data_end != foot_start):
        raise ValueError(f"its footer puts the summary at byte {footer.summary_start}; the "
                         f"data section ends at byte {data_end}")
    group = {Schema: Opcode.SCHEMA, Channel: Opcode.CHANNEL, Statistics: Opcode.STATISTICS,
             ChunkIndex: Opcode.CHUNK_INDEX, AttachmentIndex: Opcode.ATTACHMENT_INDEX,
             MetadataIndex: Opcode.METADATA_INDEX, SummaryOffset: Opcode.SUMMARY_OFFSET}
    for rec, start, _ in summary:
        if kind(rec) not in group:
            raise ValueError(f"its summary holds a {kind(rec).__name__} record at byte {start}")
    offsets = [(rec, start) for rec, start, _ in summary if kind(rec) is SummaryOffset]
    if offsets:
        first = offsets[0][1]
        if footer.summary_offset_start != first or any(
                kind(rec) is not SummaryOffset for rec, start, _ in summary if start >= first):
            raise ValueError(f"its footer puts the summary offsets at byte "
                             f"{footer.summary_offset_start}; they start at byte {first}")
    elif footer.summary_offset_start != 0:
        raise ValueError(f"its footer puts summary offsets at byte "
                         f"{footer.summary_offset_start}; it has none")
    starts = {start: (rec, end) for rec, start, end in summary}
    for rec, at in offsets:
        pos, stop = rec.group_start, rec.group_start + rec.group_length
        while pos < stop and pos in starts and group.get(kind(starts[pos][0])) == rec.group_opcode:
            pos = starts[pos][1]
        if pos != stop:
            raise ValueError(f"the summary offset at byte {at} names bytes "
                             f"{rec.group_start}-{stop}, not a run of its records")
    start = footer.summary_start or foot_start
    if footer.summary_crc != 0:
        f.seek(start)
        end = size - len(_MAGIC) - 4
        if zlib.crc32(f.read(end - start)) != footer.summary_crc:
            raise ValueError(f"its summary (bytes {start}-{end}) does not match its CRC")
    if footer.summary_start == 0:
        return
    f.seek(0)
    read = SeekingReader(f, record_size_limit=max(size, 1)).get_summary()
    if read is None:
        raise ValueError("its footer, read from the end, names no summary")
    chunks = [(start, end) for rec, start, end in layout if kind(rec) is Chunk]
    idx = read.chunk_indexes
    index_ends = [next((s for r, s, _ in layout[k + 1:] if kind(r) is not MessageIndex), 0)
                  for k, (r, _, _) in enumerate(layout) if kind(r) is Chunk]
    index_len = [layout_end - end for (_, end), layout_end in zip(chunks, index_ends,
                                                                   strict=True)]
    if idx and [(c.chunk_start_offset, c.chunk_start_offset + c.chunk_length,
                 c.message_start_time, c.message_end_time, c.compression, c.compressed_size,
                 c.uncompressed_size, c.message_index_length) for c in idx] != [
            (*span, *meta, n) for span, meta, n in zip(chunks, counted.chunks, index_len,
                                                       strict=True)]:
        raise ValueError(f"its summary indexes {len(idx)} chunk(s) that are not the "
                         f"{len(chunks)} chunk(s) it holds")
    if (read.schemas and read.schemas != counted.schemas) or (
            read.channels and read.channels != counted.channels):
        raise ValueError("its summary's schemas or channels are not those of its data")
    listed = sorted((off, ch) for c in idx for ch, off in c.message_index_offsets.items())
    indexes = sorted((start, rec.channel_id) for rec, start, _ in layout[:ends[0]]
                     if kind(rec) is MessageIndex)
    if listed and listed != indexes:
        raise ValueError("its summary's message index offsets are not where its message "
                         "indexes are")
    st = read.statistics
    if st is not None and (
            st.message_count != sum(counted.per_channel.values())
            or dict(st.channel_message_counts) != counted.per_channel
            or st.chunk_count != len(chunks) or st.channel_count != len(read.channels)
            or st.schema_count != len(read.schemas) or st.metadata_count != counted.metadata
            or st.attachment_count != counted.attachments
            or (counted.first_ns is not None
                and (st.message_start_time, st.message_end_time)
                != (counted.first_ns, counted.last_ns))):
        raise ValueError("its summary's statistics do not count what it holds")


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
