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

Workers end with their parent, however it ends (:func:`end_with_parent`): a service killed with
SIGKILL leaves no worker behind, so a supervisor that restarts it does not pile up orphans.
"""

from __future__ import annotations

import ctypes
import logging
import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor

import numpy as np

__all__ = ["Evaluator", "default_workers", "end_with_parent", "process_pool"]

log = logging.getLogger(__name__)

_WORKER_FUN: Callable[[np.ndarray], np.ndarray] | None = None
#: prctl(2) option: the signal this process gets when the thread that created it ends (Linux).
_PR_SET_PDEATHSIG = 1


def end_with_parent(*, kernel_signal: bool = True) -> None:
    """Make this worker process end as soon as the process that started it ends, however that ends.

    Call it first in a worker's initialiser. Without it, a worker of a parent killed by SIGKILL lives on
    for ever: it waits for its next task on a queue whose write end it inherited from its parent and its
    siblings at fork, so it never sees the queue close. Two mechanisms, each enough on its own:

    - on Linux, with ``kernel_signal``, the kernel sends this process SIGKILL when its parent ends
      (``prctl(PR_SET_PDEATHSIG)``). The kernel ties it to the parent *thread* that forked the worker, so
      pass ``kernel_signal=False`` when the workers are started from a thread that may end before the
      pool (the pool's workers would be killed with it);
    - everywhere, a daemon thread waits on the pipe that :mod:`multiprocessing` keeps to the parent (its
      sentinel) and ends the process when the pipe closes (on fork, the worker forked last is freed first
      and frees the ones forked before it, which it held open).

    Does nothing in a process that :mod:`multiprocessing` did not start.

    Parameters
    ----------
    kernel_signal
        Use the parent-death signal of the Linux kernel as well.
    """
    parent = multiprocessing.parent_process()
    if parent is None:
        return
    if kernel_signal and sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) != 0:
            log.warning("prctl(PR_SET_PDEATHSIG) failed (errno %d); the worker watches its parent's pipe only",
                        ctypes.get_errno())
    if os.getppid() != parent.pid:  # the parent ended before the signal was armed
        os._exit(1)

    def watch() -> None:
        parent.join()  # returns when the parent's end of the pipe closes
        os._exit(1)

    threading.Thread(target=watch, name="rivercal-parent-watch", daemon=True).start()


def _start_worker(kernel_signal: bool, initializer: Callable[..., None] | None, initargs: tuple) -> None:
    end_with_parent(kernel_signal=kernel_signal)
    if initializer is not None:
        initializer(*initargs)


def process_pool(workers: int, initializer: Callable[..., None] | None = None,
                 initargs: tuple = ()) -> ProcessPoolExecutor:
    """A pool of worker processes that end with this process (:func:`end_with_parent`).

    On Linux the workers are forked (they inherit what this process has built, e.g. a compiled model,
    without pickling); elsewhere they are spawned and ``initializer`` and ``initargs`` are pickled.
    With fork the pool starts its workers at its first submit or map, in the calling thread: call it
    first from the thread that created the pool.

    Parameters
    ----------
    workers
        Number of worker processes.
    initializer, initargs
        Called in each worker as ``initializer(*initargs)`` once it has armed its end with the parent.
    """
    method = "fork" if sys.platform.startswith("linux") else "spawn"
    # The kernel's parent-death signal is safe only if the thread that starts the workers lives as long as
    # this process; that is the main thread.
    main = threading.current_thread() is threading.main_thread()
    log.debug("starting %d %s workers", workers, method)
    return ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context(method),
                               initializer=_start_worker, initargs=(main, initializer, initargs))


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
            self._pool = process_pool(self.workers, _init_worker, (self.fun,))
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
