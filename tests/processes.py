"""The process table as the tests see it (Linux /proc): descendants of a process, and whether one lives."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path


def _stat(pid: int | str) -> list[str] | None:
    """Fields of /proc/<pid>/stat after the command name (state first, then the parent's pid), or None."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text.rpartition(")")[2].split()


def alive(pid: int) -> bool:
    """Whether a process exists and is not a zombie (PID 1 of a container may never reap orphans)."""
    fields = _stat(pid)
    return fields is not None and fields[0] not in "ZX"


def descendants(pid: int) -> set[int]:
    """Pids of the live processes below ``pid`` (children, their children, ...)."""
    parent_of = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and (fields := _stat(entry.name)) is not None and fields[0] not in "ZX":
            parent_of[int(entry.name)] = int(fields[1])
    found, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, parent in parent_of.items() if parent in frontier} - found
        found |= frontier
    return found


def survivors(pids: set[int] | list[int], within_s: float) -> list[int]:
    """The processes among ``pids`` still alive after waiting up to ``within_s`` seconds for them to end."""
    deadline = time.monotonic() + within_s
    while (left := sorted(p for p in pids if alive(p))) and time.monotonic() < deadline:
        time.sleep(0.05)
    return left


def kill_left(pids: set[int] | list[int]) -> None:
    """SIGKILL whichever of these processes (started by the test) are still alive."""
    for pid in pids:
        if alive(pid):
            os.kill(pid, signal.SIGKILL)
