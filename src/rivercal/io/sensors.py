"""Gauge series as gauges and databases deliver them, each described by a small sidecar TOML.

A sensor's export rarely looks like an observation CSV of rivercal: its times are local or carry another
offset, its values are depths above the sensor in cm, a quality flag sits beside each value, a database
writes a header block before the data. Rather than asking the user to rewrite the file, a *sidecar* says
how to read it::

    # gauges.toml — one [[series]] table per series
    [[series]]
    id = "vlissingen.h"                       # the model's series: <station>.<quantity>
    file = "waterlevel_vlissingen.txt"        # relative to this sidecar
    format = "noos"                           # a MATROOS / NOOS export with its # header block
    location = "vlissingen"                   # checked against the header's Location line

    [[series]]
    id = "P12.h"
    file = "logger_P12.csv"
    format = "csv"
    delimiter = ";"
    decimal = ","
    time_column = "Datum/tijd"
    time_format = "%d-%m-%Y %H:%M"
    time_zone = "Europe/Amsterdam"            # local clock time, summer time included
    column = "Waterdiepte [cm]"
    unit = "cm"
    measures = "depth"                        # a pressure sensor: level = depth + sensor zero
    datum_offset = 12.43                      # the sensor's zero, m above the datum of the model
    flag_column = "Kwaliteit"
    flags = { good = [0, 1], doubtful = [2], bad = [9] }

:func:`read_sidecar` reads every series of a sidecar into an :class:`~rivercal.observations.ObservationSet`
(levels in m above the model's datum, discharges in m³/s, UTC times, exactly as the gauge stamped them:
irregular and sub-hourly times are kept, never resampled). The fields are documented in
``docs/howto/your-gauges.md``; :data:`SIDECAR_SCHEMA` is their JSON Schema.

Formats
-------
``noos`` (also ``matroos``)
    The text export of Rijkswaterstaat's MATROOS series database in the NOOS exchange format: a block of
    ``# Key : value`` lines (``Location``, ``Position``, ``Source``, ``Unit``, ``Analyse time``, ``Timezone``)
    between ``#---`` rules, then one line per time, ``YYYYMMDDHHMM value`` (seconds may follow the minutes),
    separated by blanks; ``column`` picks another value column (1 is the first). The header's ``Unit`` line
    names the quantity (``waterlevel``, ``waterlevel_astro``: m) or a unit; a header without it is refused,
    because the values cannot be told apart then. The header's ``Timezone`` is the file's time zone (a
    sidecar's ``time_zone`` must agree with it).
``csv``
    Delimited text with a header row (``header_line``, 1 = the first line), optionally ``skip_lines`` lines
    (a units row) before the data; columns by their header: ``time_column`` (default the first),
    ``column`` (the values) and ``flag_column``. A long table of many gauges (one row per gauge and time, as
    databases export them) is read one gauge at a time: ``station_column`` names the column that says whose
    row it is, ``station`` the gauge. Times in ISO 8601 (a time with an offset keeps it) or by
    ``time_format`` (:meth:`datetime.strptime` codes).

Rules (each broken rule is a :class:`~rivercal.errors.CaseError` naming the file and its line)
---------------------------------------------------------------------------------------------------
- **Time zones.** ``UTC``/``GMT``; a fixed offset ``UTC+01:00``, ``+01:00``, ``GMT+1``; the abbreviations
  ``CET``/``MET`` (UTC+1), ``CEST``/``MEST`` (UTC+2), ``WET`` (UTC), ``WEST`` (UTC+1), ``EET`` (UTC+2),
  ``EEST`` (UTC+3) as the fixed offsets they name in a time stamp; or a region of the IANA time-zone
  database (``Europe/Amsterdam``) for clock time that changes to summer time. In a region, a time inside the
  hour skipped in spring does not exist, and a time inside the hour repeated in autumn is read as summer time
  until the times step back, then as winter time; a repeated-hour time with no step back around it is
  ambiguous. Each of these is an error naming the line. A file in local clock time declared with a fixed
  offset shows its autumn hour twice: a repeated or backward time, whose message says so.
- **Times** must increase; a repeated time is an error naming both lines, unless ``duplicates = "first"`` or
  ``"last"`` keeps one of them.
- **Values.** A number (``decimal = ","`` for a decimal comma), or empty / one of ``missing_values`` /
  ``nan`` for a missing value (dropped and counted, never zero). ``unit`` converts to m or m³/s (``m``,
  ``cm``, ``mm``, ``dm``, ``ft``; ``m3/s``, ``l/s``, ``m3/h``, ``m3/min``). ``datum_offset`` (m) is then added:
  the sensor's zero for ``measures = "depth"`` (required: a depth without it is not a level), or the offset of
  another datum for a level.
- **Flags.** With ``flag_column``, every flag must be listed in ``flags`` as ``good``, ``doubtful`` or ``bad``:
  bad values are dropped (counted as missing), doubtful ones kept (or dropped with ``drop_doubtful = true``);
  an unlisted flag is an error naming the line.
"""

