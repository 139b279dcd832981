"""Derive the Exp. 2b staging set (scene.toml ``[staging_set]``): a common start and five
Staging goals spread over the workspace in front of the user, each an arm configuration at
which the *locked* utensil is level (so the rigid baseline can start and end there too), each
collision-free, and each reached from the start by both the decoupled planner and the strict
±20° baseline planner (checked with the project's planners).

    .venv/bin/python examples/make_staging_set.py [--utensil spoon] [--check-planning]

Prints TOML to paste into the scene. Offsets of the tip from the spec's Staging tip position
(metres, arm base frame; the user faces −y, so +y is towards the user, +z up): centre, left,
right, lower-near, higher-far — cf. thesis Fig. 5.2 (b–f).
"""

from __future__ import annotations

import argparse

import numpy as np

from articutool.arm.ik import IKSettings, solve_pose_ik, staging_configuration
from articutool.arm.model import ArmModel
from articutool.spec import load_spec

OFFSETS = {
    "centre": (0.0, 0.0, 0.0),
    "left": (0.10, -0.03, 0.0),
    "right": (-0.10, -0.03, 0.0),
    "low_near": (0.0, 0.0, -0.10),
    "high_far": (0.04, -0.08, 0.06),
}


def level_configuration(model: ArmModel, spec, p: np.ndarray, heading: float,
                        seeds: list[np.ndarray]) -> np.ndarray | None:
    """Arm joints putting the locked utensil's tip at ``p``, level, pointing as near
    ``heading`` as possible (15° steps), collision-free."""
    y = np.array([0.0, 0.0, 1.0])
    for dh in sorted(np.radians(np.arange(-90.0, 91.0, 15.0)), key=abs):
        z = np.array([np.cos(heading + dh), np.sin(heading + dh), 0.0])
        target = np.eye(4)
        target[:3, :3] = np.column_stack([np.cross(y, z), y, z])
        target[:3, 3] = p
        for q0 in seeds:
            q = solve_pose_ik(model, "tip", target, np.r_[q0, 0.0, 0.0], IKSettings(), free=6)
            if q is not None and not model.in_collision(q):
                return q[:6]
    return None


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--utensil", default="spoon")
    ap.add_argument("--check-planning", action="store_true")
    args = ap.parse_args()
    spec = load_spec()
    model = ArmModel(spec, utensil=args.utensil)
    seeds = [spec.arm.configuration(n) for n in spec.arm.configurations]
    # The common start: the locked utensil level at Resting's tip position.
    q_rest = np.r_[spec.arm.configuration("Resting"), 0.0, 0.0]
    T = model.tip_pose(q_rest)
    start = level_configuration(model, spec, T[:3, 3], float(np.arctan2(T[1, 2], T[0, 2])),
                                [spec.arm.configuration("Resting"), *seeds])
    assert start is not None, "no level start"
    q_st = np.r_[staging_configuration(spec, model, 0)[0], 0.0, 0.0]
    Ts = model.tip_pose(q_st)
    h = float(np.arctan2(Ts[1, 2], Ts[0, 2]))
    goals = {}
    for name, off in OFFSETS.items():
        q = level_configuration(model, spec, Ts[:3, 3] + np.asarray(off), h,
                                [q_st[:6], *seeds])
        if q is None:
            print(f"# {name}: no level configuration")
            continue
        goals[name] = q
    if args.check_planning:
        from articutool.planning.api import plan
        from articutool.planning.types import PlanRequest, TransportTask

        for name, q in goals.items():
            task = TransportTask(0, tuple(start), tuple(q))
            for planner, tol in (("decoupled", None), ("strict6", 20.0)):
                r = plan(PlanRequest(planner=planner, task=task, timeout_s=10.0, seed=0,
                                     tolerance_deg=tol, utensil=args.utensil), spec)
                print(f"# {name} {planner}: {'ok' if r.success else 'FAILED'} "
                      f"{r.planning_time_s:.2f} s {r.message}")
    fmt = ", ".join
    print("[staging_set]")
    print(f"start = [{fmt(f'{x:.5f}' for x in start)}]")
    for name, q in goals.items():
        p = model.tip_pose(np.r_[q, 0.0, 0.0])[:3, 3]
        print(f'\n[[staging_set.goals]]\nname = "{name}"\nq = [{fmt(f"{x:.5f}" for x in q)}]')
        print(f'note = "tip at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m"')


if __name__ == "__main__":
    main()
