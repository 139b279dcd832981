"""A run of the shared trial runner (``run_logged``) on a real executor whose trials after
the first ``QUICK`` never end on their own, for tests/test_run_interrupt.py: it shows that an
interrupted run stops although trials are still running, and logs the ones that finished.

``python tests/interrupt_worker.py LOG N [--dask]`` runs N trials on two workers and prints
the run's summary as JSON.
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

QUICK = 2  # trials that finish at once; every other one waits (up to 10 min)


@dataclass(frozen=True)
class Item:
    key: int


def trial(item: Item) -> dict[str, int]:
    """Top level, so that spawned and Dask workers can import it."""
    if item.key >= QUICK:
        time.sleep(600)
    return {"k": item.key}


def main() -> None:
    sys.path.insert(0, str(Path(__file__).parents[1] / "src"))
    from articutool.bench.executors import DaskExecutor, LocalExecutor
    from articutool.bench.runner import run_logged

    log, n = Path(sys.argv[1]), int(sys.argv[2])
    cluster = None
    if "--dask" in sys.argv:
        from distributed import LocalCluster

        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address=None)
        ex = DaskExecutor(cluster.scheduler_address)
    else:
        ex = LocalExecutor(2)
    try:
        res = run_logged([Item(k) for k in range(n)], log, ex, trial, key=lambda r: r["k"])
    finally:
        ex.close()
        if cluster is not None:
            cluster.close()
    print(json.dumps({"ran": res.ran, "interrupted": res.interrupted,
                      "lost": len(res.lost), "keys": sorted(r["k"] for r in res.records)}),
          flush=True)


if __name__ == "__main__":
    main()
