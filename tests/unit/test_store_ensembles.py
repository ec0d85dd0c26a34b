"""State updating in the store: the latest ensemble per run (bounded size) and the forecast bands, on both servers."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.store import BandRecord, CycleRecord, EstimateRecord, Schedule, Store, StoreError
from rivercal.store import schema as store_schema

SCHEDULE = Schedule("2010-11-01T06:00:00Z", period=pd.Timedelta(days=1), window=pd.Timedelta(days=2))
SERIES = ["ZL1-5930.h_up", "ZL1-3014.Q"]


@pytest.fixture(params=["sqlite"])
def location(tmp_path: Path):
    """A SQLite file (the same tests on a real PostgreSQL server: tests/integration)."""
    return tmp_path / "service.db"


def _blob(k: int, size: int = 1 << 20) -> bytes:
    """A cycle's ensemble: ``size`` bytes that differ from cycle to cycle (random: they do not compress)."""
    return np.random.default_rng(k).bytes(size)


def _record(k: int, *, ensemble: bool = True, size: int = 1 << 20) -> CycleRecord:
    spec = SCHEDULE.spec(k)
    times = pd.date_range(spec.issue_time, periods=49, freq="h")
    mean = pd.DataFrame({s: 7.0 + 0.01 * k + 0.001 * np.arange(49) for s in SERIES}, index=times)
    return CycleRecord(k, spec.window_start, spec.window_end, spec.issue_time, estimates=[EstimateRecord("FA", 20.0,
                       "m^(1/3)/s")], forecasts={"updated": mean},
                       bands=BandRecord(low=mean - 0.05 - 0.001 * np.arange(49)[:, None], high=mean + 0.07),
                       ensemble=(spec.issue_time, 64, "test-ensemble-1", _blob(k, size)) if ensemble else None)


def _tables(store: Store) -> list[str]:
    return store._tables(store._conn) if hasattr(store, "_tables") else store_schema.user_tables(store._conn)


def _commit(store: Store, run, k: int, **kwargs) -> None:
    spec = store.begin_cycle(run.id, store.next_cycle(run.id, SCHEDULE))
    assert spec.cycle == k
    store.commit_cycle(run.id, _record(k, **kwargs))


def test_the_store_keeps_the_latest_ensemble_per_run_and_every_cycles_bands(location) -> None:
    with Store(location) as store:
        run = store.ensure_run("r", "dommel", {})
        other = store.ensure_run("other", "dommel", {})
        assert store.ensemble(run) is None and store.forecast_bands(run).empty
        for k in range(3):
            _commit(store, run, k)
        _commit(store, other, 0)
        _commit(store, run, 3, ensemble=False)  # a cycle without one (e.g. failed) leaves the last one stored
        time, cycle, members, fmt, data = store.ensemble(run)
        assert (time, cycle, members, fmt) == (SCHEDULE.spec(2).issue_time, 2, 64, "test-ensemble-1")
        assert data == _blob(2)
        assert store.ensemble(other)[1] == 0 and store.ensemble(other)[4] == _blob(0)
        assert store._conn.execute("SELECT count(*) FROM ensembles").fetchone()[0] == 2
        bands = store.forecast_bands(run)
        assert sorted(bands["cycle"].unique()) == [0, 1, 2, 3]
        one = bands[(bands["cycle"] == 1) & (bands["series"] == SERIES[0])].set_index("time")
        expected = _record(1).bands
        assert np.allclose(one["low"], expected.low[SERIES[0]]) and np.allclose(one["high"], expected.high[SERIES[0]])
        assert (one["probability"] == 0.9).all() and one["lead_h"].tolist() == list(range(49))
        # a re-run of an older cycle does not replace a later cycle's ensemble; a re-run of the owner drops it
        store.retry_cycle(run.id, 1)
        store.begin_cycle(run.id, store.next_cycle(run.id, SCHEDULE))
        store.commit_cycle(run.id, _record(1))
        assert store.ensemble(run)[1] == 2
        store.retry_cycle(run.id, 2)
        assert store.ensemble(run) is None
        assert store.integrity_check() == []
        store._conn.execute("DELETE FROM runs WHERE name = 'other'")  # cascades to its cycles and ensemble
        assert store._conn.execute("SELECT count(*) FROM ensembles").fetchone()[0] == 0


