"""Daily KNMI rain and evaporation → hourly: exact daily totals, peak hour, daytime shape."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import rivercal.cases
from rivercal.hydrology.disaggregate import (
    daylight_weights,
    disaggregate_evaporation,
    disaggregate_rain,
    hourly_forcing,
    rain_day,
    rain_day_methods,
    sin_solar_elevation,
)
from rivercal.hydrology.knmi import read_knmi_daily

EINDHOVEN = Path(rivercal.cases.__file__).parent / "dommel" / "meteo" / "etmgeg_370_20100901-20101201.txt"


@pytest.fixture(scope="module")
def daily() -> pd.DataFrame:
    return read_knmi_daily(EINDHOVEN)


@pytest.fixture(scope="module")
def hourly(daily: pd.DataFrame) -> pd.DataFrame:
    return hourly_forcing(daily)


def _day_block(series: pd.Series, day: pd.Timestamp) -> np.ndarray:
    """The 24 hourly values of a UT day (hours ending 01:00 .. 24:00)."""
    return series.loc[day + pd.Timedelta(hours=1): day + pd.Timedelta(hours=24)].to_numpy()


def test_hourly_index_is_hour_end_utc(hourly: pd.DataFrame) -> None:
    assert hourly.index[0] == pd.Timestamp("2010-09-01 01:00", tz="UTC")
    assert hourly.index[-1] == pd.Timestamp("2010-12-02 00:00", tz="UTC")
    assert len(hourly) == 92 * 24
    assert (hourly.index[1:] - hourly.index[:-1] == pd.Timedelta(hours=1)).all()
    assert list(hourly.columns) == ["P", "ETpot"]


def test_daily_totals_preserved_exactly_every_day(daily: pd.DataFrame, hourly: pd.DataFrame) -> None:
    for day, row in daily.iterrows():
        rain = _day_block(hourly["P"], day)
        evap = _day_block(hourly["ETpot"], day)
        assert rain.size == evap.size == 24
        assert abs(rain.sum() - row["RH"]) <= 1e-9, day
        assert abs(evap.sum() - row["EV24"]) <= 1e-9, day
    assert (hourly.to_numpy() >= 0.0).all()
    assert hourly["P"].sum() == pytest.approx(daily["RH"].sum(), abs=1e-9)
    assert hourly["ETpot"].sum() == pytest.approx(90.1, abs=1e-9)


def test_peak_equals_rhx_in_hour_rhxh_and_caps_every_hour(daily: pd.DataFrame, hourly: pd.DataFrame) -> None:
    methods = rain_day_methods(daily)
    assert set(methods) <= {"dry", "peak", "peak-only"}  # the 2010 file is consistent
    checked = 0
    for day, row in daily.iterrows():
        if row["RH"] == 0.0:
            continue
        rain = _day_block(hourly["P"], day)
        peak_mm, k = row["RHX"], int(row["RHXH"])
        assert rain.max() == pytest.approx(peak_mm, abs=1e-12), day
        assert rain[k - 1] == pytest.approx(peak_mm, abs=1e-12), day
        assert (rain <= peak_mm + 1e-12).all(), day
        if methods[day] == "peak":
            assert np.count_nonzero(rain) >= min(24, math.ceil(row["DR"] - 1e-9)), day
        checked += 1
    assert checked == 57


def test_november_2010_event_and_peak(hourly: pd.DataFrame) -> None:
    p = hourly["P"]
    assert p.max() == pytest.approx(6.7)
    assert p.idxmax() == pd.Timestamp("2010-09-07 05:00", tz="UTC")  # RHXH = 5 on 7 Sep
    event = p.loc["2010-11-08 01:00":"2010-11-16 00:00"].sum()
    assert event == pytest.approx(73.4, abs=1e-9)


def test_deterministic(daily: pd.DataFrame) -> None:
    a = disaggregate_rain(daily)
    b = disaggregate_rain(daily)
    assert np.array_equal(a.to_numpy(), b.to_numpy())


@pytest.mark.parametrize(
    ("args", "method", "expected_peak_hour"),
    [
        ((14.5, 6.7, 5, 8.3), "peak", 5),            # a regular day (7 Sep 2010)
        ((0.5, 0.2, 5, 0.0), "peak", 5),             # DR = 0 with rain: ceil(R / X) = 3 hours
        ((0.3, 0.5, 7, 2.0), "peak-lowered", 7),     # RH < RHX: lowered to RH, all in hour 7
        ((0.025, 0.025, 13, 0.0), "peak-only", 13),  # trace day
        ((3.0, 1.0, 24, 6.0), "peak", 24),           # peak in the last hour: window shifted into the day
        ((3.0, 1.0, 1, 6.0), "peak", 1),             # and in the first
        ((2.4, np.nan, 10, 4.0), "uniform", None),   # RHX missing
        ((2.4, 0.6, np.nan, 4.0), "peak+hour-assumed", 12),
        ((30.0, 1.0, 5, 24.0), "overfull", None),    # R > 24 X: impossible, uniform
    ],
)
def test_rain_day_edge_cases(args: tuple, method: str, expected_peak_hour: int | None) -> None:
    total, peak, hour, dur = args
    hours, used = rain_day(total, peak, hour, dur)
    assert used == method
    assert hours.shape == (24,)
    assert (hours >= 0.0).all()
    assert abs(hours.sum() - total) <= 1e-12
    if expected_peak_hour is not None:
        cap = min(peak, total)
        assert hours[expected_peak_hour - 1] == pytest.approx(cap, abs=1e-12)
        assert hours.max() == pytest.approx(cap, abs=1e-12)
    if method == "uniform":
        assert np.count_nonzero(hours) == 4 and np.allclose(hours[hours > 0], 0.6)


def test_rain_day_decaying_shape_and_missing() -> None:
    hours, _ = rain_day(14.5, 6.7, 5, 8.3)
    wet = np.flatnonzero(hours)
    assert wet.tolist() == list(range(0, 9))  # 9 hours around hour 5 (index 4)
    assert np.all(np.diff(hours[4:9]) < 0) and np.all(np.diff(hours[0:5]) > 0)
    hours, used = rain_day(np.nan, 1.0, 3, 2.0)
    assert used == "missing" and np.isnan(hours).all()
    hours, used = rain_day(0.0, 0.0, 1, 0.0)
    assert used == "dry" and (hours == 0.0).all()
    with pytest.raises(ValueError, match="decay"):
        rain_day(1.0, 0.5, 3, 2.0, decay=0.0)


def test_missing_days_and_values_become_nan_not_zero(daily: pd.DataFrame) -> None:
    gap = daily.drop(pd.Timestamp("2010-10-10", tz="UTC")).copy()
    gap.loc["2010-10-11", "RH"] = np.nan
    gap.loc["2010-10-12", "EV24"] = np.nan
    out = hourly_forcing(gap)
    assert len(out) == 92 * 24
    assert out.loc["2010-10-10 01:00":"2010-10-12 00:00", "P"].isna().all()
    assert out.loc["2010-10-10 01:00":"2010-10-11 00:00", "ETpot"].isna().all()
    assert out.loc["2010-10-12 01:00":"2010-10-13 00:00", "ETpot"].isna().all()
    assert out["P"].isna().sum() == 48 and out["ETpot"].isna().sum() == 48


def test_evaporation_is_zero_at_night_and_peaks_near_solar_noon(daily: pd.DataFrame) -> None:
    ev = disaggregate_evaporation(daily)
    for day in (pd.Timestamp("2010-09-05", tz="UTC"), pd.Timestamp("2010-11-28", tz="UTC")):
        block = _day_block(ev, day)
        assert block[:4].sum() == 0.0 and block[19:].sum() == 0.0  # 00-04 UT and 19-24 UT
        assert int(np.argmax(block)) + 1 in (12, 13)  # solar noon at 5.4 E is 11:20-11:50 UT
    w = daylight_weights(pd.Timestamp("2010-06-21"))
    assert w.sum() == pytest.approx(1.0) and (w >= 0).all()
    assert w[2] == 0.0 and w[3] > 0.0  # sunrise in Eindhoven on 21 June is 03:2x UT


def test_solar_elevation_at_noon_on_solstices() -> None:
    # solar elevation at solar noon: 90 - latitude + declination (declination +-23.44 deg)
    lat, lon = 51.45, 5.38
    for date, decl in (("2010-06-21", 23.44), ("2010-12-21", -23.44)):
        times = pd.date_range(f"{date} 10:00", f"{date} 13:00", freq="1min", tz="UTC")
        elevation = np.degrees(np.arcsin(sin_solar_elevation(times, lat, lon)))
        assert elevation.max() == pytest.approx(90.0 - lat + decl, abs=0.3)
