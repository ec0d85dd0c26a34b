"""The clock of a gauge file: time zones, time stamps, local clock time with summer time, and their order.

The rules are those of the sidecar's documentation (:mod:`rivercal.io.sensors`, "Time zones" and "Times"):
every error names the file and its line.
"""

from __future__ import annotations

import difflib
import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import TYPE_CHECKING
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

import numpy as np
import pandas as pd

from rivercal._time import parse_iso
from rivercal.errors import CaseError

if TYPE_CHECKING:
    from rivercal.io.sensors import SensorSpec, _Raw

log = logging.getLogger("rivercal.io.sensors")

#: Time-zone abbreviations as the fixed offsets (h) they name in a time stamp (``Fri Dec 6 10:00 CET 2013``).
ABBREVIATIONS = {"UTC": 0.0, "GMT": 0.0, "UT": 0.0, "Z": 0.0, "WET": 0.0, "WEST": 1.0, "CET": 1.0, "MET": 1.0,
                 "CEST": 2.0, "MEST": 2.0, "EET": 2.0, "EEST": 3.0}
#: A fixed offset as written: ``UTC+01:00``, ``+01:00``, ``GMT+1``.
_OFFSET = re.compile(r"^(?:(?:UTC|GMT)\s*)?([+-])(\d{1,2})(?::?(\d{2}))?$", re.IGNORECASE)


@dataclass(frozen=True)
class TimeZoneSpec:
    """A time zone of a file: a fixed offset, or a region whose clock changes (IANA name).

    Attributes
    ----------
    text
        As written.
    offset_h
        The fixed offset east of UTC, h (None for a region).
    region
        The IANA region (None for a fixed offset).
    """

    text: str
    offset_h: float | None = None
    region: str | None = None

    @property
    def fixed(self) -> bool:
        """True for a fixed offset."""
        return self.region is None


def parse_time_zone(text: str) -> TimeZoneSpec:
    """A time zone as written in a sidecar or a file header (module docstring).

    Raises
    ------
    ValueError
        For anything else, with the accepted forms.
    """
    raw = str(text).strip()
    key = raw.upper()
    if key in ABBREVIATIONS:
        return TimeZoneSpec(raw, offset_h=ABBREVIATIONS[key])
    m = _OFFSET.match(raw.replace(" ", ""))
    if m:
        sign, hours, minutes = m.group(1), int(m.group(2)), int(m.group(3) or 0)
        if hours > 14 or minutes >= 60:
            raise ValueError(f"time zone {raw!r}: an offset is at most ±14:00")
        offset = hours + minutes / 60.0
        return TimeZoneSpec(raw, offset_h=-offset if sign == "-" else offset)
    if "/" in raw:
        try:
            ZoneInfo(raw)
        except (ZoneInfoNotFoundError, ValueError):
            guess = difflib.get_close_matches(raw, _regions(), n=1, cutoff=0.7)
            hint = f"; did you mean {guess[0]!r}?" if guess else ""
            raise ValueError(f"time zone {raw!r} is not a region of the IANA time-zone database{hint}") from None
        return TimeZoneSpec(raw, region=raw)
    raise ValueError(f"time zone {raw!r} is not understood; write UTC, a fixed offset such as UTC+01:00, an "
                     "abbreviation (CET is UTC+1, CEST UTC+2), or a region such as Europe/Amsterdam for clock "
                     "time with summer time")


def _regions() -> list[str]:
    import zoneinfo

    try:
        return sorted(zoneinfo.available_timezones())
    except Exception:  # only for a suggestion
        return []


def parse_times(raw: _Raw, spec: SensorSpec, zone: TimeZoneSpec | None, label: str, side_error) -> np.ndarray:
    """UTC times (datetime64[ns]) of the rows, in file order."""
    fmt = spec.time_format
    naive = np.empty(len(raw.times), dtype="datetime64[ns]")
    aware = np.zeros(len(raw.times), dtype=bool)
    utc_ns = np.empty(len(raw.times), dtype="datetime64[ns]")
    for i, text in enumerate(raw.times):
        t = _one_time(text, fmt, spec.format, raw.lines[i], label)
        if t.tzinfo is not None:
            aware[i] = True
            utc_ns[i] = np.datetime64(t.astimezone(UTC).replace(tzinfo=None), "ns")
        else:
            naive[i] = np.datetime64(t, "ns")
    if (~aware).any():
        if zone is None:
            i = int(np.flatnonzero(~aware)[0])
            where = ("neither the sidecar nor the file's header says" if spec.format != "csv"
                     else "the sidecar does not say")
            raise side_error("time_zone", f"line {raw.lines[i]} of {label} has a time without an offset "
                                          f"({raw.times[i]!r}), and {where} in which zone: give time_zone (UTC, "
                                          "UTC+01:00, CET, or a region such as Europe/Amsterdam)")
        local = naive[~aware]
        lines = [raw.lines[i] for i in np.flatnonzero(~aware)]
        utc_ns[~aware] = _localize(local, zone, lines, label)
    return utc_ns


