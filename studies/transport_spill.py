"""Spilled water vs transport duration for three wrists on the same arm paths, and how well
the food check predicts it.

On the Exp. 2b paths (the scene's ``[staging_set]``: the common start to each goal), 8 g of
water placed on the soup spoon is carried by

- ``locked``: the strict ±20° plan with the wrist locked (the baseline);
- ``leveling``: the decoupled plan with the wrist's IMU loop leveling to gravity;
- ``slosh_free``: the same decoupled plan with the slosh-free wrist trajectory (the dish square
  to g − a of the planned motion) followed in TRAJECTORY mode, then LEVELING again
  (plain leveling where the tool would refuse the trajectory: recorded).

Each path is planned once (seed ``SEED0 + goal index``) and timed by TOPP-RA at ``scale`` × the
arm's velocity limits and ``scale²`` × its acceleration limits, slow to fast; scales above 1
exceed the Jaco's spec limits (the physics world's servos follow them; a what-if of a faster
arm, stated). Every trial also records the food check's prediction for the motion it
executes. Seeds ``SEED0 + k`` are disjoint from every experiment seed (``1000·S + r``).

    .venv/bin/python studies/transport_spill.py --out studies/results/transport_spill.json
    .venv/bin/python studies/transport_spill.py --plot studies/results/transport_spill.json \
        --figure docs/transport_spill.png

The JSON is rewritten after every trial (a long run can be stopped and resumed: trials
already in it are kept). CPU time per trial is the process's.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

SEED0 = 9_700_000
SPILL_G = 0.05  # g: a trial "spills" above this (the particle water's grains are 0.01-0.4 g)
# The simulated spill is what left the utensil during the transport and the settling after it
# (``lost_g``); ``simulated_spill_g`` also counts grains that fell off while the load was
# placed and landed later, which the transport did not spill.
CONDITIONS = ("locked", "leveling", "slosh_free")


def _plans(goals: list[tuple[int, Any]], start: np.ndarray,
           spec: Any) -> dict[tuple[str, str], Any]:
    """One decoupled and one strict ±20° plan per (index in the staging set, goal): the paths
    every scale re-times."""
    from articutool.planning.api import plan
    from articutool.planning.types import PlanRequest, TransportTask

    out = {}
    for i, g in goals:
        for planner, tol in (("decoupled", None), ("strict6", 20.0)):
            req = PlanRequest(planner=planner, task=TransportTask(i, tuple(start), tuple(g.q)),
                              timeout_s=30.0, seed=SEED0 + i, tolerance_deg=tol,
                              utensil="soup_spoon")
            r = plan(req, spec)
            if not r.success or r.trajectory is None:
                print(f"  {g.name} {planner}: no plan ({r.message})", flush=True)
                continue
            out[(g.name, planner)] = r.trajectory
    return out


def _params(physics: str | None, radius: float | None) -> Any:
    """The physics parameters: a file (default the packaged one), the water's particle
    radius replaced by ``radius`` (m) if given."""
    from articutool.sim.params import PhysicsParams

    params = PhysicsParams.load(physics)
    if radius is None:
        return params
    water = params.foods["water"].model_copy(update={"particle_radius": radius})
    return params.model_copy(update={"foods": {**params.foods, "water": water}})


def _trial(goal: str, cond: str, scale: float, path: Any, seed: int, load_g: float,
           start: np.ndarray, physics: str | None = None,
           radius: float | None = None) -> dict[str, Any]:
    from articutool.arm.model import ArmModel
    from articutool.arm.scene import Scene
    from articutool.food.loads import food_load
    from articutool.planning.timing import time_parameterize
    from articutool.sim import accounting as acc
    from articutool.sim.world import FeedingWorld
    from articutool.tool.api import Mode
    from articutool.verify.food import food_check, slosh_free_wrist
    from articutool.verify.verifier import verify_trajectory

    cpu0 = time.process_time()
    # No mouth region: the experimenter weighs the spoon at the goal, nobody eats from it.
    scene = Scene.load()
    scene = scene.model_copy(update={"regions": [r for r in scene.regions if r.name != "mouth"]})
    w = FeedingWorld.make("water", "soup_spoon", seed=seed, load_g=load_g, q_arm=start,
                           scene=scene, params=_params(physics, radius))
    spec = w.spec
    model = ArmModel(spec, "soup_spoon", 8, w.scene)
    arm = time_parameterize(path.positions[:, :6], tuple(spec.arm.joint_names),
                            spec.arm.max_velocity * scale,
                            spec.arm.max_acceleration * scale * scale)
    if arm is None:
        return {"goal": goal, "condition": cond, "scale": scale, "error": "no timing"}
    row: dict[str, Any] = {"goal": goal, "condition": cond, "scale": scale, "seed": seed}
    wrist_mode = Mode.DISABLED if cond == "locked" else Mode.LEVELING
    w.tool.set_mode(wrist_mode)
    w.run(1.0)
    held = w.placement.place(settle_s=1.0)
    load = food_load(w.params.definition("water"), held)
    before, n_spills = w.ledger.masses_g(), len(w.ledger.spills)
    executed, wrist_pred, used = arm, None, cond
    if cond == "locked":
        wrist_pred = np.asarray(w.wrist_q, dtype=float)
    else:
        # Above scale 1 the arm outruns the Jaco's spec; the leveling is verified against an
        # arm as much faster (the what-if), the wrist's own limits unchanged.
        fast = spec if scale <= 1.0 else spec.model_copy(update={"arm": spec.arm.model_copy(
            update={"joints": [j.model_copy(update={"max_velocity": j.max_velocity * scale})
                               for j in spec.arm.joints]})})
        rep = verify_trajectory(arm, model, fast, q_wrist_start=w.wrist_q)
        row["verified"] = rep.reason
        if not rep.feasible or rep.wrist_trajectory is None:
            row["error"] = f"the wrist cannot level it: {rep.message}"
            return row
        wrist_pred = rep.wrist_trajectory
        if cond == "slosh_free":
            sf = slosh_free_wrist(arm, model, spec, "soup_spoon", q_wrist_start=w.wrist_q,
                                  height=0.005)
            if sf.ok:
                executed, wrist_pred = sf.arm, sf.wrist
                row["sigma_s"] = sf.sigma_s
            else:
                used = "leveling"
                row["fallback"] = sf.message
    tilts: list[float] = []
    w.on_tick.append(lambda ww: tilts.append(ww.tilt_deg()))
    if used == "slosh_free":
        ok, msg = w.tool.follow_trajectory(wrist_pred)
        if not ok:
            row["refused"] = msg
    w.follow_arm(executed, wait=False)
    w.run(executed.duration)
    if used == "slosh_free":
        w.tool.set_mode(Mode.LEVELING)  # the IMU loop takes over after the motion
    w.run(1.5)
    spilled = acc.spilled_by_place(w.ledger.spills, n_spills)
    pred = food_check(executed, wrist_pred, model, spec, "soup_spoon", load,
                      "locked" if cond == "locked" else used).prediction
    row.update({
        "wrist_used": used, "duration_s": round(executed.duration, 3),
        "held_g": round(held, 4), "simulated_spill_g": round(sum(spilled.values()), 4),
        "spilled_by_place": {k: round(v, 4) for k, v in spilled.items()},
        "on_utensil_after_g": round(w.ledger.masses_g()["utensil"], 4),
        "lost_g": round(before["utensil"] - w.ledger.masses_g()["utensil"], 4),
        "max_tilt_deg": round(max(tilts), 3) if tilts else None,
        "predicted_spill_g": round(pred.spilled_g, 4),
        "predicted_peak_apparent_tilt_deg": round(pred.peak_apparent_tilt_deg, 3),
        "predicted_peak_surface_tilt_deg": round(pred.peak_surface_tilt_deg, 3),
        "predicted_min_margin_deg": round(pred.min_margin_deg, 3),
        "cpu_s": round(time.process_time() - cpu0, 2),
        "realtime_factor": round(w.realtime_factor, 3),
    })
    return row


def _summary(trials: list[dict[str, Any]]) -> dict[str, Any]:
    ok = [t for t in trials if "error" not in t]
    by: dict[str, Any] = {}
    for cond in CONDITIONS:
        rows = [t for t in ok if t["condition"] == cond]
        scales = sorted({t["scale"] for t in rows})
        by[cond] = {str(s): {
            "trials": len(r := [t for t in rows if t["scale"] == s]),
            "mean_duration_s": round(statistics.mean(t["duration_s"] for t in r), 3),
            "mean_simulated_spill_g": round(statistics.mean(t["lost_g"] for t in r), 4),
            "mean_predicted_spill_g": round(statistics.mean(t["predicted_spill_g"] for t in r), 4),
            "spilled_trials": sum(t["lost_g"] > SPILL_G for t in r)}
            for s in scales}
    # the fastest scale at which every goal's transport spilled nothing, per condition, in the
    # particle world and by the prediction
    fastest, predicted = {}, {}
    for cond in CONDITIONS:
        clean = [s for s, v in by[cond].items() if v["spilled_trials"] == 0 and v["trials"]]
        fastest[cond] = max((float(s) for s in clean), default=None)
        rows = [t for t in ok if t["condition"] == cond]
        scales = sorted({t["scale"] for t in rows})
        dry = [s for s in scales if all(t["predicted_spill_g"] <= SPILL_G
                                        for t in rows if t["scale"] == s)]
        predicted[cond] = max(dry, default=None)
    agree = [(t["predicted_spill_g"] > SPILL_G) == (t["lost_g"] > SPILL_G) for t in ok]
    err = [t["predicted_spill_g"] - t["lost_g"] for t in ok]
    lev, sf = fastest.get("leveling"), fastest.get("slosh_free")
    plev, psf = predicted.get("leveling"), predicted.get("slosh_free")
    return {
        "by_condition_and_scale": by,
        "fastest_spill_free_scale": fastest,
        "slosh_free_speedup_vs_leveling": (round(sf / lev, 3) if sf and lev else None),
        "fastest_predicted_spill_free_scale": predicted,
        "predicted_slosh_free_speedup_vs_leveling": (round(psf / plev, 3) if psf and plev
                                                     else None),
        "prediction": {
            "trials": len(ok),
            "spill_threshold_g": SPILL_G,
            "sign_agreement": round(sum(agree) / len(agree), 4) if agree else None,
            "mean_error_g": round(statistics.mean(err), 4) if err else None,
            "mean_abs_error_g": round(statistics.mean(abs(e) for e in err), 4) if err else None,
        },
    }


def plot(path: Path, figure: Path) -> None:
    """Grams spilled vs transport duration, one curve per wrist (mean over goals)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    doc = json.loads(path.read_text())
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    labels = {"locked": "locked wrist (strict ±20° plan)", "leveling": "leveling to g",
              "slosh_free": "slosh-free leveling (g − a)"}
    for cond in CONDITIONS:
        rows = doc["summary"]["by_condition_and_scale"].get(cond, {})
        if not rows:
            continue
        pts = sorted((v["mean_duration_s"], v["mean_simulated_spill_g"],
                      v["mean_predicted_spill_g"]) for v in rows.values())
        d, sim, pred = zip(*pts, strict=True)
        line, = ax.plot(d, sim, "o-", label=f"{labels[cond]}: simulated")
        ax.plot(d, pred, "x--", color=line.get_color(), alpha=0.7, label="… predicted")
    ax.set_xlabel("transport duration (s, mean over the Exp. 2b goals)")
    ax.set_ylabel("water spilled (g of 8 g)")
    ax.set_title(doc.get("water", "")[:80], fontsize=8)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    figure.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(figure, dpi=120)
    print(f"wrote {figure}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="studies/results/transport_spill.json")
    ap.add_argument("--scales", default="0.5,0.75,1.0,1.5,2.0")
    ap.add_argument("--goals", default="", help="comma-separated goal names (default all)")
    ap.add_argument("--conditions", default=",".join(CONDITIONS))
    ap.add_argument("--load-g", type=float, default=8.0)
    ap.add_argument("--water", default="the packaged physics.toml's water",
                    help="what water this run used (recorded in the JSON)")
    ap.add_argument("--physics", metavar="TOML", default=None,
                    help="physics parameters (default: the packaged physics.toml)")
    ap.add_argument("--particle-radius", type=float, default=None,
                    help="replace the water's particle radius (m), e.g. 0.00125")
    ap.add_argument("--plot", metavar="JSON", default=None)
    ap.add_argument("--figure", default="docs/transport_spill.png")
    args = ap.parse_args()
    if args.plot:
        plot(Path(args.plot), Path(args.figure))
        return
    from articutool.arm.scene import Scene
    from articutool.experiments.runner import source_version
    from articutool.spec import load_spec

    spec = load_spec()
    sset = Scene.load().staging_set
    # A goal keeps its index in the staging set (its seeds) when --goals picks a subset.
    goals = [(i, g) for i, g in enumerate(sset.goals)
             if not args.goals or g.name in args.goals.split(",")]
    start = np.asarray(sset.start, dtype=float)
    out = Path(args.out)
    doc: dict[str, Any] = json.loads(out.read_text()) if out.exists() else {}
    trials = doc.get("trials", [])
    done = {(t["goal"], t["condition"], t["scale"]) for t in trials}
    source = source_version()
    if trials and doc.get("source", source) != source:
        # One file holds one code's trials: "source" names the code of every trial in it.
        ap.exit(2, f"error: --out: {out} holds trials of code {doc['source']}; this is "
                   f"{source}: write a new file\n")
    doc.update({"water": args.water, "physics": args.physics or "packaged",
                "particle_radius_override": args.particle_radius,
                "load_g": args.load_g, "seed0": SEED0,
                "command": " ".join(sys.argv), "source": source,
                "loadavg_start": os.getloadavg()})
    plans = _plans(goals, start, spec)
    for gi, g in goals:
        for cond in args.conditions.split(","):
            planner = "strict6" if cond == "locked" else "decoupled"
            if (g.name, planner) not in plans:
                continue
            for scale in (float(s) for s in args.scales.split(",")):
                if (g.name, cond, scale) in done:
                    continue
                row = _trial(g.name, cond, scale, plans[(g.name, planner)], SEED0 + 100 * gi
                             + round(10 * scale), args.load_g, start, args.physics,
                             args.particle_radius)
                print(json.dumps(row), flush=True)
                trials.append(row)
                doc["trials"] = trials
                doc["summary"] = _summary(trials)
                out.parent.mkdir(parents=True, exist_ok=True)
                out.write_text(json.dumps(doc, indent=1) + "\n")
    doc["loadavg_end"] = os.getloadavg()
    out.write_text(json.dumps(doc, indent=1) + "\n")
    print(json.dumps(doc.get("summary", {}), indent=1))


if __name__ == "__main__":
    main()
