"""Spun-up states on disk, shared by the processes of one machine.

A twin truth, an on-line replay and its report, every calibration of a suite and every restart of a
service spin a model up from its cold start to the time they begin: for a cycle in November of the
dommel case, two months of simulated time before the first run that matters. A model that names its
cold-started runs (the embedded engine, :meth:`rivercal.engine.Simulator.spin_up_key`) has the states of
such runs kept here, so that the next process, with the same model and parameters, continues from the
latest state at or before the time it needs instead of from the start. Continuing from a state equals the
run from the start to the last bit (the engine's contract), so a state from the cache is the state a
spin-up computes.

Where: ``$RIVERCAL_CACHE_DIR/spin-ups``; without that variable ``$XDG_CACHE_HOME/rivercal/spin-ups`` or
``~/.cache/rivercal/spin-ups`` (nothing without a home folder). ``RIVERCAL_CACHE_DIR=off`` keeps nothing.
A state's name digests the model's name of the run, the engine's source code and the versions of numpy,
numba and llvmlite and the processor they compile for: a change of any of them names new states, and old
ones age out. The folder keeps at most :data:`MAX_BYTES`; the least recently used states go first.

Each state is written to a temporary file in its folder and renamed into place, so a process killed while
writing leaves no half state under a state's name (the temporary file is removed later). A file that
cannot be read is logged, removed and computed again; a folder that cannot be written is logged once and
the spin-ups go on without it.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import logging
import os
import platform
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pandas as pd

from rivercal._cache_dirs import user_cache
from rivercal._time import utc

__all__ = ["ENV_VAR", "MAX_BYTES", "SpinUpCache", "cached_state_at", "spin_up_cache"]

log = logging.getLogger(__name__)

#: The environment variable that places the cache (``off`` turns it off).
ENV_VAR = "RIVERCAL_CACHE_DIR"
#: Most bytes the cache keeps, B (the dommel case's state takes about 30 kB).
MAX_BYTES = 256 * 2**20
#: Age after which a temporary file of a killed writer is removed, s.
STALE_PART_S = 3600.0
_SUFFIX = ".state"
_PART = ".part"


class SpinUpCache:
    """States of cold-started runs in a folder: ``<root>/<name[:2]>/<name>/<time in ns>.state``.

    Parameters
    ----------
    root
        The folder (made when the first state is kept).
    max_bytes
        Most bytes kept, B.
    """

    def __init__(self, root: str | Path, max_bytes: int = MAX_BYTES):
        self.root = Path(root)
        self.max_bytes = int(max_bytes)
        self._unwritable = False

    def _folder(self, name: str) -> Path:
        return self.root / name[:2] / name

    def latest(self, name: str, at: pd.Timestamp) -> tuple[pd.Timestamp, Path] | None:
        """The latest kept state of run ``name`` at or before ``at``: its time and file; None without one."""
        limit = utc(at).value
        best = None
        try:
            with os.scandir(self._folder(name)) as entries:
                for entry in entries:
                    stem, suffix = os.path.splitext(entry.name)
                    if suffix == _SUFFIX and stem.isdigit() and int(stem) <= limit and \
                            (best is None or int(stem) > best):
                        best = int(stem)
        except OSError:   # no such folder: nothing kept
            return None
        if best is None:
            return None
        return pd.Timestamp(best, tz="UTC"), self._folder(name) / f"{best}{_SUFFIX}"

    def read(self, path: Path) -> bytes | None:
        """The bytes of a kept state (its use counts as recent); None, logged, when it cannot be read."""
        try:
            data = path.read_bytes()
            with contextlib.suppress(OSError):
                os.utime(path)
            return data
        except OSError as exc:
            log.warning("spin-up cache: cannot read %s (%s); spinning up again", path, exc)
            return None

    def discard(self, path: Path) -> None:
        """Remove a kept state that turned out unusable."""
        with contextlib.suppress(OSError):
            path.unlink()

    def keep(self, name: str, at: pd.Timestamp, data: bytes) -> None:
        """Keep the bytes of run ``name``'s state at ``at`` (written whole, then renamed into place)."""
        if self._unwritable:
            return
        folder = self._folder(name)
        target = folder / f"{utc(at).value}{_SUFFIX}"
        try:
            folder.mkdir(parents=True, exist_ok=True)
            fd, part = tempfile.mkstemp(dir=folder, suffix=_PART)
            try:
                with os.fdopen(fd, "wb") as f:
                    f.write(data)
                os.replace(part, target)
            except BaseException:
                with contextlib.suppress(OSError):
                    os.unlink(part)
                raise
        except OSError as exc:
            self._unwritable = True
            log.warning("spin-up cache: cannot write in %s (%s); spin-ups go on without it", self.root, exc)
            return
        self.prune()

    def prune(self) -> None:
        """Remove the least recently used states beyond :attr:`max_bytes`, and stale temporary files."""
        files = []
        now = time.time()
        for path in self.root.glob("*/*/*"):
            try:
                st = path.stat()
            except OSError:
                continue
            if path.suffix == _PART:
                if now - st.st_mtime > STALE_PART_S:
                    with contextlib.suppress(OSError):
                        path.unlink()
                continue
            files.append((st.st_mtime, st.st_size, path))
        total = sum(size for _, size, _ in files)
        for _, size, path in sorted(files, key=lambda f: f[0]):
            if total <= self.max_bytes:
                break
            with contextlib.suppress(OSError):
                path.unlink()
                total -= size
                with contextlib.suppress(OSError):
                    path.parent.rmdir()   # the run's last state: its folder goes too


