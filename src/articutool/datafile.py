"""Reading validated data files (spec, scene, task sets) with errors that name the field."""

from __future__ import annotations

import errno
import json
import os
import stat
import tomllib
from pathlib import Path
from typing import Any, Literal

from pydantic import ValidationError

__all__ = ["MAX_DOCUMENT_BYTES", "ResultsError", "field_path", "file_kind",
           "format_validation_error", "parse_json", "read_bytes", "read_document", "read_text"]

# The largest input file read (the packaged task set is 0.2 MB, a long recorded trajectory a
# few MB): a bound, so that a wrong path (a device, a huge log) is refused instead of filling
# memory.
MAX_DOCUMENT_BYTES = 64 << 20


class ResultsError(ValueError):
    """A results file (a run's summary, trial log, report, figure) cannot be read or written
    as articutool writes it: unreadable, malformed, of the wrong shape, or a link, FIFO or
    folder where the run's own file belongs (bad input: the message names the file)."""


_TOO_DEEP = ("is nested too deeply to read (arrays or tables inside each other hundreds of "
             "levels deep)")


def read_bytes(path: str | Path, what: str, error: type[Exception],
               max_bytes: int = MAX_DOCUMENT_BYTES, *, nofollow: bool = False,
               why: str = "a regular file is needed") -> bytes:
    """The bytes of the regular file ``path`` (at most ``max_bytes``); anything else — a
    missing file, a folder, a FIFO or device (which would block or never end), a larger
    file, with ``nofollow`` a symbolic link — raises ``error`` naming the file (``why`` ends
    the message of a file that is not regular). ``FileNotFoundError`` is chained."""
    p = Path(path)
    try:
        # O_NONBLOCK: opening a FIFO for reading must not wait for a writer.
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC
                     | (os.O_NOFOLLOW if nofollow else 0))
    except OSError as err:
        reason = ("it is a symbolic link" if nofollow and err.errno == errno.ELOOP
                  else err.strerror)
        raise error(f"cannot read {what} {p}: {reason} ({why})") from (
            err if isinstance(err, FileNotFoundError) else None)
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise error(f"cannot read {what} {p}: it is {file_kind(mode)} ({why})")
    with os.fdopen(fd, "rb") as f:
        try:
            data = f.read(max_bytes + 1)
        except OSError as err:
            raise error(f"cannot read {what} {p}: {err.strerror}") from None
    if len(data) > max_bytes:
        raise error(f"{what} {p} is larger than {max_bytes >> 20} MiB, the most read")
    return data


def file_kind(mode: int) -> str:
    """What a file that is not a regular one is, for a message (from its ``st_mode``)."""
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    return "not a regular file"


def read_text(path: str | Path, what: str, error: type[Exception],
              max_bytes: int = MAX_DOCUMENT_BYTES) -> str:
    """The UTF-8 text of the regular file ``path`` (:func:`read_bytes`); non-UTF-8 bytes
    raise ``error`` naming the file too."""
    p = Path(path)
    data = read_bytes(p, what, error, max_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        bad = err.object[err.start:err.end].hex(" ", 1).replace(" ", " 0x")
        raise error(f"{what} {p} is not UTF-8 text (byte 0x{bad} at offset {err.start}); "
                    "save it as UTF-8") from None


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number (JSON has no NaN or Infinity)")


def parse_json(text: str | bytes, what: str, error: type[Exception]) -> Any:
    """``json.loads`` whose failures — malformed text, ``NaN``/``Infinity`` (which JSON does
    not have and no articutool file holds), or nesting deeper than the parser's recursion
    limit — raise ``error`` naming ``what``."""
    try:
        return json.loads(text, parse_constant=_no_constant)
    except json.JSONDecodeError as err:
        raise error(f"{what} is not valid JSON: {err}") from None
    except RecursionError:
        raise error(f"{what} {_TOO_DEEP}") from None
    except ValueError as err:  # NaN, Infinity
        raise error(f"{what} is not valid JSON: {err}") from None


def read_document(path: str | Path, what: str, error: type[Exception],
                  fmt: Literal["json", "toml"] | None = None) -> Any:
    """Parse a TOML or JSON file (``fmt``, else by suffix: ``.json`` is JSON, ``.yaml`` and
    ``.yml`` are refused, anything else is TOML); unreadable
    (see :func:`read_text`), non-UTF-8, malformed or too deeply nested files raise ``error``
    with a message naming the file."""
    p = Path(path)
    if fmt is None and p.suffix.lower() in (".yaml", ".yml"):
        raise error(f"{what} {p}: YAML is not read; write it as TOML (or JSON, ending in "
                    ".json)")
    text = read_text(p, what, error)
    if (fmt or ("json" if p.suffix.lower() == ".json" else "toml")) == "json":
        return parse_json(text, f"{what} {p}", error)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise error(f"{what} {p} is not valid TOML: {err}") from None
    except RecursionError:
        raise error(f"{what} {p} {_TOO_DEEP}") from None


def field_path(loc: tuple[Any, ...] | list[Any]) -> str:
    """``("tasks", 3, "start")`` → ``tasks[3].start``."""
    return "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in loc).lstrip(".")


def format_validation_error(err: ValidationError, header: str) -> str:
    """One line per problem: ``  field.path: message``."""
    lines = [header]
    for e in err.errors():
        msg = e["msg"].removeprefix("Value error, ")
        lines.append(f"  {field_path(e['loc']) or '(top level)'}: {msg}")
    return "\n".join(lines)
