"""Do the physics world's outcomes change with a speed change? Before/after over many seeds.

``run``: for each food and seed, the scripted acquisition (``articutool sim --food F --script
scoop``: settle, level, tare, the spoon's scoop or the fork's skewer, lift, level) and its
outcome: grams acquired (on the utensil), grams spilled (table + critical, each item once at
its worst place), grams in the container, and a SHA-256 fingerprint of the final physics
state (qpos, qvel, act, the items' classes). Run it once on the code before a change
(``PYTHONPATH=/tmp/old/src``) and once after.

``compare``: per food, whether the fingerprints are bit-identical seed by seed (a pure
restructuring must be), and otherwise whether the outcome distributions agree: Welch's t
test on acquired and on spilled grams (p < 0.05 = different), plus the largest per-seed
difference, against the seeds' spread (SD).

    PYTHONPATH=/tmp/old/src .venv/bin/python benchmarks/sim_outcomes.py run --seeds 10 \\
        --out /tmp/before.json
    PYTHONPATH=src .venv/bin/python benchmarks/sim_outcomes.py run --seeds 10 --out /tmp/after.json
    .venv/bin/python benchmarks/sim_outcomes.py compare /tmp/before.json /tmp/after.json \\
        --out results/sim_outcomes_speed.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np


def _fingerprint(world) -> str:
    d = world.data
    h = hashlib.sha256()
    for a in (d.qpos, d.qvel, d.act, world.ledger.item_classes()):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def run(foods: list[str], seeds: list[int]) -> dict:
    from articutool.sim import accounting as acc
    from articutool.sim.scenes import acquire
    from articutool.sim.world import FeedingWorld

    rows: dict[str, list[dict]] = {}
    for food in foods:
        for seed in seeds:
            c0, t0 = time.thread_time(), time.perf_counter()
            w = FeedingWorld.make(food, seed=seed)
            acquire(w, level=True)
            g = w.ledger.masses_g()
            spilled = acc.spilled_by_place(w.ledger.spills)
            r = {"seed": seed, "acquired_g": round(g["utensil"], 4),
                 "spilled_g": round(sum(spilled.values()), 4),
                 "container_g": round(g["container"], 4), "simulated_s": round(w.time, 3),
                 "cpu_s": round(time.thread_time() - c0, 2),
                 "wall_s": round(time.perf_counter() - t0, 2),
                 "realtime_factor": round(w.realtime_factor, 3),
                 "fingerprint": _fingerprint(w)}
            rows.setdefault(food, []).append(r)
            print(food, r, flush=True)
    return rows


def _welch(a: list[float], b: list[float]) -> dict:
    from scipy import stats

    if statistics.pstdev(a) == 0 and statistics.pstdev(b) == 0:
        p = 1.0 if statistics.mean(a) == statistics.mean(b) else 0.0
        t = 0.0 if p == 1.0 else float("inf")
    else:
        res = stats.ttest_ind(a, b, equal_var=False)
        t, p = float(res.statistic), float(res.pvalue)
    return {"mean_before": round(statistics.mean(a), 4), "mean_after": round(statistics.mean(b), 4),
            "sd_before": round(statistics.stdev(a), 4) if len(a) > 1 else 0.0,
            "sd_after": round(statistics.stdev(b), 4) if len(b) > 1 else 0.0,
            "welch_t": round(t, 3), "welch_p": round(p, 4),
            "max_per_seed_diff_g": round(max(abs(x - y) for x, y in zip(a, b, strict=True)), 4),
            "same": p >= 0.05}


def compare(before: dict, after: dict) -> dict:
    out = {}
    for food, rows_b in before["runs"].items():
        rows_a = {r["seed"]: r for r in after["runs"].get(food, [])}
        pairs = [(r, rows_a[r["seed"]]) for r in rows_b if r["seed"] in rows_a]
        if not pairs:
            continue
        res = {"seeds": [b["seed"] for b, _ in pairs],
               "bit_identical": all(b["fingerprint"] == a["fingerprint"] for b, a in pairs),
               "identical_seeds": sum(b["fingerprint"] == a["fingerprint"] for b, a in pairs)}
        for key in ("acquired_g", "spilled_g"):
            res[key] = _welch([b[key] for b, _ in pairs], [a[key] for _, a in pairs])
        rb = [b["realtime_factor"] for b, _ in pairs]
        ra = [a["realtime_factor"] for _, a in pairs]
        res["realtime_factor_median_before"] = statistics.median(rb)
        res["realtime_factor_median_after"] = statistics.median(ra)
        out[food] = res
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--foods", default="pecans,water,noodles")
    r.add_argument("--seeds", type=int, default=10)
    r.add_argument("--first-seed", type=int, default=0)
    r.add_argument("--out", required=True)
    c = sub.add_parser("compare")
    c.add_argument("before")
    c.add_argument("after")
    c.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    out = Path(args.out)
    if out.exists():
        print(f"--out {out} exists; not overwritten", file=sys.stderr)
        return 2
    if args.cmd == "run":
        seeds = list(range(args.first_seed, args.first_seed + args.seeds))
        import articutool
        from articutool.experiments.runner import source_version
        src = Path(articutool.__file__).resolve().parent
        doc = {"code": str(src), "git_head": source_version(), "loadavg_start": os.getloadavg(),
               "runs": run(args.foods.split(","), seeds), "loadavg_end": os.getloadavg()}
    else:
        a, b = (json.loads(Path(p).read_text()) for p in (args.before, args.after))
        doc = {"before": {"file": args.before, "code": a.get("code"),
                          "git_head": a.get("git_head")},
               "after": {"file": args.after, "code": b.get("code"),
                         "git_head": b.get("git_head")},
               "test": "per food: fingerprints of the final state seed by seed; Welch's t on "
                       "acquired and spilled grams (same = p >= 0.05), max per-seed difference",
               "foods": compare(a, b)}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