def spin_up_cache() -> SpinUpCache | None:
    """The cache of this environment (see the module docstring); None when ``RIVERCAL_CACHE_DIR=off``."""
    value = os.environ.get(ENV_VAR)
    if value is not None and value.strip():
        if value.strip().lower() in ("off", "none", "0", "false", "no"):
            return None
        return _cache(Path(value.strip()).expanduser() / "spin-ups")
    root = user_cache("spin-ups")
    if root is None:   # no home folder known (no HOME, no passwd entry): keep nothing
        log.debug("spin-up cache: no home folder; set %s to keep spin-ups", ENV_VAR)
        return None
    return _cache(root)


@functools.cache
def _cache(root: Path) -> SpinUpCache:
    return SpinUpCache(root)


@functools.cache
def _code_digest() -> bytes:
    """SHA-256 of the engine's source files and of what compiles them (versions, the processor's name)."""
    import llvmlite
    import numba
    import numpy as np
    from llvmlite import binding

    import rivercal.engine

    digest = hashlib.sha256()
    for part in (np.__version__, numba.__version__, llvmlite.__version__, platform.machine(),
                 binding.get_host_cpu_name(), binding.get_host_cpu_features().flatten()):
        digest.update(f"{part}|".encode())
    root = Path(rivercal.engine.__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.digest()


def cached_state_at(model: Any, parameters: Mapping[str, float] | None, at: Any) -> Any:
    """``model.state_at(parameters, at)`` from the states kept by this machine's processes, and kept for them.

    For a model with ``spin_up_key`` and ``keep_state`` (the embedded engine): the latest kept state of
    the same run at or before ``at`` is handed to the model, which continues from it; the state at ``at``
    is kept in turn. Without a cache, or for another model, this is ``model.state_at(parameters, at)``.
    """
    cache = spin_up_cache()
    if cache is None or not hasattr(model, "spin_up_key") or not hasattr(model, "keep_state"):
        return model.state_at(parameters, at)
    at = utc(at)
    name = hashlib.sha256(_code_digest() + model.spin_up_key(parameters).encode()).hexdigest()
    handed = _hand_over(cache, name, model, parameters, at)
    state = model.state_at(parameters, at)
    if handed != at:
        cache.keep(name, at, model.save_state(state))
    log.debug("spin-up to %s %s", at, "from the cache" if handed == at else
              f"continued from the cache's state at {handed}" if handed is not None else "from the cold start")
    return state


def _hand_over(cache: SpinUpCache, name: str, model: Any, parameters: Mapping[str, float] | None,
               at: pd.Timestamp) -> pd.Timestamp | None:
    """Give ``model`` the latest kept state of run ``name`` at or before ``at``; its time, None without one.

    A kept state that cannot be read or used is logged and removed.
    """
    found = cache.latest(name, at)
    if found is None:
        return None
    when, path = found
    data = cache.read(path)
    if data is None:
        return None
    try:
        state = model.load_state(data, model.state_format)
        if state.time != when:
            raise ValueError(f"the state is at {state.time}, its file name says {when}")
        model.keep_state(parameters, state)
    except ValueError as exc:
        log.warning("spin-up cache: %s is unusable (%s); spinning up again", path, exc)
        cache.discard(path)
        return None
    return when
