"""A Dask cluster as the workers of rivercal's evaluations.

:class:`DaskCluster` connects to a running scheduler (``tcp://HOST:PORT``) or starts a cluster of worker
processes on this machine (``local:N``) and ships objects to its workers once per worker (see
:mod:`rivercal.evaluate._shipping`). The Dask scheduler re-runs the tasks of a worker that is lost (its
process crashed or its machine went away) on the remaining workers; a task that *raises* is not re-run,
its exception reaches the caller (a diverged model run under the ``raise`` failure policy).

Each worker runs one task at a time: a worker holds one copy of the model, and a run of the embedded
engine works in that copy's scratch arrays, so two runs at once in one worker would write over each other
(and an external model's files are one set per copy as well). A cluster whose workers run several threads
is refused; one single-threaded worker per core uses the machine.

The worker processes of a ``local:N`` cluster are Dask's own, without Dask's sampling profiler; each ends
when this process ends, however it ends, also in the middle of a model run: the kernel's parent-death signal
(armed by a worker plugin) does not wait for the worker's interpreter lock as Dask's own watch of the parent
(a thread) does.
"""

from __future__ import annotations

import logging
import os
import pickle
import re
import uuid
from collections.abc import Sequence
from concurrent.futures import Future
from typing import Any

from rivercal.errors import RivercalError
from rivercal.evaluate import _shipping
from rivercal.evaluate._pool import check_workers

__all__ = ["ClusterError", "DaskCluster"]

log = logging.getLogger(__name__)

_LOCAL = re.compile(r"local:(\d+)")


class ClusterError(RivercalError):
    """The Dask cluster cannot be used: not reachable, unsuitable workers, or Dask is not installed."""


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise ClusterError("Dask is not installed: install rivercal with the 'dask' extra "
                           "(pip install 'rivercal[dask]')") from None
    return distributed


