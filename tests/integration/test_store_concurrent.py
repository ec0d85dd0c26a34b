"""Two services write different runs into one store while a reader (a report, the dashboard) reads it.

Against a real PostgreSQL server and against the SQLite file. The services are separate processes (this
file is the service: ``python -m tests.integration.test_store_concurrent DB RUN``); the reader, in the test, reads
each run's cycles, estimates and forecasts over and over while they write, and must never see a cycle in
part: a done cycle has all its estimates and all its forecast values, because each cycle commits whole.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from rivercal.store import Store, StoreError
from tests.integration.test_store_crash import LEADS, PARAMETERS, SCHEDULE, SERIES, cycle_record, window_observations

ROOT = Path(__file__).resolve().parents[2]
CYCLES = 12
RUNS = ("north", "south")


def service(db: str, run_name: str) -> None:
    with Store(db) as store:
        run = store.ensure_run(run_name, "synthetic", {"cycles": CYCLES})
        while (spec := store.next_cycle(run.id, SCHEDULE)).cycle < CYCLES:
            store.ingest(window_observations(spec), f"feed-{run_name}")
            spec = store.begin_cycle(run.id, spec)
            time.sleep(0.02)  # the calibration
            store.commit_cycle(run.id, cycle_record(spec))


@pytest.fixture(params=["postgresql", "sqlite"])
def location(request, tmp_path: Path) -> str:
    if request.param == "postgresql":
        return request.getfixturevalue("pg_url")
    return str(tmp_path / "shared.db")


def test_two_services_and_a_reader_at_the_same_time(location: str) -> None:
    with Store(location):
        pass  # the schema exists before the services and the reader open it
    procs = [subprocess.Popen([sys.executable, "-m", "tests.integration.test_store_concurrent", location, name],
                              cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for name in RUNS]
    reads = 0
    seen_partly_done = set()
    try:
        with Store(location, readonly=True) as reader:
            while any(p.poll() is None for p in procs):
                for name in RUNS:
                    run = reader.get_run(name)
                    if run is None:
                        continue
                    done = set(reader.cycles(run.id).query("status == 'done'")["cycle"])
                    est = reader.estimates(run.id).groupby("cycle").size()
                    fc = reader.forecasts(run.id).groupby("cycle").size()
                    # a cycle's rows are all there or none; later reads may see more cycles, never fewer rows
                    assert set(est.index) >= done and (est == len(PARAMETERS)).all()
                    assert set(fc.index) >= done and (fc == 2 * len(SERIES) * LEADS).all()
                    if 0 < len(done) < CYCLES:
                        seen_partly_done.add(name)
                    reads += 1
                with pytest.raises(StoreError, match="read-only"):
                    reader.set_run_status(1, "stopped")
    finally:
        for p in procs:
            _, err = p.communicate(timeout=120)
            assert p.returncode == 0, err[-3000:]
    assert reads > 0 and seen_partly_done, "the reader never read while the services were writing"
    with Store(location) as store:
        runs = store.runs().set_index("name")
        assert sorted(runs.index) == sorted(RUNS)
        assert runs["done"].tolist() == [CYCLES, CYCLES]
        for name in RUNS:
            run = store.get_run(name)
            assert store.cycles(run.id)["attempts"].tolist() == [1] * CYCLES
            assert len(store.estimates(run.id)) == CYCLES * len(PARAMETERS)
        assert set(store.availability()["source"]) == {f"feed-{n}" for n in RUNS}
        assert store.integrity_check() == []


if __name__ == "__main__":
    service(sys.argv[1], sys.argv[2])
