"""Reading and checking CSV time series: the series of a case, and observation files.

A series file has a header row; its first column holds times (ISO 8601; times without an offset
are UTC), every other column holds numbers. Problems are reported with the file, the column, the
line and the offending text, never guessed away:

- a time that cannot be parsed, times that are not strictly increasing (duplicates, disorder);
- a gap: in a regular series (at least 90 % of the intervals equal), an interval longer than the
  regular step. Irregular series (breakpoints of a hydrograph) are accepted as they are. Observation
  files (:func:`rivercal.io.read_observations_csv`) may have gaps and skip this check;
- an empty cell or a value that is not a finite number (only in the columns a case uses, so a
  file may carry other columns, e.g. remarks). In an observation file an empty cell is a missing
  observation, not an error.

Line numbers are those an editor shows: the header is line 1.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.errors import CaseError

__all__ = ["SeriesTable", "check_coverage", "check_range", "read_series_csv", "read_series_table", "series_column"]

#: Share of equal intervals from which a series counts as regular (and a longer interval as a gap).
REGULAR_SHARE = 0.9


@dataclass(frozen=True)
class SeriesTable:
    """A series file with checked times and the raw text of its value columns.

    Attributes
    ----------
    label
        Name of the file in messages.
    time_column
        Header of the time column.
    times
        Strictly increasing UTC times, one per data line.
    text
        The value columns as text (stripped), one row per time.
    """

    label: str
    time_column: str
    times: pd.DatetimeIndex
    text: pd.DataFrame

    @property
    def columns(self) -> list[str]:
        """Names of the value columns."""
        return list(self.text.columns)


def read_series_table(path: Path, *, label: str | None = None, used_by: str | None = None,
                      allow_gaps: bool = False) -> SeriesTable:
    """Read a series CSV and check its header and times (not yet its values).

    Parameters
    ----------
    path
        The CSV file.
    label
        Name used for the file in error messages (default: the file name).
    used_by
        The case field that refers to the file (``boundaries[0].series``), for the messages.
    allow_gaps
        Accept gaps in a regular series (observations); by default a gap is an error.

    Returns
    -------
    SeriesTable
        Times and the raw text of the value columns.

    Raises
    ------
    CaseError
        When the file is missing or unreadable, has no value column or no data, or a time is
        invalid, repeated, out of order or followed by a gap.
    """
    name = label or path.name
    suffix = f" (referenced by {used_by})" if used_by else ""
    if not path.is_file():
        raise CaseError(f"file not found{suffix}", file=name)
    try:
        raw = pd.read_csv(path, header=None, dtype=str, keep_default_na=False, encoding="utf-8-sig")
    except pd.errors.EmptyDataError:
        raise CaseError(f"the file is empty{suffix}", file=name) from None
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError, OSError) as exc:
        raise CaseError(f"not a readable CSV file: {_one_line(exc)}{suffix}", file=name) from None
    raw = raw.fillna("").map(lambda v: str(v).strip())
    header = [str(h) for h in raw.iloc[0]]
    body = raw.iloc[1:].reset_index(drop=True)
    body.columns = header
    if len(header) < 2:
        raise CaseError(f"needs a time column and at least one value column (header: {header}){suffix}", file=name)
    for i, h in enumerate(header):
        if h == "":
            raise CaseError(f"column {i + 1} of the header (line 1) has no name{suffix}", file=name)
    seen: dict[str, int] = {}
    for i, h in enumerate(header):
        if h in seen:
            raise CaseError(f"the header (line 1) names column {h!r} twice (columns {seen[h] + 1} and {i + 1})"
                            f"{suffix}", file=name)
        seen[h] = i
    if body.shape[0] < 1:
        raise CaseError(f"has a header but no data lines{suffix}", file=name)
    times = _parse_times(body[header[0]].to_numpy(), name, header[0], suffix)
    if not allow_gaps:
        _check_gaps(times, name, header[0], suffix)
    text = body[header[1:]]
    text.index = times
    return SeriesTable(label=name, time_column=header[0], times=times, text=text)


def series_column(table: SeriesTable, column: str, *, used_by: str | None = None,
                  allow_missing: bool = False) -> pd.Series:
    """The numbers of one column of a series file.

    Parameters
    ----------
    table
        The file, read by :func:`read_series_table`.
    column
        Header of the value column.
    used_by
        The case field that refers to the column, for the messages.
    allow_missing
        An empty cell is a missing value (NaN) instead of an error (observations).

    Returns
    -------
    pandas.Series
        Float values on the file's UTC times.

    Raises
    ------
    CaseError
        When the column does not exist, a cell is empty (unless ``allow_missing``) or holds anything but a
        finite number.
    """
    suffix = f" (referenced by {used_by})" if used_by else ""
    if column not in table.text.columns:
        if column == table.time_column:
            reason = f"column {column!r} holds the times; refer to a value column ({', '.join(table.columns)})"
        else:
            reason = f"no column {column!r} in the header (columns: {', '.join(table.columns)})"
        raise CaseError(reason + suffix, file=table.label, field=column)
    text = table.text[column]
    values = pd.to_numeric(text, errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(values) & ~(allow_missing & (text == "").to_numpy()))
    if bad.size:
        i = int(bad[0])
        cell = str(text.iloc[i])
        if cell == "":
            what = "the value is missing (empty cell); fill the gap or remove the line"
        elif np.isnan(values[i]) and cell.lower() not in ("nan", "-nan", "+nan"):
            hint = " (use '.' as the decimal separator)" if "," in cell else ""
            what = f"{cell!r} is not a number{hint}"
        else:
            what = f"{cell!r} is not a finite number"
        raise CaseError(f"{_line(i)} ({_iso(table.times[i])}): {what}{suffix}", file=table.label, field=column)
    return pd.Series(values, index=table.times, name=column)


def read_series_csv(path: Path, *, label: str | None = None) -> pd.DataFrame:
    """Read a series CSV into a DataFrame indexed by UTC time, checking every value column.

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
    table = read_series_table(path, label=label)
    frame = pd.DataFrame({c: series_column(table, c) for c in table.columns}, index=table.times)
    frame.index.name = "time"
    return frame


