"""Sending objects to Dask workers once, and finding them there (no Dask import here).

An object (a calibration problem, a model) goes to the cluster as a *payload*: its pickle, installed
on every worker by a worker plugin, so that it travels once per worker, and again only to a worker that
joins later (e.g. one the nanny restarted after a crash). A task names the payload by its token and the
worker unpickles it on first use and keeps it.

Objects *shared* on a cluster (:meth:`rivercal.evaluate.DaskCluster.share`, e.g. the model of an on-line
service whose every cycle builds a new problem around it) are left out of other payloads: the pickler
writes a reference to the shared payload instead (a pickle *persistent id*), and the worker resolves it
to its own copy. A new problem of the same model then costs its observations and start state, not the
model again.
"""

from __future__ import annotations

import io
import pickle
import threading
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["PAYLOADS", "call_payload", "drop", "dumps", "obtain"]

#: Worker side: the installed payloads by token (filled by the worker plugin).
PAYLOADS: dict[str, bytes] = {}
_OBJECTS: dict[str, Any] = {}
_LOCK = threading.Lock()
_TAG = "rivercal-shared"


class _Pickler(pickle.Pickler):
    def __init__(self, file: io.BytesIO, shared: Mapping[int, str]):
        super().__init__(file, protocol=pickle.HIGHEST_PROTOCOL)
        self._shared = shared

    def persistent_id(self, obj: Any) -> tuple[str, str] | None:
        token = self._shared.get(id(obj))
        return None if token is None else (_TAG, token)


class _Unpickler(pickle.Unpickler):
    def persistent_load(self, pid: Any) -> Any:
        tag, token = pid
        if tag != _TAG:
            raise pickle.UnpicklingError(f"unknown persistent id {pid!r}")
        return obtain(token)


def dumps(obj: Any, shared: Mapping[int, str]) -> bytes:
    """Pickle ``obj``, writing a reference for every object whose ``id`` is in ``shared`` (id → token)."""
    buffer = io.BytesIO()
    _Pickler(buffer, shared).dump(obj)
    return buffer.getvalue()


def obtain(token: str) -> Any:
    """Worker side: the object of an installed payload, unpickled on first use."""
    with _LOCK:
        if token in _OBJECTS:
            return _OBJECTS[token]
        try:
            payload = PAYLOADS[token]
        except KeyError:
            raise RuntimeError(f"payload {token} is not installed on this worker (was its evaluator closed?)") from None
    obj = _Unpickler(io.BytesIO(payload)).load()  # outside the lock: it may obtain shared payloads
    with _LOCK:
        return _OBJECTS.setdefault(token, obj)


def drop(token: str) -> None:
    """Worker side: forget a payload and its object."""
    with _LOCK:
        PAYLOADS.pop(token, None)
        _OBJECTS.pop(token, None)


def call_payload(token: str, fn: Callable[..., Any], *args: Any) -> Any:
    """A task: ``fn(obj, *args)`` with ``obj`` the object of payload ``token``."""
    return fn(obtain(token), *args)
