"""Where numba keeps rivercal's compiled kernels: per user, one folder per version of their sources.

numba keeps the machine code of a ``cache=True`` kernel beside its source file (``__pycache__``) and
checks only that file. Two things follow for rivercal's time loop, which inlines kernels from a dozen
files and takes about a minute to compile:

- every new installation of the same version (a fresh clone, another virtual environment, a container
  layer) compiles it again, although the machine code would be the same;
- a change in one file leaves stale copies of it inlined in the kernels of other files.

:func:`install` gives numba a locator of its own for the kernels of rivercal's package: the kernels of the
files in one folder (the engine's ``engine/kernels``, the rainfall-runoff model's ``hydrology``) are kept in
``<cache>/rivercal/kernels/<folder>-<digest>/``, where the digest covers every source file in that folder
and the versions of numpy, numba and llvmlite. Another installation of the same sources finds them there;
a change of any file in the folder names a new one (kernels inline only kernels of their own folder).
numba itself still checks each kernel's source file and the processor it was compiled for (its index), and
writes each file under a temporary name before renaming it into place.

Where: ``$XDG_CACHE_HOME/rivercal/kernels`` or ``~/.cache/rivercal/kernels``. Where ``NUMBA_CACHE_DIR``
is set, numba's own locator is used (that setting wins); without a home folder, or where the folder cannot
be written, numba keeps the kernels beside their sources as before. Where that cannot be written either (a
read-only installation run by a user whose home cannot be written), numba would refuse to compile them at
all ("cannot cache function"); they are then kept in a private folder of the process (removed when it ends)
and the process compiles them for itself, with a warning that says how to keep them. At most :data:`KEEP`
versions of a folder's kernels are kept; using a new one removes the least recently used beyond that.
"""

from __future__ import annotations

import atexit
import functools
import hashlib
import logging
import os
import shutil
import tempfile
from pathlib import Path

from rivercal._cache_dirs import user_cache

__all__ = ["KEEP", "install", "kernel_folder"]

log = logging.getLogger(__name__)

#: Versions of a folder's kernels kept (about 15 MB each for the engine).
KEEP = 4
#: rivercal's package folder: the kernels of the files in its folders are placed by this module.
_PACKAGE = Path(__file__).resolve().parent


def install() -> None:
    """Put rivercal's locator first in numba's list of cache locators (once; kernels decorated later use it).

    Call it before decorating kernels with ``cache=True``. Where numba's internals differ (another numba
    version without the list), nothing changes and numba places the kernels itself.
    """
    import numba
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    classes = getattr(impl, "_locator_classes", None)
    if not isinstance(classes, list):
        log.debug("numba %s has no list of cache locators: its kernels stay in its default places",
                  numba.__version__)
        return
    locator = _locator_class()
    if locator not in classes:
        classes.insert(0, locator)
    last_resort = _private_locator_class()
    if last_resort not in classes:
        classes.append(last_resort)


def kernel_folder(source: str | Path) -> Path | None:
    """The folder where the kernels of rivercal source file ``source`` are kept; None where numba places them.

    One folder per version of the source files beside ``source`` (and below it): for the engine's kernels,
    ``<cache>/rivercal/kernels/engine.kernels-<digest>``. None for files outside a folder of rivercal's
    package, with ``NUMBA_CACHE_DIR`` set, or without a home folder.
    """
    try:
        relative = Path(source).resolve().relative_to(_PACKAGE)
    except ValueError:
        return None
    if len(relative.parts) < 2 or os.environ.get("NUMBA_CACHE_DIR", "").strip():
        return None
    root = user_cache("kernels")
    if root is None:
        return None
    folder = relative.parent
    return root / f"{'.'.join(folder.parts)}-{_digest(folder.as_posix())}"


