"""The process table as the tests see it (Linux /proc): descendants of a process, and whether one lives."""

from __future__ import annotations

import os
import signal
import time


def _stat(pid: int | str) -> list[str] | None:
    """Fields of /proc/<pid>/stat after the command name (state first, then the parent's pid), or None.

    Read with one ``os.read`` of raw bytes: the kill tests scan the whole process table every few hundredths of a
    second while a run lives, and opening each file as text took half of each scan's processor time.
    """
    try:
        fd = os.open(f"/proc/{pid}/stat", os.O_RDONLY)
    except OSError:
        return None
    try:
        data = os.read(fd, 4096)  # a stat line is a few hundred bytes (the command name at most 15 of them)
    except OSError:
        return None
    finally:
        os.close(fd)
    return data.decode("ascii", "replace").rpartition(")")[2].split()


def alive(pid: int) -> bool:
    """Whether a process exists and is not a zombie (PID 1 of a container may never reap orphans)."""
    fields = _stat(pid)
    return fields is not None and fields[0] not in "ZX"


def descendants(pid: int) -> set[int]:
    """Pids of the live processes below ``pid`` (children, their children, ...)."""
    parent_of = {}
    for name in os.listdir("/proc"):
        if name.isdigit() and (fields := _stat(name)) is not None and fields[0] not in "ZX":
            parent_of[int(name)] = int(fields[1])
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
