"""SIGKILL the on-line service in the middle of a cycle, start it again: no lost and no repeated cycle.

This file is also the worker: ``python -m tests.integration.test_online_crash DB UNTIL SLOW`` runs the service
on the toy river of :mod:`tests.unit.test_online_service` (observations of a friction jump) up to issue
time UNTIL; with SLOW > 0 every model run sleeps SLOW s, so that a cycle lasts long enough to be killed
while it is being computed. The resumed run must end with exactly the estimates, forecasts and states of
a run that was never killed: the killed cycle is recomputed from the state the previous cycle stored.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from rivercal.online.service import OnlineConfig, OnlineService
from rivercal.store import Store, StoreError

ROOT = Path(__file__).resolve().parents[2]
CONFIG = OnlineConfig(parameters=("FA", "Wd"), workers=1, deadline_s=None)
FIRST, UNTIL = "2010-10-30", "2010-11-04"


def work(db: str, until: str, slow: float) -> None:
    from tests.unit.test_online_service import MOWED, ToyRiver, _observations

    class SlowToy(ToyRiver):
        def simulate(self, *args, **kwargs):
            time.sleep(slow)
            return super().simulate(*args, **kwargs)

    with Store(db) as store:
        store.ingest(_observations(ToyRiver(), MOWED), "truth")
        OnlineService(SlowToy(), store, "toy", CONFIG, first_issue=FIRST).replay(until)


def _start(db: Path, slow: float) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "tests.integration.test_online_crash", str(db), UNTIL, str(slow)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _running_cycle(db: Path) -> int | None:
    if not db.exists():
        return None
    try:
        with Store(db, readonly=True) as store:
            run = store.get_run("toy")
            if run is None:
                return None
            cycles = store.cycles(run)
    except StoreError:  # the writer may still be creating or migrating the file
        return None
    running = cycles[cycles["status"] == "running"]
    return int(running["cycle"].iloc[0]) if len(running) else None


def _contents(db: Path) -> tuple[pd.DataFrame, pd.DataFrame, list[bytes]]:
    with Store(db, readonly=True) as store:
        run = store.get_run("toy")
        est = store.estimates(run)[["cycle", "parameter", "value", "accepted"]]
        fc = store.forecasts(run)[["cycle", "kind", "series", "time", "value"]]
        states = [store.model_state(run, "updated", cycle=c)[2] for c in store.cycles(run)["cycle"]]
        return est, fc, states


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run that was never killed: the worker's work, run in this process (no start-up of one more interpreter)."""
    db = tmp_path_factory.mktemp("reference") / "reference.sqlite"
    work(str(db), UNTIL, 0.0)
    return db


@pytest.mark.parametrize("kill_in", [2, 4])
def test_sigkill_mid_cycle_then_restart_loses_and_repeats_nothing(tmp_path: Path, reference: Path,
                                                                   kill_in: int) -> None:
    db = tmp_path / "killed.sqlite"
    proc = _start(db, 0.05)
    deadline = time.monotonic() + 240
    while _running_cycle(db) != kill_in:
        assert proc.poll() is None, proc.communicate()[1][-2000:]
        assert time.monotonic() < deadline, "the worker never reached the cycle to kill"
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)
    with Store(db, readonly=True) as store:
        cycles = store.cycles(store.get_run("toy"))
        assert cycles["status"].tolist() == ["done"] * kill_in + ["running"]
        assert store.estimates(store.get_run("toy"))["cycle"].max() == kill_in - 1  # nothing of the killed cycle

    # the restart, in this process (as the reference: no start-up of one more interpreter); the killed
    # process is gone, and all the restart has is what the store kept
    work(str(db), UNTIL, 0.0)
    with Store(db, readonly=True) as store:
        cycles = store.cycles(store.get_run("toy"))
    n = len(pd.date_range(FIRST, UNTIL, freq="D"))
    assert cycles["cycle"].tolist() == list(range(n)) and (cycles["status"] == "done").all()
    assert cycles["attempts"].tolist() == [2 if c == kill_in else 1 for c in range(n)]
    est, fc, states = _contents(db)
    ref_est, ref_fc, ref_states = _contents(reference)
    pd.testing.assert_frame_equal(est, ref_est)
    pd.testing.assert_frame_equal(fc, ref_fc)
    assert states == ref_states


if __name__ == "__main__":
    work(sys.argv[1], sys.argv[2], float(sys.argv[3]))
