"""Delft-FEWS PI-XML time series: read observations, write forecasts.

A PI-XML time-series file (namespace ``http://www.wldelft.nl/fews/PI``) looks like::

    <TimeSeries xmlns="http://www.wldelft.nl/fews/PI" version="1.2">
      <timeZone>1.0</timeZone>
      <series>
        <header>
          <type>instantaneous</type>
          <locationId>0028</locationId>
          <parameterId>H.up</parameterId>
          <timeStep unit="second" multiplier="3600"/>
          <startDate date="2010-11-01" time="00:00:00"/>
          <endDate date="2010-11-02" time="00:00:00"/>
          <missVal>-999.0</missVal>
          <units>m</units>
        </header>
        <event date="2010-11-01" time="00:00:00" value="7.31" flag="0"/>
        ...

:func:`read_pixml` turns it into a :class:`~rivercal.observations.ObservationSet`:

- **Names.** Each (locationId, parameterId) is mapped to a series id ``"<station>.<quantity>"`` by the
  caller's mapping, e.g. ``{("0028", "H.up"): "0028.h_up"}``. Series the mapping does not name are skipped
  (logged) or, with ``unmapped="error"``, refused.
- **Times.** Event dates and times are local to the file's ``<timeZone>`` (hours ahead of UTC; 0 when
  absent, the PI default) and are converted to UTC.
- **Missing values** (the header's ``missVal``, ``NaN``, or no ``value``) and values flagged unreliable or
  missing (FEWS flags 6 and above) are dropped and counted (``n_missing`` of the series, and the log), never
  guessed. Doubtful values (flags 3–5) are kept and counted, or dropped with ``drop_doubtful=True``.
- **Units** must be those of the quantity: m for levels (``h``, ``h_up``, ``h_down``; a datum suffix such
  as ``m NAP`` is accepted), m³/s for discharges (``Q``; also written ``m3/s``, ``m3 s-1``, ``m^3/s``). A
  different unit (cm, l/s, ...) is an error naming the file, the series and the unit, unless the caller
  passes a conversion table (``conversions=STANDARD_CONVERSIONS`` or its own).
- **Safety.** The file is parsed with :mod:`defusedxml` and any DTD is refused, so entity-expansion
  ("billion laughs") and external-entity files fail with a clear :class:`PiXmlError` instead of exhausting
  memory or reading other files.

:func:`write_pixml` writes series (forecasts) in the same format, for FEWS to import, and
:func:`write_pixml_series` writes :class:`PiSeries` (with qualifiers, flags and comments); both validate against
the PI schema ``pi_timeseries.xsd``.
"""

from __future__ import annotations

import logging
import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import defusedxml
import defusedxml.ElementTree as SafeET
import numpy as np
import pandas as pd

from rivercal._time import utc_index
from rivercal.errors import CaseError
from rivercal.observations import DEFAULT_SIGMA, ObservationSeries, ObservationSet

__all__ = [
    "EXPECTED_UNITS",
    "PI_NAMESPACE",
    "STANDARD_CONVERSIONS",
    "PiSeries",
    "PiXmlError",
    "read_pixml",
    "read_pixml_series",
    "unit_factor",
    "write_pixml",
    "write_pixml_series",
]

log = logging.getLogger(__name__)

PI_NAMESPACE = "http://www.wldelft.nl/fews/PI"
_PI_SCHEMA = "http://fews.wldelft.nl/schemas/version1.0/pi-schemas/pi_timeseries.xsd"
_XSI = "http://www.w3.org/2001/XMLSchema-instance"

#: The unit every quantity is expected in (normalised spelling).
EXPECTED_UNITS = {"h": "m", "h_up": "m", "h_down": "m", "Q": "m3/s"}
#: Conversion factors (file unit, expected unit) -> factor, for callers who want them: value × factor.
STANDARD_CONVERSIONS = {("cm", "m"): 0.01, ("mm", "m"): 0.001, ("l/s", "m3/s"): 0.001,
                        ("m3/h", "m3/s"): 1.0 / 3600.0, ("m3/min", "m3/s"): 1.0 / 60.0}
