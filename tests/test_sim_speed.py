"""Speed changes of the feeding world that must not change what it computes.

A settled pile restored from a :class:`SettleCache` is the state a fresh settle makes, to the
bit, and so is everything after it; a world built without a cache settles afresh.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from articutool.sim.params import PhysicsParams  # noqa: E402
from articutool.sim.world import FeedingWorld, SettleCache  # noqa: E402
from articutool.tool.api import Mode  # noqa: E402


def _state(w: FeedingWorld) -> bytes:
    d = w.data
    parts = [d.qpos, d.qvel, d.act, d.qacc_warmstart, d.ctrl, np.array([d.time]),
             d.tree_asleep, d.body_awake, w.ledger.item_classes()]
    return b"".join(np.ascontiguousarray(a).tobytes() for a in parts)


def _scene(w: FeedingWorld) -> tuple:
    """A short scene that moves the food: tilt the locked spoon with the TILT primitive."""
    w.tool.set_mode(Mode.DISABLED)
    ok, msg = w.tool.start_primitive("TILT", [math.radians(60.0), 1.0, 0.2])
    assert ok, msg
    w.run(1.0)
    r = w.report()
    return _state(w), r.masses_g, len(r.spills)


def _grains_params() -> PhysicsParams:
    """The packaged physics with water's bowl as MuJoCo's 4 mm grains (the bowl's SPH liquid
    is not MuJoCo's and settles apart: sim/bowl_liquid.py)."""
    params = PhysicsParams.load()
    grains = params.food("water").model_copy(update={"load_model": "spheres"})
    return params.model_copy(update={"foods": {**params.foods, "water": grains}})


@pytest.mark.parametrize("food,seed", [("pecans", 11), ("water", 12)])
def test_a_restored_settle_is_bit_identical_to_a_fresh_one(food: str, seed: int) -> None:
    cache, p = SettleCache(), _grains_params()
    fresh = FeedingWorld.make(food, seed=seed, settle_cache=cache, params=p)
    restored = FeedingWorld.make(food, seed=seed, settle_cache=cache, params=p)
    alone = FeedingWorld.make(food, seed=seed, params=p)  # no cache: settles afresh
    # The second world did not settle: it stepped only what follows the settle.
    assert restored._sim_stepped < fresh._sim_stepped - 0.9 * fresh.params.world.settle_s
    assert alone._sim_stepped == pytest.approx(fresh._sim_stepped)
    assert _state(restored) == _state(fresh) == _state(alone)
    assert _scene(restored) == _scene(fresh) == _scene(alone)


def test_another_seed_or_start_is_settled_afresh() -> None:
    """The cache's key holds the seed and the start (on the bowl of water as MuJoCo's grains,
    which settle in about half the pecans' CPU time; the key is the same for every food)."""
    params = _grains_params()
    cache = SettleCache()
    a = FeedingWorld.make("water", seed=11, settle_cache=cache, params=params)
    b = FeedingWorld.make("water", seed=13, settle_cache=cache, params=params)
    c = FeedingWorld.make("water", seed=11, q_wrist=(0.1, 0.0), settle_cache=cache,
                          params=params)
    settle = a.params.world.settle_s
    assert b._sim_stepped >= a._sim_stepped - 1e-9 and c._sim_stepped >= a._sim_stepped - 1e-9
    assert a._sim_stepped > settle
    assert _state(a) != _state(b) and _state(a) != _state(c)
    assert len(cache) == 3


def test_a_settle_cache_keeps_the_most_recently_used_states() -> None:
    cache = SettleCache(keep=2)
    state = (None, np.zeros(1), 0.0, 0)
    for k in ("a", "b"):
        cache.put(k, state)  # type: ignore[arg-type]
    assert cache.take("a") is state
    cache.put("a", state)  # type: ignore[arg-type]  # used last: "b" is now the oldest
    cache.put("c", state)  # type: ignore[arg-type]
    assert cache.take("b") is None and len(cache) == 2
    with pytest.raises(ValueError, match="keep"):
        SettleCache(keep=0)


def _drive(w: FeedingWorld, stepwise: bool) -> bytes:
    """Level, then swing the arm (a motion that ends halfway through) and run 1.2 s, either
    with ``run`` (batches between ticks) or one ``step`` at a time."""
    w.tool.set_mode(Mode.LEVELING)
    q = w.arm_q.copy()
    q[0] += 0.15
    w.move_arm(q, duration=0.6, wait=False)
    if stepwise:
        for _ in range(round(1.2 / w.dt)):
            w.step()
    else:
        w.run(1.2)
    return _state(w) + np.array([w.arm_tracking_error, *w.tool.state().orientation_wxyz]).tobytes()


def test_stepping_in_batches_between_ticks_is_bit_identical_to_single_steps() -> None:
    a = FeedingWorld.make("pecans", seed=14)
    b = FeedingWorld.make("pecans", seed=14)
    assert _drive(a, stepwise=False) == _drive(b, stepwise=True)
    assert not a.arm_busy and a.arm_tracking_error > 0
