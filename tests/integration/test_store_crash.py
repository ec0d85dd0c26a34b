"""Crash safety of the store: SIGKILL a service in the middle of a cycle, restart it, lose nothing.

DESIGN.md: "nothing that was stored is lost when a process is killed". This file is also the worker:
``python test_store_crash.py DB N PAUSE FOLDER`` runs cycles 0..N-1 of a fake service through the store
(ingest the window's observations, begin the cycle, "compute" by sleeping, commit estimates, alerts and
forecasts in one transaction). With PAUSE = ``<phase>:<cycle>`` it stops at that point — inside the
ingest transaction, during the computation, inside the commit transaction, or between two cycles —
writes a marker file and sleeps, so that the test can SIGKILL it exactly there. The paused points inside
transactions are reached through the store's own debug log records, so the library needs no test hooks.
"""

from __future__ import annotations

import logging
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.observations import ObservationSet
from rivercal.store import AlertRecord, BandRecord, CycleRecord, CycleStateError, EstimateRecord, Schedule, Store

HERE = Path(__file__).resolve()
SCHEDULE = Schedule("2010-11-01T06:00:00Z", period=pd.Timedelta(days=1), window=pd.Timedelta(days=2))
SERIES = ("ZL1-5930.h_up", "ZL1-5930.h_down", "ZL1-3014.Q")
PARAMETERS = ("friction:global", "weirs", "weir:ZL1-5930.crest_level")
#: Enough cycles for every kind of cycle (alerts every third, a held estimate every fourth) before and after
#: each point a test kills at, and for the latest ensemble to move on after a kill.
N_CYCLES = 6
COMPUTE_S = 0.03
LEADS = 49  # hourly forecast values, 0..48 h
ENSEMBLE_BYTES = 256 * 1024  # the ensemble a cycle hands to the next (the store keeps the latest per run)


def expected_estimates(k: int) -> dict[str, tuple[float, bool]]:
    """The fake computation's deterministic result of cycle k: parameter -> (value, accepted)."""
    return {"friction:global": (16.0 + 0.5 * k, True), "weirs": (0.3 + 0.01 * k, k % 4 != 3),
            "weir:ZL1-5930.crest_level": (7.14 - 0.01 * k, True)}


def observed(series: str, times: pd.DatetimeIndex) -> np.ndarray:
    offset = {"ZL1-5930.h_up": 7.3, "ZL1-5930.h_down": 6.9, "ZL1-3014.Q": 1.2}[series]
    hours = (times - pd.Timestamp("2010-10-01", tz="UTC")) / pd.Timedelta(hours=1)
    return offset + 0.1 * np.sin(np.asarray(hours, dtype=float) / 12.0)


def ensemble_data(k: int) -> bytes:
    """The fake ensemble of cycle k (its bytes differ from cycle to cycle)."""
    return np.random.default_rng(1000 + k).bytes(ENSEMBLE_BYTES)


def window_observations(spec) -> ObservationSet:
    times = pd.date_range(spec.window_start, spec.window_end, freq="h")
    return ObservationSet.from_frame(pd.DataFrame({s: observed(s, times) for s in SERIES}, index=times))


def cycle_record(spec) -> CycleRecord:
    k = spec.cycle
    estimates = [EstimateRecord(p, v, "m1/3 s-1" if p.startswith("friction") else "m", std=0.1, accepted=ok,
                                reason=None if ok else "jump of 5.2 std: held")
                 for p, (v, ok) in expected_estimates(k).items()]
    alerts = [AlertRecord("jump", f"cycle {k}: friction jumped", "friction:global", 4.0 + k)] if k % 3 == 2 else []
    times = pd.date_range(spec.issue_time, periods=LEADS, freq="h")
    forecasts = {kind: pd.DataFrame({s: observed(s, times) + shift for s in SERIES}, index=times)
                 for kind, shift in (("updated", 0.01), ("dss", 0.05))}
    bands = BandRecord(forecasts["updated"] - 0.05, forecasts["updated"] + 0.05)
    return CycleRecord(k, spec.window_start, spec.window_end, spec.issue_time, status="done", algorithm="dud",
                       model_runs=7 + k, cost_before=2.0, cost_after=1.0, message="converged", estimates=estimates,
                       alerts=alerts, forecasts=forecasts, bands=bands,
                       ensemble=(spec.issue_time, 64, "fake-ensemble", ensemble_data(k)))


# ---------------------------------------------------------------------------------------------------------
# the worker


class _PauseInside(logging.Handler):
    """Pause (marker + sleep) when the store logs the start of the paused phase inside its transaction."""

    def __init__(self, prefix: str, marker: Path):
        super().__init__(logging.DEBUG)
        self.prefix, self.marker = prefix, marker

    def emit(self, record: logging.LogRecord) -> None:
        if record.getMessage().startswith(self.prefix):
            pause(self.marker)