#: FEWS flags: 0–2 reliable (original, corrected, completed), 3–5 doubtful, 6 and above unreliable or missing.
DOUBTFUL_FLAGS = range(3, 6)
UNRELIABLE_FROM = 6
#: The largest flag a PI file can hold (the schema's ``xs:int``).
_MAX_FLAG = 2**31 - 1


class PiXmlError(CaseError):
    """A PI-XML file cannot be used; the message names the file and, where it applies, the series."""

    def __reduce__(self):  # keep the class when the error crosses a process boundary
        return (_rebuild, (self.reason, self.file, self.field))


def _rebuild(reason: str, file: str | None, field: str | None) -> PiXmlError:
    return PiXmlError(reason, file=file, field=field)


@dataclass(frozen=True)
class PiSeries:
    """One ``<series>`` of a PI-XML file as read (before mapping, unit checks and dropping).

    Attributes
    ----------
    location_id, parameter_id
        Header ``locationId`` and ``parameterId``.
    qualifier_ids
        Header ``qualifierId`` elements.
    series_type
        Header ``type`` (``instantaneous``, ``mean``, ``accumulative``, ...).
    units
        Header ``units`` as written, or None.
    miss_val
        Header ``missVal`` (NaN when absent, the PI default).
    times
        Event times converted to UTC.
    values
        Event values as written (NaN where there was no value or ``NaN``).
    flags
        Event flags (-1 where the event had none).
    comments
        Event ``comment`` attributes ("" where an event had none), or None when not read or written.
    """

    location_id: str
    parameter_id: str
    qualifier_ids: tuple[str, ...]
    series_type: str
    units: str | None
    miss_val: float
    times: pd.DatetimeIndex
    values: np.ndarray
    flags: np.ndarray
    comments: tuple[str, ...] | None = None

    @property
    def label(self) -> str:
        """How messages name the series."""
        q = f" qualifierId={','.join(self.qualifier_ids)}" if self.qualifier_ids else ""
        return f"series locationId={self.location_id} parameterId={self.parameter_id}{q}"


def _q(tag: str, ns: str) -> str:
    return f"{{{ns}}}{tag}" if ns else tag


def _parse(path: Path) -> ET.Element:
    try:
        return SafeET.parse(str(path), forbid_dtd=True, forbid_entities=True, forbid_external=True).getroot()
    except defusedxml.DefusedXmlException as exc:
        raise PiXmlError(f"refused to parse: the file declares a DTD or XML entities ({type(exc).__name__}: {exc}); "
                         "PI-XML never needs them, and they are how entity-expansion ('billion laughs') and "
                         "external-entity attacks work", file=str(path)) from None
    except SafeET.ParseError as exc:
        raise PiXmlError(f"not well-formed XML ({exc})", file=str(path)) from None
    except OSError as exc:
        raise PiXmlError(f"cannot read the file ({exc.strerror or exc})", file=str(path)) from None


def _time_zone(root: ET.Element, ns: str, path: Path) -> float:
    node = root.find(_q("timeZone", ns))
    if node is None or not (node.text or "").strip():
        log.debug("%s: no <timeZone>; times are taken as UTC (the PI default)", path)
        return 0.0
    try:
        hours = float(node.text)
    except ValueError:
        raise PiXmlError(f"<timeZone> {node.text.strip()!r} is not a number of hours", file=str(path)) from None
    if not (math.isfinite(hours) and -12.0 <= hours <= 14.0):
        raise PiXmlError(f"<timeZone> {hours} h is not a time-zone offset (-12 to 14 h)", file=str(path))
    return hours


