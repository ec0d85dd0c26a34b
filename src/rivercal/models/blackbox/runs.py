"""Run folders of a black box: one per evaluation and worker process, kept on failure (the newest N).

Each run gets ``<base>/run-<pid>-<n>``: the model folder copied into it (templates' sources left out),
so concurrent runs of several worker processes never write a shared file. A successful run's folder is
removed (unless ``keep``); a failed one is renamed ``failed-<time>-<pid>-<n>`` and kept for inspection,
the oldest failed folders beyond ``keep_failed`` removed.
"""

from __future__ import annotations

import itertools
import logging
import os
import shutil
import tempfile
import time
from collections.abc import Iterable
from pathlib import Path

__all__ = ["RunFolders"]

log = logging.getLogger(__name__)


class RunFolders:
    """Makes, keeps and removes the run folders of one model.

    Parameters
    ----------
    name
        Model name (the default base folder is ``<tmp>/rivercal-runs/<name>``).
    base
        Where the run folders go.
    keep_failed
        Failed run folders kept (the newest).
    keep
        Keep successful run folders too.
    exclude
        File names (relative to the model folder) not copied.
    """

    def __init__(self, name: str, *, base: Path | None = None, keep_failed: int = 5, keep: bool = False,
                 exclude: Iterable[str] = ()):
        self.base = Path(base) if base is not None else Path(tempfile.gettempdir()) / "rivercal-runs" / name
        self.keep_failed = int(keep_failed)
        self.keep = keep
        self.exclude = {str(Path(e)) for e in exclude}
        self._count = itertools.count()

    def new(self, folder: Path) -> Path:
        """A fresh run folder holding a copy of ``folder``."""
        self.base.mkdir(parents=True, exist_ok=True)
        run_dir = self.base / f"run-{os.getpid()}-{next(self._count)}"
        if run_dir.exists():  # left by an earlier process with the same pid
            shutil.rmtree(run_dir, ignore_errors=True)
        base = self.base.resolve()
        folder = folder.resolve()

        def ignore(directory: str, names: list[str]) -> set[str]:
            here = Path(directory)
            return {n for n in names
                    if str((here / n).relative_to(folder)) in self.exclude or (here / n).resolve() == base}

        shutil.copytree(folder, run_dir, ignore=ignore)
        return run_dir

    def done(self, run_dir: Path) -> None:
        """A run succeeded: remove its folder unless asked to keep it."""
        if not self.keep:
            shutil.rmtree(run_dir, ignore_errors=True)

    def failed(self, run_dir: Path) -> Path:
        """A run failed: keep its folder under a ``failed-`` name, prune the oldest beyond ``keep_failed``."""
        stamp = time.strftime("%Y%m%dT%H%M%S")
        kept = run_dir.with_name(f"failed-{stamp}-{run_dir.name[len('run-'):]}")
        try:
            run_dir.rename(kept)
        except OSError:
            kept = run_dir
        failed = sorted((p for p in self.base.glob("failed-*") if p.is_dir()), key=lambda p: p.stat().st_mtime)
        for old in failed[: max(0, len(failed) - self.keep_failed)]:
            shutil.rmtree(old, ignore_errors=True)
        log.info("kept the folder of a failed run: %s", kept)
        return kept
