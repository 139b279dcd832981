"""Checks that this process computes as a CPU without AVX-512 does, and says how::

    NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" OPENBLAS_CORETYPE=Haswell \\
        python tests/avx2_paths.py

Two libraries choose their kernels from the CPU at run time, so the last bits of what they
compute differ between CPUs (and a chaotic physics run amplifies them):

- NumPy's own SIMD loops (``NPY_DISABLE_CPU_FEATURES`` switches targets off; NumPy ignores a
  name it does not dispatch on with only an ImportWarning, so each name given must be a
  dispatch target and be off);
- OpenBLAS (NumPy's ``@``, ``linalg``: even a 3×3 product's bits depend on its kernel;
  ``OPENBLAS_CORETYPE`` picks one: Haswell is what an AVX2 CPU runs, SkylakeX an AVX-512 one).

Exit 1 naming what did not take effect.
"""

from __future__ import annotations

import ctypes
import os
import sys
from pathlib import Path

import numpy as np
from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__


def openblas_core() -> str:
    """The kernel set NumPy's OpenBLAS runs (its ``get_corename``), or "" if not found."""
    libs = sorted((Path(np.__file__).parent.parent / "numpy.libs").glob("libscipy_openblas*"))
    for lib in libs:
        so = ctypes.CDLL(str(lib))
        for name in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename"):
            f = getattr(so, name, None)
            if f is not None:
                f.restype = ctypes.c_char_p
                return str(f().decode())
    return ""


def main() -> int:
    off = os.environ.get("NPY_DISABLE_CPU_FEATURES", "").split()
    bad = {k: ("not a NumPy dispatch target" if k not in __cpu_dispatch__ else "still on")
           for k in off if k not in __cpu_dispatch__ or __cpu_features__.get(k)}
    want = os.environ.get("OPENBLAS_CORETYPE", "")
    core = openblas_core()
    if want and core.lower() != want.lower():
        bad["OPENBLAS_CORETYPE"] = f"OpenBLAS runs {core or 'an unknown core'}, not {want}"
    if bad:
        print(f"not as asked: {bad}", file=sys.stderr)
        return 1
    print(f"NumPy dispatches without {' '.join(off) or 'nothing switched off'}; "
          f"OpenBLAS runs {core or 'an unknown core'} kernels")
    return 0


if __name__ == "__main__":
    sys.exit(main())