def _events(series: ET.Element, ns: str, label: str, zone_h: float,
            path: Path) -> tuple[pd.DatetimeIndex, np.ndarray, np.ndarray, tuple[str, ...]]:
    events = series.findall(_q("event", ns))
    stamps, texts, flags, comments = [], [], [], []
    for i, ev in enumerate(events, 1):
        date, time = ev.get("date"), ev.get("time")
        if not date or not time:
            raise PiXmlError(f"event {i} has no date or time attribute", file=str(path), field=label)
        stamps.append(f"{date.strip()}T{time.strip()}")
        texts.append((ev.get("value") or "").strip())
        comments.append(ev.get("comment") or "")
        flag = (ev.get("flag") or "").strip()
        if flag and not (flag.isascii() and flag.isdigit() and int(flag) <= _MAX_FLAG):
            raise PiXmlError(f"event {i} ({date} {time}): flag {flag[:40]!r} is not a FEWS flag (a whole number 0, 1, "
                             "2, ...)", file=str(path), field=label)
        flags.append(int(flag) if flag else -1)
    local = pd.to_datetime(pd.Series(stamps, dtype=object), format="ISO8601", errors="coerce")
    bad = np.flatnonzero(local.isna().to_numpy())
    if bad.size:
        i = int(bad[0])
        raise PiXmlError(f"event {i + 1}: {stamps[i].replace('T', ' ')!r} is not a date and time "
                         "(YYYY-MM-DD HH:MM:SS)", file=str(path), field=label)
    times = pd.DatetimeIndex(local - pd.Timedelta(hours=zone_h)).tz_localize("UTC")
    text = pd.Series(texts, dtype=object)
    values = pd.to_numeric(text.replace("", np.nan), errors="coerce").to_numpy(dtype=float)
    wrong = np.flatnonzero(np.isnan(values) & (text != "").to_numpy() & (text.str.lower() != "nan").to_numpy())
    if wrong.size:
        i = int(wrong[0])
        raise PiXmlError(f"event {i + 1} ({stamps[i].replace('T', ' ')}): value {texts[i]!r} is not a number",
                         file=str(path), field=label)
    return times, values, np.asarray(flags, dtype=int), tuple(comments)


def read_pixml_series(path: str | Path) -> tuple[PiSeries, ...]:
    """Every ``<series>`` of a PI-XML time-series file, times converted to UTC, nothing dropped yet.

    Raises
    ------
    PiXmlError
        For a file that cannot be read, is not well-formed, declares a DTD or entities, is not a PI
        time-series file, or has an event without a valid time or value.
    """
    path = Path(path)
    root = _parse(path)
    ns, _, local = root.tag[1:].partition("}") if root.tag.startswith("{") else ("", "", root.tag)
    if local != "TimeSeries":
        raise PiXmlError(f"not a PI-XML time-series file: the root element is <{local}>, not <TimeSeries>",
                         file=str(path))
    if ns != PI_NAMESPACE:
        log.warning("%s: namespace %r is not the PI namespace %r; reading it anyway", path, ns, PI_NAMESPACE)
    zone_h = _time_zone(root, ns, path)
    out = []
    for k, series in enumerate(root.findall(_q("series", ns)), 1):
        header = series.find(_q("header", ns))
        if header is None:
            raise PiXmlError(f"<series> number {k} has no <header>", file=str(path))

        def text(tag: str, header: ET.Element = header) -> str | None:
            node = header.find(_q(tag, ns))
            return node.text.strip() if node is not None and node.text and node.text.strip() else None

        location, parameter = text("locationId"), text("parameterId")
        if not location or not parameter:
            raise PiXmlError(f"<series> number {k} has no locationId or parameterId in its header", file=str(path))
        qualifiers = tuple((q.text or "").strip() for q in header.findall(_q("qualifierId", ns)))
        label = f"series locationId={location} parameterId={parameter}"
        miss_text = text("missVal")
        try:
            miss_val = float(miss_text) if miss_text else math.nan
        except ValueError:
            raise PiXmlError(f"missVal {miss_text!r} is not a number", file=str(path), field=label) from None
        times, values, flags, comments = _events(series, ns, label, zone_h, path)
        out.append(PiSeries(location, parameter, qualifiers, text("type") or "instantaneous", text("units"),
                            miss_val, times, values, flags, comments))
    log.debug("%s: %d series, time zone %+g h", path, len(out), zone_h)
    return tuple(out)


