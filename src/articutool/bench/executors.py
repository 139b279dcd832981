"""Pluggable executors for the benchmark runner: a local process pool or a Dask cluster.

Both run a top-level, picklable function over independent items and yield
``(item, result, error)`` as each finishes (completion order, not submission order), so the
runner can append every finished trial to its log at once. ``error`` is the exception a
trial raised or the failure of the worker running it (a crashed process, a lost Dask
worker); the runner does not record such trials, so a rerun resumes them.

Both stop when the runner's ``stop`` event is set (SIGINT or SIGTERM to the main process):
the trials already finished are still yielded (the runner logs them), the running ones are
abandoned (local: their processes are terminated; Dask: their tasks are cancelled) and the
rest never start; a rerun resumes them.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing as mp
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any, Protocol, TypeVar

__all__ = ["MAX_WORKERS", "DaskExecutor", "Executor", "ExecutorError", "LocalExecutor"]

T = TypeVar("T")
Outcome = tuple[Any, Any, BaseException | None]
# How often a waiting executor looks at the stop event (s): the delay of an interruption.
POLL_S = 0.2


class ExecutorError(RuntimeError):
    """The executor cannot start (e.g. no Dask scheduler at the address)."""


class Executor(Protocol):
    """What the runner needs: run ``fn`` over ``items``, yield outcomes as they finish."""

    description: str

    def run(self, fn: Callable[[Any], Any], items: Sequence[Any],
            stop: threading.Event | None = None) -> Iterator[Outcome]:
        """Yield ``(item, fn(item), None)`` or ``(item, None, error)`` per item, unordered;
        once ``stop`` is set, only the items already finished, then return."""
        ...

    def close(self) -> None:
        """Release workers and connections."""
        ...


# The most local worker processes: one per core of a large workstation and then some. A
# larger number is a typo (1e20 overflowed the pool's C int), not a machine.
MAX_WORKERS = 1024


class LocalExecutor:
    """``concurrent.futures.ProcessPoolExecutor`` with ``workers`` processes.

    Processes are started with ``spawn`` (a fresh interpreter; forking a parent that holds
    OMPL/Pinocchio state and threads is not safe). If a worker process dies, the pool is
    broken: the trials still pending are yielded with that error and left for a rerun.
    """

    def __init__(self, workers: int) -> None:
        if isinstance(workers, bool) or not isinstance(workers, int) \
                or not 1 <= workers <= MAX_WORKERS:
            raise ValueError(f"workers must be an integer in [1, {MAX_WORKERS}]; got "
                             f"{workers!r}")
        self.workers = workers
        self.description = f"local process pool ({workers} worker{'s' * (workers > 1)})"
        self._pool: cf.ProcessPoolExecutor | None = None

    def run(self, fn: Callable[[Any], Any], items: Sequence[Any],
            stop: threading.Event | None = None) -> Iterator[Outcome]:
        if not items:
            return
        if self._pool is None:
            self._pool = cf.ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"),
                                                initializer=_worker_init,
                                                initargs=(os.getpid(),))
        futures = {self._pool.submit(fn, item): item for item in items}
        pending = set(futures)
        try:
            while pending:
                done, pending = cf.wait(pending, timeout=POLL_S,
                                        return_when=cf.FIRST_COMPLETED)
                for fut in done:
                    yield _outcome(futures[fut], fut)
                if stop is not None and stop.is_set():
                    self._terminate()
                    # Results that arrived while the workers were stopped are kept too.
                    late = {f for f in pending if f.done() and not f.cancelled()
                            and f.exception() is None}
                    pending -= late
                    for fut in late:
                        yield _outcome(futures[fut], fut)
                    return
        finally:
            for fut in pending:
                fut.cancel()

    def _terminate(self) -> None:
        """Stop the pool now: its worker processes are terminated (their running trials are
        abandoned) and reaped, so none outlives the run."""
        pool, self._pool = self._pool, None
        if pool is None:
            return
        procs = list((getattr(pool, "_processes", None) or {}).values())
        for p in procs:
            p.terminate()
        for p in procs:
            p.join(timeout=5)
            if p.is_alive():
                p.kill()
                p.join()
        pool.shutdown(wait=True, cancel_futures=True)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def _outcome(item: Any, fut: Any) -> Outcome:
    try:
        return item, fut.result(), None
    except Exception as err:  # the trial or its process failed
        return item, None, err


def _worker_init(parent: int) -> None:
    """In each local worker: leave SIGINT to the main process (a Ctrl-C reaches the whole
    process group; the main process decides what stops), and exit when the main process is
    gone (killed with SIGKILL, say), so no worker is ever left running on its own."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


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

    def run(self, fn: Callable[[Any], Any], items: Sequence[Any],
            stop: threading.Event | None = None) -> Iterator[Outcome]:
        if not items:
            return
        from distributed import wait

        futures = {}
        for item in items:
            fut = self.client.submit(fn, item, pure=False)
            futures[fut.key] = (fut, item)
        pending = [f for f, _ in futures.values()]
        try:
            while pending:
                with contextlib.suppress(TimeoutError):  # a poll of the stop event
                    wait(pending, timeout=POLL_S, return_when="FIRST_COMPLETED")
                done = [f for f in pending if f.done()]
                pending = [f for f in pending if not f.done()]
                for fut in done:
                    yield _outcome(futures[fut.key][1], fut)
                if stop is not None and stop.is_set():
                    return  # the finally cancels the rest on the cluster
        finally:
            if pending:
                self.client.cancel(pending)

    def close(self) -> None:
        if self._owns_client:
            self.client.close()
