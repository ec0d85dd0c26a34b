"""Worker processes of an Evaluator end when their parent is killed (SIGKILL), and not before.

This file is also the parent: ``python -m tests.integration.test_evaluate_workers MODE`` starts a pool of two
workers, evaluates a batch, prints ``ready`` and sleeps until it is killed. MODE ``main`` starts the pool
from the main thread (the Linux parent-death signal and the parent-pipe watchdog both armed); ``thread``
starts it from a thread that ends before the pool is used again (the watchdog alone; the kernel's signal
would wrongly fire when that thread ends); ``bare`` is a plain ProcessPoolExecutor without the guard, the
control that shows the orphans the guard prevents.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from rivercal.evaluate import Evaluator
from tests.processes import descendants, kill_left, survivors

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the process table in /proc")


def _pid(x: np.ndarray) -> np.ndarray:
    return np.array([float(os.getpid())])


def parent(mode: str) -> None:
    xs = [np.zeros(1)] * 8
    if mode == "bare":
        pool = ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork"))
        list(pool.map(_pid, xs))
    else:
        holder: list[Evaluator] = []

        def start() -> None:
            holder.append(Evaluator(_pid, workers=2))
            holder[0](xs)

        if mode == "main":
            start()
        else:
            thread = threading.Thread(target=start)
            thread.start()
            thread.join()
            time.sleep(0.5)  # a worker wrongly killed with the thread would be gone by now
        assert len({float(r[0]) for r in holder[0](xs)} - {float(os.getpid())}) >= 1  # still computing in workers
    print("ready", flush=True)
    time.sleep(600)


def kill_parent(mode: str) -> list[int]:
    """Start a parent in ``mode``, SIGKILL it once its pool works; return its workers' pids."""
    proc = subprocess.Popen([sys.executable, "-m", "tests.integration.test_evaluate_workers", mode], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        assert line.strip() == "ready", proc.stderr.read()[-2000:]
        workers = sorted(descendants(proc.pid))
        assert len(workers) == 2, workers
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        proc.stdout.close()
        proc.stderr.close()
    return workers


@pytest.mark.parametrize("mode", ["main", "thread"])
def test_workers_end_within_seconds_of_a_sigkilled_parent(mode: str) -> None:
    workers = kill_parent(mode)
    try:
        assert survivors(workers, within_s=5.0) == []
    finally:
        kill_left(workers)


def test_without_the_guard_the_workers_outlive_their_parent() -> None:
    workers = kill_parent("bare")
    try:
        assert survivors(workers, within_s=2.0) == workers  # the orphans the guard prevents
    finally:
        kill_left(workers)


if __name__ == "__main__":
    parent(sys.argv[1])