def _norm_unit(unit: str) -> str:
    """One spelling per unit: ``m³/s``, ``m3 s-1``, ``m^3/s`` -> ``m3/s``; ``m NAP``, ``metre`` -> ``m``."""
    u = unit.strip().lower().replace("³", "3").replace("^", "").replace("**", "").replace(" ", "")
    u = re.sub(r"[.·*]?s-1$", "/s", u).replace("/sec", "/s")
    if u in ("meter", "metre", "meters", "metres") or re.fullmatch(r"m\+?(nap|ad|msl|taw|odn|ngf)", u):
        return "m"
    return u


def unit_factor(units: str, quantity: str, conversions: Mapping[tuple[str, str], float] | None = None) -> float | None:
    """The factor from a file's unit to the unit of ``quantity`` (1 when they are the same), or None.

    Parameters
    ----------
    units
        The unit as a file writes it (``m``, ``m NAP``, ``cm``, ``m3 s-1``, ...).
    quantity
        ``h``, ``h_up``, ``h_down`` or ``Q`` (see :data:`EXPECTED_UNITS`).
    conversions
        (file unit, expected unit) -> factor, e.g. :data:`STANDARD_CONVERSIONS`; without it only the
        quantity's own unit (in any of its spellings) has a factor.
    """
    expected = EXPECTED_UNITS.get(quantity)
    if expected is None:
        return None
    unit = _norm_unit(units)
    if unit == expected:
        return 1.0
    table = {(_norm_unit(a), _norm_unit(b)): float(f) for (a, b), f in (conversions or {}).items()}
    return table.get((unit, expected))


def _factor(pi: PiSeries, series_id: str, conversions: Mapping[tuple[str, str], float] | None,
            path: Path) -> tuple[float, str | None]:
    """(factor, problem): the factor to the expected unit, or a problem message."""
    quantity = series_id.rpartition(".")[2]
    expected = EXPECTED_UNITS.get(quantity)
    if expected is None:
        return 1.0, f"{pi.label} (-> {series_id}): quantity {quantity!r} is not one of {', '.join(EXPECTED_UNITS)}"
    if pi.units is None:
        log.warning("%s: %s has no <units>; taken to be %s as %s expects", path, pi.label, expected, series_id)
        return 1.0, None
    factor = unit_factor(pi.units, quantity, conversions)
    if factor == 1.0:
        return 1.0, None
    if factor is not None:
        log.info("%s: %s: converted from %s to %s (x %g)", path, pi.label, pi.units, expected, factor)
        return factor, None
    unit = _norm_unit(pi.units)
    hint = STANDARD_CONVERSIONS.get((unit, expected))
    advice = (f"; pass conversions={{({unit!r}, {expected!r}): {hint:g}}} (or STANDARD_CONVERSIONS) to convert"
              if hint is not None else "; convert the file or pass a conversions table")
    return 1.0, (f"{pi.label} (-> {series_id}): unit {pi.units!r} where {expected!r} is expected for quantity "
                 f"{quantity}{advice}")


def _clean(pi: PiSeries, drop_doubtful: bool) -> tuple[np.ndarray, dict[str, int]]:
    """Values with missing and unreliable ones set to NaN, and what was dropped or kept doubtful."""
    values = pi.values.copy()
    missing = np.isnan(values)
    if not math.isnan(pi.miss_val):
        missing |= values == pi.miss_val
    unreliable = ~missing & (pi.flags >= UNRELIABLE_FROM)
    doubtful = ~missing & np.isin(pi.flags, list(DOUBTFUL_FLAGS))
    values[missing | unreliable] = np.nan
    if drop_doubtful:
        values[doubtful] = np.nan
    return values, {"missing": int(missing.sum()), "unreliable": int(unreliable.sum()),
                    "doubtful": int(doubtful.sum())}


