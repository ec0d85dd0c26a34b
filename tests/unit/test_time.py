"""UTC times and interpolation in time (rivercal._time)."""

from __future__ import annotations

import re
from datetime import datetime, timedelta, timezone

import numpy as np
import pandas as pd
import pytest

from rivercal._time import interpolate_at, utc, utc_index


def test_naive_times_are_utc_and_aware_times_are_converted() -> None:
    want = pd.Timestamp("2010-11-01T06:00Z")
    assert utc("2010-11-01T06:00") == want and utc("2010-11-01T06:00").tz is not None
    assert utc("2010-11-01T07:00+01:00") == want and str(utc("2010-11-01T07:00+01:00").tz) == "UTC"
    assert utc(datetime(2010, 11, 1, 4, tzinfo=timezone(timedelta(hours=-2)))) == want
    index = utc_index(["2010-11-01T06:00", "2010-11-01T07:00"])
    assert str(index.tz) == "UTC" and index[0] == want
    assert (utc_index(index.tz_convert("Europe/Amsterdam")) == index).all()


@pytest.mark.parametrize("value", [None, pd.NaT, "yesterday"])
def test_what_is_not_a_time_is_refused(value) -> None:
    with pytest.raises(ValueError):
        utc(value)


def test_interpolation_is_exact_for_a_linear_series_and_constant_beyond_it() -> None:
    index = pd.date_range("2010-11-01", periods=25, freq="h", tz="UTC")
    hours = np.arange(25.0)
    values = 3.0 + 0.25 * hours  # m, linear in time
    times = pd.DatetimeIndex(["2010-10-31T23:00Z", "2010-11-01T00:30Z", "2010-11-01T10:45Z", "2010-11-02T03:00Z"])
    got = interpolate_at(index, values, times)
    np.testing.assert_allclose(got, [3.0, 3.125, 3.0 + 0.25 * 10.75, 9.0], rtol=0, atol=1e-12)
    same = interpolate_at(index, values, times, origin=pd.Timestamp("2010-01-01T00:00Z"))
    np.testing.assert_allclose(same, got, rtol=0, atol=1e-12)


@pytest.mark.parametrize(("text", "message"), [
    ("10-11-2010", "'10-11-2010' is ambiguous: day first it is 2010-11-10, month first 2010-10-11"),
    ("10/11/10", "'10/11/10' is ambiguous: day first it is 2010-11-10, month first 2010-10-11"),
    ("13-11-2010", "'13-11-2010' is not an ISO 8601 date; write it as ISO 8601, YYYY-MM-DD"),
    ("Nov 10 2010", "'Nov 10 2010' is not a date or time in ISO 8601"),
    ("2300-01-01", "'2300-01-01' lies outside the times rivercal can hold (1677 to 2262)"),
])
def test_a_date_that_is_not_iso_8601_is_refused_not_guessed(text: str, message: str) -> None:
    """pandas reads 10-11-2010 as October 11 without a word; a Dutch user meant 10 November."""
    assert pd.Timestamp("10-11-2010").month == 10  # what pandas would have made of it
    with pytest.raises(ValueError, match="^" + re.escape(message)):
        utc(text)


@pytest.mark.parametrize("text", ["2010-11-10", "20101110", "2010-11-10T00:00", "2010-11-10 00:00:00",
                                  "2010-11-10T01:00+01:00", "2010-11-10T00:00Z", "2010-W45-3"])
def test_every_iso_8601_form_of_a_date_is_read(text: str) -> None:
    assert utc(text) == pd.Timestamp("2010-11-10T00:00Z")


@pytest.mark.parametrize(("start", "message"), [
    (20200101, "case.start: 20200101 is a number, not a date"),
    ("01-02-2020", "case.start: '01-02-2020' is ambiguous: day first it is 2020-02-01, month first 2020-01-02"),
])
def test_a_case_file_date_is_iso_8601_never_a_guess(start, message) -> None:
    """pydantic alone read 20200101 as seconds since 1970 (21 August 1970) and '20200101' the same way."""
    import tomllib

    from rivercal.case.load import case_from_dict, resolve_case_path
    from rivercal.errors import CaseError

    root = resolve_case_path("synthetic")
    data = tomllib.loads((root / "case.toml").read_text(encoding="utf-8"))
    with pytest.raises(CaseError, match=re.escape(message)):
        case_from_dict({**data, "case": {**data["case"], "start": start}}, root)
    basic = case_from_dict({**data, "case": {**data["case"], "start": "20200101"}}, root)
    assert basic.start == pd.Timestamp("2020-01-01T00:00Z")  # ISO 8601's basic form