def pause(marker: Path) -> None:
    marker.write_text(str(os.getpid()))
    time.sleep(120)  # the test kills us here
    raise SystemExit("pause was not ended by a kill")


def worker(db: str, n: int, pause_at: str, folder: Path) -> None:
    phase, _, at = pause_at.partition(":")
    at_cycle = int(at) if at else -1
    marker = folder / "paused"
    log = logging.getLogger("rivercal.store")
    log.setLevel(logging.DEBUG)
    current = {"cycle": -1}
    if phase in ("commit", "ingest"):
        handler = _PauseInside("commit cycle" if phase == "commit" else "ingest ", marker)
        handler.addFilter(lambda record: current["cycle"] == at_cycle)
        log.addHandler(handler)
    with Store(db) as store:
        run = store.ensure_run("crash-test", "synthetic", {"cycles": n})
        (folder / "alive").write_text(str(os.getpid()))
        while (spec := store.next_cycle(run.id, SCHEDULE)).cycle < n:
            current["cycle"] = spec.cycle
            store.ingest(window_observations(spec), "feed")
            spec = store.begin_cycle(run.id, spec)
            if phase == "compute" and spec.cycle == at_cycle:
                pause(marker)
            time.sleep(COMPUTE_S)  # the fake calibration
            store.commit_cycle(run.id, cycle_record(spec))
            if phase == "between" and spec.cycle == at_cycle:
                pause(marker)


# ---------------------------------------------------------------------------------------------------------
# the tests


@pytest.fixture(params=["sqlite", "postgresql"])
def backend(request, tmp_path: Path) -> tuple[str, Path]:
    """(store location, folder of the worker's marker files): a SQLite file or a real PostgreSQL database."""
    if request.param == "postgresql":
        return request.getfixturevalue("pg_url"), tmp_path
    return str(tmp_path / "service.db"), tmp_path


