"""What the physics benchmarks share: the machine they ran on (with its load, since this
machine is shared) and writing their JSON."""

from __future__ import annotations

import json
import os
import platform
import sys
from pathlib import Path
from typing import Any

import mujoco


def machine() -> dict[str, Any]:
    """Python, platform, CPUs, MuJoCo version and the load average at the start."""
    return {"python": sys.version.split()[0], "platform": platform.platform(),
            "cpus": os.cpu_count(), "mujoco": mujoco.__version__,
            "cpu": cpu(), "loadavg_start": os.getloadavg()}


def cpu() -> dict[str, Any]:
    """The CPU's model and whether it has AVX-512: the machines these figures were measured
    on differed in both, and NumPy picks its kernels by them."""
    info = Path("/proc/cpuinfo")
    text = info.read_text() if info.exists() else ""
    model = next((ln.split(":", 1)[1].strip() for ln in text.splitlines()
                  if ln.startswith("model name")), platform.processor())
    flags = next((ln.split(":", 1)[1].split() for ln in text.splitlines()
                  if ln.startswith("flags")), [])
    return {"model": model, "avx512f": "avx512f" in flags}


def write_json(path: str | Path, doc: dict[str, Any]) -> None:
    """Write ``doc`` to ``path`` (its folder made) and say so."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {path}")