class DaskCluster:
    """Workers of a Dask cluster for rivercal's evaluations.

    Parameters
    ----------
    address
        ``local:N`` starts N single-threaded worker processes on this machine (they end with this
        process); ``tcp://HOST:PORT`` (or ``tls://``) connects to a running scheduler.
    timeout_s
        How long to wait for the scheduler, s.

    Raises
    ------
    ValueError
        For an address of neither form, or ``local:N`` with N outside 1 … the cores available
        (:func:`~rivercal.evaluate.check_workers`).
    ClusterError
        If Dask is not installed, the scheduler does not answer, or a worker runs more than one thread.

    Examples
    --------
    >>> from rivercal.evaluate import DaskCluster, Evaluator
    >>> with DaskCluster("local:2") as cluster:                                    # doctest: +SKIP
    ...     with Evaluator(problem.residuals, workers=cluster) as batch:
    ...         residuals = batch([x1, x2, x3])
    """

    def __init__(self, address: str, *, timeout_s: float = 30.0):
        self.address = str(address).strip()
        local = _LOCAL.fullmatch(self.address)
        if local is None and not re.fullmatch(r"(tcp|tls|ucx|inproc)://\S+", self.address):
            raise ValueError(f"Dask address {address!r}: expected local:N (N worker processes on this machine) or "
                             "tcp://HOST:PORT (a running scheduler)")
        if local is not None:
            check_workers(int(local.group(1)), f"Dask address {address!r}: local:N with N =")
        distributed = _distributed()
        self._cluster: Any = None
        self._shared: dict[int, tuple[str, Any]] = {}
        try:
            if local is not None:
                import dask

                # Dask's sampling profiler (a thread in every worker that walks the stacks every 10 ms) took about
                # 0.05 of a core per worker beside its model runs: 1.08 instead of 1.03 cores for one busy worker
                with dask.config.set({"distributed.worker.profile.enabled": False}):
                    self._cluster = distributed.LocalCluster(
                        n_workers=int(local.group(1)), threads_per_worker=1, processes=True,
                        dashboard_address="127.0.0.1:0",  # its HTTP server on a free port of this machine only
                        silence_logs=logging.WARNING)
                self.client = distributed.Client(self._cluster, timeout=timeout_s)
                from rivercal.evaluate._plugin import EndWithParent

                self.client.register_plugin(EndWithParent(os.getpid()), name="rivercal-end-with-parent")
            else:
                self.client = distributed.Client(self.address, timeout=timeout_s)
        except (OSError, TimeoutError) as exc:
            self._close_cluster()
            raise ClusterError(f"cannot reach the Dask scheduler at {self.address}: {exc}") from None
        self._executor = self.client.get_executor(pure=False)
        try:
            self._check_threads()
        except ClusterError:
            self.close()
            raise
        log.info("Dask cluster %s: %d workers", self.address, self.n_workers)

    def _check_threads(self) -> None:
        threads = {w: int(info.get("nthreads", 1)) for w, info in self.client.scheduler_info()["workers"].items()}
        crowded = {w: n for w, n in threads.items() if n > 1}
        if crowded:
            worker, n = next(iter(crowded.items()))
            raise ClusterError(f"Dask worker {worker} runs {n} threads; rivercal runs one model at a time per "
                               "worker process (the runs of a worker share its copy of the model): start the workers "
                               "with --nthreads 1 and as many processes as cores "
                               "(dask worker ADDRESS --nthreads 1 --nworkers N)")

    @property
    def n_workers(self) -> int:
        """Workers connected now."""
        return len(self.client.scheduler_info()["workers"])

    def share(self, obj: Any) -> str:
        """Install ``obj`` on every worker once for the cluster's lifetime; later payloads refer to it.

        Returns its token. Sharing an object twice installs it once.
        """
        held = self._shared.get(id(obj))
        if held is not None:
            return held[0]
        token = self.install(obj)
        self._shared[id(obj)] = (token, obj)  # keep obj alive: its id must not be reused by another object
        return token

    def install(self, obj: Any) -> str:
        """Install ``obj`` on every worker (and on each that joins later); returns its token."""
        from rivercal.evaluate._plugin import Install

        token = uuid.uuid4().hex
        try:
            payload = _shipping.dumps(obj, {k: t for k, (t, _) in self._shared.items()})
        except (pickle.PicklingError, TypeError, AttributeError) as exc:
            raise ClusterError(f"cannot send {type(obj).__name__} to the Dask workers: it cannot be pickled "
                               f"({exc})") from None
        self.client.register_plugin(Install(token, payload), name=f"rivercal-{token}")
        log.debug("installed %s (%d bytes) on the workers as %s", type(obj).__name__, len(payload), token)
        return token

    def uninstall(self, token: str) -> None:
        """Remove an installed object from the workers."""
        if self.client.status == "running":
            self.client.unregister_worker_plugin(f"rivercal-{token}")

    def submit(self, token: str, fn: Any, *args: Any) -> Future:
        """Run ``fn(obj, *args)`` on a worker, ``obj`` the installed object ``token``; a concurrent future."""
        return self._executor.submit(_shipping.call_payload, token, fn, *args)

    def submit_many(self, token: str, fn: Any, calls: Sequence[tuple]) -> list[Future]:
        """:meth:`submit` of ``fn(obj, *args)`` for each ``args`` of ``calls``, sent to the scheduler as one graph.

        One message for all the tasks instead of one per task: the client and the scheduler build and
        read one graph (on one worker, no-op tasks cost about 0.8 ms less each). The scheduler starts the
        tasks in the order of ``calls``, as when they are submitted one by one (a test checks it); their keys
        (``rivercal-<batch>-<position>``) name them in Dask's own dashboard and logs.
        """
        wrap = getattr(self._executor, "_wrap_future", None)   # how the executor makes its futures (distributed's own)
        if wrap is None or len(calls) < 2:
            return [self.submit(token, fn, *args) for args in calls]
        n = len(calls)
        batch = uuid.uuid4().hex
        columns = [list(column) for column in zip(*calls, strict=True)]
        futures = self.client.map(_shipping.call_payload, [token] * n, [fn] * n, *columns,
                                  key=[f"rivercal-{batch}-{i:06d}" for i in range(n)])
        return [wrap(f) for f in futures]

    def _close_cluster(self) -> None:
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def close(self) -> None:
        """Disconnect (and stop the workers of a ``local:N`` cluster)."""
        client = getattr(self, "client", None)
        if client is not None:
            client.close()
        self._close_cluster()
        self._shared.clear()

    def __enter__(self) -> DaskCluster:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"DaskCluster({self.address!r})"

