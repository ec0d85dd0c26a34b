"""Observation series and the observation CSV reader."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.errors import CaseError
from rivercal.io.observations import read_observations_csv, write_observations_csv
from rivercal.observations import DEFAULT_SIGMA, ObservationSeries, ObservationSet

TIMES = pd.date_range("2020-01-01", periods=6, freq="h", tz="UTC")


def test_missing_values_are_dropped_and_counted_never_zero() -> None:
    s = ObservationSeries.from_series(pd.Series([1.0, np.nan, 3.0, np.nan, 5.0, 6.0], index=TIMES), id="A.h")
    assert len(s) == 4 and s.n_missing == 2
    assert list(s.values) == [1.0, 3.0, 5.0, 6.0]
    assert list(s.times) == [TIMES[0], TIMES[2], TIMES[4], TIMES[5]]


@pytest.mark.parametrize("bad", ["A", "A.x", ".h", "A.level"])
def test_series_ids_name_station_and_quantity(bad: str) -> None:
    with pytest.raises(ValueError, match=r"<station>\.<quantity>"):
        ObservationSeries.from_series(pd.Series([1.0], index=TIMES[:1]), id=bad)


def test_frame_gives_default_sigma_by_quantity() -> None:
    frame = pd.DataFrame({"S.h_up": np.ones(6), "S.Q": np.ones(6)}, index=TIMES)
    obs = ObservationSet.from_frame(frame, sigma={**DEFAULT_SIGMA, "S.Q": None})
    assert obs["S.h_up"].sigma == 0.025
    assert obs["S.Q"].sigma is None  # thesis Eq. 2-6 weight
    assert obs.within(TIMES[2], TIMES[3]).n_values == 4


def test_csv_round_trip_keeps_gaps(tmp_path) -> None:
    frame = pd.DataFrame({"S.h": [1.0, np.nan, 3.0, 4.0, 5.0, 6.0], "S.Q": [0.1] * 6}, index=TIMES)
    path = write_observations_csv(ObservationSet.from_frame(frame), tmp_path / "obs.csv")
    back = read_observations_csv(path)
    assert back["S.h"].n_missing == 1 and len(back["S.h"]) == 5
    np.testing.assert_allclose(back["S.Q"].values, 0.1)


def test_csv_with_gaps_and_empty_cells_reads_them_as_missing(tmp_path) -> None:
    path = tmp_path / "obs.csv"
    path.write_text("time,S.h,S.Q\n2020-01-01T00:00Z,1.0,\n2020-01-01T01:00Z,,0.5\n2020-01-01T02:00Z,1.2,0.6\n"
                    "2020-01-01T03:00Z,1.3,0.7\n2020-01-01T09:00+01:00,1.4,0.8\n", encoding="utf-8")
    obs = read_observations_csv(path)  # the last line is 08:00 UTC: a gap of 5 h in an hourly series
    assert obs["S.h"].times[-1] == pd.Timestamp("2020-01-01T08:00Z")
    assert (obs["S.h"].n_missing, obs["S.Q"].n_missing) == (1, 1)
    np.testing.assert_array_equal(obs["S.h"].values, [1.0, 1.2, 1.3, 1.4])


@pytest.mark.parametrize(("text", "message"), [
    ("time,S.h\n2020-01-01T00:00Z,1.0\n2020-01-01T01:00Z,abc\n", "line 3 .*'abc' is not a number"),
    ("time,S.h\nyesterday,1.0\n", "line 2: 'yesterday' is not a time"),
    ("time,S.h\n2020-01-01T01:00Z,1.0\n2020-01-01T00:00Z,1.0\n", "line 3: the time .* is earlier than"),
    ("time,S.h\n2020-01-01T01:00Z,1.0\n2020-01-01T01:00Z,1.0\n", "line 3: the time .* appears twice"),
    ("time,S.h,S.h\n2020-01-01T00:00Z,1.0,2.0\n", "names column 'S.h' twice"),
    ("time,S.h\n2020-01-01T00:00Z,inf\n", "line 2 .*'inf' is not a finite number"),
    ("time,S.h\n", "no data lines"),
    ("time,S.level\n2020-01-01T00:00Z,1.0\n", "<station>.<quantity>"),
])
def test_csv_errors_name_file_line_and_column(tmp_path, text: str, message: str) -> None:
    path = tmp_path / "obs.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(CaseError, match=message) as info:
        read_observations_csv(path)
    assert "obs.csv" in str(info.value)
