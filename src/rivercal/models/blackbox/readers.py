"""Output readers of a black box: files in its run folder → series named ``<station>.<quantity>``.

- ``csv``: a column of ISO 8601 times (``time_column``; times without offset are UTC) and one column per
  variable;
- ``netcdf``: a CF NetCDF file read with xarray; a variable over ``time`` (``name``) or one series of a CF
  timeSeries variable (``name@id``, the id in the coordinate whose ``cf_role`` is ``timeseries_id``), as
  :meth:`rivercal.results.SimulationResult.to_netcdf` writes them;
- ``pixml``: a Delft-FEWS PI-XML time-series file (:func:`rivercal.io.read_pixml_series`), a variable
  being ``locationId/parameterId``;
- ``swmm``: EPA SWMM's binary output (:func:`rivercal.models.swmm.output.read_swmm_output`), a variable
  being ``node:<id>`` (head, m) or ``link:<id>`` (flow, m³/s).

What is read is bounded: a text output (CSV, PI-XML) holds at most :data:`MAX_TEXT_BYTES` and a CSV line
at most :data:`MAX_LINE_BYTES`; anything larger is refused before it is parsed. A CSV cell in a column of
numbers that is text is refused naming its line and column (a text longer than :data:`MAX_FIELD_CHARS`
characters without being parsed), and every message quotes at most :data:`EXCERPT` characters of a
file. A time written twice in one output is refused (naming the file and the time): which of the two
rows the program meant cannot be told.

Every reader raises ValueError naming the file (by the label it is given: its name in the run folder)
and what is wrong (missing, not a regular file, too large, unreadable, truncated, a time or value that
is not one, a variable it does not hold); the black box turns that into a failed run.
"""

from __future__ import annotations

import csv
import io
import os
import re
import stat
import warnings
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.models.blackbox.paths import kind_of

__all__ = ["EXCERPT", "MAX_FIELD_CHARS", "MAX_LINE_BYTES", "MAX_TEXT_BYTES", "READERS", "excerpt", "read_output"]

#: Largest CSV or PI-XML output read, bytes (256 MiB).
MAX_TEXT_BYTES = 256 << 20
#: Longest CSV line read, bytes (1 MiB).
MAX_LINE_BYTES = 1 << 20
#: Longest text a CSV cell of a number column may hold to be tried as a number, characters.
MAX_FIELD_CHARS = 100
#: Characters of a file's content a message quotes at most.
EXCERPT = 40
#: Texts a CSV value may be that mean "no number" (besides pandas' own missing-value marks such as ``NA``; they
#: become NaN or ±inf, and the run then fails if they fall on its grid).
_NAN_TEXTS = {"nan", "-nan", "+nan", "NaN", "NAN", "inf", "+inf", "-inf", "Inf", "+Inf", "-Inf", "INF", "-INF",
              "infinity", "-infinity", "Infinity", "-Infinity"}


def excerpt(text: object, limit: int = EXCERPT) -> str:
    """``text`` quoted on one line, shortened to ``limit`` characters (with the length it had)."""
    text = str(text)
    if len(text) <= limit:
        return repr(text)
    return f"{text[:limit]!r}… ({len(text):,} characters)"


def _clip(message: str, limit: int = 300) -> str:
    """A message from a library on one line and at most ``limit`` characters."""
    message = " ".join(message.split())
    return message if len(message) <= limit else message[:limit] + "…"


def _longest_line(path: Path, label: str) -> None:
    """ValueError when a line of the file is longer than :data:`MAX_LINE_BYTES` (read in blocks, never whole)."""
    current, number = 0, 1
    with open(path, "rb") as f:
        while block := f.read(1 << 20):
            ends = np.flatnonzero(np.frombuffer(block, dtype=np.uint8) == 10)
            if ends.size == 0:
                current += len(block)
            else:
                first = current + int(ends[0])
                gaps = np.diff(ends)
                longest = max(first, int(gaps.max()) - 1 if gaps.size else 0)
                if longest > MAX_LINE_BYTES:
                    where = 0 if first > MAX_LINE_BYTES else int(np.argmax(gaps)) + 1
                    raise ValueError(f"{label}: line {number + where:,} is longer than {MAX_LINE_BYTES:,} bytes")
                number += ends.size
                current = len(block) - int(ends[-1]) - 1
            if current > MAX_LINE_BYTES:
                raise ValueError(f"{label}: line {number:,} is longer than {MAX_LINE_BYTES:,} bytes")


def _line(path: Path, row: int) -> int:
    """The line of the file that holds data row ``row`` (0-based; the header and blank lines skipped)."""
    seen = -1
    with open(path, "rb") as f:
        for n, line in enumerate(f, start=1):
            if n > 1 and line.strip():
                seen += 1
                if seen == row:
                    return n
    return row + 2


