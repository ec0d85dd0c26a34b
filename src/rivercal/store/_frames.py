"""Conversions between the store's rows and pandas objects (no database access here).

Data times are stored as integer Unix seconds (UTC); wall-clock stamps as ISO 8601 UTC text with
milliseconds. See :mod:`rivercal.store.schema` for the units of every column.
"""

from __future__ import annotations

import datetime as dt
import json
import logging
import threading
from collections.abc import Iterable, Mapping, Sequence
from pathlib import PurePath
from typing import Any

import numpy as np
import pandas as pd

from rivercal._time import utc, utc_index
from rivercal.store.records import FORECAST_KINDS

log = logging.getLogger("rivercal.store")

_NS_PER_S = 1_000_000_000


_last_stamp = dt.datetime.min.replace(tzinfo=dt.UTC)
_stamp_lock = threading.Lock()


def now_stamp() -> str:
    """Wall-clock time now as stored: ISO 8601 UTC with milliseconds (``2010-11-01T06:00:03.125Z``).

    Strictly increasing within a process: two writes in the same millisecond get stamps 1 ms apart, so
    that "the value ingested last wins" never depends on the order a query happens to return ties in.
    """
    global _last_stamp
    with _stamp_lock:
        now = dt.datetime.now(dt.UTC)
        now = now.replace(microsecond=now.microsecond // 1000 * 1000)
        _last_stamp = max(now, _last_stamp + dt.timedelta(milliseconds=1))
        return _last_stamp.isoformat(timespec="milliseconds").replace("+00:00", "Z")


def stamp_to_time(stamps: Any) -> Any:
    """Stored wall-clock stamp(s) to UTC Timestamp(s) (None/NaN stays NaT)."""
    return pd.to_datetime(stamps, utc=True, format="ISO8601")


def to_unix(time: Any, what: str = "time") -> int:
    """A time as integer Unix seconds (UTC; a naive time is UTC).

    Raises
    ------
    ValueError
        If the time has a fraction of a second (the store keeps whole seconds; nothing is rounded).
    """
    ns = utc(time).value
    if ns % _NS_PER_S:
        raise ValueError(f"{what} {utc(time).isoformat()} has a fraction of a second; the store keeps whole "
                         "seconds")
    return ns // _NS_PER_S


def index_to_unix(index: Any, what: str) -> np.ndarray:
    """A time index (naive = UTC) as int64 Unix seconds; refuses fractions of a second."""
    times = utc_index(index)
    ns = times.as_unit("ns").asi8
    frac = ns % _NS_PER_S != 0
    if frac.any():
        raise ValueError(f"{what}: time {times[int(np.flatnonzero(frac)[0])].isoformat()} has a fraction of a "
                         "second; the store keeps whole seconds")
    return ns // _NS_PER_S


def from_unix(seconds: Any) -> Any:
    """Stored Unix seconds to UTC Timestamp(s)."""
    return pd.to_datetime(seconds, unit="s", utc=True)


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (pd.Timestamp, dt.datetime, dt.date)):
        return value.isoformat()
    if isinstance(value, (pd.Timedelta, dt.timedelta)):
        return pd.Timedelta(value).isoformat()
    if isinstance(value, PurePath):
        return str(value)
    if isinstance(value, (set, frozenset)):
        return sorted(value)
    raise TypeError(f"cannot store a {type(value).__name__} in a run configuration: {value!r}")


def config_json(config: Mapping[str, Any]) -> str:
    """A run configuration as canonical JSON (sorted keys; numpy, times and paths converted).

    Raises
    ------
    TypeError, ValueError
        For a value that is not JSON (an object, NaN or infinity).
    """
    if not isinstance(config, Mapping):
        raise TypeError(f"a run configuration must be a mapping, got {type(config).__name__}")
    return json.dumps(dict(config), sort_keys=True, allow_nan=False, default=_json_default)


#: Keys of a run's configuration that say where its model lies, not how the run computes: a case folder may move
#: between a run's cycles, so they are not compared when a run resumes.
LOCATION_KEYS = frozenset({"model_source"})


def config_differences(stored: Mapping[str, Any], given: Mapping[str, Any]) -> list[str]:
    """Top-level keys whose values differ between two configurations (after JSON normalisation).

    :data:`LOCATION_KEYS` are not compared.
    """
    a = json.loads(config_json(stored))
    b = json.loads(config_json(given))
    return sorted(k for k in (set(a) | set(b)) - LOCATION_KEYS if a.get(k, _MISSING) != b.get(k, _MISSING))