def read_pixml(path: str | Path, mapping: Mapping[tuple[str, str], str] | None = None, *,
               sigma: Mapping[str, float | None] | None = None,
               conversions: Mapping[tuple[str, str], float] | None = None, drop_doubtful: bool = False,
               unmapped: Literal["skip", "error"] = "skip") -> ObservationSet:
    """Read observations from a Delft-FEWS PI-XML time-series file.

    Parameters
    ----------
    path
        The file.
    mapping
        (locationId, parameterId) -> series id ``"<station>.<quantity>"``; the series come back in the
        mapping's order. Without a mapping, ``"<locationId>.<parameterId>"`` must itself be a series id.
    sigma
        σ per series id or quantity (default :data:`rivercal.observations.DEFAULT_SIGMA`), m or m³/s.
    conversions
        (file unit, expected unit) -> factor, e.g. ``{("cm", "m"): 0.01}`` or :data:`STANDARD_CONVERSIONS`.
        Without it a unit other than the quantity's is an error.
    drop_doubtful
        Also drop values flagged doubtful (FEWS flags 3–5); by default they are kept (and counted).
    unmapped
        What to do with series the mapping does not name: ``"skip"`` (logged) or ``"error"``.

    Returns
    -------
    ObservationSet
        One series per mapped id, in m AD or m³/s at UTC times; ``n_missing`` counts the values dropped as
        missing or unreliable.

    Raises
    ------
    PiXmlError
        Naming the file and series: unsafe or malformed XML, unit mismatches (all of them at once), a series
        id that is not ``"<station>.<quantity>"``, repeated times, or no mapped series at all.

    Examples
    --------
    A telemetry file whose level series is called ``H.up`` at location ``0028``:

    >>> import tempfile
    >>> import pandas as pd
    >>> frame = pd.DataFrame({"0028.h_up": [14.21, None, 14.25]},
    ...                      index=pd.date_range("2010-11-01", periods=3, freq="h", tz="UTC"))
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = write_pixml(Path(folder) / "telemetry.xml", frame, ids={"0028.h_up": ("0028", "H.up")})
    ...     obs = read_pixml(path, {("0028", "H.up"): "0028.h_up"})
    >>> obs["0028.h_up"].to_series().tolist(), obs.n_missing
    ([14.21, 14.25], 1)
    """
    path = Path(path)
    raw = read_pixml_series(path)
    if mapping is None:
        mapping = {(s.location_id, s.parameter_id): f"{s.location_id}.{s.parameter_id}" for s in raw}
    skipped = sorted({(s.location_id, s.parameter_id) for s in raw} - set(mapping))
    if skipped and unmapped == "error":
        raise PiXmlError(f"series not in the mapping: {', '.join(f'{a}/{b}' for a, b in skipped)}", file=str(path))
    if skipped:
        log.info("%s: skipped %d series the mapping does not name: %s", path, len(skipped),
                 ", ".join(f"{a}/{b}" for a, b in skipped))
    parts: dict[str, list[pd.Series]] = {}
    counts: dict[str, dict[str, int]] = {}
    problems: list[str] = []
    for pi in raw:
        series_id = mapping.get((pi.location_id, pi.parameter_id))
        if series_id is None:
            continue
        factor, problem = _factor(pi, series_id, conversions, path)
        if problem:
            problems.append(problem)
            continue
        if pi.series_type != "instantaneous":
            log.warning("%s: %s is of type %r; its values are used as instantaneous values at their time stamps",
                        path, pi.label, pi.series_type)
        values, dropped = _clean(pi, drop_doubtful)
        total = counts.setdefault(series_id, {"missing": 0, "unreliable": 0, "doubtful": 0})
        for key, n in dropped.items():
            total[key] += n
        parts.setdefault(series_id, []).append(pd.Series(values * factor, index=pi.times))
    if len(problems) == 1:
        raise PiXmlError(problems[0], file=str(path))
    if problems:
        raise PiXmlError(f"{len(problems)} series cannot be used:\n  " + "\n  ".join(problems), file=str(path))
    if not parts:
        found = ", ".join(f"{s.location_id}/{s.parameter_id}" for s in raw) or "none"
        raise PiXmlError(f"no series of the file is in the mapping (the file has: {found})", file=str(path))
    sigma = dict(DEFAULT_SIGMA if sigma is None else sigma)
    out = []
    for series_id in [i for i in dict.fromkeys(mapping.values()) if i in parts]:
        joined = pd.concat(parts[series_id]).sort_index(kind="stable")
        repeated = joined.index[joined.index.duplicated()]
        if len(repeated):
            raise PiXmlError(f"{series_id}: time {repeated[0].isoformat()} occurs more than once", file=str(path))
        quantity = series_id.rpartition(".")[2]
        try:
            obs = ObservationSeries.from_series(joined, id=series_id, sigma=sigma.get(series_id, sigma.get(quantity)),
                                                source=str(path))
        except ValueError as exc:
            raise PiXmlError(str(exc), file=str(path)) from None
        c = counts[series_id]
        if c["missing"] or c["unreliable"] or c["doubtful"]:
            log.info("%s: %s: %d values; dropped %d missing (missVal or NaN) and %d flagged unreliable; %d doubtful "
                     "%s", path, series_id, len(obs), c["missing"], c["unreliable"], c["doubtful"],
                     "dropped" if drop_doubtful else "kept")
        out.append(obs)
    result = ObservationSet(tuple(out))
    log.info("%s: read %d series, %d values (%d dropped as missing or unreliable)", path, len(result),
             result.n_values, result.n_missing)
    return result


