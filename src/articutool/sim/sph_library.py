"""Loading SPlisHSPlasH (``pysplishsplash``), the liquid solver, without crashing the process.

The 2.19 wheel bundles its own ``libGLdispatch``; on machines with libglvnd the system's
``libGLX`` constructor calls into that bundled copy and the import segfaults. Loading the
system's ``libGLdispatch.so.0`` first, globally, makes the bundled copy's symbols resolve to
it. A segfault cannot be caught, so the first import is tried in a child process: a missing
or broken library becomes a :class:`LiquidLibraryError` naming the package and the fix.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import importlib
import subprocess
import sys
from functools import cache
from types import ModuleType

__all__ = ["PACKAGE", "LiquidLibraryError", "library_version", "load_splishsplash"]

PACKAGE = "pysplishsplash"
_FIX = f"install it with `pip install {PACKAGE}==2.19.0` (or `make` in the repository)"


class LiquidLibraryError(RuntimeError):
    """The liquid solver cannot be loaded; the message names the package and the fix."""


def _preload_gldispatch() -> None:
    name = ctypes.util.find_library("GLdispatch")
    if name is None:  # no libglvnd on this machine: nothing calls the bundled copy
        return
    try:
        ctypes.CDLL(name, mode=ctypes.RTLD_GLOBAL)
    except OSError:
        return


_PROBE = (
    "import ctypes, ctypes.util\n"
    "n = ctypes.util.find_library('GLdispatch')\n"
    "n and ctypes.CDLL(n, mode=ctypes.RTLD_GLOBAL)\n"
    "import pysplishsplash, pysplishsplash.Utilities\n"
)


@cache
def _probe() -> str | None:
    """None when a child process imports the library cleanly, else why it did not."""
    try:
        r = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                           timeout=120, check=False)
    except (OSError, subprocess.TimeoutExpired) as e:
        return f"the import check could not run ({e})"
    if r.returncode == 0:
        return None
    if f"No module named '{PACKAGE}'" in r.stderr:
        return f"{PACKAGE} is not installed"
    tail = (r.stderr.strip().splitlines() or [f"exit status {r.returncode}"])[-1]
    if r.returncode < 0:
        tail = f"the import crashed with signal {-r.returncode}"
    return f"{PACKAGE} is installed but cannot be imported: {tail}"


@cache
def load_splishsplash() -> ModuleType:
    """The ``pysplishsplash`` module, imported safely; raises :class:`LiquidLibraryError`."""
    if PACKAGE not in sys.modules:
        why = _probe()
        if why is not None:
            raise LiquidLibraryError(f"the liquid solver SPlisHSPlasH is unavailable: {why}; "
                                     f"{_FIX}")
        _preload_gldispatch()
    module = importlib.import_module(PACKAGE)
    importlib.import_module(f"{PACKAGE}.Utilities")
    return module


def library_version() -> str:
    """The installed ``pysplishsplash`` version (from its package metadata)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(PACKAGE)
    except PackageNotFoundError as e:
        raise LiquidLibraryError(f"{PACKAGE} is not installed; {_FIX}") from e
