"""How a workflow says what it is doing (the caller renders it), and JSON-friendly summaries."""

from __future__ import annotations

import math
from typing import Any, Protocol

__all__ = ["NO_PROGRESS", "Progress", "jsonable"]


class Progress(Protocol):
    """What a workflow reports while it runs; the command line draws it on stderr."""

    def stage(self, text: str) -> None:
        """What happens now, e.g. 'computing the twin truth'."""

    def step(self, done: int, total: int | None, text: str) -> None:
        """``done`` of ``total`` units of work (cycles, scenarios); ``total`` None when unknown."""

    def note(self, text: str) -> None:
        """A line worth keeping (a finished cycle, a skipped file)."""


class _Silent:
    def stage(self, text: str) -> None:
        pass

    def step(self, done: int, total: int | None, text: str) -> None:
        pass

    def note(self, text: str) -> None:
        pass


#: A :class:`Progress` that reports nothing.
NO_PROGRESS: Progress = _Silent()


def jsonable(value: Any) -> Any:
    """JSON-safe: numpy scalars to Python, NaN and ±inf to None, containers recursively, the rest as str."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if hasattr(value, "item") and getattr(value, "ndim", 1) == 0:
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, bool | int | str):
        return value
    return str(value)
