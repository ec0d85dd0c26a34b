"""Run folders of a black box: one per evaluation and worker process, kept on failure (the newest N).

Each run gets ``<base>/run-<pid>-<started>-<n>``: the model folder copied into it
(:func:`~rivercal.models.blackbox.paths.copy_tree`; the templates' sources left out), so concurrent runs of
several worker processes never write a shared file. A successful run's folder is removed (unless
``keep``); a failed one is renamed ``failed-<time>-<pid>-<started>-<n>`` and kept for inspection, the
oldest failed folders beyond ``keep_failed`` removed; an interrupted one (Ctrl-C) is removed.

A process that was killed (SIGKILL, a power cut) cannot remove its run folder. The folder's name says
which process made it: its pid and its start time (``<started>``, clock ticks since boot from
``/proc/<pid>/stat``, so that a reused pid does not pass for the old owner). When a model is loaded, and
before a process's first run, the base folder is swept: the ``run-`` folders of a process that no longer
lives are removed (kept with ``keep``), after their programs, if any still runs, are killed (a program
carries its run folder in the environment variable :data:`MARKER`; found through ``/proc``).
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import re
import shutil
import signal
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path

from rivercal.models.blackbox.paths import copy_tree

__all__ = ["MARKER", "RunFolders", "default_base", "stop_marked"]

log = logging.getLogger(__name__)

#: Environment variable that holds the run folder in the environment of a run's program (and of every
#: process it starts that keeps its environment).
MARKER = "RIVERCAL_BLACKBOX_RUN"
_RUN = re.compile(r"^run-(\d+)-(\d+)-\d+$")


def default_base(name: str) -> Path:
    """Where the run folders of model ``name`` go without ``runs_dir``: under the system's temporary folder."""
    user = getattr(os, "getuid", lambda: "")()
    return Path(tempfile.gettempdir()) / f"rivercal-runs-{user}" / name


def _started(pid: int) -> int | None:
    """When a live process started (clock ticks since boot), 0 where /proc does not say, None when it is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_bytes()
    except FileNotFoundError:
        return None
    except OSError:
        return _exists(pid)
    fields = text.rpartition(b")")[2].split()
    if fields[0] in (b"Z", b"X"):
        return None
    return int(fields[19])


def _exists(pid: int) -> int | None:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return None
    except PermissionError:
        pass
    return 0


def _alive(pid: int, started: int) -> bool:
    """Whether process ``pid`` that started at ``started`` (clock ticks) still lives."""
    now = _started(pid) if Path("/proc").is_dir() else _exists(pid)
    return now is not None and (now == started or started == 0 or now == 0)


class RunFolders:
    """Makes, keeps and removes the run folders of one model.

    Parameters
    ----------
    name
        Model name (the default base folder is :func:`default_base`).
    base
        Where the run folders go.
    keep_failed
        Failed run folders kept (the newest).
    keep
        Keep successful run folders too.
    exclude
        Paths relative to the model folder (``/``-separated) not copied.
    """

    def __init__(self, name: str, *, base: Path | None = None, keep_failed: int = 5, keep: bool = False,
                 exclude: Iterable[str] = ()):
        self.base = Path(base) if base is not None else default_base(name)
        self.keep_failed = int(keep_failed)
        self.keep = keep
        self.exclude = set(exclude)
        self._count = itertools.count()
        self._swept: int | None = None  # the pid that swept last

    def _owner(self) -> str:
        """``<pid>-<started>`` of this process; the base folder swept at its first run."""
        pid = os.getpid()
        if self._swept != pid:
            self.sweep()
            self._swept = pid
        started = _started(pid) if Path("/proc").is_dir() else 0
        return f"{pid}-{started or 0}"

    def sweep(self) -> list[Path]:
        """Remove the run folders of processes that no longer live (and stop their programs); those removed."""
        try:
            entries = list(self.base.iterdir())
        except OSError:
            return []
        stale = []
        for entry in entries:
            m = _RUN.match(entry.name)
            if m and not _alive(int(m.group(1)), int(m.group(2))) and entry.is_dir() and not entry.is_symlink():
                stale.append(entry)
        if not stale:
            return []
        stop_marked({str(p) for p in stale})
        if self.keep:  # every run folder is kept, a killed run's too (its processes are stopped)
            return []
        for path in stale:
            shutil.rmtree(path, ignore_errors=True)
        log.info("removed %d run folders of ended processes in %s", len(stale), self.base)
        return stale

    # -- runs -------------------------------------------------------------------------------------

    def new(self, folder: Path) -> Path:
        """A fresh run folder holding a copy of ``folder``.

        Raises
        ------
        OSError
            When the base folder or the copy cannot be written.
        ValueError
            For an entry of the model folder that cannot be copied safely (a link that leads outside).
        """
        self.base.mkdir(parents=True, exist_ok=True)
        owner = self._owner()
        run_dir = self.base / f"run-{owner}-{next(self._count)}"
        try:
            copy_tree(folder, run_dir, exclude=self.exclude, skip=[self.base])
        except BaseException:
            shutil.rmtree(run_dir, ignore_errors=True)
            raise
        return run_dir

    def done(self, run_dir: Path) -> None:
        """A run succeeded: remove its folder unless asked to keep it."""
        if not self.keep:
            shutil.rmtree(run_dir, ignore_errors=True)

    def discard(self, run_dir: Path) -> None:
        """A run was interrupted: remove its folder."""
        shutil.rmtree(run_dir, ignore_errors=True)

    def failed(self, run_dir: Path) -> Path:
        """A run failed: keep its folder under a ``failed-`` name, prune the oldest beyond ``keep_failed``."""
        stamp = time.strftime("%Y%m%dT%H%M%S")
        kept = run_dir.with_name(f"failed-{stamp}-{run_dir.name[len('run-'):]}")
        try:
            run_dir.rename(kept)
        except OSError:
            kept = run_dir
        failed = []
        for p in self.base.glob("failed-*"):
            with contextlib.suppress(OSError):
                if p.is_dir() and not p.is_symlink():
                    failed.append((p.stat().st_mtime, p.name, p))
        failed.sort()
        for _, _, old in failed[: max(0, len(failed) - self.keep_failed)]:
            shutil.rmtree(old, ignore_errors=True)
        log.info("kept the folder of a failed run: %s", kept)
        return kept


def stop_marked(run_dirs: set[str]) -> list[int]:
    """SIGKILL the processes of this user whose :data:`MARKER` names one of ``run_dirs`` (Linux /proc); their pids."""
    if not run_dirs or not Path("/proc").is_dir():
        return []
    wanted = {f"{MARKER}={d}".encode() for d in run_dirs}
    me = os.getpid()
    killed = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == me:
            continue
        try:
            with open(f"/proc/{entry}/environ", "rb") as f:
                env = f.read(1 << 20).split(b"\0")
        except OSError:  # another user's process, or ended
            continue
        if wanted.intersection(env):
            with contextlib.suppress(OSError):
                os.kill(int(entry), signal.SIGKILL)
                killed.append(int(entry))
    if killed:
        log.info("stopped %d processes left by ended runs", len(killed))
    return killed
