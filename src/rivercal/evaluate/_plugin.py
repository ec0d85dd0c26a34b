"""The Dask worker plugin that installs a payload on each worker (imported only where Dask is)."""

from __future__ import annotations

from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin

from rivercal.evaluate import _shipping

__all__ = ["Install"]


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
