"""Reader for KNMI daily station files (``etmgeg_<stn>.txt``, ``neerslaggeg_<name>_<stn>.txt``).

Format
------
KNMI's daily files start with a free-text header (licence, column descriptions), followed by one
column-header line ``STN,YYYYMMDD,DDVEC,...`` -- in newer files prefixed with ``#`` -- and then one
row per station and day: comma-separated, fixed-width integers. A field of blanks is a missing
value. Some rows end with a trailing comma (the precipitation-network files); it is ignored.

What the reader does with the raw codes
---------------------------------------
- **Units.** Values are converted to physical units: 0.1 mm → mm (``RH``, ``RHX``, ``EV24``,
  ``RD``), 0.1 h → h (``DR``, ``SQ``), 0.1 °C → °C, 0.1 m/s → m/s, 0.1 hPa → hPa. Columns that
  give the hour of an extreme (``RHXH``, ``TXH``, ...) stay integer *hour indices* (pandas
  ``Int64``): hour ``k`` (1–24) is the interval from ``k-1`` to ``k`` UT. :data:`UNITS` lists
  every known column.
- **Trace code -1.** In ``RH``, ``RHX`` (precipitation) and ``SQ`` (sunshine) KNMI writes -1 for
  "more than zero but less than 0.05" (mm or h). The reader replaces it with ``trace_value``
  (default :data:`TRACE_VALUE` = 0.025, half the resolution, so that a trace day is wet but
  adds almost nothing to sums). The count and dates of trace values per column are in
  ``frame.attrs["trace"]``. In every other column -1 is an ordinary value (e.g. -0.1 °C).
- **Missing fields.** A blank field becomes NaN (``<NA>`` in hour columns), never zero. The
  number of missing values per column is in ``frame.attrs["missing"]`` and is logged as a
  warning.

The day of an ``etmgeg`` row is the UT day 00–24 UT of ``YYYYMMDD``; the index of the returned
frame is that day's start (00:00 UTC). The precipitation-network files (``RD``) use the
08–08 UT day ending on ``YYYYMMDD`` at 08 UT; the reader does not shift them.

Source of the codes: KNMI, "Daggegevens van het weer in Nederland", the column descriptions in
the header of every ``etmgeg`` file. Data © KNMI, CC BY 4.0 ("Bron: KNMI").
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.errors import CaseError

__all__ = [
    "HOUR_COLUMNS",
    "TRACE_COLUMNS",
    "TRACE_VALUE",
    "UNITS",
    "MeteoFormatError",
    "read_knmi_daily",
]

logger = logging.getLogger(__name__)

#: Value (mm or h) that replaces the KNMI trace code -1 ("< 0.05") in :data:`TRACE_COLUMNS`.
TRACE_VALUE = 0.025

#: Columns in which -1 is the trace code "more than 0 but less than 0.05 (mm or h)".
TRACE_COLUMNS = ("RH", "RHX", "SQ")

#: Columns that hold the hour (1–24, hour ending at that UT hour) or 6-hour block of an extreme.
HOUR_COLUMNS = (
    "FHXH", "FHNH", "FXXH", "TNH", "TXH", "T10NH", "RHXH", "PXH", "PNH", "VVNH", "VVXH", "UXH", "UNH",
)

# column -> (factor from the file's integer to the physical value, physical unit)
_SCALE: dict[str, tuple[float, str]] = {
    "DDVEC": (1.0, "degree"),
    "FHVEC": (0.1, "m/s"), "FG": (0.1, "m/s"), "FHX": (0.1, "m/s"), "FHN": (0.1, "m/s"), "FXX": (0.1, "m/s"),
    "TG": (0.1, "degC"), "TN": (0.1, "degC"), "TX": (0.1, "degC"), "T10N": (0.1, "degC"),
    "SQ": (0.1, "h"), "SP": (1.0, "%"), "Q": (1.0, "J/cm2"),
    "DR": (0.1, "h"), "RH": (0.1, "mm"), "RHX": (0.1, "mm"), "RD": (0.1, "mm"),
    "PG": (0.1, "hPa"), "PX": (0.1, "hPa"), "PN": (0.1, "hPa"),
    "VVN": (1.0, "code"), "VVX": (1.0, "code"), "NG": (1.0, "octa"), "SX": (1.0, "code"),
    "UG": (1.0, "%"), "UX": (1.0, "%"), "UN": (1.0, "%"),
    "EV24": (0.1, "mm"),
}

#: Physical unit of every known column after reading ("hour" = hour index 1–24, hour ending).
UNITS: dict[str, str] = {
    "STN": "-",
    **{name: unit for name, (_, unit) in _SCALE.items()},
    **{name: "hour" for name in HOUR_COLUMNS},
}
UNITS["T10NH"] = "6-hour block (6, 12, 18, 24)"


class MeteoFormatError(CaseError):
    """A meteorological input file does not have the expected format.

    Parameters
    ----------
    message
        What is wrong.
    file
        The offending file.
    line
        1-based line number in the file, if the problem is on one line.
    column
        Name of the offending column, if known.
    """

    def __init__(self, message: str, *, file: str, line: int | None = None, column: str | None = None):
        self.line = line
        self.column = column
        where = []
        if line is not None:
            where.append(f"line {line}")
        if column is not None:
            where.append(f"column {column}")
        super().__init__(message, file=file, field=", ".join(where) or None)


def read_knmi_daily(
    path: str | Path,
    *,
    trace_value: float = TRACE_VALUE,
    station: int | None = None,
) -> pd.DataFrame:
    """Read a KNMI daily station file into a DataFrame in physical units.

    Parameters
    ----------
    path
        The file (``etmgeg_370.txt`` or an extract of it; ``neerslaggeg_*.txt`` also works).
    trace_value
        Value (mm for ``RH``/``RHX``, h for ``SQ``) that replaces the trace code -1 ("< 0.05").
        Must lie in [0, 0.05).
    station
        The station number to keep when the file holds several stations; required then.

    Returns
    -------
    pandas.DataFrame
        Indexed by the start of each UT day (``DatetimeIndex`` named ``date``, UTC, strictly
        increasing; gaps allowed and logged). Column ``STN`` (int), physical columns as float
        (see :data:`UNITS`), hour columns as ``Int64``. ``attrs``: ``source`` (path),
        ``station``, ``units`` (column → unit), ``missing`` (column → number of NaN values),
        ``trace`` (column → list of dates whose value was the trace code), ``trace_value``.

    Raises
    ------
    FileNotFoundError
        When ``path`` does not exist.
    MeteoFormatError
        When the header line is absent, a row has the wrong number of fields, a field is not an
        integer, a date is invalid, or dates repeat or run backwards. The message names the file,
        the line and the column.
    """
    path = Path(path)
    name = str(path)
    if not path.is_file():
        raise FileNotFoundError(f"KNMI file not found: {path}")
    if not 0.0 <= trace_value < 0.05:
        raise ValueError(f"trace_value must lie in [0, 0.05) (mm or h), got {trace_value}")
    lines = path.read_text(encoding="latin-1").splitlines()

    header_no, columns = _find_header(lines, name)
    ncol = len(columns)
    rows: list[list[int | None]] = []
    line_numbers: list[int] = []
    for no in range(header_no + 1, len(lines) + 1):
        text = lines[no - 1]
        if not text.strip() or text.lstrip().startswith("#"):
            continue
        fields = text.split(",")
        if len(fields) == ncol + 1 and not fields[-1].strip():
            fields = fields[:-1]
        if len(fields) != ncol:
            raise MeteoFormatError(f"expected {ncol} comma-separated fields, found {len(fields)}",
                                   file=name, line=no)
        row: list[int | None] = []
        for col, field in zip(columns, fields, strict=True):
            field = field.strip()
            if not field:
                row.append(None)
                continue
            try:
                row.append(int(field))
            except ValueError:
                raise MeteoFormatError(f"{field!r} is not an integer", file=name, line=no, column=col) from None
        rows.append(row)
        line_numbers.append(no)
    if not rows:
        raise MeteoFormatError("no data rows after the header line", file=name, line=header_no)

    raw = {col: [r[j] for r in rows] for j, col in enumerate(columns)}
    stations = _required_ints(raw, "STN", name, line_numbers)
    dates_raw = _required_ints(raw, "YYYYMMDD", name, line_numbers)
    keep = np.ones(len(rows), dtype=bool)
    unique_stations = sorted(set(stations.tolist()))
    if station is not None:
        keep = stations == station
        if not keep.any():
            raise MeteoFormatError(f"station {station} not in the file (stations: {unique_stations})", file=name)
    elif len(unique_stations) > 1:
        raise MeteoFormatError(f"the file holds several stations {unique_stations}; pass station=", file=name)
    idx = np.flatnonzero(keep)

    dates = _parse_dates(dates_raw[idx], [line_numbers[i] for i in idx], name)
    frame = pd.DataFrame(index=pd.DatetimeIndex(dates, name="date"))
    frame["STN"] = stations[idx]
    missing: dict[str, int] = {}
    trace: dict[str, list[str]] = {}
    units = {"STN": "-"}
    for col in columns:
        if col in ("STN", "YYYYMMDD"):
            continue
        values = [raw[col][i] for i in idx]
        is_missing = np.array([v is None for v in values])
        ints = np.array([0 if v is None else v for v in values], dtype=np.int64)
        if is_missing.any():
            missing[col] = int(is_missing.sum())
        if col in HOUR_COLUMNS:
            frame[col] = pd.array(np.where(is_missing, None, ints).tolist(), dtype="Int64")
            units[col] = UNITS[col]
            continue
        factor, unit = _SCALE.get(col, (1.0, "raw integer (unknown column)"))
        phys = ints.astype(float) * factor
        if col in TRACE_COLUMNS:
            is_trace = (ints == -1) & ~is_missing
            if is_trace.any():
                phys[is_trace] = trace_value
                trace[col] = [d.strftime("%Y-%m-%d") for d in frame.index[is_trace]]
        phys[is_missing] = np.nan
        frame[col] = phys
        units[col] = unit

    if missing:
        # reported, not alarming: most columns (wind, visibility, ...) are not used; the functions that use
        # a column (disaggregation of RH, EV24) refuse its missing days themselves
        logger.info("%s: missing values (NaN): %s", name, ", ".join(f"{c} {n}" for c, n in missing.items()))
    steps = np.diff(frame.index.to_numpy()).astype("timedelta64[D]").astype(int)
    if (steps > 1).any():
        logger.warning("%s: %d gap(s) in the dates (the longest %d days)", name, int((steps > 1).sum()),
                       int(steps.max()))
    frame.attrs.update(source=name, station=int(stations[idx[0]]), units=units, missing=missing,
                       trace=trace, trace_value=trace_value)
    return frame


def _find_header(lines: list[str], name: str) -> tuple[int, list[str]]:
    """Line number (1-based) and column names of the ``STN,YYYYMMDD,...`` header line."""
    for no, text in enumerate(lines, 1):
        stripped = text.strip().lstrip("#").strip()
        if stripped.replace(" ", "").upper().startswith("STN,YYYYMMDD"):
            columns = [c.strip().upper() for c in stripped.split(",")]
            if columns and not columns[-1]:
                columns = columns[:-1]
            if any(not c for c in columns):
                raise MeteoFormatError("empty column name in the header line", file=name, line=no)
            if len(set(columns)) != len(columns):
                raise MeteoFormatError(f"duplicate column names {columns}", file=name, line=no)
            return no, columns
    raise MeteoFormatError("no column-header line starting with 'STN,YYYYMMDD' (not a KNMI daily file?)",
                           file=name)


def _required_ints(raw: dict[str, list[int | None]], col: str, name: str, line_numbers: list[int]) -> np.ndarray:
    values = raw[col]
    for v, no in zip(values, line_numbers, strict=True):
        if v is None:
            raise MeteoFormatError("value is missing", file=name, line=no, column=col)
    return np.array(values, dtype=np.int64)


def _parse_dates(values: np.ndarray, line_numbers: list[int], name: str) -> pd.DatetimeIndex:
    parsed = pd.to_datetime(pd.Series(values.astype(str)), format="%Y%m%d", errors="coerce", utc=True)
    bad = np.flatnonzero(parsed.isna().to_numpy())
    if bad.size:
        i = int(bad[0])
        raise MeteoFormatError(f"{values[i]} is not a valid date YYYYMMDD", file=name, line=line_numbers[i],
                               column="YYYYMMDD")
    index = pd.DatetimeIndex(parsed)
    steps = np.diff(index.asi8)
    back = np.flatnonzero(steps <= 0)
    if back.size:
        i = int(back[0]) + 1
        raise MeteoFormatError(f"date {values[i]} repeats or runs backwards", file=name, line=line_numbers[i],
                               column="YYYYMMDD")
    return index