from __future__ import annotations

import csv
import difflib
import logging
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from rivercal.errors import CaseError
from rivercal.io._clock import TimeZoneSpec, check_order, parse_time_zone, parse_times
from rivercal.observations import QUANTITIES, ObservationSeries, ObservationSet

__all__ = ["SIDECAR_SCHEMA", "FlagMeaning", "SensorSpec", "Sidecar", "TimeZoneSpec", "parse_time_zone",
           "read_sensor_series", "read_sidecar"]

log = logging.getLogger(__name__)

#: Conversion of a unit of the file to the unit of its quantity: (unit, factor to m or m³/s).
LEVEL_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "dm": 0.1, "ft": 0.3048}
DISCHARGE_UNITS = {"m3/s": 1.0, "l/s": 0.001, "m3/h": 1.0 / 3600.0, "m3/min": 1.0 / 60.0}
_UNIT_SPELLINGS = {"m³/s": "m3/s", "m^3/s": "m3/s", "m3 s-1": "m3/s", "m3.s-1": "m3/s", "cms": "m3/s",
                   "m³/h": "m3/h", "m³/min": "m3/min", "feet": "ft", "l/sec": "l/s", "meter": "m", "metre": "m"}
#: MATROOS quantity names that are water levels (values in m).
_NOOS_LEVELS = re.compile(r"^water_?level", re.IGNORECASE)
_NOOS_DISCHARGES = re.compile(r"^(discharge|flow|debiet)", re.IGNORECASE)


# -- the sidecar schema ------------------------------------------------------------------------------------


class FlagMeaning(BaseModel):
    """What the codes of a quality-flag column mean: each code listed once (as text or a whole number)."""

    model_config = ConfigDict(extra="forbid")

    good: list[str | int] = Field(default_factory=list, description="Codes of reliable values (kept).")
    doubtful: list[str | int] = Field(
        default_factory=list, description="Codes of doubtful values (kept, or dropped with drop_doubtful).")
    bad: list[str | int] = Field(default_factory=list, description="Codes of unreliable or missing values (dropped).")

    def codes(self) -> dict[str, str]:
        """Every code (as stripped text) with its meaning (``good``, ``doubtful`` or ``bad``)."""
        out: dict[str, str] = {}
        for meaning in ("good", "doubtful", "bad"):
            for code in getattr(self, meaning):
                text = str(code).strip()
                if text in out and out[text] != meaning:
                    raise ValueError(f"flag {text!r} is listed as both {out[text]} and {meaning}")
                out[text] = meaning
        return out