@functools.cache
def _digest(folder: str) -> str:
    """Short SHA-256 of a package folder's sources (paths, contents) and of numpy's, numba's, llvmlite's versions."""
    import llvmlite
    import numba
    import numpy as np

    digest = hashlib.sha256()
    for part in (np.__version__, numba.__version__, llvmlite.__version__):
        digest.update(f"{part}|".encode())
    where = _PACKAGE / folder
    for path in sorted(where.rglob("*.py")):
        digest.update(path.relative_to(where).as_posix().encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _source_stamp(path: str) -> str:
    """SHA-256 of a source file: numba's check that a kept kernel was compiled from this file."""
    st = os.stat(path)
    return _file_digest(path, st.st_mtime_ns, st.st_size)


@functools.cache
def _file_digest(path: str, mtime_ns: int, size: int) -> str:
    """SHA-256 of a file's content (read again when its time or size changes)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@functools.cache
def _in_use(version: Path) -> None:
    """Mark a version folder as used now (its time) and remove the least recently used versions beyond KEEP."""
    try:
        os.utime(version)
        versions = sorted((p for p in version.parent.glob(version.name.rsplit("-", 1)[0] + "-*") if p.is_dir()),
                          key=lambda p: p.stat().st_mtime, reverse=True)
    except OSError as exc:
        log.debug("kernel cache: cannot look at %s: %s", version.parent, exc)
        return
    for old in versions[KEEP:]:
        if old != version:
            log.info("kernel cache: removing the compiled kernels of an older version, %s", old)
            shutil.rmtree(old, ignore_errors=True)


@functools.cache
def _locator_class() -> type:
    """The numba cache locator of rivercal's kernels (a class built on numba's, made when numba is imported)."""
    from numba.core.caching import _CacheLocator

    class KernelLocator(_CacheLocator):
        """Places the kernels of a rivercal source file in :func:`kernel_folder`."""

        def __init__(self, py_func, py_file: str, folder: Path):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._folder = folder

        def get_cache_path(self) -> str:
            return str(self._folder)

        def get_source_stamp(self) -> str:
            return _source_stamp(self._py_file)

        def get_disambiguator(self) -> str:
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func, py_file):
            version = kernel_folder(py_file)
            if version is None:
                return None
            self = cls(py_func, py_file, version)
            try:
                self.ensure_cache_path()
            except OSError as exc:
                _unwritable(version, str(exc))
                return None
            _in_use(version)
            return self

    return KernelLocator


_REPORTED: set[Path] = set()


def _unwritable(version: Path, reason: str) -> None:
    """Report once per folder that kernels cannot be kept there."""
    if version in _REPORTED:
        return
    _REPORTED.add(version)
    log.warning("the compiled kernels cannot be kept in %s (%s); numba keeps them in its default place where it "
                "can write", version, reason)


@functools.cache
def _private_locator_class() -> type:
    """The last numba cache locator: rivercal's kernels in a private folder of this process, when no other can."""
    from numba.core.caching import _CacheLocator

    class PrivateKernelLocator(_CacheLocator):
        """Places the kernels of a rivercal source file in this process's own folder (none could be written)."""

        def __init__(self, py_func, py_file: str, folder: Path):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._folder = folder

        def get_cache_path(self) -> str:
            return str(self._folder)

        def get_source_stamp(self) -> str:
            return _source_stamp(self._py_file)

        def get_disambiguator(self) -> str:
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func, py_file):
            try:
                relative = Path(py_file).resolve().relative_to(_PACKAGE)
            except (ValueError, OSError):
                return None
            folder = _private_folder()
            if folder is None:
                return None
            self = cls(py_func, py_file, folder / ".".join(relative.parent.parts))
            try:
                self.ensure_cache_path()
            except OSError:
                return None
            _report_private(folder)
            return self

    return PrivateKernelLocator


_PRIVATE: dict[int, Path | None] = {}


def _private_folder() -> Path | None:
    """The folder of this process's own kernels (made once, 0700, removed when the process that made it ends)."""
    pid = os.getpid()
    if pid not in _PRIVATE:
        try:
            folder = Path(tempfile.mkdtemp(prefix="rivercal-kernels-"))
        except OSError as exc:
            log.warning("the compiled kernels cannot be kept anywhere (%s)", exc)
            _PRIVATE[pid] = None
            return None
        _PRIVATE[pid] = folder
        atexit.register(_remove_private, pid, folder)
    return _PRIVATE[pid]


def _remove_private(pid: int, folder: Path) -> None:
    if os.getpid() == pid:  # not in a forked child that ends normally: the folder is its parent's
        shutil.rmtree(folder, ignore_errors=True)


def _report_private(folder: Path) -> None:
    """Say once per process that the kernels are compiled for this process only."""
    if folder in _REPORTED:
        return
    _REPORTED.add(folder)
    log.warning("the compiled kernels cannot be kept on disk (neither the user's cache folder nor the folder of "
                "rivercal's sources can be written): this process compiles them for itself (about a minute) and "
                "keeps them in %s until it ends. Set XDG_CACHE_HOME (or NUMBA_CACHE_DIR) to a folder you can write "
                "to keep them for the next runs", folder)
