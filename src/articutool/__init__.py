"""articutool: robot-assisted feeding with a decoupled 2-DOF active wrist.

Top-level names are the ones most users need; subsystems live in subpackages:
``tool`` (onboard wrist software), ``arm`` (Jaco + Articutool models), ``verify``
(plan-then-verify), ``planning``, ``link``, ``sim``, ``feeding``, ``bench``.
"""

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