class SensorSpec(BaseModel):
    """How to read one series (a ``[[series]]`` table of a sidecar; module docstring).

    Units: ``datum_offset`` in m; ``sigma`` in m (levels) or m³/s (discharges).
    """

    model_config = ConfigDict(extra="forbid")

    id: str = Field(description="The model's series, '<station>.<quantity>' (h, h_up, h_down or Q).")
    file: str = Field(min_length=1, description="The data file, relative to the sidecar.")
    format: Literal["noos", "matroos", "csv"] = Field(description="'noos' (a MATROOS export; 'matroos' is the "
                                                                  "same) or 'csv'.")
    measures: Literal["level", "depth", "discharge"] | None = Field(
        default=None, description="What the values are: a level, a depth above the sensor (needs datum_offset) "
                                  "or a discharge; default from the quantity of id.")
    unit: str | None = Field(default=None, description="Unit of the values in the file: m, cm, mm, dm, ft; m3/s, "
                                                       "l/s, m3/h, m3/min. Default: a noos header's unit, else m "
                                                       "or m3/s.")
    datum_offset: float | None = Field(
        default=None, description="Added to every value after the unit conversion, m: the sensor's zero for a "
                                  "depth (required), the offset of another datum for a level.")
    time_zone: str | None = Field(
        default=None, description="Zone of the times without an offset: UTC, UTC+01:00, CET (fixed UTC+1), "
                                  "Europe/Amsterdam (clock time with summer time). Default: a noos header's.")
    location: str | None = Field(default=None, description="noos: the header's Location must be this.")
    column: str | int | None = Field(
        default=None, description="csv: the header of the value column (required); noos: the value column, "
                                  "1 = the first (default).")
    time_column: str | None = Field(default=None, description="csv: the header of the time column (default the "
                                                              "first column).")
    time_format: str | None = Field(default=None, description="strptime codes of the times, e.g. '%d-%m-%Y %H:%M' "
                                                              "(default: ISO 8601; noos: %Y%m%d%H%M).")
    delimiter: str = Field(default=",", description="csv: the separator: ',', ';', 'tab' or 'space' (blanks).")
    decimal: Literal[".", ","] = Field(default=".", description="The decimal separator of the values.")
    header_line: int = Field(default=1, ge=1, description="csv: the line that holds the column headers.")
    skip_lines: int = Field(default=0, ge=0, description="csv: lines between the header and the first data line.")
    flag_column: str | None = Field(default=None, description="csv: the header of a quality-flag column.")
    station_column: str | None = Field(
        default=None, description="csv: the header of a column naming the gauge of each row (a long table of many "
                                  "gauges); only the rows whose cell is station are read.")
    station: str | None = Field(default=None, description="csv: the gauge's name in station_column.")
    flags: FlagMeaning | None = Field(default=None, description="The meaning of every flag (with flag_column).")
    drop_doubtful: bool = Field(default=False, description="Drop doubtful values too.")
    missing_values: list[float | str] = Field(default_factory=list,
                                              description="Codes of a missing value, e.g. [-999, 'NA'].")
    duplicates: Literal["error", "first", "last"] = Field(
        default="error", description="A time that appears twice: an error (default), or keep the first or last.")
    sigma: float | None = Field(default=None, gt=0, description="Standard deviation of the values, m or m3/s "
                                                                "(default by quantity: 0.025 m, 0.1 m3/s).")

    @field_validator("id")
    @classmethod
    def _series_id(cls, value: str) -> str:
        station, _, quantity = value.rpartition(".")
        if not station or quantity not in QUANTITIES:
            raise ValueError(f"{value!r} must be '<station>.<quantity>' with quantity one of {', '.join(QUANTITIES)}")
        return value

    @field_validator("flags")
    @classmethod
    def _flag_codes(cls, value: FlagMeaning | None) -> FlagMeaning | None:
        if value is not None:
            value.codes()
        return value

    @property
    def quantity(self) -> str:
        """``h``, ``h_up``, ``h_down`` or ``Q``."""
        return self.id.rpartition(".")[2]


class Sidecar(BaseModel):
    """A sidecar file: one ``[[series]]`` table per series."""

    model_config = ConfigDict(extra="forbid")

    series: list[SensorSpec] = Field(min_length=1, description="The series, one table each.")


#: JSON Schema of a sidecar file.
SIDECAR_SCHEMA: dict[str, Any] = Sidecar.model_json_schema()


# -- reading ---------------------------------------------------------------------------------------------


@dataclass
class _Raw:
    """The rows of a data file: line numbers, time text, value text, flag text (or None)."""

    lines: list[int]
    times: list[str]
    values: list[str]
    flags: list[str] | None
    header_zone: tuple[str, int] | None = None  # (text, line) of a noos Timezone line
    header_unit: tuple[str, int] | None = None


