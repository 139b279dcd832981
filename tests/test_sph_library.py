"""Loading the liquid solver: a missing or crashing library is a clear error, never a segfault
of the caller (each case runs in a child process whose import path holds a stand-in)."""

import subprocess
import sys
import textwrap
from pathlib import Path

CALL = textwrap.dedent("""
    import sys
    from articutool.sim.sph_library import LiquidLibraryError, load_splishsplash
    try:
        load_splishsplash()
    except LiquidLibraryError as e:
        print("ERROR", e)
        sys.exit(2)
    print("LOADED")
""")


def _run(tmp_path: Path, stand_in: str | None) -> subprocess.CompletedProcess[str]:
    import os

    env_path = [str(Path(__file__).parents[1] / "src")]
    if stand_in is not None:
        pkg = tmp_path / "pysplishsplash"
        pkg.mkdir()
        (pkg / "__init__.py").write_text(stand_in)
        (pkg / "Utilities.py").write_text("")
        env_path.insert(0, str(tmp_path))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(env_path))
    return subprocess.run([sys.executable, "-c", CALL], capture_output=True, text=True,
                          env=env, timeout=300, check=False)


def test_a_library_that_segfaults_on_import_is_a_clear_error(tmp_path: Path) -> None:
    r = _run(tmp_path, "import os, signal\nos.kill(os.getpid(), signal.SIGSEGV)\n")
    assert r.returncode == 2, r.stderr
    assert "pysplishsplash" in r.stdout and "crashed with signal 11" in r.stdout
    assert "pip install pysplishsplash" in r.stdout


def test_a_broken_library_names_its_import_error(tmp_path: Path) -> None:
    r = _run(tmp_path, "raise ImportError('libfoo.so: cannot open shared object file')\n")
    assert r.returncode == 2, r.stderr
    assert "cannot be imported" in r.stdout and "libfoo.so" in r.stdout


def test_the_installed_library_loads_in_process(tmp_path: Path) -> None:
    r = _run(tmp_path, None)
    assert r.returncode == 0 and "LOADED" in r.stdout, r.stdout + r.stderr
