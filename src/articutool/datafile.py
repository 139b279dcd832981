"""Reading validated data files (spec, scene, task sets) with errors that name the field."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

from pydantic import ValidationError

__all__ = ["field_path", "format_validation_error", "read_document"]


def read_document(path: str | Path, what: str, error: type[Exception]) -> Any:
    """Parse a TOML or JSON file (by suffix); unreadable, non-UTF-8 or malformed files raise
    ``error`` with a message naming the file."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as err:
        raise error(f"cannot read {what} {p}: {err.strerror}") from None
    except UnicodeDecodeError as err:
        bad = err.object[err.start:err.end].hex(" ", 1).replace(" ", " 0x")
        raise error(f"{what} {p} is not UTF-8 text (byte 0x{bad} at offset {err.start}); "
                    "save it as UTF-8") from None
    if p.suffix.lower() == ".json":
        try:
            return json.loads(text)
        except json.JSONDecodeError as err:
            raise error(f"{what} {p} is not valid JSON: {err}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise error(f"{what} {p} is not valid TOML: {err}") from None


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
