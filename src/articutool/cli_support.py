"""What every ``articutool`` command shares: the bad-input error, the ``--spec`` option and
the checks of output files and folders (the developers' guide: bad input exits 2 naming the
field; a user's file is never overwritten).

A neutral module below all the sub-CLIs (``*/cli.py``, ``onboard.py``, ``sim/demo.py``) and
the top-level :mod:`articutool.cli` that gathers them, so no layer imports the top one.
"""

from __future__ import annotations

import argparse
import math
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from articutool.spec import Spec

__all__ = ["MAX_RUN_S", "MAX_WAIT_S", "UsageError", "add_spec_option", "new_output_file",
           "output_dir", "seconds", "spec_from_args"]

# The longest wait, timeout or planning budget a command takes: an hour (the thesis' planning
# budget was 1000 s); longer is a slip of units or a typo, not a wait (``demo --timeout 1e308``
# gave up after 20 ms, saying "no path found within 1e+308 s").
MAX_WAIT_S = 3600.0
# The longest run a command is told to last (``tool --duration``, ``view --duration``): a week.
MAX_RUN_S = 7 * 86400.0

# The most food a load or a threshold may name on a command line (g): more than any utensil of
# the spec holds (a soup spoon's capacity is ~15 g).
MAX_MASS_G = 100.0


class UsageError(Exception):
    """Bad input from the user: printed as ``error: …`` with exit code 2."""


def seconds(most: float, *, zero: bool = False) -> Callable[[str], float]:
    """An argparse ``type`` for a duration option: a number of seconds in ``(0, most]``
    (``[0, most]`` with ``zero``). Anything else — not a number, NaN, an infinity, negative,
    beyond ``most`` — is refused by argparse with exit 2, naming the option and the range."""
    lo = "[0" if zero else "(0"

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            v = math.nan
        if not (math.isfinite(v) and (v >= 0 if zero else v > 0) and v <= most):
            raise argparse.ArgumentTypeError(
                f"must be a number of seconds in {lo}, {most:g}]; got {text!r}")
        return v

    parse.__name__ = "seconds"
    return parse


def add_spec_option(p: argparse.ArgumentParser) -> None:
    """The ``--spec FILE`` option every hardware-facing command takes."""
    p.add_argument("--spec", metavar="FILE", default=None,
                   help="hardware spec TOML (default: the packaged spec)")


def new_output_file(opt: str, path: str | None, suffixes: tuple[str, ...]) -> Path | None:
    """``path`` checked as a new output file for option ``opt`` (``None`` passes through):
    one of ``suffixes``, not existing and not a link, even a dangling one (nothing is
    overwritten or written through), creatable (it is created and removed again, so a folder
    that cannot be written, e.g. in ``/proc``, is found before any work); ``UsageError``
    naming the option otherwise. The file is then written by an exclusive create or
    :func:`articutool.datafile.publish_new`, which never replace anything either."""
    if path is None:
        return None
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise UsageError(f"{opt} must end in {' or '.join(suffixes)}; got {p.name!r}")
    if p.is_symlink():
        dangling = "" if p.exists() else " to nothing"
        raise UsageError(f"{opt}: {p} is a symbolic link{dangling}; refusing to write through "
                         "it (choose a new file)")
    if p.exists():
        raise UsageError(f"{opt}: {p} exists; refusing to overwrite it (choose a new file)")
    if not p.parent.is_dir():
        raise UsageError(f"{opt}: folder {p.parent} does not exist")
    try:
        p.open("xb").close()
    except OSError as err:
        raise UsageError(f"{opt}: cannot create {p}: {err.strerror}") from None
    p.unlink()
    return p


def output_dir(opt: str, path: str | Path, files: tuple[str, ...] = (),
               own: str | None = None) -> Path:
    """The results folder ``path`` of option ``opt`` (or, with ``own``, the run's own
    subfolder ``path/own``), created if needed and checked writable (with an unnamed
    temporary file: nothing is left in it). The folder the user named may be a link they
    made; ``own`` must be a real folder, and each of ``files`` inside that exists must be a
    regular file, not a link, FIFO or folder (:mod:`articutool.datafile`: a run writes its own
    files only). ``UsageError`` naming the option otherwise."""
    from articutool.datafile import ResultsError, check_own, own_folder

    p = Path(path)
    if p.exists() and not p.is_dir():
        raise UsageError(f"{opt} {p} exists and is not a directory")
    try:
        p = own_folder(p, *([own] if own else []), opt=opt)
        tempfile.TemporaryFile(dir=p).close()
    except ResultsError as err:
        raise UsageError(str(err)) from None
    except OSError as err:
        raise UsageError(f"{opt}: cannot write into the folder {p}: {err.strerror}") from None
    for name in files:
        try:
            check_own(p / name, opt)
        except ResultsError as err:
            raise UsageError(f"{err} (this run's {name})") from None
    return p


def spec_from_args(args: argparse.Namespace) -> Spec:
    """Load the spec named by ``--spec`` (SpecError propagates as bad input)."""
    from articutool.spec import load_spec

    return load_spec(args.spec)