def test_a_bad_band_is_refused_before_anything_is_written_and_the_forecast_kinds_stay(location) -> None:
    with Store(location) as store:
        run = store.ensure_run("r", "dommel", {})
        spec = store.begin_cycle(run.id, store.next_cycle(run.id, SCHEDULE))
        good = _record(0)
        with pytest.raises(ValueError, match=r"high .* is below low"):
            store.commit_cycle(run.id, CycleRecord(0, spec.window_start, spec.window_end, spec.issue_time,
                                                   ensemble=good.ensemble,
                                                   bands=BandRecord(good.bands.high, good.bands.low)))
        assert store.cycles(run)["status"].tolist() == ["running"] and store.ensemble(run) is None
        with pytest.raises(ValueError, match="probability must be between 0 and 1"):
            BandRecord(good.bands.low, good.bands.high, probability=90)
        with pytest.raises(ValueError, match="ensemble must be"):
            CycleRecord(0, spec.window_start, spec.window_end, spec.issue_time, ensemble=(spec.issue_time, 0, "x",
                                                                                          b"1"))
        # the forecasts table still takes only its two kinds
        with pytest.raises(StoreError):
            with store._transaction() as conn:
                conn.execute("INSERT INTO forecasts (cycle_id, kind, series, time, lead_h, value) "
                             "VALUES (1, 'band', 'a.h', 0, 0, 1.0)")


def test_a_version_5_store_migrates_to_6_and_keeps_its_data(location, monkeypatch) -> None:
    monkeypatch.setattr("rivercal.store.base.MIGRATIONS", store_schema.MIGRATIONS[:5])
    monkeypatch.setattr("rivercal.store.base.SCHEMA_VERSION", 5)
    with Store(location) as store:
        assert store.schema_version == 5
        run = store.ensure_run("r", "dommel", {"window_days": 2})
        store.begin_cycle(run.id, store.next_cycle(run.id, SCHEDULE))
        with store._transaction() as conn:  # a cycle as version 5 stored it
            conn.execute("UPDATE cycles SET status = 'done', finished = '2026-01-05T10:00:04.500Z'")
            conn.execute("INSERT INTO estimates (cycle_id, parameter, value, std, unit, accepted, reason) "
                         "VALUES (1, 'FA', 20.0, NULL, 'm^(1/3)/s', 1, NULL)")
            conn.execute("INSERT INTO forecasts (cycle_id, kind, series, time, lead_h, value) "
                         "VALUES (1, 'updated', 'a.h', 1288591200, 0, 7.5)")
            conn.execute("INSERT INTO model_states (cycle_id, name, time, format, data) VALUES (1, 'updated', "
                         "1288591200, 'f', ?)", (b"state",))
        assert "ensembles" not in _tables(store)
    monkeypatch.undo()
    with Store(location) as store:
        assert store.schema_version == store_schema.SCHEMA_VERSION
        assert {"ensembles", "forecast_bands"} <= set(_tables(store))
        described = store._conn.execute("SELECT description FROM schema_version WHERE version = 6").fetchone()[0]
        assert described == "the latest ensemble per run, forecast uncertainty bands"
        run = store.get_run("r")
        assert store.estimates(run)["value"].tolist() == [20.0] and store.forecasts(run)["value"].tolist() == [7.5]
        assert store.model_state(run, "updated")[2] == b"state"
        assert store.ensemble(run) is None and store.forecast_bands(run).empty
        _commit(store, run, 1)
        assert store.ensemble(run)[1] == 1 and len(store.forecast_bands(run)) == 2 * 49
        assert store.integrity_check() == []


def test_the_file_does_not_grow_with_the_ensembles_of_the_cycles(tmp_path: Path) -> None:
    """Ten cycles of a 1 MB ensemble: the file holds about one (freed pages are reused), not ten."""
    path = tmp_path / "service.db"
    sizes = []
    with Store(path) as store:
        run = store.ensure_run("r", "dommel", {})
        for k in range(10):
            _commit(store, run, k)
            store._conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
            sizes.append(path.stat().st_size)
    one = len(_blob(0))
    assert sizes[0] > one                       # the first ensemble is in the file
    assert sizes[-1] - sizes[1] < 0.25 * one    # and the next nine take no more room than two of them did
