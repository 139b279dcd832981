"""Reading validated data files (spec, scene, task sets) with errors that name the field, and
a run's own result files, read and written without following symbolic links.

A run's own files in a results folder, read and written without following symbolic links.

A results folder (``bench transport --out``, ``experiment … --out``) holds files a run writes
and rewrites: its trial log (appended), ``run.json``, summaries, CSV tables, figures and the
report. The folder the user names is used as given (it may be a link the user made); inside
it nothing is written through a symbolic link, a FIFO or a device: a run's own file or
subfolder found as one is refused (:class:`~articutool.datafile.ResultsError`, naming it),
and every write opens its file with ``O_NOFOLLOW`` — a rewrite goes to a new temporary file
in the same folder that then replaces the old one (``rename``: a link there would be
replaced, never written through), an append opens the log itself with ``O_NOFOLLOW``, a new
file is linked into place (``link`` never replaces anything). So a link planted in a results
folder can neither redirect a write to a user's file nor have it appended to or cut.
"""

from __future__ import annotations

import contextlib
import errno
import json
import math
import os
import secrets
import stat
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError

__all__ = [
    "MAX_DOCUMENT_BYTES",
    "Finite",
    "NonNegative",
    "Positive",
    "ResultsError",
    "StrictModel",
    "Unit",
    "Vec3",
    "append_own",
    "check_finite",
    "check_own",
    "field_path",
    "file_kind",
    "format_validation_error",
    "own_folder",
    "parse_json",
    "publish_new",
    "read_bytes",
    "read_document",
    "read_own_bytes",
    "read_own_json",
    "read_text",
    "replace_own",
    "save_figure",
]

# The largest input file read (the packaged task set is 0.2 MB, a long recorded trajectory a
# few MB): a bound, so that a wrong path (a device, a huge log) is refused instead of filling
# memory.
MAX_DOCUMENT_BYTES = 64 << 20


class ResultsError(ValueError):
    """A results file (a run's summary, trial log, report, figure) cannot be read or written
    as articutool writes it: unreadable, malformed, of the wrong shape, or a link, FIFO or
    folder where the run's own file belongs (bad input: the message names the file)."""


def check_finite(v: float) -> float:
    """``v`` if finite (a pydantic validator: NaN or an infinity is refused)."""
    if not math.isfinite(v):
        raise ValueError("must be a finite number (got NaN or inf)")
    return v


Finite = Annotated[float, AfterValidator(check_finite)]
Positive = Annotated[float, AfterValidator(check_finite), Field(gt=0)]
NonNegative = Annotated[float, AfterValidator(check_finite), Field(ge=0)]
Unit = Annotated[float, AfterValidator(check_finite), Field(ge=0, le=1)]
Vec3 = tuple[Finite, Finite, Finite]


class StrictModel(BaseModel):
    """The base of every validated data file's models (the spec, the scene, the physics
    parameters, the action library, the experiments): an unknown field is an error (a typo
    never passes silently) and a loaded value never changes."""

    model_config = ConfigDict(extra="forbid", frozen=True)


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


def parse_json(text: str | bytes, what: str, error: type[Exception]) -> Any:
    """``json.loads`` whose failures — malformed text, or nesting deeper than the parser's
    recursion limit — raise ``error`` naming ``what``. (``NaN`` and ``Infinity``, which
    Python's parser accepts, are left to the validating model, which names the field.)"""
    try:
        return json.loads(text)
    except json.JSONDecodeError as err:
        raise error(f"{what} is not valid JSON: {err}") from None
    except RecursionError:
        raise error(f"{what} {_TOO_DEEP}") from None


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


# ------------------------------------------------------------ a run's own files --
_NOFOLLOW_HINT = ("articutool writes a run's own files itself and never through a link, a "
                  "FIFO or a device: move it away or use another folder")


def check_own(path: str | Path, opt: str = "--out") -> None:
    """``path`` is absent or a regular file (not a link to one): else ResultsError naming
    ``opt``, the file and what it is."""
    p = Path(path)
    try:
        mode = os.lstat(p).st_mode
    except FileNotFoundError:
        return
    except OSError as err:
        raise ResultsError(f"{opt}: cannot check {p}: {err.strerror}") from None
    if not stat.S_ISREG(mode):
        raise ResultsError(f"{opt}: {p} is {file_kind(mode)}; {_NOFOLLOW_HINT}")


def own_folder(root: str | Path, *parts: str, opt: str = "--out") -> Path:
    """``root/parts…``: ``root`` (the folder the user named) is created if needed and may be
    a link; each of ``parts`` is this run's own subfolder, created if absent and refused if it
    is a link or not a folder."""
    p = Path(root)
    if p.is_symlink() and not p.exists():
        raise ResultsError(f"{opt}: {p} is a symbolic link to nothing; name a folder")
    try:
        p.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ResultsError(f"{opt}: cannot create the folder {p}: {err.strerror}") from None
    for part in parts:
        p = p / part
        try:
            os.mkdir(p)
            continue
        except FileExistsError:
            pass
        except OSError as err:
            raise ResultsError(f"{opt}: cannot create the folder {p}: {err.strerror}") from None
        mode = os.lstat(p).st_mode
        if not stat.S_ISDIR(mode):
            raise ResultsError(f"{opt}: {p} is {file_kind(mode)} (this run's folder); "
                               f"{_NOFOLLOW_HINT}")
    return p