_MISSING = object()


def _check_series_id(series_id: Any, what: str) -> str:
    name = str(series_id)
    station, _, quantity = name.rpartition(".")
    if not station or not quantity:
        raise ValueError(f"{what}: series id {name!r} must be '<station>.<quantity>'")
    return name


def forecast_rows(forecasts: Mapping[str, pd.DataFrame], cycle: int,
                  issue_time: pd.Timestamp) -> list[tuple[str, str, int, float, float]]:
    """Rows ``(kind, series, time [s], lead_h [h], value)`` of a cycle's forecasts; NaN values dropped.

    Raises
    ------
    ValueError
        For an unknown kind, a bad series id, a time before the issue time or with a fraction of a second,
        or repeated times.
    """
    t0 = to_unix(issue_time, f"cycle {cycle} issue time")
    rows: list[tuple[str, str, int, float, float]] = []
    for kind, frame in forecasts.items():
        if kind not in FORECAST_KINDS:
            raise ValueError(f"cycle {cycle}: forecast kind must be one of {FORECAST_KINDS}, got {kind!r}")
        what = f"cycle {cycle} forecast {kind!r}"
        if frame.empty:
            continue
        times = index_to_unix(frame.index, what)
        if np.unique(times).size != times.size:
            raise ValueError(f"{what}: repeated times")
        if (times < t0).any():
            first = from_unix(int(times.min())).isoformat()
            raise ValueError(f"{what}: time {first} is before the issue time {issue_time.isoformat()}; store only "
                             "t >= issue time")
        lead = (times - t0) / 3600.0
        values = frame.to_numpy(dtype=float)
        dropped = 0
        for j, col in enumerate(frame.columns):
            series = _check_series_id(col, what)
            ok = np.isfinite(values[:, j])
            dropped += int((~ok).sum())
            n = int(ok.sum())
            rows.extend(zip([kind] * n, [series] * n, times[ok].tolist(), lead[ok].tolist(), values[ok, j].tolist(),
                            strict=True))
        if dropped:
            log.warning("%s: %d non-finite forecast values not stored", what, dropped)
    return rows


def band_rows(bands: Any, cycle: int, issue_time: pd.Timestamp) -> list[tuple[str, int, float, float, float, float]]:
    """Rows ``(series, time [s], lead_h [h], probability, low, high)`` of a cycle's forecast band (None: none).

    Checked as the forecasts are (:func:`forecast_rows`); a time where either side is NaN is not stored.

    Raises
    ------
    ValueError
        As :func:`forecast_rows`, and for a high side below the low side.
    """
    if bands is None:
        return []
    high = {(r[1], r[2]): r[4] for r in forecast_rows({"updated": bands.high}, cycle, issue_time)}
    rows = []
    for _, series, time, lead, low in forecast_rows({"updated": bands.low}, cycle, issue_time):
        if (series, time) in high:
            if high[series, time] < low:
                raise ValueError(f"cycle {cycle} forecast band: {series} at {from_unix(time).isoformat()}: high "
                                 f"{high[series, time]} is below low {low}")
            rows.append((series, time, lead, float(bands.probability), low, high[series, time]))
    return rows


def resolve_sources(rows: pd.DataFrame, sources: Sequence[str] | None, keep: Sequence[str] = ()) -> pd.DataFrame:
    """One value per (series, time) from stored rows with columns series, time, source, value, ingested.

    With ``sources`` (in priority order) only those sources count and the first listed wins; without,
    every source counts and the value ingested last wins. ``keep`` names further columns to return.
    """
    columns = ["series", "time", "value", *keep]
    if rows.empty:
        return rows[columns]
    if sources is not None:
        rank = {s: i for i, s in enumerate(sources)}
        rows = rows[rows["source"].isin(rank)].assign(_rank=lambda f: f["source"].map(rank))
        rows = rows.sort_values(["series", "time", "_rank"], kind="stable")
    else:
        rows = rows.sort_values(["series", "time", "ingested"], ascending=[True, True, False], kind="stable")
    n = len(rows)
    rows = rows.drop_duplicates(["series", "time"], keep="first")
    if n > len(rows):
        log.debug("%d values at times another source also covers were set aside", n - len(rows))
    return rows[columns].reset_index(drop=True)


def frame(rows: Iterable[Sequence[Any]], columns: Sequence[str]) -> pd.DataFrame:
    """A DataFrame of query rows (empty with the right columns when there are none)."""
    return pd.DataFrame.from_records(list(rows), columns=list(columns))
