"""articutool: robot-assisted feeding with a decoupled 2-DOF active wrist.

Subsystems live in subpackages, and every name is imported from the module that defines it
(``from articutool.spec import load_spec``): ``tool`` (onboard wrist software), ``arm``
(Jaco + Articutool models), ``verify`` (plan-then-verify), ``planning``, ``link``, ``sim``,
``feeding``, ``experiments``, ``bench``, ``viewer``, ``ros2``.
"""

import os

# MuJoCo fixes its GL backend the first time anything imports it; choose headless EGL here,
# before any articutool module can import mujoco, unless the caller chose a backend.
os.environ.setdefault("MUJOCO_GL", "egl")

__version__ = "0.2.0"

__all__ = ["__version__"]
