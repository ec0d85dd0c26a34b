"""The store's API: runs, the cycle life cycle, results, observations, scores and exports."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from rivercal.observations import ObservationSet
from rivercal.online.metrics import score_forecasts
from rivercal.store import (
    AlertRecord,
    CycleRecord,
    CycleSpec,
    CycleStateError,
    EstimateRecord,
    Schedule,
    Store,
    StoreError,
    export_estimates_csv,
    export_forecasts_csv,
    to_netcdf,
)

T0 = pd.Timestamp("2010-11-01T06:00:00Z")
SCHEDULE = Schedule(T0)


@pytest.fixture(params=["sqlite"])
def location(tmp_path: Path):
    """Where a store lives: a SQLite file (the same tests on a real PostgreSQL server: tests/integration)."""
    return tmp_path / "service.db"


@pytest.fixture
def store(location):
    with Store(location) as s:
        yield s


@pytest.fixture
def run_id(store: Store) -> int:
    return store.create_run("dommel-2010", "dommel", {"window_days": 7, "algorithm": "dud"})


def record(spec: CycleSpec, *, friction: float = 16.0, forecasts: dict | None = None, **kw) -> CycleRecord:
    return CycleRecord(spec.cycle, spec.window_start, spec.window_end, spec.issue_time,
                       estimates=[EstimateRecord("friction:global", friction, "m1/3 s-1", std=0.4),
                                  EstimateRecord("weirs", 0.5, "1", std=0.05)],
                       forecasts=forecasts or {}, **kw)


def hourly(start: pd.Timestamp, hours: int, **columns) -> pd.DataFrame:
    index = pd.date_range(start, periods=hours + 1, freq="h")
    return pd.DataFrame({k: np.broadcast_to(np.asarray(v, float), (hours + 1,)) for k, v in columns.items()},
                        index=index)


def run_cycles(store: Store, run_id: int, n: int, **kw) -> None:
    for _ in range(n):
        spec = store.begin_cycle(run_id, store.next_cycle(run_id, SCHEDULE))
        store.commit_cycle(run_id, record(spec, friction=16.0 + spec.cycle, **kw))


# -- runs -----------------------------------------------------------------------------------------------------


def test_runs_are_created_once_and_resumed_only_with_the_same_configuration(store: Store) -> None:
    config = {"window_days": np.int64(7), "case_path": Path("/cases/dommel"), "start": T0, "sigma": np.array([1.0])}
    run = store.ensure_run("r", "dommel", config)
    assert run.config == {"window_days": 7, "case_path": "/cases/dommel", "start": "2010-11-01T06:00:00+00:00",
                          "sigma": [1.0]}
    assert store.ensure_run("r", "dommel", dict(config)).id == run.id
    with pytest.raises(StoreError, match=r"another configuration \(keys differ: window_days\)"):
        store.ensure_run("r", "dommel", {**config, "window_days": 3})
    with pytest.raises(StoreError, match="serves case 'dommel', not 'other'"):
        store.ensure_run("r", "other", config)
    with pytest.raises(StoreError, match="exists already"):
        store.create_run("r", "dommel", {})
    with pytest.raises(ValueError):
        store.create_run("nan", "dommel", {"x": float("nan")})
    assert store.get_run("missing") is None
    store.set_run_status(run.id, "stopped")
    assert store.runs()[["name", "status", "cycles"]].values.tolist() == [["r", "stopped", 0]]


# -- the cycle life cycle -------------------------------------------------------------------------------------


def test_next_cycle_follows_the_schedule_and_waits_until_due(store: Store, run_id: int) -> None:
    spec = store.next_cycle(run_id, SCHEDULE)
    assert (spec.cycle, spec.issue_time, spec.window_start, spec.window_end) == (0, T0, T0 - pd.Timedelta(days=7), T0)
    assert store.next_cycle(run_id, SCHEDULE, now=T0 - pd.Timedelta(seconds=1)) is None
    run_cycles(store, run_id, 2)
    spec = store.next_cycle(run_id, SCHEDULE)
    assert (spec.cycle, spec.issue_time) == (2, T0 + pd.Timedelta(days=2))
    weekly = Schedule(T0, period=pd.Timedelta(days=7))  # a changed period applies from the next new cycle on
    assert store.next_cycle(run_id, weekly).issue_time == T0 + pd.Timedelta(days=8)
    assert store.next_cycle(run_id, SCHEDULE, now="2010-11-03 06:00").cycle == 2  # naive = UTC


def test_a_cycle_is_begun_committed_and_then_final(store: Store, run_id: int) -> None:
    spec = store.begin_cycle(run_id, store.next_cycle(run_id, SCHEDULE))
    assert (spec.status, spec.attempts) == ("running", 1)
    assert store.first_unfinished(run_id) == spec
    store.commit_cycle(run_id, record(spec, algorithm="dud", model_runs=9, cost_before=3.0, cost_after=0.5,
                                      message="converged", wall_time_s=2.5))
    row = store.cycles(run_id).iloc[0]
    assert (row["status"], row["model_runs"], row["wall_time_s"], row["cost_after"]) == ("done", 9, 2.5, 0.5)
    assert row["finished"] >= row["started"]
    assert store.first_unfinished(run_id) is None
    with pytest.raises(CycleStateError, match="already done; it is not stored twice"):
        store.commit_cycle(run_id, record(spec))
    with pytest.raises(CycleStateError, match="already done"):
        store.begin_cycle(run_id, spec)
    assert len(store.estimates(run_id)) == 2


def test_gaps_overlaps_and_changed_windows_are_refused(store: Store, run_id: int) -> None:
    with pytest.raises(CycleStateError, match="would leave a gap"):
        store.begin_cycle(run_id, SCHEDULE.spec(1))
    spec0 = store.begin_cycle(run_id, SCHEDULE.spec(0))
    with pytest.raises(CycleStateError, match="cycle 0 is unfinished"):
        store.begin_cycle(run_id, SCHEDULE.spec(1))
    moved = CycleSpec(0, spec0.window_start + pd.Timedelta(hours=1), spec0.window_end, spec0.issue_time)
    with pytest.raises(CycleStateError, match="is stored with window"):
        store.commit_cycle(run_id, record(moved))
    with pytest.raises(StoreError, match="no run with id 99"):
        store.begin_cycle(99, SCHEDULE.spec(0))


def test_a_cycle_left_running_is_resumed_and_counted(store: Store, run_id: int, caplog) -> None:
    spec = store.begin_cycle(run_id, store.next_cycle(run_id, SCHEDULE))
    store._conn.execute("UPDATE cycles SET owner = '999999999@elsewhere'")  # as if a dead process had begun it
    with caplog.at_level(logging.WARNING, logger="rivercal.store"):
        again = store.begin_cycle(run_id, store.next_cycle(run_id, SCHEDULE))
    assert (again.cycle, again.attempts) == (spec.cycle, 2)
    assert "left running by 999999999@elsewhere" in caplog.text


def test_an_owner_is_a_process_id_and_its_start_time_so_a_reused_id_does_not_block(tmp_path: Path, caplog) -> None:
    """After a reboot or a container restart a live program has the dead service's process id: it is not the owner.

    The live process here is this test's parent (alive while the test runs, and not this process).
    """
    import os
    import socket

    import psutil

    other = os.getppid()
    started = psutil.Process(other).create_time()
    host = socket.gethostname()
    with Store(tmp_path / "service.db") as store:
        run = store.create_run("r", "dommel")
        store.begin_cycle(run, store.next_cycle(run, SCHEDULE))

        def owned_by(owner: str, begun: str = "2000-01-01T00:00:00.000Z") -> None:
            store._conn.execute("UPDATE cycles SET owner = ?, started = ?", (owner, begun))

        owned_by(f"{other}@{host}/{started:.2f}")  # the live process began it: refused, with the way out
        with pytest.raises(CycleStateError, match=rf"being computed by process {other}@{host} \(started .*still "
                                                  r"alive.*rivercal online --take-over"):
            store.begin_cycle(run, store.next_cycle(run, SCHEDULE))
        owned_by(f"{other}@{host}/{started - 3600:.2f}")  # a process of that id that started an hour earlier: dead
        assert store.begin_cycle(run, store.next_cycle(run, SCHEDULE)).attempts == 2
        # a record of a store written before start times were kept: the process of that id started after the
        # cycle was begun, so it cannot be the one that began it
        owned_by(f"{other}@{host}", begun="2000-01-01T00:00:00.000Z")
        assert store.begin_cycle(run, store.next_cycle(run, SCHEDULE)).attempts == 3
        # ... unless it started before: then only the override takes the cycle over (and says so)
        owned_by(f"{other}@{host}", begun=pd.Timestamp(started + 60, unit="s").strftime("%Y-%m-%dT%H:%M:%S.000Z"))
        with pytest.raises(CycleStateError, match="still alive"):
            store.begin_cycle(run, store.next_cycle(run, SCHEDULE))
        with caplog.at_level(logging.WARNING, logger="rivercal.store"):
            assert store.begin_cycle(run, store.next_cycle(run, SCHEDULE), take_over=True).attempts == 4
        assert f"taking it over from process {other}@{host}" in caplog.text
        mine = store.cycles(run)["owner"].iloc[0]
        assert mine == f"{os.getpid()}@{host}/{psutil.Process().create_time():.2f}"


def test_commit_without_begin_inserts_the_next_cycle(store: Store, run_id: int) -> None:
    store.commit_cycle(run_id, record(SCHEDULE.spec(0), status="failed", message="engine diverged"))
    assert store.cycles(run_id)[["cycle", "status", "attempts"]].values.tolist() == [[0, "failed", 1]]
    assert store.next_cycle(run_id, SCHEDULE).cycle == 1  # failed is final: the service moves on


def test_a_commit_that_fails_halfway_stores_nothing(store: Store, run_id: int, monkeypatch) -> None:
    spec = store.begin_cycle(run_id, store.next_cycle(run_id, SCHEDULE))

    def fail_midway(msg, *args, **kw):
        if msg.startswith("commit cycle"):
            raise OSError("killed")

    monkeypatch.setattr("rivercal.store.sqlite.log.debug", fail_midway)
    with pytest.raises(OSError, match="killed"):
        store.commit_cycle(run_id, record(spec, alerts=[AlertRecord("jump", "big jump", "weirs", 5.0)]))
    assert store.cycles(run_id)["status"].tolist() == ["running"]
    assert store.estimates(run_id).empty and store.alerts(run_id).empty
    monkeypatch.undo()
    store.commit_cycle(run_id, record(spec))
    assert store.cycles(run_id)["status"].tolist() == ["done"]


def test_bad_forecasts_are_refused_before_anything_is_written(store: Store, run_id: int) -> None:
    spec = store.begin_cycle(run_id, store.next_cycle(run_id, SCHEDULE))
    early = {"updated": hourly(spec.issue_time - pd.Timedelta(hours=1), 3, **{"a.h": 1.0})}
    with pytest.raises(ValueError, match="before the issue time"):
        store.commit_cycle(run_id, record(spec, forecasts=early))
    odd = hourly(spec.issue_time, 2, **{"a.h": 1.0})
    odd.index = odd.index + pd.Timedelta(milliseconds=500)
    with pytest.raises(ValueError, match="fraction of a second"):
        store.commit_cycle(run_id, record(spec, forecasts={"updated": odd}))
    with pytest.raises(ValueError, match=r"'<station>\.<quantity>'"):
        store.commit_cycle(run_id, record(spec, forecasts={"updated": hourly(spec.issue_time, 2, level=1.0)}))
    assert store.cycles(run_id)["status"].tolist() == ["running"] and store.estimates(run_id).empty


def test_records_validate_what_they_hold() -> None:
    with pytest.raises(ValueError, match="needs a reason"):
        EstimateRecord("weirs", 0.5, "1", accepted=False)
    with pytest.raises(ValueError, match="value must be finite"):
        EstimateRecord("weirs", float("nan"), "1")
    with pytest.raises(ValueError, match="status must be one of done, failed, aborted"):
        record(SCHEDULE.spec(0), status="running")
    with pytest.raises(ValueError, match="forecast kinds"):
        record(SCHEDULE.spec(0), forecasts={"ensemble": pd.DataFrame()})
    with pytest.raises(ValueError, match="window end"):
        CycleSpec(0, T0, T0, T0)


def test_retry_reopens_a_final_cycle_without_its_results(store: Store, run_id: int) -> None:
    run_cycles(store, run_id, 2, forecasts=None)
    store.retry_cycle(run_id, 0)
    assert store.cycles(run_id)["status"].tolist() == ["pending", "done"]
    assert store.estimates(run_id)["cycle"].tolist() == [1, 1]
    assert store.next_cycle(run_id, SCHEDULE).cycle == 0


# -- results --------------------------------------------------------------------------------------------------


def test_estimates_alerts_and_the_warm_start(store: Store, run_id: int) -> None:
    run_cycles(store, run_id, 2)
    spec = store.begin_cycle(run_id, store.next_cycle(run_id, SCHEDULE))
    store.commit_cycle(run_id, CycleRecord(
        spec.cycle, spec.window_start, spec.window_end, spec.issue_time,
        estimates=[EstimateRecord("friction:global", 25.0, "m1/3 s-1", std=0.5, accepted=False,
                                  reason="jump of 16 std: held until confirmed"),
                   EstimateRecord("weirs", 0.45, "1", std=0.05)],
        alerts=[AlertRecord("jump", "friction jumped from 17.0 to 25.0 (mowing?)", "friction:global", 16.0)]))
    est = store.estimates(run_id)
    assert est.shape == (6, 11)
    assert est.loc[~est["accepted"], "reason"].tolist() == ["jump of 16 std: held until confirmed"]
    assert store.estimates(run_id, accepted_only=True).shape[0] == 5
    assert store.last_accepted(run_id) == {"friction:global": 17.0, "weirs": 0.45}
    alerts = store.alerts(run_id)
    assert alerts[["cycle", "parameter", "kind", "magnitude"]].values.tolist() == [[2, "friction:global", "jump", 16.0]]
    assert alerts["issue_time"][0] == T0 + pd.Timedelta(days=2)


def test_forecasts_are_stored_with_their_lead_time(store: Store, run_id: int, caplog) -> None:
    spec = store.begin_cycle(run_id, store.next_cycle(run_id, SCHEDULE))
    up = hourly(spec.issue_time.tz_localize(None), 48, **{"ZL1-5930.h_up": 7.2, "ZL1-3014.Q": 1.5})  # naive = UTC
    up.iloc[3, 1] = np.nan
    with caplog.at_level(logging.WARNING, logger="rivercal.store"):
        store.commit_cycle(run_id, record(spec, forecasts={"updated": up, "dss": up + 0.1}))
    assert "1 non-finite forecast values not stored" in caplog.text
    fc = store.forecasts(run_id)
    assert len(fc) == 2 * 2 * 49 - 2
    one = store.forecasts(run_id, cycle=0, kind="dss", series=["ZL1-5930.h_up"])
    assert one["lead_h"].tolist() == list(map(float, range(49)))
    assert (one["time"] - one["issue_time"]).eq(pd.to_timedelta(one["lead_h"], unit="h")).all()
    assert one["value"].tolist() == pytest.approx([7.3] * 49)


# -- observations ---------------------------------------------------------------------------------------------


def obs_set(start: str, hours: int, **columns) -> ObservationSet:
    return ObservationSet.from_frame(hourly(pd.Timestamp(start, tz="UTC"), hours, **columns))


def test_ingest_stores_each_value_once_and_reports_conflicts(store: Store, caplog) -> None:
    inserted, duplicates = store.ingest(obs_set("2010-11-01", 23, **{"a.h": 1.0, "b.Q": 2.0}), "telemetry")
    assert (inserted, duplicates) == (48, 0)
    result = store.ingest(obs_set("2010-11-01T12:00", 23, **{"a.h": 1.0}), "telemetry")
    assert (result.inserted, result.duplicates, result.conflicts) == (12, 12, 0)
    with caplog.at_level(logging.WARNING, logger="rivercal.store"):
        result = store.ingest(obs_set("2010-11-01T00:00", 1, **{"a.h": 1.5}), "telemetry")
    assert (result.inserted, result.duplicates, result.conflicts) == (0, 2, 2)
    assert ("2 values differ from the stored ones (first at 2010-11-01T00:00:00+00:00: stored 1.0, new 1.5)"
            in caplog.text)
    assert store.observations(["a.h"], "2010-11-01", "2010-11-01T01:00")["a.h"].values.tolist() == [1.0, 1.0]
    store.ingest(obs_set("2010-11-01T00:00", 1, **{"a.h": 1.5}), "telemetry", on_conflict="replace")
    assert store.observations(["a.h"], "2010-11-01", "2010-11-01T01:00")["a.h"].values.tolist() == [1.5, 1.5]
    assert tuple(store.ingest(obs_set("2010-11-01", 23, **{"a.h": 1.0}), "validated")) == (24, 0)  # other source


def test_observations_for_a_window_with_source_priority_and_sigma(store: Store) -> None:
    store.ingest(obs_set("2010-11-01", 47, **{"a.h": 1.0, "b.Q": 2.0}), "telemetry")
    store.ingest(obs_set("2010-11-02", 5, **{"a.h": 1.1}), "validated")
    got = store.observations(["b.Q", "a.h", "c.h"], "2010-11-01T12:00", "2010-11-02T12:00", sigma={"h": 0.01})
    assert got.ids == ["b.Q", "a.h", "c.h"]
    assert [len(s) for s in got] == [25, 25, 0]
    assert [s.sigma for s in got] == [None, 0.01, 0.01]  # sigma given for quantity h only
    assert got["a.h"].times[0] == pd.Timestamp("2010-11-01T12:00Z")
    assert set(got["a.h"].values) == {1.0, 1.1}  # where both have a value the latest ingested wins
    prefer = store.observations(["a.h"], "2010-11-02", "2010-11-02T05:00", sources=["telemetry", "validated"])
    assert set(prefer["a.h"].values) == {1.0}
    only = store.observations(["a.h"], "2010-11-01", "2010-11-03", sources=["validated"])
    assert len(only["a.h"]) == 6


def test_availability_shows_counts_and_gaps(store: Store) -> None:
    frame = hourly(pd.Timestamp("2010-11-01", tz="UTC"), 23, **{"a.h": 1.0})
    frame.iloc[5:9] = np.nan  # a 5-hour gap: missing values are dropped, never stored
    store.ingest(ObservationSet.from_frame(frame), "telemetry")
    avail = store.availability(["a.h"], "2010-11-01", "2010-11-02")
    assert avail[["series", "source", "n", "max_gap_h"]].values.tolist() == [["a.h", "telemetry", 20, 5.0]]
    assert avail["last"][0] == pd.Timestamp("2010-11-01T23:00Z")
    assert store.availability(["a.h"], "2010-11-03", "2010-11-04").empty


def test_spikes_are_flagged_at_ingestion_kept_and_left_out_and_gaps_recorded(store: Store) -> None:
    from rivercal.observations import ScreenRule

    # a flood wave (1 m in 2 days) with two 80 cm spikes, the second at the end of the first delivery (on the
    # rising limb the values within 3 h spread by ±10 cm: 5 robust σ of them are 49 cm, the smallest spike seen)
    t = pd.date_range("2010-11-01", periods=97, freq="h", tz="UTC")
    level = 10.0 + 0.5 * (1 - np.cos(2 * np.pi * np.arange(97) / 96.0))
    level[[20, 48]] += 0.8
    frame = pd.DataFrame({"a.h": level}, index=t)
    frame.iloc[60:66] = np.nan  # a 7-hour gap
    first = store.ingest(ObservationSet.from_frame(frame.iloc[:49]), "telemetry", screen=ScreenRule())
    assert first.outliers == 1  # the last value has no values after it yet: not judged
    second = store.ingest(ObservationSet.from_frame(frame.iloc[49:]), "telemetry", screen=ScreenRule())
    assert second.outliers == 1 and second.gaps == 1  # the spike at the seam, judged with the values after it
    counts = store.flag_counts(["a.h"]).set_index("flag")["n"].to_dict()
    assert counts == {"ok": 89, "outlier": 2}  # 97 − 6 missing values, every stored value kept
    got = store.observations(["a.h"], t[0], t[-1])["a.h"]
    assert len(got) == 89 and pd.Timestamp(t[20]) not in set(got.times) and pd.Timestamp(t[48]) not in set(got.times)
    # the rise and fall of the wave itself is not a spike
    assert np.allclose(got.values, pd.Series(level, index=t).loc[got.times].values)
    gaps = store.gaps(["a.h"])
    assert gaps[["start", "end", "hours"]].values.tolist() == [[t[59], t[66], 7.0]]
    # without a screen nothing is flagged
    store.ingest(ObservationSet.from_frame(frame.rename(columns={"a.h": "b.h"})), "telemetry")
    assert store.flag_counts(["b.h"])["flag"].tolist() == ["ok"]


def test_a_discharge_switched_on_and_off_is_not_a_spike_while_its_spikes_are() -> None:
    """A pump's discharge every 10 minutes: 2.5 m³/s for 40 minutes, then nothing for 80 (a rainfall-runoff
    delivery or a pump switching as in real telemetry). Each window of ±3 h holds more of "off" than of "on",
    so its median and MAD are those of "off" and the Hampel test alone flags every "on" value; two spikes (an
    isolated reading of 1.8 m³/s while off, one of 6 m³/s while on) are what the screen must find."""
    from rivercal.observations import screen_outliers

    t = pd.date_range("2010-11-01", periods=144, freq="10min", tz="UTC")
    q = np.where(np.arange(144) % 12 < 4, 2.5, 0.0) + 0.01 * np.sin(np.arange(144))
    q[[30, 50]] = [1.8, 6.0]  # 30: off (30 % 12 = 6); 50: on (50 % 12 = 2)
    flagged = screen_outliers(t, q, "Q")
    assert flagged.nonzero()[0].tolist() == [30, 50]


# -- scores ---------------------------------------------------------------------------------------------------


def score(store: Store, run_id: int, buckets_h=(0, 6, 12, 24)) -> pd.DataFrame:
    """Score every stored forecast against the stored observations and store the scores."""
    fc = store.forecasts(run_id)
    observed = store.observation_table(fc["series"].unique(), fc["time"].min(), fc["time"].max())
    scores = score_forecasts(fc, observed, buckets_h)
    store.put_scores(run_id, scores)
    return scores


def test_forecasts_are_scored_per_lead_time_bucket_against_stored_observations(store: Store, run_id: int) -> None:
    spec = store.begin_cycle(run_id, store.next_cycle(run_id, SCHEDULE))
    fc = hourly(spec.issue_time, 24, **{"a.h": 1.0})
    store.commit_cycle(run_id, record(spec, forecasts={"updated": fc + 0.1, "dss": fc - 0.3}))
    assert score(store, run_id).empty  # no observations yet
    assert store.scores(run_id).empty
    store.ingest(obs_set("2010-11-01T06:00", 12, **{"a.h": 1.0}), "telemetry")  # leads 0..12 h
    scores = score(store, run_id)
    assert scores[["kind", "lead_from_h", "lead_to_h", "n"]].values.tolist() == [
        ["dss", 0.0, 6.0, 7], ["dss", 6.0, 12.0, 6], ["updated", 0.0, 6.0, 7], ["updated", 6.0, 12.0, 6]]
    assert scores["rmse"].tolist() == pytest.approx([0.3, 0.3, 0.1, 0.1])
    assert scores["bias"].tolist() == pytest.approx([-0.3, -0.3, 0.1, 0.1])
    store.ingest(obs_set("2010-11-01T18:00", 12, **{"a.h": 1.0}), "telemetry")  # the rest arrives: score again
    score(store, run_id)
    stored = store.scores(run_id)
    assert stored.groupby("kind")["n"].sum().to_dict() == {"dss": 25, "updated": 25}
    assert len(stored) == 6


def test_scores_of_an_unknown_cycle_are_refused_whole(store: Store, run_id: int) -> None:
    run_cycles(store, run_id, 1)
    row = {"kind": "dss", "series": "a.h", "lead_from_h": 0.0, "lead_to_h": 6.0, "rmse": 0.1, "bias": 0.1, "n": 3}
    with pytest.raises(CycleStateError, match="no cycle 7"):
        store.put_scores(run_id, pd.DataFrame([{"cycle": 0, **row}, {"cycle": 7, **row}]))
    assert store.scores(run_id).empty  # one transaction: cycle 0's row was not kept either


def test_a_cycle_commits_the_scores_of_earlier_cycles_with_its_own_results(store: Store, run_id: int) -> None:
    run_cycles(store, run_id, 2)
    row = {"kind": "dss", "series": "a.h", "lead_from_h": 0.0, "lead_to_h": 6.0, "rmse": 0.1, "bias": 0.1, "n": 3}
    store.put_scores(run_id, pd.DataFrame([{"cycle": 0, **row}]))
    spec = store.begin_cycle(run_id, store.next_cycle(run_id, SCHEDULE))
    bad = pd.DataFrame([{"cycle": 1, **row, "rmse": 0.2}, {"cycle": 9, **row}])
    with pytest.raises(CycleStateError, match="no cycle 9"):
        store.commit_cycle(run_id, record(spec, scores=bad))
    assert store.cycles(run_id)["status"].tolist() == ["done", "done", "running"]  # nothing of the commit kept
    assert store.scores(run_id)[["cycle", "rmse"]].values.tolist() == [[0, 0.1]]
    good = pd.DataFrame([{"cycle": 0, **row, "rmse": 0.3}, {"cycle": 1, **row, "rmse": 0.2}])
    store.commit_cycle(run_id, record(spec, scores=good))
    assert store.scores(run_id)[["cycle", "rmse"]].values.tolist() == [[0, 0.3], [1, 0.2]]  # cycle 0's replaced


# -- exports --------------------------------------------------------------------------------------------------


def test_csv_exports_round_trip(store: Store, run_id: int, tmp_path: Path) -> None:
    run_cycles(store, run_id, 2, forecasts={"updated": hourly(T0 + pd.Timedelta(days=3), 2, **{"a.h": 1.0})})
    est = pd.read_csv(export_estimates_csv(store, run_id, tmp_path / "estimates.csv"))
    assert est.columns.tolist() == ["cycle", "issue_time", "window_start", "window_end", "status", "parameter",
                                    "value", "std", "unit", "accepted", "reason"]
    assert est["issue_time"].tolist()[::2] == ["2010-11-01T06:00:00Z", "2010-11-02T06:00:00Z"]
    assert est["value"].tolist()[::2] == [16.0, 17.0]
    fc = pd.read_csv(export_forecasts_csv(store, run_id, tmp_path / "forecasts.csv", cycle=1))
    assert fc.columns.tolist() == ["cycle", "issue_time", "kind", "series", "lead_h", "time", "value"]
    assert fc["time"].tolist() == ["2010-11-04T06:00:00Z", "2010-11-04T07:00:00Z", "2010-11-04T08:00:00Z"]
    assert fc["lead_h"].tolist() == [48.0, 49.0, 50.0]


def test_netcdf_export_follows_cf(store: Store, run_id: int, tmp_path: Path) -> None:
    for k in range(3):
        spec = store.begin_cycle(run_id, store.next_cycle(run_id, SCHEDULE))
        fc = hourly(spec.issue_time, 48, **{"ZL1-5930.h_up": 7.0 + k, "ZL1-5930.h_down": 6.5, "ZL1-3014.Q": 1.2})
        store.commit_cycle(run_id, record(spec, friction=16.0 + k, forecasts={"updated": fc, "dss": fc + 0.2},
                                          model_runs=5))
    path = to_netcdf(store, run_id, tmp_path / "run.nc")
    with xr.open_dataset(path) as ds:
        assert ds.attrs["Conventions"] == "CF-1.8"
        assert ds["friction_global"].attrs["units"] == "m1/3 s-1"
        assert ds["friction_global"].attrs["rivercal_parameter"] == "friction:global"
        assert ds["friction_global"].values.tolist() == [16.0, 17.0, 18.0]
        assert ds["friction_global_std"].values.tolist() == [0.4] * 3
        assert ds["weirs"].attrs["units"] == "1"
        assert ds["time"].values[1] == np.datetime64("2010-11-02T06:00")
        assert ds["time"].attrs["bounds"] == "time_bnds"
        assert ds["time_bnds"].values[0, 0] == np.datetime64("2010-10-25T06:00")
        assert ds["lead_time"].attrs == {"standard_name": "forecast_period", "units": "hours",
                                         "long_name": "lead time"}
        assert ds["reference_time"].attrs["standard_name"] == "forecast_reference_time"
        level = ds["water_level"]
        assert level.dims == ("kind", "reference_time", "lead_time", "level_series")
        assert level.attrs["units"] == "m"
        assert level.attrs["standard_name"] == "water_surface_height_above_reference_datum"
        first = level.sel(kind="dss", level_series="ZL1-5930.h_up").values[:, 0]
        assert first.tolist() == pytest.approx([7.2, 8.2, 9.2])
        assert ds["discharge"].attrs["units"] == "m3 s-1"
        assert ds["valid_time"].values[2, 48] == np.datetime64("2010-11-05T06:00")
    with open(path, "rb") as raw:  # times are encoded as seconds since the epoch, in UTC
        import netCDF4

        nc = netCDF4.Dataset("in-memory", memory=raw.read())
        assert nc["time"].units == "seconds since 1970-01-01"
        assert nc["water_level"].coordinates == "valid_time"
        nc.close()


def test_readers_see_committed_data_while_a_writer_holds_the_lock(location) -> None:
    path = location
    with Store(path) as writer, Store(path, readonly=True) as reader, Store(path, timeout_s=0.1) as other:
        run = writer.create_run("r", "c", {})
        with writer._transaction() as conn:  # a long write, as a cycle's commit
            conn.execute("UPDATE runs SET status = 'stopped'")
            assert reader.get_run("r").status == "active"  # WAL: the reader is not blocked, sees the last commit
            with pytest.raises(StoreError, match="cannot start a write"):
                other.set_run_status(run, "failed")
        assert reader.get_run("r").status == "stopped"


def test_model_states_are_committed_with_the_cycle_and_read_back(location) -> None:
    """The hot-start state travels with its cycle: stored atomically, replaced on retry, latest final one wins."""
    with Store(location) as store:
        run = store.create_run("states", "dommel", {})
        schedule = Schedule(first_issue="2010-11-01")
        blobs = {}
        for k in range(2):
            spec = store.begin_cycle(run, store.next_cycle(run, schedule))
            blobs[k] = bytes([k]) * 100
            store.commit_cycle(run, CycleRecord(spec.cycle, spec.window_start, spec.window_end, spec.issue_time,
                                                states={"updated": (spec.issue_time, "fmt-1", blobs[k])}))
        time, fmt, data = store.model_state(run, "updated")
        assert (time, fmt, data) == (pd.Timestamp("2010-11-02", tz="UTC"), "fmt-1", blobs[1])
        assert store.model_state(run, "updated", cycle=0)[2] == blobs[0]
        assert store.model_state(run, "dss") is None
        # a cycle begun but not committed (a killed process) hands over nothing; the last final one counts
        store.begin_cycle(run, store.next_cycle(run, schedule))
        assert store.model_state(run, "updated")[2] == blobs[1]
        store.retry_cycle(run, 1)
        assert store.model_state(run, "updated")[2] == blobs[0]
    with pytest.raises(ValueError, match="state 'updated' must be"):
        CycleRecord(0, "2010-10-25", "2010-11-01", "2010-11-01", states={"updated": ("2010-11-01", "", b"x")})