def _pi_datetime(parent: ET.Element, tag: str, time: pd.Timestamp) -> None:
    ET.SubElement(parent, tag, date=time.strftime("%Y-%m-%d"), time=time.strftime("%H:%M:%S"))


def _local(times: Any, time_zone: float) -> pd.DatetimeIndex:
    """UTC times (naive = UTC) as naive local times of a file whose ``<timeZone>`` is ``time_zone`` h."""
    return (utc_index(times) + pd.Timedelta(hours=time_zone)).tz_localize(None)


def write_pixml_series(path: str | Path, series: Sequence[PiSeries], *, time_zone: float = 0.0,
                       forecast_date: Any | None = None) -> Path:
    """Write series as a PI-XML time-series file (the inverse of :func:`read_pixml_series`).

    The file validates against the PI schema ``pi_timeseries.xsd`` (version 1.2 header elements only, in
    the schema's order).

    Parameters
    ----------
    path
        The file to write.
    series
        The series: ids, qualifiers, type, units and missing value from each :class:`PiSeries`; its times
        are UTC; a NaN value is written as the series' ``miss_val`` (NaN when that is NaN); a flag below 0
        is not written; ``comments`` (if given) become the events' ``comment`` attributes.
    time_zone
        Hours ahead of UTC for the file's times (``<timeZone>``).
    forecast_date
        The forecast's issue time (header ``forecastDate``), if a forecast.
    """
    ET.register_namespace("", PI_NAMESPACE)
    ET.register_namespace("xsi", _XSI)
    root = ET.Element(_q("TimeSeries", PI_NAMESPACE), {f"{{{_XSI}}}schemaLocation": f"{PI_NAMESPACE} {_PI_SCHEMA}",
                                                         "version": "1.2"})
    ET.SubElement(root, _q("timeZone", PI_NAMESPACE)).text = f"{time_zone:.1f}"
    t0_local = _local([forecast_date], time_zone)[0] if forecast_date is not None else None
    for pi in series:
        if not len(pi.times):
            raise ValueError(f"{pi.label}: a PI series needs at least one event (its header has start and end dates)")
        local = _local(pi.times, time_zone)
        step = np.diff(pd.DatetimeIndex(pi.times).as_unit("ns").asi8) // 1_000_000_000
        node = ET.SubElement(root, _q("series", PI_NAMESPACE))
        header = ET.SubElement(node, _q("header", PI_NAMESPACE))

        def add(tag: str, text: str, header: ET.Element = header) -> None:
            ET.SubElement(header, _q(tag, PI_NAMESPACE)).text = text

        add("type", pi.series_type)
        add("locationId", pi.location_id)
        add("parameterId", pi.parameter_id)
        for qualifier in pi.qualifier_ids:
            add("qualifierId", qualifier)
        if step.size and (step == step[0]).all() and step[0] > 0:
            ET.SubElement(header, _q("timeStep", PI_NAMESPACE), unit="second", multiplier=str(int(step[0])))
        else:
            ET.SubElement(header, _q("timeStep", PI_NAMESPACE), unit="nonequidistant")
        _pi_datetime(header, _q("startDate", PI_NAMESPACE), local[0])
        _pi_datetime(header, _q("endDate", PI_NAMESPACE), local[-1])
        if t0_local is not None:
            _pi_datetime(header, _q("forecastDate", PI_NAMESPACE), t0_local)
        miss = "NaN" if math.isnan(pi.miss_val) else repr(float(pi.miss_val))
        add("missVal", miss)
        if pi.units is not None:
            add("units", pi.units)
        flags = np.asarray(pi.flags, dtype=int)
        for i, (t, v) in enumerate(zip(local, np.asarray(pi.values, dtype=float), strict=True)):
            attrs = {"date": t.strftime("%Y-%m-%d"), "time": t.strftime("%H:%M:%S"),
                     "value": format(v, ".10g") if math.isfinite(v) else miss}
            if flags[i] >= 0:
                attrs["flag"] = str(int(flags[i]))
            if pi.comments is not None and pi.comments[i]:
                attrs["comment"] = pi.comments[i]
            ET.SubElement(node, _q("event", PI_NAMESPACE), attrs)
    ET.indent(root, space="  ")
    path = Path(path)
    ET.ElementTree(root).write(path, encoding="UTF-8", xml_declaration=True)
    return path