def _one_time(text: str, fmt: str | None, file_format: str, line: int, label: str) -> datetime:
    text = text.strip()
    if fmt is None and file_format != "csv":
        digits = text
        if digits.isdigit() and len(digits) in (12, 14):
            try:
                return datetime.strptime(digits, "%Y%m%d%H%M%S" if len(digits) == 14 else "%Y%m%d%H%M")
            except ValueError:
                pass
        raise CaseError(f"line {line}: {text!r} is not a time YYYYMMDDHHMM", file=label)
    if fmt is not None:
        try:
            return datetime.strptime(text, fmt)
        except ValueError:
            raise CaseError(f"line {line}: {text!r} does not match time_format {fmt!r}", file=label) from None
    try:
        return parse_iso(text).to_pydatetime()
    except ValueError as exc:
        raise CaseError(f"line {line}: {exc}; or give time_format", file=label) from None


def _localize(local: np.ndarray, zone: TimeZoneSpec, lines: Sequence[int], label: str) -> np.ndarray:
    """UTC of local times in ``zone`` (file order); errors for non-existent and ambiguous clock times."""
    if zone.fixed:
        return local - np.timedelta64(round(zone.offset_h * 3600), "s")
    index = pd.DatetimeIndex(local)
    skipped = index.tz_localize(zone.region, ambiguous="NaT", nonexistent="NaT")
    probe = index.tz_localize(zone.region, ambiguous=np.ones(len(index), dtype=bool), nonexistent="NaT")
    gap = np.flatnonzero(probe.isna())
    if gap.size:
        i = int(gap[0])
        raise CaseError(f"line {lines[i]}: {index[i]:%Y-%m-%d %H:%M} does not exist in {zone.region}: the clocks were "
                        "put forward an hour that night (summer time began); a file in winter time all year is "
                        f"UTC+01:00 (say time_zone = 'UTC+01:00' or 'CET'), not {zone.region}", file=label)
    ambiguous = np.flatnonzero(skipped.isna())
    if not ambiguous.size:
        return skipped.tz_convert("UTC").tz_localize(None).to_numpy()
    # in the repeated hour: summer time (the first pass) until the local clock steps back, then winter time
    dst = np.ones(len(index), dtype=bool)
    ns = index.asi8
    for run in _runs(ambiguous):
        back = [j for j in run[1:] if ns[j] <= ns[j - 1]]
        if not back and not (run[0] > 0 and ns[run[0]] <= ns[run[0] - 1]):
            i = run[0]
            raise CaseError(f"line {lines[i]}: {index[i]:%Y-%m-%d %H:%M} is ambiguous in {zone.region}: that clock "
                            "hour came twice (summer time ended), and nothing in the file tells which pass this is "
                            "(the times do not step back); a file in winter time all year is UTC+01:00 (time_zone = "
                            "'UTC+01:00' or 'CET')", file=label)
        switch = back[0] if back else run[0]
        dst[[j for j in run if j >= switch]] = False
    out = index.tz_localize(zone.region, ambiguous=dst, nonexistent="raise")
    return out.tz_convert("UTC").tz_localize(None).to_numpy()


def _runs(positions: np.ndarray) -> list[list[int]]:
    """Consecutive positions grouped into runs."""
    runs: list[list[int]] = []
    for p in positions.tolist():
        if runs and p == runs[-1][-1] + 1:
            runs[-1].append(p)
        else:
            runs.append([p])
    return runs


def check_order(times: np.ndarray, lines: Sequence[int], spec: SensorSpec, label: str,
                 zone: TimeZoneSpec | None) -> tuple[pd.DatetimeIndex, np.ndarray]:
    """The UTC index in file order (duplicates resolved by ``spec.duplicates``) and the positions it keeps."""
    order = np.arange(times.size)
    steps = np.diff(times)
    back = np.flatnonzero(steps < np.timedelta64(0, "ns"))
    if back.size:
        i = int(back[0]) + 1
        raise CaseError(f"line {lines[i]}: {_show(times[i])} comes before {_show(times[i - 1])} on line "
                        f"{lines[i - 1]}; times must increase{_dst_hint(times[i - 1], times[i], zone)}", file=label)
    same = np.flatnonzero(steps == np.timedelta64(0, "ns"))
    if same.size:
        if spec.duplicates == "error":
            i = int(same[0]) + 1
            raise CaseError(f"line {lines[i]}: the time {_show(times[i])} appears twice (also on line {lines[i - 1]})"
                            f"{_dst_hint(times[i - 1], times[i], zone)}; if the repeats are expected, say duplicates "
                            "= 'first' or 'last'", file=label)
        drop = same + 1 if spec.duplicates == "first" else same
        order = np.delete(order, drop)
        log.info("%s: %d repeated time(s); the %s value of each kept", label, same.size, spec.duplicates)
    index = pd.DatetimeIndex(times[order]).tz_localize("UTC")
    return index, order


def _dst_hint(before: np.datetime64, after: np.datetime64, zone: TimeZoneSpec | None) -> str:
    """Advice when a step back or a repeat looks like the end of summer time in a file read with a fixed offset."""
    if zone is None or not zone.fixed:
        return ""
    back = (before - after) / np.timedelta64(1, "m")
    t = pd.Timestamp(after)
    sunday = t.weekday() == 6
    autumn = (t.month == 10 and t.day >= 25) or (t.month == 11 and t.day <= 7)  # Europe's last Sunday, the US's first
    if sunday and autumn and 0 <= back <= 60:
        return ("; the clocks went back an hour that night (summer time ended): if the file is in local clock time, "
                "give its region (time_zone = 'Europe/Amsterdam') instead of a fixed offset")
    return ""


def _show(t: np.datetime64) -> str:
    return f"{pd.Timestamp(t):%Y-%m-%d %H:%M:%S} UTC"
