"""The local pool of worker processes behind :class:`rivercal.evaluate.Evaluator`.

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
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from typing import Any

__all__ = ["call_installed", "check_workers", "default_workers", "end_with_parent", "install", "process_pool"]

log = logging.getLogger(__name__)

_WORKER_OBJ: Any = None
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


def install(obj: Any) -> None:
    """Initialiser of a pool worker: the object its tasks work on (inherited at fork, or unpickled once)."""
    global _WORKER_OBJ
    _WORKER_OBJ = obj


def call_installed(fn: Callable[..., Any], *args: Any) -> Any:
    """A pool task: ``fn(obj, *args)`` with the installed object."""
    return fn(_WORKER_OBJ, *args)


def default_workers() -> int:
    """Worker processes to use by default: the cores available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)




def check_workers(workers: int | None, what: str = "workers") -> int:
    """The number of local worker processes asked for, checked: a whole number from 1 to :func:`default_workers`.

    More processes than the cores available to this process are refused, not cut down: each worker
    holds its own model and runs one model run at a time, so extra workers only share the same cores (and
    memory) and make every run slower, and a silent cut would leave the caller believing the runs go
    wider than they do. None means all the cores.

    Parameters
    ----------
    workers
        The number asked for, or None.
    what
        How messages name the setting (``--workers``, ``property 'workers'``).

    Returns
    -------
    int
        The number of workers to use.

    Raises
    ------
    ValueError
        Naming ``what``, the value and the allowed range.
    """
    limit = default_workers()
    if workers is None:
        return limit
    if isinstance(workers, bool) or not isinstance(workers, int | float) or workers != int(workers):
        raise ValueError(f"{what} {workers!r}: expected a whole number of worker processes, 1 to {limit}")
    if not 1 <= workers <= limit:
        raise ValueError(f"{what} {int(workers)}: give 1 to {limit} worker processes ({limit} processor "
                         f"core{'s are' if limit != 1 else ' is'} available to this process; more workers than "
                         "cores only share them)")
    return int(workers)
