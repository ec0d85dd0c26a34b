"""Evaluating batches of parameter vectors: in this process, on a pool of local workers, or on a Dask cluster.

The optimisers of :mod:`rivercal.optimise` hand independent points (DuD's p + 1 initial runs, finite-
difference Jacobians, SCE-UA complexes, grid and GLUE samples) to a ``batch`` callable.
:class:`Evaluator` is that callable. Where it runs is its ``workers``:

- ``1``: in this process;
- ``N > 1`` (default: the cores of this machine; at most that many, :func:`check_workers`): a pool of N
  worker processes
  (:func:`process_pool`) whose workers each hold their own copy of the function — for a calibration
  problem, their own model and engine state — so runs never share state. On Linux they are forked after
  the problem is built and inherit it without pickling; they end with this process, however it ends;
- a :class:`DaskCluster` (``DaskCluster("local:4")``, ``DaskCluster("tcp://scheduler:8786")``): the
  function goes to each Dask worker once (not once per evaluation) and the points run as Dask tasks;
  the scheduler re-runs the points of a worker that is lost.

A function that can evaluate several points at once in this process (``batch``: for a calibration on the
embedded engine, :meth:`rivercal.problem.CalibrationProblem.residuals_batch`, which runs the points' models
on threads of this process) replaces the local processes: with two or more workers, every batch of two or
more points is one such call with as many threads as there would be workers. With one worker the points run
one by one, as a batch on one thread would. A Dask cluster keeps its tasks.

Either way the results come back in the order of the points, and an exception raised by a run (a diverged
run under the ``raise`` failure policy) reaches the caller unchanged. :meth:`Evaluator.as_completed`
yields results as they finish. :meth:`Evaluator.within` runs a batch up to a deadline: no run starts after
it, so that an optimiser's deadline (:mod:`rivercal.optimise`) holds inside a batch too.

:class:`Tasks` is the same machinery for whole jobs over one shared object, e.g. every calibration of a
twin suite over one model: all of them are submitted at once, so that a cluster stays busy.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor
from concurrent.futures import as_completed as _as_completed
from concurrent.futures import wait as _wait
from typing import Any

import numpy as np

from rivercal.evaluate._dask import ClusterError, DaskCluster
from rivercal.evaluate._pool import (
    call_installed,
    check_workers,
    default_workers,
    end_with_parent,
    install,
    process_pool,
)
from rivercal.optimise import start_first, until_deadline

__all__ = ["ClusterError", "DaskCluster", "Evaluator", "Tasks", "Workers", "as_completed", "check_workers",
           "default_workers", "describe_workers", "end_with_parent", "process_pool"]

log = logging.getLogger(__name__)

#: Where work runs: a number of local processes (None: all cores; 1: this process) or a Dask cluster.
Workers = int | DaskCluster | None

as_completed = _as_completed


def describe_workers(workers: Workers) -> int | str:
    """``workers`` for a summary: the number of local processes, or the Dask address."""
    if isinstance(workers, DaskCluster):
        return f"dask {workers.address} ({workers.n_workers} workers)"
    return default_workers() if workers is None else int(workers)


class Tasks:
    """Run ``fn(obj, *args)`` jobs over one object on workers: this process, local processes or a Dask cluster.

    Parameters
    ----------
    obj
        The object every job works on (a model, a calibration problem); it goes to each worker once.
    workers
        See :data:`Workers`.

    Raises
    ------
    ValueError
        For a number of local workers outside 1 … the cores available (:func:`check_workers`).
    """

    def __init__(self, obj: Any, workers: Workers = None):
        self.obj = obj
        self.cluster = workers if isinstance(workers, DaskCluster) else None
        if self.cluster is None:
            self.workers = check_workers(workers)
        else:
            self.workers = self.cluster.n_workers
        self._pool: ProcessPoolExecutor | None = None
        self._token: str | None = None

    @property
    def parallel(self) -> bool:
        """Whether jobs run outside this process."""
        return self.cluster is not None or self.workers > 1

    def submit(self, fn: Callable[..., Any], *args: Any) -> Future:
        """Start ``fn(obj, *args)``; a :class:`concurrent.futures.Future` of its result.

        ``fn`` must be a module-level function (it is pickled by reference). Without workers the job runs
        now, in this process, and the future is done when this returns.
        """
        if self.cluster is not None:
            if self._token is None:
                self._token = self.cluster.install(self.obj)
            return self.cluster.submit(self._token, fn, *args)
        if self.workers > 1:
            if self._pool is None:
                self._pool = process_pool(self.workers, install, (self.obj,))
            return self._pool.submit(call_installed, fn, *args)
        future: Future = Future()
        try:
            future.set_result(fn(self.obj, *args))
        except Exception as exc:  # handed to the caller through the future, as a pool does
            future.set_exception(exc)
        return future

    def submit_all(self, fn: Callable[..., Any], calls: Sequence[tuple]) -> list[Future]:
        """``[submit(fn, *args) for args in calls]``; on a Dask cluster in one message to its scheduler."""
        if self.cluster is not None and len(calls) > 1:
            if self._token is None:
                self._token = self.cluster.install(self.obj)
            return self.cluster.submit_many(self._token, fn, calls)
        return [self.submit(fn, *args) for args in calls]

    def map(self, fn: Callable[..., Any], items: Sequence[Any]) -> list[Any]:
        """``[fn(obj, item) for item in items]``, all submitted at once; the first failure is raised."""
        futures = self.submit_all(fn, [(item,) for item in items])
        try:
            return [f.result() for f in futures]
        except BaseException:
            for f in futures:
                f.cancel()
            raise

    def close(self) -> None:
        """Stop the local workers, or remove the object from the cluster's workers."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self._token is not None and self.cluster is not None:
            self.cluster.uninstall(self._token)
            self._token = None

    def __enter__(self) -> Tasks:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _call(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray) -> np.ndarray:
    return fun(x)


