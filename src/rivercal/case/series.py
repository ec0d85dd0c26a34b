"""Reading and checking the CSV time series of a case.

A series file has a header row; its first column holds times (ISO 8601; times without an offset
are UTC), every other column holds numbers. Problems are reported with the file, the column, the
row and the offending text, never guessed away:

- a time that cannot be parsed, times that are not strictly increasing (duplicates, disorder);
- an empty cell or a value that is not a finite number;
- a gap: in a regular series (at least 90 % of the intervals equal), an interval longer than the
  regular step. Irregular series (breakpoints of a hydrograph) are accepted as they are.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.errors import CaseError

__all__ = ["check_coverage", "read_series_csv"]


def read_series_csv(path: Path, *, label: str | None = None) -> pd.DataFrame:
    """Read a series CSV into a DataFrame indexed by UTC time.

    Parameters
    ----------
    path
        The CSV file.
    label
        Name used for the file in error messages (default: the file name).

    Returns
    -------
    pandas.DataFrame
        One float column per value column, indexed by a strictly increasing UTC DatetimeIndex.

    Raises
    ------
    CaseError
        When the file is missing or unreadable, or any value breaks the rules of this module.
    """
    name = label or path.name
    if not path.is_file():
        raise CaseError("file not found", file=name)
    try:
        raw = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise CaseError(f"not a readable CSV file ({exc})", file=name) from exc
    if raw.shape[1] < 2:
        raise CaseError("needs a time column and at least one value column", file=name)
    if raw.shape[0] < 1:
        raise CaseError("has no data rows", file=name)
    raw.columns = [str(c).strip() for c in raw.columns]
    if len(set(raw.columns)) != len(raw.columns):
        raise CaseError(f"duplicate column names in {list(raw.columns)}", file=name)
    time_col = raw.columns[0]
    times = _parse_times(raw[time_col].to_numpy(), name, time_col)
    data = {}
    for col in raw.columns[1:]:
        data[col] = _parse_values(raw[col].to_numpy(), times, name, col)
    frame = pd.DataFrame(data, index=times)
    frame.index.name = "time"
    _check_gaps(frame.index, name)
    return frame


def _row(i: int) -> str:
    # Row numbers as a user sees them in an editor: the header is line 1.
    return f"line {i + 2}"


def _parse_times(text: np.ndarray, file: str, column: str) -> pd.DatetimeIndex:
    parsed = pd.to_datetime(pd.Series(text).str.strip(), utc=True, errors="coerce", format="ISO8601")
    bad = np.flatnonzero(parsed.isna().to_numpy())
    if bad.size:
        i = int(bad[0])
        raise CaseError(f"{_row(i)}: not a time: {text[i]!r} (expected ISO 8601, e.g. 2010-09-01T00:00:00Z)",
                        file=file, field=column)
    index = pd.DatetimeIndex(parsed)
    step = np.diff(index.asi8)
    if np.any(step == 0):
        i = int(np.flatnonzero(step == 0)[0]) + 1
        raise CaseError(f"{_row(i)}: duplicate time {index[i].isoformat()}", file=file, field=column)
    if np.any(step < 0):
        i = int(np.flatnonzero(step < 0)[0]) + 1
        raise CaseError(f"{_row(i)}: time {index[i].isoformat()} is earlier than the previous row",
                        file=file, field=column)
    return index


def _parse_values(text: np.ndarray, times: pd.DatetimeIndex, file: str, column: str) -> np.ndarray:
    stripped = pd.Series(text).str.strip()
    values = pd.to_numeric(stripped, errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        i = int(bad[0])
        what = "missing value (gap)" if stripped[i] == "" else f"not a finite number: {text[i]!r}"
        raise CaseError(f"{_row(i)} ({times[i].isoformat()}): {what}", file=file, field=column)
    return values


def _check_gaps(index: pd.DatetimeIndex, file: str) -> None:
    if len(index) < 3:
        return
    step = np.diff(index.asi8)
    values, counts = np.unique(step, return_counts=True)
    regular = values[np.argmax(counts)]
    if counts.max() < 0.9 * step.size:
        return
    long = np.flatnonzero(step > regular)
    if long.size:
        i = int(long[0])
        raise CaseError(
            f"gap in a regular series (step {pd.Timedelta(int(regular), 'ns')}): nothing between "
            f"{index[i].isoformat()} and {index[i + 1].isoformat()}",
            file=file,
        )


def check_coverage(series: pd.Series, start: pd.Timestamp, end: pd.Timestamp, *, file: str, field: str) -> None:
    """Raise :class:`CaseError` unless ``series`` covers ``[start, end]``.

    Parameters
    ----------
    series
        A series indexed by UTC time.
    start, end
        The period that must be covered.
    file, field
        Where the series comes from, for the message.
    """
    first, last = series.index[0], series.index[-1]
    if first > start or last < end:
        raise CaseError(
            f"the series covers {first.isoformat()} .. {last.isoformat()}, which does not cover the "
            f"simulated period {start.isoformat()} .. {end.isoformat()}",
            file=file,
            field=field,
        )
