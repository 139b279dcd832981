"""Reading validated data files (spec, scene, task sets) with errors that name the field."""

from __future__ import annotations

import json
import os
import stat
import tomllib
from pathlib import Path
from typing import Any, Literal

from pydantic import ValidationError

__all__ = ["MAX_DOCUMENT_BYTES", "field_path", "format_validation_error", "parse_json",
           "read_document", "read_text"]

# The largest input file read (the packaged task set is 0.2 MB, a long recorded trajectory a
# few MB): a bound, so that a wrong path (a device, a huge log) is refused instead of filling
# memory.
MAX_DOCUMENT_BYTES = 64 << 20
_TOO_DEEP = ("is nested too deeply to read (arrays or tables inside each other hundreds of "
             "levels deep)")


def read_text(path: str | Path, what: str, error: type[Exception],
              max_bytes: int = MAX_DOCUMENT_BYTES) -> str:
    """The UTF-8 text of the regular file ``path`` (at most ``max_bytes``); anything else — a
    missing file, a folder, a FIFO or device (which would block or never end), a larger file,
    non-UTF-8 bytes — raises ``error`` naming the file."""
    p = Path(path)
    try:
        # O_NONBLOCK: opening a FIFO for reading must not wait for a writer.
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as err:
        raise error(f"cannot read {what} {p}: {err.strerror}") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        kind = "a folder" if stat.S_ISDIR(mode) else "not a regular file"
        raise error(f"cannot read {what} {p}: it is {kind} (a regular file is needed)")
    with os.fdopen(fd, "rb") as f:
        try:
            data = f.read(max_bytes + 1)
        except OSError as err:
            raise error(f"cannot read {what} {p}: {err.strerror}") from None
    if len(data) > max_bytes:
        raise error(f"{what} {p} is larger than {max_bytes >> 20} MiB, the most read")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        bad = err.object[err.start:err.end].hex(" ", 1).replace(" ", " 0x")
        raise error(f"{what} {p} is not UTF-8 text (byte 0x{bad} at offset {err.start}); "
                    "save it as UTF-8") from None


def parse_json(text: str | bytes, what: str, error: type[Exception]) -> Any:
    """``json.loads`` whose failures — malformed text, or nesting deeper than the parser's
    recursion limit — raise ``error`` naming ``what``."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise error(f"{what} is not valid JSON: {err}") from None
    except RecursionError:
        raise error(f"{what} {_TOO_DEEP}") from None


def read_document(path: str | Path, what: str, error: type[Exception],
                  fmt: Literal["json", "toml"] | None = None) -> Any:
    """Parse a TOML or JSON file (``fmt``, else by suffix: ``.json`` is JSON); unreadable
    (see :func:`read_text`), non-UTF-8, malformed or too deeply nested files raise ``error``
    with a message naming the file."""
    p = Path(path)
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