def write_pixml(path: str | Path, frame: pd.DataFrame, *, ids: Mapping[str, tuple[str, str]] | None = None,
                units: Mapping[str, str] | None = None, time_zone: float = 0.0, miss_val: float = -999.0,
                forecast_date: Any | None = None, qualifiers: Sequence[str] = (),
                series_type: str = "instantaneous") -> Path:
    """Write series (e.g. a forecast) as a PI-XML time-series file that Delft-FEWS imports.

    Parameters
    ----------
    path
        The file to write.
    frame
        Values indexed by time (UTC; naive = UTC), one column per series ``"<station>.<quantity>"``, in m AD
        or m³/s; NaN is written as ``miss_val`` (without a flag), a value with flag 0 (original, reliable).
    ids
        Series id -> (locationId, parameterId) (default: split the id at its last ``.``).
    units
        Series id -> unit text (default by quantity: ``m`` or ``m3/s``).
    time_zone
        Hours ahead of UTC for the file's times (``<timeZone>``).
    miss_val
        The missing-value number.
    forecast_date
        The forecast's issue time (header ``forecastDate``), if a forecast.
    qualifiers
        Header ``qualifierId`` of every series (e.g. ``("dss",)`` to tell a forecast from another).
    series_type
        Header ``type``: ``instantaneous``, ``mean`` or ``accumulative``.
    """
    out = []
    for col in frame.columns:
        series_id = str(col)
        station, _, quantity = series_id.rpartition(".")
        location, parameter = (ids or {}).get(series_id, (station, quantity))
        values = frame[col].to_numpy(dtype=float)
        out.append(PiSeries(location, parameter, tuple(qualifiers), series_type,
                            (units or {}).get(series_id, EXPECTED_UNITS.get(quantity, "-")), float(miss_val),
                            utc_index(frame.index), values, np.where(np.isfinite(values), 0, -1)))
    return write_pixml_series(path, out, time_zone=time_zone, forecast_date=forecast_date)
