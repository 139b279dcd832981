"""How often the food accounting's class of some item depends on the order and direction of
MuJoCo's contact pairs: random contact graphs of 3–13 items, each classified as
listed and again with its pairs shuffled and flipped.

    .venv/bin/python examples/accounting_order.py [--graphs 1500] [--seed 2026]

Run it against another checkout's ``src`` (``PYTHONPATH=<checkout>/src``) to compare code
versions.
"""

from __future__ import annotations

import argparse

import numpy as np

from articutool.sim import accounting as acc

SURFACES = np.array([acc.CONTAINER, acc.CONTAINER, acc.TABLE, acc.CRITICAL, acc.CRITICAL])


def changed(rng: np.random.Generator) -> bool:
    """One random graph: does shuffling and flipping its pairs change some item's class?"""
    n = int(rng.integers(3, 14))
    e = rng.integers(0, n, (int(rng.integers(1, 3 * n + 1)), 2))
    e = e[e[:, 0] != e[:, 1]] if (e[:, 0] != e[:, 1]).any() else np.array([[0, 1]])
    u = rng.integers(0, n, int(rng.integers(0, 4)))
    k = int(rng.integers(0, 5))
    s = np.column_stack([rng.integers(0, n, k), rng.integers(0, len(SURFACES), k)])
    rest = (np.full(n, acc.AIRBORNE), np.full(n, -1), np.zeros(n, dtype=bool))
    c1, _ = acc.classify_items(n, e, u, s, SURFACES, *rest)
    e2 = e[rng.permutation(len(e))]
    flip = rng.random(len(e2)) < 0.5
    e2[flip] = e2[flip][:, ::-1]
    c2, _ = acc.classify_items(n, e2, u, s, SURFACES, *rest)
    return not np.array_equal(c1, c2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--graphs", type=int, default=1500)
    ap.add_argument("--seed", type=int, default=2026)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    bad = sum(changed(rng) for _ in range(args.graphs))
    print(f"{bad} of {args.graphs} random graphs changed some item's class")


if __name__ == "__main__":
    main()
