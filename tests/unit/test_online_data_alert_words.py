"""A data alert over many thin series counts them and names the worst few; over few, it names them all."""

from __future__ import annotations

import pandas as pd

from rivercal.observations import ObservationSeries, ObservationSet
from rivercal.online.guardrails import DATA_ALERT_NAMES, data_alerts

START = pd.Timestamp("2010-10-01", tz="UTC")


def _set(hours: dict[str, int]) -> ObservationSet:
    """Series with the given number of hourly values from START (one window of 2 days: 49 values)."""
    return ObservationSet(tuple(
        ObservationSeries.from_series(pd.Series(1.0, index=pd.date_range(START, periods=n, freq="h")), id=name,
                                      sigma=0.01, source="test")
        for name, n in hours.items() if n))


def test_few_thin_series_are_all_named_with_their_coverage() -> None:
    (alert,) = data_alerts(_set({"A.h": 49, "B.h": 10, "C.h": 24}), "2D", 3600.0, 0.8)
    assert alert.kind == "data"
    assert alert.message.endswith("B.h (20%), C.h (49%)")


def test_many_thin_series_are_counted_and_the_worst_named() -> None:
    hours = {f"S{k:03d}.h": (1 + k % 30) for k in range(500)} | {f"G{k}.h": 49 for k in range(40)}
    (alert,) = data_alerts(_set(hours), "2D", 3600.0, 0.8)
    text = alert.message
    assert "500 of 540 series" in text
    # the worst five (one value each of 49: 2 %), in name order among equals, then how many more
    worst = sorted(n for n, v in hours.items() if v == 1)[:5]
    assert ", ".join(f"{n} (2%)" for n in worst) + " and 495 more" in text
    assert "data_coverage.csv" in text
    assert sum(name in text for name in hours) == 5 < DATA_ALERT_NAMES
    assert len(text) < 400
