"""Build and install the ``articutool_interfaces`` ROS 2 package (and, where they are missing,
the two interface packages of the trajectory path ADA uses) into this Python environment.

``make`` runs ``python -m articutool.ros2.build_interfaces`` after installing the ``ros`` extra:
plain ``cmake`` with the rosidl and ament wheels from PyPI, installed into ``sys.prefix`` (laid
out like a ROS install space), so ``import articutool_interfaces.srv`` works with no
environment set-up. The package's ``.srv``/``.action`` files are the ones the link's CDR
messages are parsed from (``articutool/link/articutool_interfaces``): one definition.
``control_msgs`` and ``controller_manager_msgs`` are not on PyPI: their served types' field
layout (``articutool/ros2/peer_interfaces``) is built the same way unless a real package is
installed already.

Two facts measured with these wheels (``docs/notes/2026-11-22-ros2-from-pypi.md``): their
``*__rosidl_generator_pyExport.cmake`` files name the wheel builder's Python and NumPy include
directories, which CMake rejects as non-existent paths, so they are rewritten to this
interpreter's (idempotent; a forced reinstall of a wheel undoes it and the next run redoes it);
and the wheels exist for CPython 3.11 on x86-64 only: elsewhere this says so and exits 0, so the
rest of the project installs and tests without ROS 2.

Exit codes: 0 built, already up to date, or skipped (no wheels); 1 the build failed.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import platform
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

__all__ = ["PACKAGES", "SOURCE", "fix_export_paths", "main", "skip_reason"]

SOURCE = Path(__file__).resolve().parent.parent / "link" / "articutool_interfaces"
PEERS = Path(__file__).resolve().parent / "peer_interfaces"
PACKAGES = (SOURCE, PEERS / "control_msgs", PEERS / "controller_manager_msgs")
PREFIX = Path(sys.prefix)
_STAMP_NAME = ".articutool-source-sha256"
# INTERFACE_INCLUDE_DIRECTORIES entries that point at the wheel builder's interpreter.
_PY_INCLUDE = re.compile(r"[^;\"]*/include/python3\.\d+(?=[;\"])")
_NP_INCLUDE = re.compile(r"[^;\"]*/numpy/_core/include(?=[;\"])")


def skip_reason() -> str:
    """Why the package cannot be built here ('' when it can)."""
    if platform.machine() != "x86_64" or sys.version_info[:2] != (3, 11) \
            or platform.python_implementation() != "CPython":
        return (f"the ROS 2 wheels exist for CPython 3.11 on x86_64 only; this is "
                f"{platform.python_implementation()} {platform.python_version()} on "
                f"{platform.machine()}")
    for mod in ("rclpy", "rosidl_cmake", "ament_package", "catkin_pkg"):
        if importlib.util.find_spec(mod) is None:
            return f"the Python module {mod!r} is missing (install the 'ros' extra)"
    if shutil.which("cmake") is None:
        return "cmake is not installed"
    return ""


def fix_export_paths(prefix: Path = PREFIX) -> list[Path]:
    """Point the wheels' Python/NumPy include directories at this interpreter's; idempotent.

    Returns the files changed (none on a second run).
    """
    import numpy

    py_inc = sysconfig.get_paths()["include"]
    np_inc = numpy.get_include()
    changed = []
    for f in sorted(prefix.glob("share/*/cmake/*__rosidl_generator_pyExport.cmake")):
        text = f.read_text()
        new = _NP_INCLUDE.sub(lambda _m: np_inc, _PY_INCLUDE.sub(lambda _m: py_inc, text))
        if new != text:
            f.write_text(new)
            changed.append(f)
    return changed


def _source_digest(source: Path) -> str:
    h = hashlib.sha256()
    for f in sorted(p for p in source.rglob("*") if p.is_file()):
        h.update(str(f.relative_to(source)).encode() + b"\0" + f.read_bytes())
    return h.hexdigest()


def _importable(pkg: str) -> bool:
    kinds = sorted({p.parent.name for p in (SOURCE.parent / pkg).glob("*/*.*")}
                   | {d.name for d in (PEERS / pkg).glob("*") if d.is_dir()})
    mods = ", ".join(f"{pkg}.{k}" for k in kinds if k in ("msg", "srv", "action")) or pkg
    return subprocess.run([sys.executable, "-c", f"import {mods}"],
                          capture_output=True).returncode == 0


def _build(source: Path) -> int:
    """Configure, build and install one package into the prefix; 0 or 1."""
    env = dict(os.environ, AMENT_PREFIX_PATH=str(PREFIX))
    with tempfile.TemporaryDirectory(prefix=f"{source.name}-") as build:
        steps = [
            ["cmake", "-S", str(source), "-B", build, f"-DCMAKE_PREFIX_PATH={PREFIX}",
             f"-DCMAKE_INSTALL_PREFIX={PREFIX}", f"-DPython3_EXECUTABLE={sys.executable}",
             "-DBUILD_TESTING=OFF", "-DCMAKE_BUILD_TYPE=Release"],
            ["cmake", "--build", build, "--parallel", "2"],
            ["cmake", "--install", build],
        ]
        print(f"{source.name}: building with cmake into {PREFIX}")
        for cmd in steps:
            done = subprocess.run(cmd, env=env, capture_output=True, text=True)
            if done.returncode != 0:
                print(done.stdout[-4000:], done.stderr[-4000:], sep="\n", file=sys.stderr)
                print(f"{source.name}: `{' '.join(cmd[:3])} …` failed "
                      f"(exit {done.returncode})", file=sys.stderr)
                return 1
    return 0


def main() -> int:
    """Build and install each package unless up to date (or, for the peers, installed by
    someone else); print what happened."""
    why = skip_reason()
    if why:
        print(f"articutool_interfaces: not built ({why}); `articutool ros2` and its tests "
              "are unavailable, everything else works")
        return 0
    fixed = fix_export_paths()
    if fixed:
        print(f"articutool_interfaces: fixed the include paths in {len(fixed)} ROS 2 CMake "
              "export files")
    for source in PACKAGES:
        pkg = source.name
        stamp = PREFIX / "share" / pkg / _STAMP_NAME
        digest = _source_digest(source)
        if source != SOURCE and not stamp.is_file() and _importable(pkg):
            print(f"{pkg}: installed already (not ours); using it")
            continue
        if stamp.is_file() and stamp.read_text() == digest and _importable(pkg):
            print(f"{pkg}: up to date")
            continue
        if _build(source):
            return 1
        if not _importable(pkg):
            print(f"{pkg}: installed but its Python modules do not import", file=sys.stderr)
            return 1
        stamp.write_text(digest)
        print(f"{pkg}: built and installed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