def read_sidecar(path: str | Path) -> ObservationSet:
    r"""Read every series a sidecar describes (module docstring).

    Parameters
    ----------
    path
        The sidecar TOML file; the data files are found relative to its folder.

    Returns
    -------
    ObservationSet
        One series per ``[[series]]`` table, in their order (levels in m, discharges in m³/s, UTC times).

    Raises
    ------
    CaseError
        Naming the sidecar and its field and line, or the data file and its line, and what is wrong.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / "p1.csv").write_text("time;depth_cm\n2021-03-28 01:50;41,0\n2021-03-28 03:10;42,5\n")
    >>> _ = (folder / "p1.toml").write_text('''
    ... [[series]]
    ... id = "P1.h"
    ... file = "p1.csv"
    ... format = "csv"
    ... delimiter = ";"
    ... decimal = ","
    ... column = "depth_cm"
    ... unit = "cm"
    ... measures = "depth"
    ... datum_offset = 10.0
    ... time_zone = "Europe/Amsterdam"
    ... ''')
    >>> obs = read_sidecar(folder / "p1.toml")
    >>> s = obs["P1.h"]
    >>> [f"{t:%H:%M}Z" for t in s.times], s.values.round(3).tolist()
    (['00:50Z', '01:10Z'], [10.41, 10.425])
    """
    path = Path(path)
    label = str(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise CaseError("file not found", file=label) from None
    except UnicodeDecodeError as exc:
        raise CaseError(f"not UTF-8 text: {_one_line(exc)}", file=label) from None
    except OSError as exc:
        raise CaseError(f"cannot be read: {exc.strerror or exc}", file=label) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(f"not valid TOML: {_one_line(exc)}", file=label) from None
    try:
        sidecar = Sidecar.model_validate(data)
    except ValidationError as exc:
        raise _schema_error(exc, text, label) from None
    specs = sidecar.series
    ids = [s.id for s in specs]
    for k, sid in enumerate(ids):
        if sid in ids[:k]:
            raise CaseError(f"{_key_line(text, k, 'id')}series {sid!r} is described twice (also "
                            f"series[{ids.index(sid)}])", file=label, field=f"series[{k}].id")
    out = [read_sensor_series(spec, path.parent, sidecar=(label, text, k)) for k, spec in enumerate(specs)]
    return ObservationSet(tuple(out))


def read_sensor_series(spec: SensorSpec, root: str | Path, *,
                       sidecar: tuple[str, str, int] | None = None) -> ObservationSeries:
    """Read one series as ``spec`` describes it (module docstring).

    Parameters
    ----------
    spec
        The description.
    root
        The folder ``spec.file`` is relative to.
    sidecar
        (file name, text, index of the series) of the sidecar, for messages about its fields.

    Raises
    ------
    CaseError
        Naming the file and line (the data file's, or the sidecar's field) and what is wrong.
    """
    side_label, side_text, k = sidecar if sidecar is not None else ("sidecar", "", 0)

    def side_error(key: str, reason: str) -> CaseError:
        return CaseError(f"{_key_line(side_text, k, key)}{reason}", file=side_label, field=f"series[{k}].{key}")

    measures = spec.measures or ("discharge" if spec.quantity == "Q" else "level")
    if (measures == "discharge") != (spec.quantity == "Q"):
        raise side_error("measures", f"series {spec.id!r} is a {'discharge' if spec.quantity == 'Q' else 'level'}; "
                                     f"it cannot measure '{measures}'")
    if measures == "depth" and spec.datum_offset is None:
        raise side_error("measures", f"series {spec.id!r} measures a depth above the sensor, which is not a level "
                                     "until the sensor's zero is known: give datum_offset = the level of the "
                                     "sensor's zero (m above the model's datum)")
    if measures == "discharge" and spec.datum_offset is not None:
        raise side_error("datum_offset", "a discharge has no datum; remove datum_offset")
    if spec.format == "csv" and spec.column is None:
        raise side_error("column", "a csv series needs column = the header of its value column")
    if spec.flag_column is not None and spec.flags is None:
        raise side_error("flags", f"flag_column {spec.flag_column!r} needs flags = {{ good = [...], doubtful = "
                                  "[...], bad = [...] }}: what each code means")
    if (spec.station_column is None) != (spec.station is None):
        key = "station" if spec.station is None else "station_column"
        raise side_error(key, "station_column and station go together: the column that names the gauge of each row, "
                              "and this gauge's name in it")
    if spec.flags is not None and spec.flag_column is None:
        raise side_error("flag_column", "flags are given but no flag_column names where they are")
    zone = None
    if spec.time_zone is not None:
        try:
            zone = parse_time_zone(spec.time_zone)
        except ValueError as exc:
            raise side_error("time_zone", str(exc)) from None
    factor = None
    if spec.unit is not None:
        factor = _unit_factor(spec.unit, measures)
        if factor is None:
            raise side_error("unit", _unit_problem(spec.unit, measures))
    file = Path(root) / spec.file
    label = str(file)
    if not file.is_file():
        raise side_error("file", f"{spec.file!r} not found in {Path(root)}" if not file.is_dir()
                         else f"{spec.file!r} is a folder, not a file")
    lines = _read_lines(file)
    if spec.format == "csv":
        raw = _read_csv(lines, spec, label)
    else:
        raw = _read_noos(lines, spec, label, side_error)
    # the time zone: the sidecar's, else the header's; both must agree
    if raw.header_zone is not None:
        header_text, header_line = raw.header_zone
        try:
            header = parse_time_zone(header_text)
        except ValueError as exc:
            raise CaseError(f"line {header_line}: {exc}", file=label) from None
        if zone is None:
            zone = header
        elif (zone.offset_h, zone.region) != (header.offset_h, header.region):
            raise side_error("time_zone", f"time_zone {spec.time_zone!r} contradicts line {header_line} of {label} "
                                          f"(Timezone : {header_text})")
    if factor is None:
        factor = 1.0
        if raw.header_unit is not None:
            header_text, header_line = raw.header_unit
            factor = _header_unit_factor(header_text, header_line, measures, spec, label)
    elif raw.header_unit is not None:
        header_text, header_line = raw.header_unit
        unit = _norm_unit(header_text)
        known = _unit_factor(unit, measures)
        if known is not None and not math.isclose(known, factor):
            raise side_error("unit", f"unit {spec.unit!r} contradicts line {header_line} of {label} (Unit : "
                                     f"{header_text})")
        _header_unit_factor(header_text, header_line, measures, spec, label)  # the quantity must fit
    times = parse_times(raw, spec, zone, label, side_error)
    values, missing = _parse_values(raw, spec, label)
    keep = np.ones(len(values), dtype=bool)
    n_flagged = 0
    if raw.flags is not None and spec.flags is not None:
        meaning = spec.flags.codes()
        listed = ", ".join(f"{m}: {', '.join(repr(c) for c, v in meaning.items() if v == m) or '-'}"
                           for m in ("good", "doubtful", "bad"))
        for i, flag in enumerate(raw.flags):
            what = meaning.get(flag.strip())
            if what is None:
                shown = "an empty flag" if not flag.strip() else f"flag {flag.strip()!r}"
                raise CaseError(f"line {raw.lines[i]}: {shown} in column {spec.flag_column!r} is not listed in "
                                f"the sidecar's flags ({listed})", file=label)
            if what == "bad" or (what == "doubtful" and spec.drop_doubtful):
                if keep[i] and not missing[i]:
                    n_flagged += 1
                keep[i] = False
    values = values * factor + (spec.datum_offset or 0.0)
    index, order = check_order(times, raw.lines, spec, label, zone)
    values, missing, keep = values[order], missing[order], keep[order]
    values = np.where(keep & ~missing, values, np.nan)
    if n_flagged:
        log.info("%s: %d value(s) flagged unreliable were dropped", label, n_flagged)
    series = pd.Series(values, index=index, name=spec.id)
    try:
        return ObservationSeries.from_series(series, id=spec.id, sigma=spec.sigma, source=Path(spec.file).name)
    except ValueError as exc:  # the checks above leave nothing for it: a message rather than a trace
        raise CaseError(str(exc), file=label) from None


# -- files ----------------------------------------------------------------------------------------------


def _read_lines(file: Path) -> list[str]:
    label = str(file)
    try:
        data = file.read_bytes()
    except OSError as exc:
        raise CaseError(f"cannot be read: {exc.strerror or exc}", file=label) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = data.decode("latin-1")  # old loggers write Windows-1252 / ISO 8859-1 headers (° and µ)
    if "\x00" in text:
        raise CaseError("is a binary file, not text (an Excel workbook? export it as CSV)", file=label)
    lines = text.splitlines()
    if not any(line.strip() for line in lines):
        raise CaseError("the file is empty", file=label)
    return lines


def _read_noos(lines: list[str], spec: SensorSpec, label: str, side_error) -> _Raw:
    header: dict[str, tuple[str, int]] = {}
    first_data = None
    for n, line in enumerate(lines, start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            if first_data is None:
                body = stripped.lstrip("#").strip()
                if ":" in body and not set(body) <= {"-", "="}:
                    key, _, value = body.partition(":")
                    header.setdefault(key.strip().lower(), (value.strip(), n))
            continue
        first_data = first_data or n
    if first_data is None:
        raise CaseError("has a header but no data lines", file=label)
    header_end = first_data - 1
    if "unit" not in header:
        raise CaseError(f"line {header_end}: the header block (lines 1-{header_end}) has no 'Unit' line; a MATROOS "
                        "export names the quantity of its values there (e.g. '# Unit        : waterlevel'), without "
                        "it the values cannot be told apart (a level, a predicted tide, a wave height)", file=label)
    if spec.location is not None:
        if "location" not in header:
            raise CaseError(f"line {header_end}: the header has no 'Location' line, and the sidecar expects location "
                            f"{spec.location!r}", file=label)
        found, n = header["location"]
        if found.lower() != spec.location.lower():
            raise CaseError(f"line {n}: the file is of location {found!r}, the sidecar expects {spec.location!r} "
                            f"(series {spec.id!r}); the wrong file?", file=label)
    column = spec.column if spec.column is not None else 1
    if isinstance(column, str):
        if not column.isdigit():
            raise side_error("column", "in a noos file the value columns have no names: give their number, 1 = the "
                                       "first after the time")
        column = int(column)
    if column < 1:
        raise side_error("column", "columns count from 1 (the first after the time)")
    rows: tuple[list[int], list[str], list[str]] = ([], [], [])
    for n, line in enumerate(lines[first_data - 1:], start=first_data):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        parts = stripped.split()
        if len(parts) == column:  # the time alone (or too few values): the last value column is empty
            parts.append("")
        if len(parts) < 1 + column:
            raise CaseError(f"line {n}: {stripped!r} has no value column {column} (expected 'YYYYMMDDHHMM value')",
                            file=label)
        rows[0].append(n)
        rows[1].append(parts[0])
        rows[2].append(parts[column])
    return _Raw(list(rows[0]), list(rows[1]), list(rows[2]), None, header_zone=header.get("timezone"),
                header_unit=header.get("unit"))


def _read_csv(lines: list[str], spec: SensorSpec, label: str) -> _Raw:
    delimiter = {"tab": "\t", "\\t": "\t", "space": " ", "blank": " "}.get(spec.delimiter, spec.delimiter)
    if len(delimiter) != 1:
        raise CaseError(f"delimiter {spec.delimiter!r} must be one character, 'tab' or 'space'", file=label)
    if spec.header_line > len(lines):
        raise CaseError(f"has {len(lines)} lines; header_line = {spec.header_line} lies beyond them", file=label)

    def split(line: str) -> list[str]:
        if delimiter == " ":
            return line.split()
        return [c.strip() for c in next(csv.reader([line], delimiter=delimiter))] if line.strip() else []

    header = split(lines[spec.header_line - 1])
    hl = spec.header_line
    if len(header) < 2:
        raise CaseError(f"line {hl}: the header {lines[hl - 1].strip()!r} has fewer than two columns with "
                        f"delimiter {spec.delimiter!r}; is the delimiter right?", file=label)

    def index_of(name: str | int, what: str) -> int:
        if isinstance(name, int):
            if not 1 <= name <= len(header):
                raise CaseError(f"line {hl}: there is no column {name} ({len(header)} columns)", file=label)
            return name - 1
        if name in header:
            return header.index(name)
        guess = difflib.get_close_matches(name, header, n=1, cutoff=0.6)
        hint = f"; did you mean {guess[0]!r}?" if guess else f" (columns: {', '.join(map(repr, header))})"
        raise CaseError(f"line {hl}: the header has no {what} column {name!r}{hint}", file=label)

    t_col = index_of(spec.time_column, "time") if spec.time_column is not None else 0
    v_col = index_of(spec.column, "value")  # type: ignore[arg-type]
    f_col = index_of(spec.flag_column, "flag") if spec.flag_column is not None else None
    s_col = index_of(spec.station_column, "station") if spec.station_column is not None else None
    need = max(c for c in (t_col, v_col, f_col, s_col) if c is not None) + 1
    out_lines, times, values, flags = [], [], [], []
    seen: dict[str, None] = {}
    for n in range(hl + spec.skip_lines + 1, len(lines) + 1):
        line = lines[n - 1]
        if not line.strip():
            continue
        cells = split(line)
        if len(cells) < need:
            raise CaseError(f"line {n}: {len(cells)} column(s), the header has {len(header)} ({line.strip()[:80]!r})",
                            file=label)
        if s_col is not None:
            seen.setdefault(cells[s_col], None)
            if cells[s_col] != spec.station:
                continue
        out_lines.append(n)
        times.append(cells[t_col])
        values.append(cells[v_col])
        if f_col is not None:
            flags.append(cells[f_col])
    if not out_lines and s_col is not None and seen:
        shown = ", ".join(repr(v) for v in list(seen)[:10]) + (" …" if len(seen) > 10 else "")
        raise CaseError(f"no row has {spec.station!r} in column {spec.station_column!r} (it holds {shown})",
                        file=label)
    if not out_lines:
        raise CaseError(f"has a header (line {hl}) but no data lines", file=label)
    return _Raw(out_lines, times, values, flags if f_col is not None else None)


# -- values and units -------------------------------------------------------------------------------------


def _parse_values(raw: _Raw, spec: SensorSpec, label: str) -> tuple[np.ndarray, np.ndarray]:
    """Values (file unit) and a mask of missing ones."""
    codes = {str(c).strip() for c in spec.missing_values}
    numbers = {float(c) for c in spec.missing_values if isinstance(c, int | float)}
    values = np.full(len(raw.values), np.nan)
    missing = np.zeros(len(raw.values), dtype=bool)
    for i, text in enumerate(raw.values):
        cell = text.strip()
        if cell == "" or cell in codes or cell.lower() in ("nan", "-nan", "na", "n/a"):
            missing[i] = True
            continue
        shown = cell.replace(",", ".") if spec.decimal == "," else cell
        try:
            v = float(shown)
        except ValueError:
            hint = ""
            if spec.decimal == "." and re.fullmatch(r"[-+]?\d+,\d+", cell):
                hint = " (a decimal comma? say decimal = ',')"
            raise CaseError(f"line {raw.lines[i]}: {cell!r} is not a number{hint}", file=label) from None
        if v in numbers:
            missing[i] = True
            continue
        if not math.isfinite(v):
            raise CaseError(f"line {raw.lines[i]}: {cell!r} is not a finite number", file=label)
        values[i] = v
    return values, missing


def _norm_unit(unit: str) -> str:
    u = " ".join(unit.strip().split()).replace("³", "3")
    low = u.lower()
    low = _UNIT_SPELLINGS.get(low, low)
    # a datum after a length unit ("m NAP", "cm TAW") names the datum, not another unit
    m = re.fullmatch(r"(m|cm|mm|dm)\s*(\+|above)?\s*[a-z]{2,6}", low)
    if m and low not in DISCHARGE_UNITS:
        return m.group(1)
    return low


def _unit_factor(unit: str, measures: str) -> float | None:
    table = DISCHARGE_UNITS if measures == "discharge" else LEVEL_UNITS
    return table.get(_norm_unit(unit))


def _unit_problem(unit: str, measures: str) -> str:
    table = DISCHARGE_UNITS if measures == "discharge" else LEVEL_UNITS
    other = LEVEL_UNITS if measures == "discharge" else DISCHARGE_UNITS
    if _norm_unit(unit) in other:
        return f"{unit!r} is a unit of {'levels' if measures == 'discharge' else 'discharges'}, and this series " \
               f"measures a {measures}"
    return f"unit {unit!r} is not known for a {measures}; use one of {', '.join(table)}"


def _header_unit_factor(text: str, line: int, measures: str, spec: SensorSpec, label: str) -> float:
    """The factor of a noos header's Unit line: a quantity name (m for levels) or a unit."""
    if measures != "discharge" and _NOOS_LEVELS.match(text.strip()):
        if "astro" in text.lower():
            log.info("%s: the values are a predicted (astronomical) tide, read as observations of %s", label, spec.id)
        return 1.0
    if measures == "discharge" and _NOOS_DISCHARGES.match(text.strip()):
        return 1.0
    factor = _unit_factor(text, measures)
    if factor is not None:
        return factor
    raise CaseError(f"line {line}: Unit '{text}' is not a {'discharge' if measures == 'discharge' else 'water level'} "
                    f"(series {spec.id!r} is one); the wrong file, or give the sidecar's unit if it is a unit",
                    file=label)


# -- messages ----------------------------------------------------------------------------------------------


def _key_line(text: str, k: int, key: str | None = None) -> str:
    """``"line N: "`` of the k-th ``[[series]]`` table (of its ``key`` when written there), or nothing."""
    if not text:
        return ""
    lines = text.splitlines()
    starts = [n for n, line in enumerate(lines, start=1) if re.match(r"^\s*\[\[\s*series\s*\]\]", line)]
    if k >= len(starts):
        return ""
    start = starts[k]
    if key:
        pattern = re.compile(rf"^\s*{re.escape(key)}\s*=")
        for n in range(start + 1, len(lines) + 1):
            line = lines[n - 1]
            if re.match(r"^\s*\[", line):
                break
            if pattern.match(line):
                return f"line {n}: "
    return f"line {start}: "


def _schema_error(exc: ValidationError, text: str, label: str) -> CaseError:
    errors = exc.errors(include_url=False)
    err = next((e for e in errors if e.get("type") == "extra_forbidden"), errors[0])
    loc = tuple(err.get("loc", ()))
    kind = err.get("type", "")
    ctx = err.get("ctx") or {}
    k = loc[1] if len(loc) > 1 and loc[0] == "series" and isinstance(loc[1], int) else None
    key = str(loc[2]) if k is not None and len(loc) > 2 and isinstance(loc[2], str) else None
    field = ".".join(f"[{p}]" if isinstance(p, int) else str(p) for p in loc).replace(".[", "[")
    where = _key_line(text, k, key) if k is not None else ""
    if kind == "missing":
        if loc == ("series",):
            msg = "no [[series]] table: describe each series in one (id, file, format, ...)"
        else:
            msg = "required field is missing"
    elif kind == "extra_forbidden":
        name = str(loc[-1])
        fields = list(SensorSpec.model_fields) if k is not None and len(loc) == 3 else (
            list(FlagMeaning.model_fields) if "flags" in loc else list(Sidecar.model_fields))
        guess = difflib.get_close_matches(name, fields, n=1, cutoff=0.6)
        msg = f"unknown field {name!r}" + (f"; did you mean {guess[0]!r}?" if guess else
                                           f"; the fields here are {', '.join(fields)}")
    elif kind == "literal_error":
        msg = f"{err.get('input')!r} is not allowed; expected {ctx.get('expected', '?')}"
    else:
        msg = " ".join(str(err.get("msg", "invalid value")).removeprefix("Value error, ").split())
        if "input" in err and kind.endswith("_type"):
            msg += f", got {err['input']!r}"
    more = len(errors) - 1
    if more:
        msg += f" (and {more} more problem{'s' if more > 1 else ''})"
    return CaseError(f"{where}{msg}", file=label, field=field or None)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())

