"""Regenerate the example arm trajectories under examples/ (deterministic).

    .venv/bin/python examples/make_examples.py

Each is a straight joint-space move between two configurations with a quintic (minimum-jerk)
time scaling, slowed until every arm joint stays within the spec's velocity limit.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from articutool.spec import load_spec
from articutool.trajectory import JointTrajectory

HERE = Path(__file__).parent


def joint_move(q0: np.ndarray, q1: np.ndarray, vmax: np.ndarray, n: int = 200,
               speed_fraction: float = 0.8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quintic joint-space move with duration set by the slowest joint's velocity limit."""
    dq = q1 - q0
    # Peak of the quintic's velocity is 15/8 · |dq| / T.
    duration = float(np.max(15.0 / 8.0 * np.abs(dq) / (speed_fraction * vmax)))
    s = np.linspace(0.0, 1.0, n)
    pos = 10 * s**3 - 15 * s**4 + 6 * s**5
    vel = (30 * s**2 - 60 * s**3 + 30 * s**4) / duration
    return s * duration, q0 + np.outer(pos, dq), np.outer(vel, dq)


def main() -> int:
    spec = load_spec()
    arm = spec.arm
    vmax = arm.max_velocity
    cases = {
        # AbovePlate to Resting (over the bowl): the wrist keeps the spoon level.
        "transport_feasible.json": (arm.configuration("AbovePlate"),
                                    arm.configuration("Resting")),
        # A naive joint-space move AbovePlate -> Home tips the tool base past vertical: the
        # leveling solution must flip branch (pitch jumps by π), which no motor can do in a step.
        "transport_flip.json": (arm.configuration("AbovePlate"), arm.configuration("Home")),
    }
    for name, (q0, q1) in cases.items():
        t, q, qd = joint_move(q0, q1, vmax)
        path = HERE / name
        path.unlink(missing_ok=True)
        JointTrajectory(tuple(arm.joint_names), t, q, qd).save(path)
        print(f"wrote {path} ({len(t)} points, {t[-1]:.2f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