def _line(i: int) -> str:
    # Line numbers as a user sees them in an editor: the header is line 1.
    return f"line {i + 2}"


def _iso(ts: pd.Timestamp) -> str:
    return ts.strftime("%Y-%m-%dT%H:%M:%SZ")


def _td(value) -> str:
    seconds = pd.Timedelta(value).total_seconds()
    for unit, size in (("d", 86400), ("h", 3600), ("min", 60)):
        if seconds >= size and seconds % size == 0:
            return f"{seconds / size:g} {unit}"
    return f"{seconds:g} s"


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split())


def _parse_times(text: np.ndarray, file: str, column: str, suffix: str) -> pd.DatetimeIndex:
    parsed = pd.to_datetime(pd.Series(text, dtype=object), utc=True, errors="coerce", format="ISO8601")
    bad = np.flatnonzero(parsed.isna().to_numpy())
    if bad.size:
        i = int(bad[0])
        shown = "an empty cell" if text[i] == "" else repr(text[i])
        raise CaseError(
            f"{_line(i)}: {shown} is not a time (expected ISO 8601, e.g. 2020-01-01T00:00:00Z){suffix}",
            file=file, field=column,
        )
    index = pd.DatetimeIndex(parsed)
    steps = (index[1:] - index[:-1]).to_numpy()
    zero = np.flatnonzero(steps == np.timedelta64(0, "ns"))
    if zero.size:
        i = int(zero[0]) + 1
        raise CaseError(f"{_line(i)}: the time {_iso(index[i])} appears twice (also on {_line(i - 1)}){suffix}",
                        file=file, field=column)
    back = np.flatnonzero(steps < np.timedelta64(0, "ns"))
    if back.size:
        i = int(back[0]) + 1
        raise CaseError(
            f"{_line(i)}: the time {_iso(index[i])} is earlier than {_iso(index[i - 1])} on {_line(i - 1)}; "
            f"lines must be in time order{suffix}",
            file=file, field=column,
        )
    return index


def _check_gaps(index: pd.DatetimeIndex, file: str, column: str, suffix: str) -> None:
    if len(index) < 3:
        return
    steps = (index[1:] - index[:-1]).to_numpy()
    values, counts = np.unique(steps, return_counts=True)
    regular = values[np.argmax(counts)]
    if counts.max() < REGULAR_SHARE * steps.size:
        return
    long = np.flatnonzero(steps > regular)
    if long.size:
        i = int(long[0])
        raise CaseError(
            f"{_line(i + 1)}: gap in a regular series: nothing between {_iso(index[i])} and {_iso(index[i + 1])}, "
            f"while the step is {_td(regular)}; fill in the missing lines{suffix}",
            file=file, field=column,
        )


def check_coverage(
    series: pd.Series, start: pd.Timestamp, end: pd.Timestamp, *, file: str, field: str, used_by: str | None = None
) -> None:
    """Raise :class:`CaseError` unless ``series`` covers ``[start, end]``.

    Parameters
    ----------
    series
        A series indexed by UTC time.
    start, end
        The period that must be covered.
    file, field
        Where the series comes from (the file and its column), for the message.
    used_by
        The case field that refers to the series, for the message.
    """
    first, last = series.index[0], series.index[-1]
    if first > start or last < end:
        who = used_by or "the series"
        missing = f"starts {_td(first - start)} too late" if first > start else f"ends {_td(end - last)} too early"
        raise CaseError(
            f"the series covers {_iso(first)} .. {_iso(last)} and {missing}: {who} must cover the whole simulated "
            f"period {_iso(start)} .. {_iso(end)} (case.start .. case.end)",
            file=file,
            field=field,
        )


def check_range(
    series: pd.Series, limit: float, unit: str, *, file: str, field: str, used_by: str | None = None
) -> None:
    """Raise :class:`CaseError` when a value of ``series`` lies outside ±``limit``.

    Parameters
    ----------
    series
        A series indexed by UTC time.
    limit
        The largest plausible magnitude (e.g. 1e4 m AD for levels, 1e6 m³/s for discharges).
    unit
        Unit of the values, for the message.
    file, field
        Where the series comes from (the file and its column), for the message.
    used_by
        The case field that refers to the series, for the message.
    """
    values = series.to_numpy(dtype=float)
    bad = np.flatnonzero(np.abs(values) > limit)
    if bad.size:
        i = int(bad[0])
        suffix = f" (referenced by {used_by})" if used_by else ""
        raise CaseError(
            f"{_iso(series.index[i])}: {values[i]:g} {unit} lies outside the plausible range ±{limit:g} {unit}{suffix}",
            file=file,
            field=field,
        )
