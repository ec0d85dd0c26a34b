"""Functions the Dask tests send to the workers (importable there: the workers get this sys.path)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

#: Per worker process: how often a Counted object was unpickled there.
LOADS: dict[str, int] = {}


class Counted:
    """An object that counts, in the process that unpickles it, how often that happened (by its label)."""

    def __init__(self, label: str, size: int = 0):
        self.label = label
        self.ballast = np.zeros(size)  # a model-sized payload

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        LOADS[self.label] = LOADS.get(self.label, 0) + 1


class Scaled:
    """fun(x) = factor * x, with a Counted model it refers to."""

    def __init__(self, model: Counted, factor: float):
        self.model = model
        self.factor = factor

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return self.factor * np.asarray(x, dtype=float)


def loads(label: str) -> int:
    """On a worker: how often ``label`` was unpickled in this process."""
    return LOADS.get(label, 0)


class KillOnce:
    """fun(x) = 2x, but the first call anywhere (marker file absent) ends its worker process abruptly."""

    def __init__(self, marker: Path):
        self.marker = Path(marker)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        if float(x[0]) == 3.0 and not self.marker.exists():
            self.marker.write_text(str(os.getpid()))
            os._exit(1)  # the worker dies mid-task, as on a crash or a lost machine
        return 2.0 * np.asarray(x, dtype=float)


class Logged:
    """fun(x) = x², after ``seconds`` of waiting; each call first appends its start (``time.monotonic``, one clock
    for every process of this machine) to ``path``: a model run long enough for a deadline to fall in a batch."""

    def __init__(self, path: Path, seconds: float):
        self.path = Path(path)
        self.seconds = seconds

    def __call__(self, x: np.ndarray) -> np.ndarray:
        import time

        with self.path.open("a") as f:
            f.write(f"{time.monotonic()!r}\n")
        time.sleep(self.seconds)
        return np.asarray(x, dtype=float) ** 2

    def starts(self) -> list[float]:
        """The start of every call so far."""
        return [float(t) for t in self.path.read_text().split()] if self.path.exists() else []


def started(path: Path, x: float, seconds: float) -> float:
    """A task that appends ``x`` and its start (``time.monotonic``) to ``path``, waits ``seconds`` and returns ``x``."""
    import time

    with Path(path).open("a") as f:
        f.write(f"{x!r} {time.monotonic()!r}\n")
    time.sleep(seconds)
    return x


def hold_interpreter(additions: float, started: Path | None = None) -> float:
    """Add ``additions`` times in one compiled call that keeps the interpreter lock (the worst case for a worker's
    own threads: Python code, or compiled code without ``nogil``, in the middle of a long task). With ``started``,
    that file is written once the function is compiled, just before the long call begins."""
    import numba

    @numba.njit
    def spin(n: int) -> float:
        x = 0.0
        for _ in range(n):
            x += 1e-9
        return x

    spin(1)  # compiled now, not in the long call
    if started is not None:
        Path(started).write_text(str(os.getpid()))
    return spin(int(additions))