class Evaluator:
    """A ``batch(list_of_x) -> list_of_results`` callable over ``fun``: serial, local processes or Dask.

    Parameters
    ----------
    fun
        The function of one parameter vector (e.g. ``CalibrationProblem.residuals``); picklable when
        workers are spawned (not on Linux) or on a Dask cluster.
    workers
        See :data:`Workers`: None uses :func:`default_workers`, 1 evaluates in this process, a
        :class:`DaskCluster` its workers.
    batch
        ``batch(points, threads=n) -> results``: ``fun`` of several points at once, in this process on ``n``
        threads (module docstring); used for every batch of two or more points when there are two or more
        local workers. Its results and its failures must be those of ``fun`` point by point.

    Examples
    --------
    >>> import numpy as np
    >>> with Evaluator(np.square, workers=1) as batch:
    ...     batch([np.array([2.0]), np.array([3.0])])
    [array([4.]), array([9.])]
    """

    def __init__(self, fun: Callable[[np.ndarray], np.ndarray], workers: Workers = None, *,
                 batch: Callable[..., Sequence[np.ndarray]] | None = None):
        self.fun = fun
        self._tasks = Tasks(fun, workers)
        self.workers = self._tasks.workers
        self.cluster = self._tasks.cluster
        #: ``fun`` of several points in this process (None: none, one worker, or a Dask cluster).
        self.batch = batch if self.cluster is None and self.workers > 1 else None

    def _batched(self, points: list[np.ndarray]) -> list[np.ndarray]:
        results = list(self.batch(points, threads=self.workers))  # type: ignore[misc]
        if len(results) != len(points):
            raise RuntimeError(f"the batch function returned {len(results)} results for {len(points)} points")
        return results

    def as_completed(self, xs: Sequence[np.ndarray]) -> Iterator[tuple[int, np.ndarray]]:
        """``(index, fun(xs[index]))`` as each evaluation finishes; the first failure is raised."""
        points = [np.asarray(x, dtype=float) for x in xs]
        if self.batch is not None and len(points) > 1:
            yield from enumerate(self._batched(points))
            return
        if self.cluster is None and (self.workers == 1 or len(points) <= 1):
            for i, x in enumerate(points):
                yield i, self.fun(x)
            return
        futures = {f: i for i, f in enumerate(self._tasks.submit_all(_call, [(x,) for x in points]))}
        try:
            for future in as_completed(futures):
                yield futures[future], future.result()
        finally:
            for future in futures:
                future.cancel()

    def __call__(self, xs: Sequence[np.ndarray]) -> list[np.ndarray]:
        """Evaluate ``fun`` at every point; the results in the order of the points.

        If runs fail, the error raised is that of the first failed point in the order of the points, as
        in a serial loop (not whichever failure finished first), so a failure reads the same wherever
        the batch ran.
        """
        points = [np.asarray(x, dtype=float) for x in xs]
        if self.batch is not None and len(points) > 1:
            return self._batched(points)
        if self.cluster is None and (self.workers == 1 or len(points) <= 1):
            return [self.fun(x) for x in points]
        futures = self._tasks.submit_all(_call, [(x,) for x in points])
        try:
            return [future.result() for future in futures]
        finally:
            for future in futures:
                future.cancel()

    def within(self, xs: Sequence[np.ndarray], deadline: float, *, keep: int | None = None) -> list[np.ndarray | None]:
        """:meth:`__call__` up to ``deadline`` (a :func:`time.monotonic` time): the runs not done by then are None.

        No run starts after the deadline, except the point ``keep`` (an optimiser's start point), which is
        run and awaited whatever the time, alone if the deadline has passed. The points go out one per worker
        at a time (a batched engine call in groups of one point per worker), the kept point first. A run that
        is going at the deadline cannot be interrupted in this process, in a batched call or on a local worker
        process: it finishes, and counts where the evaluator waits for it (this process, a batched call). On
        local worker processes and a Dask cluster the evaluator stops waiting at the deadline (a Dask worker
        drops the result of a run it was computing). A failure is raised as in :meth:`__call__`: the first in
        the order of the points among the runs that finished.
        """
        points = [np.asarray(x, dtype=float) for x in xs]
        out: list[np.ndarray | None]
        if self.cluster is None and (self.workers == 1 or len(points) <= 1 or self.batch is not None):
            width = self.workers if self.batch is not None else 1
            out = until_deadline(points, deadline, keep, self._group, width)
        else:
            out = [None] * len(points)
            self._in_flight(points, start_first(len(points), keep), deadline, keep, out)
        cut = sum(r is None for r in out)
        if cut:
            log.info("deadline: %d of %d runs of the batch not run", cut, len(points))
        return out

    def _group(self, points: list[np.ndarray]) -> list[np.ndarray]:
        """One group of :meth:`within` in this process: a batched call, or ``fun`` for a single point."""
        return self._batched(points) if len(points) > 1 else [self.fun(points[0])]

    def _in_flight(self, points: list[np.ndarray], order: list[int], deadline: float, keep: int | None,
                   out: list[np.ndarray | None]) -> None:
        """:meth:`within` on worker processes or a cluster: one run per worker in flight, none sent after the deadline.

        Sending the points one per free worker (not all at once) leaves nothing queued at the deadline: a
        process pool cannot take back what it has queued, and a cluster cancels pending tasks one by one.
        """
        futures: dict[int, Future] = {}
        queue = iter(order[1:] if keep is not None else order)
        try:
            if keep is not None:
                futures[keep] = self._tasks.submit(_call, points[keep])
            while True:
                running = [f for f in futures.values() if not f.done()]
                failed = any(f.done() and not f.cancelled() and f.exception() is not None for f in futures.values())
                while not failed and len(running) < self.workers and time.monotonic() < deadline:
                    i = next(queue, None)
                    if i is None:
                        break
                    futures[i] = self._tasks.submit(_call, points[i])
                    running.append(futures[i])
                left = deadline - time.monotonic()
                if failed or not running or left <= 0:
                    break
                _wait(running, timeout=left, return_when=FIRST_COMPLETED)
            for i, future in futures.items():
                if i != keep and not future.done():
                    future.cancel()
            if keep is not None:
                _wait([futures[keep]])
            for i in sorted(futures):
                if futures[i].done() and not futures[i].cancelled():
                    out[i] = futures[i].result()
        finally:
            for future in futures.values():
                future.cancel()

    def close(self) -> None:
        """Stop the worker processes (or remove the function from the Dask workers)."""
        self._tasks.close()

    def __enter__(self) -> Evaluator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
