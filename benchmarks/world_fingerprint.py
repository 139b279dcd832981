"""Does a change to the feeding world's code change what it computes? Fingerprints per seed.

For each food and seed it builds worlds and drives them through every path of the world's
API: a world on its filled container (settle, level, a short arm swing, the locked spoon tilted
with the TILT primitive, the user eating what is on the utensil); a world with a load placed by
hand (placement, the F/T reading, a second tare, the experimenter's scale); for the first seed
a world restored from a :class:`~articutool.sim.world.SettleCache`. Each scenario's final state
(qpos, qvel, act, the solver's warm start, controls, time, the items' classes, the ledger's
masses and spills, the tool's state, every reading) is hashed with SHA-256.

``run`` writes the fingerprints; ``compare`` says whether two runs are bit-identical, scenario
by scenario. A pure restructuring must be: run it on the code before (``PYTHONPATH=/tmp/old/src``)
and after, then compare.

    PYTHONPATH=src .venv/bin/python benchmarks/world_fingerprint.py run --seeds 10 \\
        --out /tmp/after.json
    .venv/bin/python benchmarks/world_fingerprint.py compare /tmp/before.json /tmp/after.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

# The load each food's hand-placed scenario places (g): within both utensils' capacity.
LOADS_G = {"pecans": 3.0, "water": 6.0}


def _build(food: str | None, **kw: Any) -> Any:
    from articutool.sim.world import FeedingWorld

    # The keyword factory is ``make`` (``build`` takes a ``WorldConfig``); older checkouts
    # build with keywords through ``build`` or the constructor: all are fingerprinted.
    make = getattr(FeedingWorld, "make", None) or getattr(FeedingWorld, "build", FeedingWorld)
    return make(food, **kw)


def _fingerprint(w: Any, extra: Any) -> str:
    """SHA-256 of the world's physics, ledger and tool state plus ``extra`` (JSON-able)."""
    d = w.data
    h = hashlib.sha256()
    for a in (d.qpos, d.qvel, d.act, d.qacc_warmstart, d.ctrl, np.array([d.time]),
              w.ledger.item_classes(), np.array([w.arm_tracking_error])):
        h.update(np.ascontiguousarray(a).tobytes())
    st = w.tool.state()
    tool = (st.stamp, st.mode.name, st.position, st.velocity, st.orientation_wxyz,
            st.angular_velocity, st.linear_acceleration, st.fault)
    ledger = (w.ledger.masses_g(), [asdict(s) for s in w.ledger.spills])
    h.update(repr((tool, ledger, extra)).encode())
    return h.hexdigest()


def _report(w: Any, measure_ft: bool = False) -> dict[str, Any]:
    out = w.report(measure_ft).to_dict()
    out.pop("realtime_factor")  # CPU time: not the world's physics
    return out


def bowl(food: str, seed: int, cache: Any = None) -> str:
    """The food settled in its container; level, swing the arm, tilt the locked spoon, eat."""
    from articutool.tool.api import Mode

    w = _build(food, seed=seed, settle_cache=cache)
    built = _report(w, measure_ft=True)
    w.tool.set_mode(Mode.LEVELING)
    q = w.arm_q.copy()
    q[0] += 0.15
    w.move_arm(q, duration=0.6, wait=False)
    w.run(1.2)
    w.tool.set_mode(Mode.DISABLED)
    ok, msg = w.tool.start_primitive("TILT", [math.radians(60.0), 1.0, 0.2])
    assert ok, msg
    w.run(1.0)
    tilted = _report(w)
    eaten = w.ledger.eat_from_utensil()
    w.run(0.2)
    return _fingerprint(w, (built, tilted, eaten, _report(w), w.tilt_deg(),
                            w.tool_base_tilt_deg(), w.tip_pose().tolist()))


def loaded(food: str, seed: int) -> str:
    """A load placed by hand on the tared utensil, weighed by the F/T sensor and a scale."""
    w = _build(food, seed=seed, load_g=LOADS_G[food], mouth=False)
    placed = w.placement.place()
    wg = w.weighing
    readings = (placed, wg.comparable(), wg.ft_mass_g(), wg.utensil_mass_g(), wg.carried_g(),
                _report(w, measure_ft=True))
    w.weighing.tare(0.1)
    return _fingerprint(w, (readings, w.weighing.ft_mass_g(0.2), w.ledger.item_g.tolist()))


def run(foods: list[str], seeds: list[int], noodles: bool) -> dict[str, str]:
    from articutool.sim.world import SettleCache

    rows: dict[str, str] = {}

    def note(key: str, fn: Any, *args: Any) -> None:
        c0 = time.thread_time()
        rows[key] = fn(*args)
        print(f"{key}: {rows[key][:16]} ({time.thread_time() - c0:.1f} CPU s)", flush=True)

    for food in foods:
        for seed in seeds:
            note(f"{food}/{seed}/bowl", bowl, food, seed)
            note(f"{food}/{seed}/loaded", loaded, food, seed)
        cache = SettleCache()
        note(f"{food}/{seeds[0]}/bowl-cached-fresh", bowl, food, seeds[0], cache)
        note(f"{food}/{seeds[0]}/bowl-cached-restored", bowl, food, seeds[0], cache)
    if noodles:
        def noodle() -> str:
            w = _build("noodles", seed=5100, settle=False)
            w.run(0.3)
            return _fingerprint(w, _report(w))
        note("noodles/5100/unsettled", noodle)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--foods", default="pecans,water")
    r.add_argument("--seeds", type=int, default=10)
    r.add_argument("--noodles", action="store_true", help="also one short unsettled noodle world")
    r.add_argument("--out", required=True)
    c = sub.add_parser("compare")
    c.add_argument("before")
    c.add_argument("after")
    args = ap.parse_args(argv)
    if args.cmd == "run":
        out = Path(args.out)
        if out.exists():
            print(f"--out {out} exists; not overwritten", file=sys.stderr)
            return 2
        rows = run(args.foods.split(","), list(range(args.seeds)), args.noodles)
        out.write_text(json.dumps(rows, indent=1) + "\n")
        return 0
    a, b = (json.loads(Path(p).read_text()) for p in (args.before, args.after))
    differ = sorted(k for k in a.keys() | b.keys() if a.get(k) != b.get(k))
    print(f"{len(a.keys() & b.keys()) - len(set(differ) & a.keys() & b.keys())} of "
          f"{len(a.keys() | b.keys())} scenarios bit-identical")
    for k in differ:
        print(f"  differs: {k}")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
