"""Where a system's planning CPU time goes, by function, over a task set (cProfile, CPU clock).

Plans the first ``--limit`` tasks of the packaged Exp. 2a set (or ``--tasks FILE``) with one
system twice in this process: once plain, for the CPU time per plan (``time.process_time``;
medians), and once under cProfile with the CPU clock, for the inclusive CPU time of the
functions that make up a plan — the OMPL search (its validity callbacks, each one function
with the leveling IK or the band and one collision call; the straight-motion check), the
collision checks outside the callbacks (coal through Pinocchio), toppra's time
parameterisation (its solver passes), the dense re-check and verification. Shares are of the
profiled total; cProfile charges each Python call a little, so the Python-heavy parts read
larger than they are (compare ``profiled_cpu_total_s`` with ``profiled_plain_cpu_s``).
``--middle`` profiles only the plans about the median. Also the CPU cost of
one collision check of the executed 8-DOF model, called three ways, and the plain CPU of each
piece of the ten single-attempt plans nearest the median, each piece run warm ten times
(``pieces_about_median``).

    .venv/bin/python benchmarks/plan_profile.py --system decoupled --limit 88 --out FILE
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from pathlib import Path

from articutool.planning.types import PLANNERS, PlanRequest
from plan_breakdown import emit, selected_tasks

# (label, (module path suffix, function name) ...): inclusive CPU time, summed.
PARTS = (
    ("search: OMPL query incl. its checks", (("planning/ompl_planner.py", "solve"),)),
    ("search: straight-motion check", (("planning/ompl_planner.py", "straight_motion_valid"),)),
    ("search: OMPL validity callbacks (leveling IK or band, one collision call each)",
     (("planning/ompl_planner.py", "checker"),)),
    ("collision checks outside the callbacks", (("planning/queries.py", "collides"),
                                                ("arm/model.py", "collisions"))),
    ("timing: toppra + wrist-rate constraint", (("planning/timing.py", "time_parameterize"),)),
    # toppra_speeds, or toppra's own TOPPRA loop where a tree runs that
    ("timing: toppra's solver passes", (("planning/timing.py", "toppra_speeds"),
                                        ("reachability_algorithm.py",
                                         "compute_parameterization"))),
    ("timing: wrist-rate constraint", (("planning/ompl_planner.py", "sdot_max"),)),
    ("recheck: dense re-check", (("planning/ompl_planner.py", "check_trajectory"),)),
    ("verify: verify_trajectory", (("verify/verifier.py", "verify_trajectory"),)),
    ("setup: problem + endpoint checks", (("planning/ompl_planner.py", "__post_init__"),
                                          ("planning/ompl_planner.py", "endpoint_problem"))),
)


def _inclusive(stats: pstats.Stats, targets: tuple[tuple[str, str], ...]) -> float:
    total = 0.0
    for (path, _line, name), (_cc, _nc, _tt, ct, _callers) in stats.stats.items():  # type: ignore[attr-defined]
        if any(path.endswith(p) and name == f for p, f in targets):
            total += ct
    return total


def _collision_cost(spec, tasks) -> dict[str, float]:
    """CPU µs per collision check of the executed 8-DOF model at the tasks' start and goal
    configurations (wrist level at zero): one Python call per configuration through the
    overloaded ``computeCollisions``, the planner's batch-of-one call, and a batch call."""
    import numpy as np
    import pinocchio as pin

    from articutool.arm.model import TOOL_BASE_FRAME, ArmModel
    from articutool.planning.queries import ArmQueries

    model = ArmModel(spec, dof=8)
    kin = ArmQueries(model, TOOL_BASE_FRAME)
    q = np.array([list(t.start) + [0.0, 0.0] for t in tasks]
                 + [list(t.goal) + [0.0, 0.0] for t in tasks])
    reps = max(1, 4000 // len(q))

    def per_check(f) -> float:
        c0 = time.process_time()
        for _ in range(reps):
            f()
        return round((time.process_time() - c0) / (reps * len(q)) * 1e6, 2)

    m, d, bp = model.model, model.data, model.broadphase
    return {
        "python_call_per_configuration_us": per_check(
            lambda: [pin.computeCollisions(m, d, bp, x, True) for x in q]),
        "planner_batch_of_one_us": per_check(lambda: [kin.collides(x) for x in q]),
        "batch_call_us": per_check(lambda: model.collisions(q)),
    }


def _pieces(spec, requests: list[PlanRequest], cpu: list[float], count: int = 10,
            reps: int = 10) -> dict:
    """Plain CPU (ms, no profiler) of each piece of the ``count`` solved plans nearest the
    median, each piece run ``reps`` times warm (median per plan, then median over the plans):
    the whole plan, the problem and endpoint checks, the search (the straight-motion check,
    or OMPL's search and simplification), time parameterisation, the dense re-check and its
    collision calls alone, verification."""
    import numpy as np

    from articutool.planning.ompl_planner import (
        PlannerSettings,
        _Phases,
        _Problem,
        _seed,
        plan_transport,
    )
    from articutool.planning.queries import dense_times
    from articutool.planning.timing import time_parameterize
    from articutool.verify.verifier import verify_trajectory

    order = sorted(range(len(requests)), key=lambda k: abs(cpu[k] - float(np.median(cpu))))
    rows: dict[str, list[float]] = {}
    ids = []
    settings = PlannerSettings()
    for k in order:
        if len(ids) == count:
            break
        req = requests[k]
        r = plan_transport(req, spec)
        if not r.success or r.attempts != 1:
            continue
        ids.append(req.task.task_id)
        traj, wt = r.trajectory, r.wrist_trajectory
        prob = _Problem(req, spec, settings, "rejection")
        waypoints, _ = prob.solve(_seed(req.seed, 1), req.timeout_s, _Phases())
        assert waypoints is not None
        names = tuple(prob.model.joint_names)
        vmax, amax = prob.model.velocity_limits, spec.arm.max_acceleration
        if prob.strict8:
            amax = np.concatenate([amax, np.full(2, amax.max())])
        sdot = prob.sdot_limit() if req.planner == "decoupled" else None
        t = dense_times(traj, settings.check_step)
        q = traj.sample(t)[0]
        kin = prob.kin
        if wt is not None:
            q, kin = np.hstack([q, wt.sample(t)[0]]), prob.executed

        def setup(req: PlanRequest = req) -> None:
            _Problem(req, spec, settings, "rejection").endpoint_problem()

        pieces = {
            "plan": lambda req=req: plan_transport(req, spec),
            "setup": setup,
            "search": lambda req=req, prob=prob: prob.solve(_seed(req.seed, 1), req.timeout_s,
                                                            _Phases()),
            "timing": lambda w=waypoints, v=vmax, a=amax, sd=sdot, n=names: time_parameterize(
                w, n, v, a, sdot_max=sd, grid_step=settings.toppra_grid),
            "recheck": lambda prob=prob, traj=traj, wt=wt: prob.check_trajectory(traj, wrist=wt),
            "recheck_collisions": lambda kin=kin, q=q: kin.first_collision(q),
        }
        if wt is not None:
            pieces["verify"] = lambda traj=traj, prob=prob, req=req: verify_trajectory(
                traj, prob.model, spec, q_wrist_start=req.task.start_wrist)
        for name, f in pieces.items():
            times = []
            for _ in range(reps):
                c0 = time.process_time()
                f()
                times.append(time.process_time() - c0)
            rows.setdefault(name, []).append(float(np.median(times)) * 1e3)
    return {"tasks": ids, "reps": reps,
            "median_ms": {k: round(float(np.median(v)), 3) for k, v in rows.items()},
            "mean_ms": {k: round(float(np.mean(v)), 3) for k, v in rows.items()}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tasks", metavar="FILE", default=None, help="task file (default: packaged)")
    ap.add_argument("--system", default="decoupled", help=f"one of {', '.join(PLANNERS)}")
    ap.add_argument("--limit", type=int, default=None, help="only the first N tasks")
    ap.add_argument("--timeout", type=float, default=60.0, help="per plan, s (default 60)")
    ap.add_argument("--middle", action="store_true",
                    help="profile only the middle half of the tasks by plain CPU time (the "
                         "plans about the median; the tail is a few long searches)")
    ap.add_argument("--top", type=int, default=15, help="functions listed by own CPU time")
    ap.add_argument("--out", metavar="FILE", default=None, help="also write the JSON here")
    args = ap.parse_args(argv)
    tasks, bad = selected_tasks(args.tasks, args.limit, args.timeout, [args.system],
                                "--system")
    if bad:
        print(bad, file=sys.stderr)
        return 2
    import numpy as np  # the planner and the statistics: once the options are good

    from articutool.planning.ompl_planner import plan_transport
    from articutool.spec import load_spec

    spec = load_spec()
    requests = [PlanRequest(args.system, t, timeout_s=args.timeout) for t in tasks]
    plan_transport(requests[0], spec)  # models built and cached outside the figures
    cpu = []
    for req in requests:
        c0 = time.process_time()
        plan_transport(req, spec)
        cpu.append(time.process_time() - c0)
    profiled = requests
    if args.middle:
        lo, hi = np.percentile(cpu, [25, 75])
        profiled = [r for r, c in zip(requests, cpu, strict=True) if lo <= c <= hi]
    prof = cProfile.Profile(time.process_time)
    prof.enable()
    for req in profiled:
        plan_transport(req, spec)
    prof.disable()
    stats = pstats.Stats(prof)
    total = _inclusive(stats, (("planning/ompl_planner.py", "plan_transport"),))
    parts = {}
    for label, targets in PARTS:
        ct = _inclusive(stats, targets)
        parts[label] = {"cpu_s": round(ct, 4), "share": round(ct / total, 3)}
    own = sorted(stats.stats.items(), key=lambda kv: -kv[1][2])[: args.top]  # type: ignore[attr-defined]
    out = {
        "system": args.system, "tasks": len(tasks), "clock": "process CPU (time.process_time)",
        "plain_cpu_median_ms": round(float(np.median(cpu)) * 1e3, 3),
        "profiled_tasks": [r.task.task_id for r in profiled],
        "profiled_plain_cpu_s": round(sum(c for r, c in zip(requests, cpu, strict=True)
                                          if r in profiled), 3),
        "profiled_cpu_total_s": round(total, 3),
        "parts": parts,
        "collision_check_cpu": _collision_cost(spec, tasks),
        "pieces_about_median": _pieces(spec, requests, cpu),
        "top_own_time": [{"function": f"{Path(k[0]).name}:{k[1]}({k[2]})", "calls": v[1],
                          "own_cpu_s": round(v[2], 4)} for k, v in own],
    }
    emit(out, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
