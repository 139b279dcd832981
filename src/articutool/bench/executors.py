"""Pluggable executors for the benchmark runner: a local process pool or a Dask cluster.

Both run a top-level, picklable function over independent items and yield
``(item, result, error)`` as each finishes (completion order, not submission order), so the
runner can append every finished trial to its log at once. ``error`` is the exception a
trial raised or the failure of the worker running it (a crashed process, a lost Dask
worker); the runner does not record such trials, so a rerun resumes them.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
from collections.abc import Callable, Iterator, Sequence
from typing import Any, Protocol, TypeVar

__all__ = ["DaskExecutor", "Executor", "ExecutorError", "LocalExecutor"]

T = TypeVar("T")
Outcome = tuple[Any, Any, BaseException | None]


class ExecutorError(RuntimeError):
    """The executor cannot start (e.g. no Dask scheduler at the address)."""


class Executor(Protocol):
    """What the runner needs: run ``fn`` over ``items``, yield outcomes as they finish."""

    description: str

    def run(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[Outcome]:
        """Yield ``(item, fn(item), None)`` or ``(item, None, error)`` per item, unordered."""
        ...

    def close(self) -> None:
        """Release workers and connections."""
        ...


class LocalExecutor:
    """``concurrent.futures.ProcessPoolExecutor`` with ``workers`` processes.

    Processes are started with ``spawn`` (a fresh interpreter; forking a parent that holds
    OMPL/Pinocchio state and threads is not safe). If a worker process dies, the pool is
    broken: the trials still pending are yielded with that error and left for a rerun.
    """

    def __init__(self, workers: int) -> None:
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers must be an integer >= 1; got {workers!r}")
        self.workers = workers
        self.description = f"local process pool ({workers} worker{'s' * (workers > 1)})"
        self._pool: cf.ProcessPoolExecutor | None = None

    def run(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[Outcome]:
        if not items:
            return
        if self._pool is None:
            self._pool = cf.ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"))
        futures = {self._pool.submit(fn, item): item for item in items}
        try:
            for fut in cf.as_completed(futures):
                item = futures[fut]
                try:
                    yield item, fut.result(), None
                except Exception as err:  # the trial or its process failed
                    yield item, None, err
        finally:
            for fut in futures:
                fut.cancel()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


class DaskExecutor:
    """A ``dask.distributed`` cluster at ``address`` (e.g. ``tcp://10.0.0.5:8786``).

    Each trial is one task (``pure=False``: identical trials with another seed or a rerun
    are never deduplicated). ``client`` may be passed instead of an address (tests).
    """

    def __init__(self, address: str | None = None, *, client: Any = None,
                 timeout_s: float = 10.0) -> None:
        if client is None:
            if not address:
                raise ValueError("DaskExecutor needs a scheduler address or a client")
            try:
                from distributed import Client
            except ImportError as err:  # pragma: no cover - pinned dependency
                raise ExecutorError(f"dask.distributed is not installed: {err}") from None
            try:
                client = Client(address, timeout=timeout_s)
            except (OSError, TimeoutError, ValueError) as err:
                raise ExecutorError(
                    f"cannot connect to the Dask scheduler at {address!r}: {err}") from None
            self._owns_client = True
        else:
            self._owns_client = False
        self.client = client
        self.description = f"Dask cluster at {client.scheduler.address}"

    def run(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[Outcome]:
        if not items:
            return
        from distributed import as_completed

        futures = {}
        for item in items:
            fut = self.client.submit(fn, item, pure=False)
            futures[fut.key] = (fut, item)
        try:
            for fut in as_completed([f for f, _ in futures.values()]):
                item = futures[fut.key][1]
                try:
                    yield item, fut.result(), None
                except Exception as err:  # the trial failed or its worker was lost
                    yield item, None, err
        finally:
            for fut, _ in futures.values():
                fut.cancel()

    def close(self) -> None:
        if self._owns_client:
            self.client.close()
