"""The Dask worker plugin that installs a payload on each worker (imported only where Dask is)."""

from __future__ import annotations

from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin

from rivercal.evaluate import _shipping

__all__ = ["EndWithParent", "Install"]


class Install(WorkerPlugin):
    """Keep one payload (a pickled object) on a worker under its token, from set-up to tear-down."""

    idempotent = True

    def __init__(self, token: str, payload: bytes):
        self.token = token
        self.payload = payload

    def setup(self, worker: Any) -> None:
        """Called on every worker, also on one that joins after the registration."""
        _shipping.PAYLOADS[self.token] = self.payload

    def teardown(self, worker: Any) -> None:
        """Called when the plugin is removed (or the worker closes)."""
        _shipping.drop(self.token)


class EndWithParent(WorkerPlugin):
    """Make each worker process of a ``local:N`` cluster end as soon as the process that started it ends.

    Dask's own watch of the parent is a thread of the worker, which needs the interpreter lock: a worker in
    the middle of Python code that keeps it (an external model's or a case's loading, a long numpy call)
    could outlive a killed parent until that ends. The kernel's parent-death signal does not wait
    (:func:`rivercal.evaluate.end_with_parent`). A worker that another process started (a remote cluster's
    worker, or one whose parent is not ``parent_pid``) is left alone.
    """

    idempotent = True

    def __init__(self, parent_pid: int):
        self.parent_pid = parent_pid

    def setup(self, worker: Any) -> None:
        """Arm the signal in a worker whose parent is ``parent_pid``."""
        import os

        from rivercal.evaluate._pool import end_with_parent

        if os.getppid() == self.parent_pid:
            end_with_parent()
