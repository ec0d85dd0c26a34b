"""Evaluating batches of parameter vectors, serially or on a pool of worker processes.

The optimisers of :mod:`rivercal.optimise` hand independent points (DuD's p + 1 initial runs, finite-
difference Jacobians, SCE-UA complexes, grid and GLUE samples) to a ``batch`` callable.
:class:`Evaluator` is that callable: with one worker it maps the function in this process; with more it
runs a :class:`concurrent.futures.ProcessPoolExecutor` whose workers each hold their own copy of the
function — for a calibration problem, their own model and engine state — so runs never share state.

On Linux the workers are forked from this process after the problem is built, so they inherit the
compiled model without pickling it or recompiling; elsewhere they are spawned and receive the function
pickled once, at start-up. Exceptions raised in a worker (a diverged run under the ``raise`` failure
policy) reach the caller unchanged.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor

import numpy as np

__all__ = ["Evaluator", "default_workers"]

log = logging.getLogger(__name__)

_WORKER_FUN: Callable[[np.ndarray], np.ndarray] | None = None


def _init_worker(fun: Callable[[np.ndarray], np.ndarray]) -> None:
    global _WORKER_FUN
    _WORKER_FUN = fun


def _call(x: np.ndarray) -> np.ndarray:
    return _WORKER_FUN(x)  # type: ignore[misc]


def default_workers() -> int:
    """Worker processes to use by default: the cores available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


class Evaluator:
    """A ``batch(list_of_x) -> list_of_results`` callable over ``fun``, serial or parallel.

    Parameters
    ----------
    fun
        The function of one parameter vector (e.g. ``CalibrationProblem.residuals``); picklable when
        workers are spawned (not on Linux).
    workers
        Number of worker processes; None uses :func:`default_workers`, 1 evaluates in this process.

    Examples
    --------
    >>> import numpy as np
    >>> with Evaluator(np.square, workers=1) as batch:
    ...     batch([np.array([2.0]), np.array([3.0])])
    [array([4.]), array([9.])]
    """

    def __init__(self, fun: Callable[[np.ndarray], np.ndarray], workers: int | None = None):
        self.fun = fun
        self.workers = default_workers() if workers is None else int(workers)
        if self.workers < 1:
            raise ValueError(f"workers must be at least 1, got {workers}")
        self._pool: ProcessPoolExecutor | None = None

    def _ensure_pool(self) -> ProcessPoolExecutor:
        if self._pool is None:
            method = "fork" if sys.platform.startswith("linux") else "spawn"
            context = multiprocessing.get_context(method)
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=context,
                                             initializer=_init_worker, initargs=(self.fun,))
            log.debug("started %d %s workers", self.workers, method)
        return self._pool

    def __call__(self, xs: Sequence[np.ndarray]) -> list[np.ndarray]:
        """Evaluate ``fun`` at every point, in order; parallel when there are several points and workers."""
        xs = [np.asarray(x, dtype=float) for x in xs]
        if self.workers == 1 or len(xs) <= 1:
            return [self.fun(x) for x in xs]
        return list(self._ensure_pool().map(_call, xs))

    def close(self) -> None:
        """Stop the worker processes."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __enter__(self) -> Evaluator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
