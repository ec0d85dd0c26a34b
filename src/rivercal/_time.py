"""Times in rivercal are UTC: a naive time is taken to be UTC, an aware one is converted.

One conversion for a time (:func:`utc`), one for a time index (:func:`utc_index`), and the linear
interpolation of a series to other times (:func:`interpolate_at`, e.g. simulated values at the
observation times).

Times written as text are read as ISO 8601 only (:func:`parse_iso`): ``2010-11-10``,
``2010-11-10T06:00``, ``2010-11-10 06:00:00+01:00``, ``20101110``. A date such as ``10-11-2010`` is
refused, not guessed: it is 10 November to a Dutch reader and October 11 to pandas.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping
from datetime import datetime
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

__all__ = ["ISO_EXAMPLE", "Window", "Windows", "interpolate_at", "iso_datetime", "parse_iso", "seconds_since", "utc",
           "utc_index"]

#: How messages show the expected form of a time.
ISO_EXAMPLE = "ISO 8601, YYYY-MM-DD with an optional time, e.g. 2010-10-18 or 2010-10-18T06:00Z"
#: Day, month and year in some order, separated by -, / or . (10-11-2010, 11/10/2010, 10.11.10).
_NUMERIC_DATE = re.compile(r"^\s*(\d{1,2})[-/.](\d{1,2})[-/.](\d{2}|\d{4})\b")


def parse_iso(text: str) -> pd.Timestamp:
    """A time written in ISO 8601 as a pandas Timestamp (naive or aware, as written).

    Accepted: the forms of :meth:`datetime.fromisoformat` — ``YYYY-MM-DD`` (or ``YYYYMMDD``, or an ISO week
    date ``YYYY-Www-D``), optionally followed by ``T`` or a space and a time ``HH[:MM[:SS[.ffffff]]]``, and
    an offset ``Z`` or ``±HH:MM``.

    Raises
    ------
    ValueError
        Naming the text and the expected form; a date of numbers in another order (``10-11-2010``) is
        called ambiguous, with both readings.
    """
    if not isinstance(text, str):
        raise ValueError(f"not a time: {text!r}")
    stripped = text.strip()
    try:
        parsed = datetime.fromisoformat(stripped.replace("z", "Z"))
    except ValueError:
        raise ValueError(_not_iso(stripped)) from None
    try:
        return pd.Timestamp(parsed).as_unit("ns")
    except (ValueError, OverflowError):
        raise ValueError(f"{stripped!r} lies outside the times rivercal can hold ({pd.Timestamp.min:%Y} to "
                         f"{pd.Timestamp.max:%Y})") from None


def _not_iso(text: str) -> str:
    """Why ``text`` is refused: ambiguous (with its readings) or not ISO 8601 at all."""
    numeric = _NUMERIC_DATE.match(text)
    if numeric is not None:
        first, second, year = numeric.groups()
        year = year if len(year) == 4 else f"{'19' if int(year) > 50 else '20'}{year}"
        readings = []
        for day, month in ((first, second), (second, first)):
            try:
                readings.append(datetime(int(year), int(month), int(day)).strftime("%Y-%m-%d"))
            except ValueError:
                continue
        if len(set(readings)) > 1:
            return (f"{text!r} is ambiguous: day first it is {readings[0]}, month first {readings[1]}; write the date "
                    f"in {ISO_EXAMPLE}")
        return f"{text!r} is not an ISO 8601 date; write it as {ISO_EXAMPLE}" + (
            f" (here {readings[0]})" if readings else "")
    return f"{text!r} is not a date or time in {ISO_EXAMPLE}"


def iso_datetime(value: Any) -> Any:
    """A date field of a file (``case.toml``, ``model.toml``) before pydantic reads it: ISO 8601 or a TOML date.

    Text is read by :func:`parse_iso` (a date such as ``10-11-2010`` is refused with its readings); a TOML
    date or date-time passes as it is; a number is refused — pydantic would take ``20101018`` for seconds
    since 1970 and give 21 August 1970.

    Raises
    ------
    ValueError
        For text that is not ISO 8601, or a number.
    """
    if isinstance(value, bool | int | float):
        raise ValueError(f"{value!r} is a number, not a date; write the date in {ISO_EXAMPLE} (as text or a TOML "
                         "date)")
    if isinstance(value, str):
        return parse_iso(value).to_pydatetime()
    return value


def utc(time: Any) -> pd.Timestamp:
    """A time as a UTC pandas Timestamp (a naive time is taken to be UTC).

    Parameters
    ----------
    time
        Text in ISO 8601 (:func:`parse_iso`; other text is refused, never guessed), a datetime, a
        Timestamp, a numpy datetime64 or a number of ns.

    Raises
    ------
    ValueError
        If ``time`` is not a time (text that is not ISO 8601, None, NaT).
    """
    ts = parse_iso(time) if isinstance(time, str) else pd.Timestamp(time)
    if ts is pd.NaT or pd.isna(ts):
        raise ValueError(f"not a time: {time!r}")
    ts = ts.tz_localize("UTC") if ts.tzinfo is None else ts.tz_convert("UTC")
    return ts.as_unit("ns")  # one resolution whatever the input's: indexes built from it compare equal


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


class Window(NamedTuple):
    """A period [start, end] in UTC, e.g. a named calibration window of a case; unpacks as ``start, end``."""

    start: pd.Timestamp
    end: pd.Timestamp

    def __repr__(self) -> str:
        return f"Window({self.start:%Y-%m-%d %H:%M} … {self.end:%Y-%m-%d %H:%M} UTC)"

    @property
    def duration(self) -> pd.Timedelta:
        """``end - start``."""
        return self.end - self.start


class Windows(Mapping[str, Window]):
    """Named windows (name → :class:`Window`), read-only; a name that is not there is a KeyError naming those that are.

    Parameters
    ----------
    windows
        Name → (start, end); the times are taken as UTC (:func:`utc`).
    owner
        What holds the windows, for the message of a missing name (e.g. ``"case dommel"``).
    """

    def __init__(self, windows: Mapping[str, tuple[Any, Any]] | None = None, owner: str = ""):
        self._items = {str(k): Window(utc(a), utc(b)) for k, (a, b) in (windows or {}).items()}
        self._owner = owner

    def __getitem__(self, name: str) -> Window:
        try:
            return self._items[name]
        except KeyError:
            pass
        folded = [k for k in self._items if isinstance(name, str) and k.lower() == name.lower()]
        hint = f"; did you mean {folded[0]!r}?" if len(folded) == 1 else ""
        where = f"{self._owner} has" if self._owner else "the windows are"
        raise KeyError(f"no window {name!r}: {where} {', '.join(map(repr, self._items)) or 'none'}{hint}") from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __repr__(self) -> str:
        inner = ", ".join(f"{k!r}: {v!r}" for k, v in self._items.items())
        return f"Windows({{{inner}}})"
