"""Forecast scores: RMSE and bias per lead-time bucket against observations at equal times."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.online.metrics import SCORE_COLUMNS, score_forecasts

ISSUE = pd.Timestamp("2010-11-01T06:00Z")


def forecast(cycle: int, kind: str, series: str, values: np.ndarray) -> pd.DataFrame:
    """Hourly forecast values from lead 0 h on, issued one day later per cycle."""
    issue = ISSUE + pd.Timedelta(days=cycle)
    lead = np.arange(values.size, dtype=float)
    return pd.DataFrame({"cycle": cycle, "issue_time": issue, "kind": kind, "series": series, "lead_h": lead,
                         "time": issue + pd.to_timedelta(lead, unit="h"), "value": values})


def test_rmse_and_bias_per_bucket_match_a_direct_computation() -> None:
    rng = np.random.default_rng(3)
    truth = pd.Series(rng.normal(5.0, 0.2, 24 * 4), index=pd.date_range(ISSUE, periods=24 * 4, freq="h"))
    fc = pd.concat([forecast(c, k, "a.h", truth.iloc[24 * c:24 * c + 30].to_numpy() + rng.normal(off, 0.05, 30))
                    for c in (0, 1) for k, off in (("updated", 0.02), ("dss", -0.3))], ignore_index=True)
    observed = truth.drop(truth.index[[3, 4, 40]])  # missing observations are skipped, not zero
    obs = pd.DataFrame({"series": "a.h", "time": observed.index, "value": observed.to_numpy()})
    got = score_forecasts(fc, obs, (0, 6, 12, 24))
    assert got.columns.tolist() == SCORE_COLUMNS
    assert len(got) == 2 * 2 * 3  # leads 25..29 h lie beyond the last edge and are not scored
    for row in got.itertuples():
        part = fc[(fc["cycle"] == row.cycle) & (fc["kind"] == row.kind)]
        inside = (part["lead_h"] > row.lead_from_h) | ((row.lead_from_h == 0) & (part["lead_h"] == 0))
        part = part[inside & (part["lead_h"] <= row.lead_to_h) & part["time"].isin(observed.index)]
        err = part["value"].to_numpy() - observed.loc[part["time"]].to_numpy()
        assert row.n == err.size
        assert row.rmse == pytest.approx(np.sqrt(np.mean(err**2)), rel=1e-12)
        assert row.bias == pytest.approx(err.mean(), rel=1e-12)
    first = got[(got["cycle"] == 0) & (got["kind"] == "dss")].iloc[0]
    assert (first.lead_from_h, first.lead_to_h, first.n) == (0.0, 6.0, 5)  # leads 0..6 h less the 2 missing
    assert first.bias == pytest.approx(-0.3, abs=0.05)


def test_nothing_to_score() -> None:
    fc = forecast(0, "updated", "a.h", np.ones(5))
    empty = pd.DataFrame({"series": pd.Series([], dtype=object), "time": pd.DatetimeIndex([], tz="UTC"),
                          "value": pd.Series([], dtype=float)})
    assert score_forecasts(fc, empty).empty
    other = pd.DataFrame({"series": "b.h", "time": fc["time"], "value": 1.0})
    assert score_forecasts(fc, other).columns.tolist() == SCORE_COLUMNS


@pytest.mark.parametrize("buckets", [(0,), (0, 6, 6), (12, 6), [[0, 6]]])
def test_bad_buckets_are_refused(buckets) -> None:
    with pytest.raises(ValueError, match="at least two increasing edges"):
        score_forecasts(forecast(0, "dss", "a.h", np.ones(3)), pd.DataFrame(columns=["series", "time", "value"]),
                        buckets)
