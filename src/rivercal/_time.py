"""Times in rivercal are UTC: a naive time is taken to be UTC, an aware one is converted.

One conversion for a time (:func:`utc`), one for a time index (:func:`utc_index`), and the linear
interpolation of a series to other times (:func:`interpolate_at`, e.g. simulated values at the
observation times).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

__all__ = ["interpolate_at", "seconds_since", "utc", "utc_index"]


def utc(time: Any) -> pd.Timestamp:
    """A time as a UTC pandas Timestamp (a naive time is taken to be UTC).

    Parameters
    ----------
    time
        Anything :class:`pandas.Timestamp` takes: text (ISO 8601), a datetime, a Timestamp, a number of ns.

    Raises
    ------
    ValueError
        If ``time`` is not a time (text that does not parse, None, NaT).
    """
    ts = pd.Timestamp(time)
    if ts is pd.NaT or pd.isna(ts):
        raise ValueError(f"not a time: {time!r}")
    return ts.tz_localize("UTC") if ts.tzinfo is None else ts.tz_convert("UTC")


def utc_index(times: Any) -> pd.DatetimeIndex:
    """Times as a UTC DatetimeIndex (naive times are taken to be UTC)."""
    index = pd.DatetimeIndex(times)
    return index.tz_localize("UTC") if index.tz is None else index.tz_convert("UTC")


def seconds_since(times: Any, origin: pd.Timestamp) -> np.ndarray:
    """Times as float seconds after ``origin`` (both tz-aware, or both naive)."""
    return np.asarray((pd.DatetimeIndex(times) - origin).total_seconds(), dtype=float)


def interpolate_at(index: Any, values: Any, times: Any, origin: pd.Timestamp | None = None) -> np.ndarray:
    """The values of a series at other times, linear in time; constant beyond its first and last time.

    Parameters
    ----------
    index
        Increasing times of the series.
    values
        Its values (any unit; the result has the same).
    times
        Where the values are wanted.
    origin
        Time from which seconds are counted for the interpolation (default: the series' first time).
    """
    origin = pd.DatetimeIndex(index)[0] if origin is None else origin
    return np.interp(seconds_since(times, origin), seconds_since(index, origin), np.asarray(values, dtype=float))