def read_own_bytes(path: str | Path, what: str, max_bytes: int = MAX_DOCUMENT_BYTES
                   ) -> bytes | None:
    """The bytes of the run's own file ``path`` (``None`` if it does not exist), read
    without following a link and without waiting on a FIFO; a link, a folder, a FIFO, a
    device or a file over ``max_bytes`` raise ResultsError naming ``what``."""
    try:
        return read_bytes(path, what, ResultsError, max_bytes, nofollow=True,
                          why=_NOFOLLOW_HINT)
    except ResultsError as err:
        if isinstance(err.__cause__, FileNotFoundError):
            return None
        raise


def read_own_json(path: str | Path, what: str, model: type[Any] | None = None) -> Any:
    """The JSON document of the run's own file ``path`` (``None`` if absent), validated
    against the pydantic ``model`` when given (extra fields allowed by the model decide):
    unreadable (:func:`read_own_bytes`), non-UTF-8, malformed, too deep, or of a wrong shape
    (a NaN or Infinity where the model reads a finite number) raise ResultsError naming the
    file and the field."""
    data = read_own_bytes(path, what)
    if data is None:
        return None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ResultsError(f"{what} {path} is not UTF-8 text (offset {err.start}); it is not "
                           "a file articutool wrote: move it away or use another folder"
                           ) from None
    doc = parse_json(text, f"{what} {path}", ResultsError)
    if model is None:
        return doc
    try:
        return model.model_validate(doc)
    except ValidationError as err:
        raise ResultsError(format_validation_error(
            err, f"{what} {path} is not as articutool writes it:")) from None


def _open_parent(p: Path) -> int:
    try:
        return os.open(p.parent, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError as err:
        raise ResultsError(f"cannot write into the folder {p.parent}: {err.strerror}") from None


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def _temp_in(dfd: int, p: Path) -> tuple[str, int]:
    """A new temporary file beside ``p`` (exclusive, never a link; hidden, with ``p``'s
    suffix, which writers choose their format by): (name, fd)."""
    for _ in range(16):
        name = f".{p.stem}.{secrets.token_hex(6)}.tmp{p.suffix}"
        try:
            fd = os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW
                         | os.O_CLOEXEC, 0o666, dir_fd=dfd)
            return name, fd
        except FileExistsError:
            continue
        except OSError as err:
            raise ResultsError(f"cannot write {p}: {err.strerror}") from None
    raise ResultsError(f"cannot write {p}: no free temporary name beside it")


def replace_own(path: str | Path, data: bytes | str, opt: str = "--out") -> Path:
    """Write ``data`` as the run's own file ``path``, replacing the previous version
    atomically (a reader sees the old or the new file, never half of one) and never writing
    through a link: one found at ``path`` is refused (:func:`check_own`)."""
    p = Path(path)
    raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    check_own(p, opt)
    dfd = _open_parent(p)
    try:
        name, fd = _temp_in(dfd, p)
        try:
            try:
                _write_all(fd, raw)
                os.fsync(fd)
            finally:
                os.close(fd)
            os.replace(name, p.name, src_dir_fd=dfd, dst_dir_fd=dfd)
        except OSError as err:
            with contextlib.suppress(OSError):
                os.unlink(name, dir_fd=dfd)
            raise ResultsError(f"cannot write {p}: {err.strerror}") from None
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(name, dir_fd=dfd)
            raise
    finally:
        os.close(dfd)
    return p


def save_figure(fig: Any, path: str | Path, dpi: int = 120) -> Path:
    """Save a matplotlib figure as the run's own file ``path`` (format by its suffix),
    rendered in memory and written by :func:`replace_own`."""
    import io

    p = Path(path)
    buf = io.BytesIO()
    fig.savefig(buf, format=p.suffix.lower().lstrip(".") or "png", dpi=dpi)
    return replace_own(p, buf.getvalue())


def append_own(path: str | Path, opt: str = "--out") -> int:
    """A descriptor appending to the run's own log ``path`` (created if absent), opened
    without following a link: a link, FIFO or device there raises ResultsError."""
    p = Path(path)
    try:
        fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_NOFOLLOW | os.O_NONBLOCK
                     | os.O_CLOEXEC, 0o666)
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise ResultsError(f"{opt}: {p} is a symbolic link; {_NOFOLLOW_HINT}") from None
        raise ResultsError(f"{opt}: cannot write {p}: {err.strerror}") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise ResultsError(f"{opt}: {p} is {file_kind(mode)}; {_NOFOLLOW_HINT}")
    os.set_blocking(fd, True)
    return fd


def publish_new(path: str | Path, write: Callable[[Path], object]) -> Path:
    """Create the new file ``path`` by ``write(tmp)`` into a temporary file beside it, then
    linking that into place: nothing at ``path`` — a file, a dangling link — is ever
    replaced or written through (``FileExistsError`` becomes ResultsError), and a failed
    ``write`` leaves nothing behind."""
    p = Path(path)
    dfd = _open_parent(p)
    try:
        name, fd = _temp_in(dfd, p)
        os.close(fd)
        tmp = p.parent / name
        try:
            write(tmp)
            os.link(name, p.name, src_dir_fd=dfd, dst_dir_fd=dfd, follow_symlinks=False)
        except FileExistsError:
            raise ResultsError(f"{p} exists (or is a link); refusing to overwrite it") from None
        finally:
            with contextlib.suppress(OSError):
                os.unlink(name, dir_fd=dfd)
    finally:
        os.close(dfd)
    return p