def _start(backend: tuple[str, Path], pause_at: str = "none", n: int = N_CYCLES) -> subprocess.Popen:
    db, folder = backend
    return subprocess.Popen([sys.executable, str(HERE), db, str(n), pause_at, str(folder)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _wait_for(path: Path, proc: subprocess.Popen, timeout_s: float = 30.0) -> None:
    end = time.monotonic() + timeout_s
    while not path.exists():
        if proc.poll() is not None:
            raise AssertionError(f"worker exited ({proc.returncode}) before {path.name}: {proc.stderr.read()}")
        if time.monotonic() > end:
            proc.kill()
            raise AssertionError(f"worker did not reach {path.name} in {timeout_s} s")
        time.sleep(0.005)


def _kill(proc: subprocess.Popen) -> None:
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL
    proc.stdout.close()
    proc.stderr.close()


def _finish(backend: tuple[str, Path]) -> None:
    """The restart that runs to the end, in this process (no start-up of one more interpreter): the killed
    worker is gone, and all the restart has is what the store kept, here as in a new process."""
    db, folder = backend
    log = logging.getLogger("rivercal.store")
    level = log.level
    try:
        worker(db, N_CYCLES, "none", folder)
    finally:
        log.setLevel(level)  # the worker turns the store's debug log on


def _n_observations(k_last: int) -> int:
    """Unique hourly values of all series over the windows of cycles 0..k_last."""
    if k_last < 0:
        return 0
    first = SCHEDULE.spec(0).window_start
    last = SCHEDULE.spec(k_last).window_end
    return len(SERIES) * (int((last - first) / pd.Timedelta(hours=1)) + 1)


def assert_complete(db: str) -> None:
    """Every cycle once and done, results matching the cycles, nothing duplicated, a sound file."""
    with Store(db) as store:
        run = store.get_run("crash-test")
        cycles = store.cycles(run.id)
        assert cycles["cycle"].tolist() == list(range(N_CYCLES))
        assert (cycles["status"] == "done").all()
        for k, row in cycles.set_index("cycle").iterrows():
            assert row["issue_time"] == SCHEDULE.spec(k).issue_time
            assert row["model_runs"] == 7 + k
        est = store.estimates(run.id)
        assert len(est) == N_CYCLES * len(PARAMETERS)
        for row in est.itertuples():
            value, accepted = expected_estimates(row.cycle)[row.parameter]
            assert (row.value, row.accepted) == (pytest.approx(value), accepted)
        assert sorted(store.alerts(run.id)["cycle"]) == [k for k in range(N_CYCLES) if k % 3 == 2]
        fc = store.forecasts(run.id)
        assert fc.groupby("cycle").size().tolist() == [2 * len(SERIES) * LEADS] * N_CYCLES
        assert not fc.duplicated(["cycle", "kind", "series", "time"]).any()
        assert store.forecast_bands(run.id).groupby("cycle").size().tolist() == [len(SERIES) * LEADS] * N_CYCLES
        assert store.ensemble(run.id)[1:] == (N_CYCLES - 1, 64, "fake-ensemble", ensemble_data(N_CYCLES - 1))
        avail = store.availability()
        assert avail["n"].sum() == _n_observations(N_CYCLES - 1)
        assert (avail["max_gap_h"] == 1.0).all()
        last_ok = max(k for k in range(N_CYCLES) if expected_estimates(k)["weirs"][1])
        assert store.last_accepted(run.id)["weirs"] == pytest.approx(expected_estimates(last_ok)["weirs"][0])
        assert store.integrity_check() == []
        if not db.startswith("postgresql://"):
            assert store._conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def _state_after_kill(db: str, phase: str, k: int) -> list[int]:
    """What a kill at ``phase`` of cycle ``k`` must leave behind: committed cycles only, no partial rows.

    Returns the done cycles.
    """
    with Store(db) as store:
        run = store.get_run("crash-test")
        if run is None:  # killed before the run was created
            return []
        cycles = store.cycles(run.id).set_index("cycle")
        done = [c for c, s in cycles["status"].items() if s == "done"]
        assert done == list(range(len(done)))
        assert (cycles["status"].drop(done) == "running").all()  # at most the one cycle that was killed
        est = store.estimates(run.id)
        fc = store.forecasts(run.id)
        assert sorted(est["cycle"].unique()) == done == sorted(fc["cycle"].unique())
        assert est.groupby("cycle").size().eq(len(PARAMETERS)).all()
        assert fc.groupby("cycle").size().eq(2 * len(SERIES) * LEADS).all()
        # the ensemble is the last done cycle's, whole (never a killed commit's, never half of one)
        assert sorted(store.forecast_bands(run.id)["cycle"].unique()) == done
        ensemble = store.ensemble(run.id)
        if done:
            assert ensemble[1:] == (done[-1], 64, "fake-ensemble", ensemble_data(done[-1]))
        else:
            assert ensemble is None
        if phase in ("compute", "commit"):
            assert done == list(range(k))
            assert cycles.loc[k, "status"] == "running"
            assert cycles.loc[k, "attempts"] == 1
        elif phase == "between":
            assert done == list(range(k + 1))
            assert k + 1 not in cycles.index
        elif phase == "ingest":
            assert done == list(range(k))
            assert k not in cycles.index
            assert store.availability()["n"].sum() == _n_observations(k - 1)  # the half ingest rolled back
        assert store.integrity_check() == []
        return done


@pytest.mark.slow
@pytest.mark.parametrize("pause_at", ["compute:3", "commit:0", "commit:4", "ingest:2", "between:5"])
def test_sigkill_at_a_point_then_resume(backend: tuple[str, Path], pause_at: str) -> None:
    db, folder = backend
    phase, _, at = pause_at.partition(":")
    proc = _start(backend, pause_at)
    _wait_for(folder / "paused", proc)
    if phase == "compute":  # a second service on the same run is refused while the first one lives
        with Store(db) as store:
            run = store.get_run("crash-test")
            with pytest.raises(CycleStateError, match="still alive"):
                store.begin_cycle(run.id, store.first_unfinished(run.id))
    _kill(proc)
    _state_after_kill(db, phase, int(at))
    _finish(backend)  # after "between:5" (the last cycle) the restart finds nothing to do
    assert_complete(db)
    with Store(db) as store:
        attempts = store.cycles(store.get_run("crash-test").id).set_index("cycle")["attempts"]
    again = int(at) if phase in ("compute", "commit") else None
    assert attempts.to_dict() == {k: 2 if k == again else 1 for k in range(N_CYCLES)}


@pytest.mark.slow
@pytest.mark.parametrize("seed", [11])
def test_sigkill_at_random_times_then_resume(backend: tuple[str, Path], seed: int) -> None:
    """Four kills at random moments of the work (any phase, or none), then a run to the end."""
    rng = random.Random(seed)
    db, folder = backend
    progress = [0]
    for _ in range(4):
        alive = folder / "alive"
        alive.unlink(missing_ok=True)
        proc = _start(backend)
        _wait_for(alive, proc)
        time.sleep(rng.uniform(0.0, N_CYCLES * COMPUTE_S * 0.6))
        if proc.poll() is None:
            _kill(proc)
        else:
            proc.communicate()
        progress.append(len(_state_after_kill(db, "random", -1)))
    assert progress == sorted(progress)  # nothing committed is ever lost
    _finish(backend)
    assert_complete(db)


if __name__ == "__main__":
    worker(sys.argv[1], int(sys.argv[2]), sys.argv[3], Path(sys.argv[4]))
