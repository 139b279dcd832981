"""articutool: robot-assisted feeding with a decoupled 2-DOF active wrist.

Top-level names are the ones most users need; subsystems live in subpackages:
``tool`` (onboard wrist software), ``arm`` (Jaco + Articutool models), ``verify``
(plan-then-verify), ``planning``, ``link``, ``sim``, ``feeding``, ``bench``.
"""

import os

# MuJoCo fixes its GL backend the first time anything imports it; choose headless EGL here,
# before any articutool module can import mujoco, unless the caller chose a backend.
os.environ.setdefault("MUJOCO_GL", "egl")

from articutool.spec import Spec, SpecError, load_spec
from articutool.tool.kinematics import (
    jacobian,
    jacobian_pinv,
    leveling_solutions,
    rotation,
    singularity_measure,
    up_vector,
)

__version__ = "0.1.0"

__all__ = [
    "Spec",
    "SpecError",
    "__version__",
    "jacobian",
    "jacobian_pinv",
    "leveling_solutions",
    "load_spec",
    "rotation",
    "singularity_measure",
    "up_vector",
]