def _times(column: pd.Series) -> tuple[pd.DatetimeIndex, int | None]:
    """The ISO 8601 times of a CSV column (UTC when without offset) and the first row that holds none (or None)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        times = pd.to_datetime(column.astype(str), format="ISO8601", utc=True, errors="coerce")
    bad = np.flatnonzero(times.isna().to_numpy())
    return pd.DatetimeIndex(times), (int(bad[0]) if bad.size else None)


def _numbers(column: pd.Series) -> tuple[np.ndarray, int | None]:
    """The numbers of a CSV column (a missing cell or nan/inf: NaN/±inf) and the first row that is text (or None)."""
    if pd.api.types.is_numeric_dtype(column.dtype) and not pd.api.types.is_bool_dtype(column.dtype):
        return column.to_numpy(dtype=float), None
    text = column.astype(object).where(column.notna(), "").astype(str)
    short = np.fromiter((len(t) <= MAX_FIELD_CHARS for t in text), dtype=bool, count=len(text))
    numbers = pd.to_numeric(text.where(short, "x"), errors="coerce").to_numpy(dtype=float)
    nan = np.flatnonzero(np.isnan(numbers))
    if nan.size:
        blank = text.iloc[nan].str.strip().isin(_NAN_TEXTS | {""}).to_numpy()
        nan = nan[~blank]
    return numbers, (int(nan[0]) if nan.size else None)


def _csv(path: Path, series: Mapping[str, str], time_column: str, label: str) -> pd.DataFrame:
    _longest_line(path, label)
    with open(path, "rb") as f:
        first = f.readline()
    try:
        header = next(csv.reader(io.StringIO(first.decode("utf-8-sig"))), [])
    except UnicodeDecodeError:
        raise ValueError(f"{label}: not a readable CSV file (its header line is not UTF-8 text)") from None
    names = [h.strip() for h in header]
    if time_column not in names:
        shown = ", ".join(excerpt(n) for n in names[:20]) + (", …" if len(names) > 20 else "")
        raise ValueError(f"{label}: no time column {excerpt(time_column, 80)} (columns: {shown or 'none'})")
    wanted = {time_column, *series.values()}
    for name, column in series.items():
        if column not in names:
            raise ValueError(f"{label}: no column {excerpt(column, 80)} for {name}")
    for column in wanted:
        if names.count(column) > 1:
            raise ValueError(f"{label}: column {excerpt(column, 80)} appears {names.count(column)} times")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", pd.errors.ParserWarning)  # the first row longer than the header
            frame = pd.read_csv(path, index_col=False, skipinitialspace=True, skip_blank_lines=True,
                                encoding="utf-8-sig", na_values=sorted(_NAN_TEXTS), keep_default_na=True)
    except pd.errors.ParserWarning:
        raise ValueError(f"{label}: line {_line(path, 0)} holds more fields than its header") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError) as exc:
        fields = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", str(exc))
        if fields:
            cause = f"line {fields.group(2)} holds {fields.group(3)} fields, its header {fields.group(1)}"
        elif isinstance(exc, UnicodeDecodeError):
            cause = "not UTF-8 text"
        else:
            cause = f"not a readable CSV file ({_clip(str(exc), 120)})"
        raise ValueError(f"{label}: {cause}") from None
    frame = frame[[c for c in frame.columns if c.strip() in wanted]]
    frame.columns = [c.strip() for c in frame.columns]
    index, bad = _times(frame[time_column])
    if bad is not None:
        cell = frame[time_column].iloc[bad]
        text = "" if pd.isna(cell) else str(cell).strip()
        what = "an empty time" if not text else f"{excerpt(text)}, not an ISO 8601 time"
        raise ValueError(f"{label} line {_line(path, bad):,}: column {time_column!r} holds {what}")
    out = {}
    for name, column in series.items():
        out[name], bad = _numbers(frame[column])
        if bad is not None:
            raise ValueError(f"{label} line {_line(path, bad):,}: column {column!r} holds "
                             f"{excerpt(str(frame[column].iloc[bad]).strip())}, not a number")
    return pd.DataFrame(out, index=index)


def _netcdf(path: Path, series: Mapping[str, str], time_column: str, label: str) -> pd.DataFrame:
    import xarray as xr

    try:
        ds = xr.open_dataset(path)
    except OSError as exc:
        raise ValueError(f"{label}: not a readable NetCDF file ({exc.strerror or 'the file is damaged'})") from None
    except (ValueError, TypeError, KeyError):  # xarray's own words speak to a Python user (engine=...)
        raise ValueError(f"{label}: not a readable NetCDF file (not NetCDF, or damaged)") from None
    with ds:
        if "time" not in ds.coords:
            raise ValueError(f"{label}: no time coordinate")
        try:
            index = pd.DatetimeIndex(pd.to_datetime(ds["time"].values, utc=True))
        except (ValueError, TypeError, OverflowError):
            raise ValueError(f"{label}: its time coordinate does not hold times") from None
        out = {}
        for name, spec in series.items():
            var, _, ident = spec.partition("@")
            if var not in ds.data_vars:
                raise ValueError(f"{label}: no variable {excerpt(var, 80)} for {name}")
            da = ds[var]
            if ident:
                dims = [d for d in da.dims if d != "time"]
                coord = next((ds[d] for d in dims if d in ds and ds[d].attrs.get("cf_role") == "timeseries_id"), None)
                if coord is None:
                    raise ValueError(f"{label}: variable {excerpt(var, 80)} has no timeseries_id coordinate")
                ids = [str(v) for v in coord.values]
                if ident not in ids:
                    shown = ", ".join(excerpt(i) for i in ids[:20]) + (", …" if len(ids) > 20 else "")
                    raise ValueError(f"{label}: {excerpt(var, 80)} has no series {excerpt(ident, 80)} (has {shown})")
                da = da.isel({coord.name: ids.index(ident)})
            if da.dims != ("time",):
                raise ValueError(f"{label}: {excerpt(spec, 80)} is not one series over time (dimensions {da.dims})")
            try:
                out[name] = np.asarray(da.values, dtype=float)
            except (ValueError, TypeError):
                raise ValueError(f"{label}: variable {excerpt(var, 80)} does not hold numbers") from None
    return pd.DataFrame(out, index=index)


def _pixml(path: Path, series: Mapping[str, str], time_column: str, label: str) -> pd.DataFrame:
    from rivercal.io import read_pixml_series

    try:
        found = {f"{s.location_id}/{s.parameter_id}": s for s in read_pixml_series(path)}
    except ValueError as exc:
        reason = getattr(exc, "reason", str(exc))
        raise ValueError(f"{label}: not a readable PI-XML file ({_clip(reason, 200)})") from None
    parts = []
    for name, key in series.items():
        s = found.get(key)
        if s is None:
            shown = ", ".join(excerpt(k) for k in list(found)[:20]) + (", …" if len(found) > 20 else "")
            raise ValueError(f"{label}: no series {excerpt(key, 80)} (locationId/parameterId) for {name}; has "
                             f"{shown or 'none'}")
        values = np.where(s.values == s.miss_val, np.nan, s.values.astype(float))
        parts.append(pd.Series(values, index=pd.DatetimeIndex(s.times), name=name))
        if parts[-1].index.has_duplicates:
            _duplicate(parts[-1].index, label)
    return pd.concat(parts, axis=1)


def _swmm(path: Path, series: Mapping[str, str], time_column: str, label: str) -> pd.DataFrame:
    from rivercal.models.swmm.output import read_swmm_output

    try:
        return read_swmm_output(path, series)
    except ValueError as exc:
        raise ValueError(_clip(str(exc).replace(str(path), label))) from None


#: Reader name → function(path, series, time_column, label) → DataFrame.
READERS: dict[str, Callable[[Path, Mapping[str, str], str, str], pd.DataFrame]] = {
    "csv": _csv, "netcdf": _netcdf, "pixml": _pixml, "swmm": _swmm}
_TEXT = ("csv", "pixml")


def _duplicate(index: pd.DatetimeIndex, label: str) -> None:
    when = index[index.duplicated()][0]
    raise ValueError(f"{label}: the time {when.isoformat()} is written more than once (which row holds the "
                     "run's value cannot be told)")


def read_output(reader: str, path: str | Path, series: Mapping[str, str], time_column: str = "time",
                label: str | None = None) -> pd.DataFrame:
    """The series of one output file, columns named as the keys of ``series``, indexed by UTC time (sorted).

    Parameters
    ----------
    reader
        ``csv``, ``netcdf``, ``pixml`` or ``swmm``.
    path
        The file.
    series
        Column name → variable (module docstring).
    time_column
        ``csv``: the column of times.
    label
        The file's name in messages (default: the path).

    Raises
    ------
    ValueError
        For a missing, empty, non-regular, too large or unreadable file, a bad time or value, a time
        written twice, or a variable the file does not hold (naming the file).
    """
    path = Path(path)
    label = label or str(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        what = kind_of(path)
        raise ValueError(f"the program wrote no {label}" if what == "missing" else f"{label} is {what}") from None
    except OSError as exc:
        raise ValueError(f"{label} cannot be read ({exc.strerror})") from None
    if not stat.S_ISREG(info.st_mode):
        raise ValueError(f"{label} is {kind_of(path)}, not a file")
    if info.st_size == 0:
        raise ValueError(f"{label} is empty")
    if reader in _TEXT and info.st_size > MAX_TEXT_BYTES:
        raise ValueError(f"{label} holds {info.st_size:,} bytes, more than the {MAX_TEXT_BYTES:,} rivercal reads of "
                         f"a {reader} output")
    frame = READERS[reader](path, series, time_column, label)
    if frame.index.has_duplicates:
        _duplicate(frame.index, label)
    return frame.sort_index()
