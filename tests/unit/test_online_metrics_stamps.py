"""Run metrics on readings off the forecasts' hours: each reading against the forecast at its time.

A store holds two cycles of hourly forecasts (leads 0–12 h) of a curved level and its band, and readings a
minute and seven seconds after each hour, or every 31 minutes with second offsets, as sensors deliver them.
No reading falls on a forecast's time; every metric must still score them, each against the forecast
interpolated linearly to the reading's time (the reference below, computed reading by reading), and never
outside a forecast's span.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.observations import ObservationSet
from rivercal.online.metrics import band_coverage, forecast_errors, mae_by_lead, run_metrics, score_forecasts
from rivercal.store import BandRecord, CycleRecord, Store

SERIES = "G.h"
FIRST = pd.Timestamp("2021-06-01T00:00Z")
LEADS = np.arange(13)


def _truth(times: pd.DatetimeIndex) -> np.ndarray:
    hours = (times - FIRST).total_seconds().to_numpy() / 3600.0
    return 1.0 + 0.5 * np.sin(hours / 3.0)


def _forecast(cycle: int, kind: str) -> pd.Series:
    issue = FIRST + pd.Timedelta(hours=6 * cycle)
    times = issue + pd.to_timedelta(LEADS, unit="h")
    miss = {"updated": 0.02, "dss": 0.15}[kind] * (1 + LEADS / 6.0)     # grows with the lead
    return pd.Series(_truth(times) + miss, index=times)


def _stamps(kind: str) -> pd.DatetimeIndex:
    if kind == "minute-off":
        return FIRST + pd.to_timedelta(np.arange(0, 20), unit="h") + pd.Timedelta(minutes=1, seconds=7)
    seconds = np.random.default_rng(1).integers(1, 59, 40)
    return FIRST + pd.to_timedelta(31 * 60 * np.arange(1, 41) + seconds, unit="s")


@pytest.fixture(params=["minute-off", "31-minute"])
def store(request, tmp_path):
    stamps = _stamps(request.param)
    readings = pd.Series(_truth(stamps) + 0.01 * np.cos(np.arange(stamps.size)), index=stamps)
    with Store(tmp_path / "run.sqlite") as s:
        run = s.create_run("r", "synthetic", {"window": "6h", "period": "6h", "horizon": "12h",
                                              "first_issue": FIRST.isoformat(), "dss": {}, "parameters": []})
        s.ingest(ObservationSet.from_frame(readings.rename(SERIES).to_frame()), source="sensor")
        for k in (0, 1):
            issue = FIRST + pd.Timedelta(hours=6 * k)
            up = _forecast(k, "updated")
            band = BandRecord(low=(up - 0.03).to_frame(SERIES), high=(up + 0.03).to_frame(SERIES))
            s.commit_cycle(run, CycleRecord(k, issue - pd.Timedelta("6h"), issue, issue, forecasts={
                kind: _forecast(k, kind).to_frame(SERIES) for kind in ("updated", "dss")}, bands=band,
                issued="updated"))
        yield s, s.get_run("r"), readings


def _reference(readings: pd.Series, value_of) -> pd.DataFrame:
    """Reading by reading: the two hourly forecast values either side, weighted by the distance in time."""
    rows = []
    for k in (0, 1):
        issue = FIRST + pd.Timedelta(hours=6 * k)
        for t, y in readings.items():
            lead = (t - issue).total_seconds() / 3600.0
            if not 0 <= lead <= LEADS[-1]:
                continue
            below = int(np.floor(lead))
            above = min(below + 1, LEADS[-1])
            w = lead - below
            rows.append({"cycle": k, "lead_h": lead, "obs": y,
                         **{kind: (1 - w) * value_of(k, kind)[below] + w * value_of(k, kind)[above]
                            for kind in ("updated", "dss", "low", "high")}})
    return pd.DataFrame(rows)


def _values(k: int, kind: str) -> np.ndarray:
    base = "updated" if kind in ("low", "high") else kind
    shift = {"low": -0.03, "high": 0.03}.get(kind, 0.0)
    return _forecast(k, base).to_numpy() + shift


def test_no_reading_falls_on_a_forecast_time(store) -> None:
    s, run, readings = store
    assert not readings.index.isin(s.forecasts(run)["time"]).any()


def test_mae_by_lead_is_the_interpolated_reference(store) -> None:
    s, run, readings = store
    ref = _reference(readings, _values)
    got = mae_by_lead(s, run, [SERIES])
    first = ref[ref["lead_h"] <= 6]
    for kind in ("updated", "dss"):
        assert got[kind]["0-6h"] == pytest.approx(float((first[kind] - first["obs"]).abs().mean()), rel=1e-9)
        later = ref[ref["lead_h"] > 6]
        assert got[kind]["6-12h"] == pytest.approx(float((later[kind] - later["obs"]).abs().mean()), rel=1e-9)
        assert got[kind]["12-24h"] is None        # nothing beyond the forecasts' span is extrapolated


def test_scores_errors_and_band_coverage_pair_every_reading_inside_the_forecasts(store) -> None:
    s, run, readings = store
    ref = _reference(readings, _values)
    fc = s.forecasts(run)
    observed = s.observation_table([SERIES], fc["time"].min(), fc["time"].max())
    scores = score_forecasts(fc, observed, (0, 6, 12))
    assert int(scores["n"].sum()) == 2 * len(ref)
    row = scores[(scores["cycle"] == 1) & (scores["kind"] == "dss") & (scores["lead_to_h"] == 6)].iloc[0]
    part = ref[(ref["cycle"] == 1) & (ref["lead_h"] <= 6)]
    assert row.n == len(part)
    assert row.rmse == pytest.approx(float(np.sqrt(np.mean((part["dss"] - part["obs"]) ** 2))), rel=1e-9)
    errors = forecast_errors(s, run)
    scored = ref[ref["lead_h"] > 0]
    assert errors["n"] == len(scored)
    assert errors["updated_mae_m"] == pytest.approx(float((scored["updated"] - scored["obs"]).abs().mean()))
    assert errors["dss_mae_m"] == pytest.approx(float((scored["dss"] - scored["obs"]).abs().mean()))
    cover = band_coverage(s, run)
    inside = (scored["obs"] >= scored["low"]) & (scored["obs"] <= scored["high"])
    assert cover["n"] == len(scored) and cover["fraction"] == pytest.approx(float(inside.mean()))
    metrics = run_metrics(s, run)
    assert metrics["forecast_mae_ratio"] == pytest.approx(errors["dss_mae_m"] / errors["updated_mae_m"])
    assert metrics["lead_h"] == LEADS[-1] < 24   # the headline says the forecasts' 12-h horizon, not "up to 24 h"
    assert metrics["forecast_mae_by_lead"]["updated"]["0-6h"] is not None
