"""Mascaret's text files: the geometry (``.geo``, ``.georef``) and the hydraulic laws (``.loi``).

**Geometry** (the "LIDO 3.0" format, ``<format>2</format>`` in the case file; TELEMAC-Mascaret's reader
``LEC_GEOM_V3P0``): lines starting with ``#`` are comments; each profile starts with a header line
``PROFIL <reach> <profile> <abscissa>`` (names without blanks, abscissa in m along the reach) followed by one
line per survey point ``<y> <z> <bed>``: the horizontal position across the valley (m), the level (m) and
``B`` for a point of the minor bed (bathymetry) or ``T`` for a point of the major bed (topography). The
minor bed is the one run of ``B`` points; a profile without ``B`` points is minor bed throughout. Profiles of
a reach follow each other with strictly increasing abscissae; a new reach name starts the next reach.
Georeferenced files (``.georef``) add map coordinates: ``... <abscissa> <x1> <y1> <x2> <y2> AXE <xa> <ya>``
on the header (the axis point ``AXE`` is where the reach's axis crosses the profile) and ``<x> <y>`` after
each point; they are read and the axis points give the reach its map geometry.

**Laws** (``LEC_HYDRAU``): ``#`` comment lines; a law in time starts with a line that names the time unit
(``S`` seconds, ``M`` minutes, ``H`` hours, ``J`` days); then one line per point. The columns depend on the
law's type (given in the case file):

====  ============================  ==========================
type  law                           columns
====  ============================  ==========================
1     hydrograph Q(t)               t, Q
2     limnigraph Z(t)               t, Z
3     limni-hydrograph Z(t), Q(t)   t, Z, Q
4     rating Z = f(Q)               Q, Z
5     rating Q = f(Z)               Z, Q
6     weir law Zup = f(Zdown, Q)    Q, Zdown, Zup
7     gate levels Zlow(t), Zup(t)   t, Zlow, Zup
====  ============================  ==========================

Levels in m, discharges in m³/s, times converted to s. Every bad value is a
:class:`~rivercal.errors.CaseError` naming the file and the line.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rivercal.errors import CaseError

__all__ = ["LAW_COLUMNS", "LAW_NAMES", "GeoPoint", "GeoProfile", "Geometry", "Law", "read_geometry", "read_law",
           "read_station_list"]

#: Column names of each law type (see the module docstring).
LAW_COLUMNS: dict[int, tuple[str, ...]] = {
    1: ("time", "discharge"),
    2: ("time", "level"),
    3: ("time", "level", "discharge"),
    4: ("discharge", "level"),
    5: ("level", "discharge"),
    6: ("discharge", "level_down", "level_up"),
    7: ("time", "level_low", "level_up"),
}
#: What each law type is, in words.
LAW_NAMES = {1: "hydrograph Q(t)", 2: "limnigraph Z(t)", 3: "limni-hydrograph Z(t), Q(t)", 4: "rating Z = f(Q)",
             5: "rating Q = f(Z)", 6: "weir law Zup = f(Zdown, Q)", 7: "gate levels Zlow(t), Zup(t)"}
_TIME_UNITS = {"S": 1.0, "M": 60.0, "H": 3600.0, "J": 86400.0}


def _lines(path: Path, what: str) -> list[tuple[int, str]]:
    """The non-empty, non-comment lines of a text file with their numbers (1-based)."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise CaseError(f"cannot read the {what}: {exc.strerror or exc}", file=str(path)) from None
    text = raw.decode("utf-8", errors="strict") if _is_utf8(raw) else raw.decode("latin-1")
    out = []
    for k, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if stripped and not stripped.startswith("#"):
            out.append((k, stripped))
    return out


def _is_utf8(raw: bytes) -> bool:
    try:
        raw.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return True


def _number(word: str, path: Path, line: int, what: str) -> float:
    try:
        value = float(word.replace("D", "e").replace("d", "e"))
    except ValueError:
        raise CaseError(f"{what}: {word!r} is not a number", file=str(path), field=f"line {line}") from None
    if not math.isfinite(value):
        raise CaseError(f"{what}: {word!r} is not a finite number", file=str(path), field=f"line {line}")
    return value


# -- geometry ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class GeoPoint:
    """A survey point: position across the valley ``y`` (m), level ``z`` (m), ``B`` (minor bed) or ``T`` (major)."""

    y: float
    z: float
    bed: str
    line: int


@dataclass
class GeoProfile:
    """A surveyed cross-section of a reach.

    Attributes
    ----------
    reach, name
        Reach and profile names.
    abscissa
        Position along the reach, m (Mascaret's relative abscissa).
    points
        The survey points from one bank to the other.
    line
        Line of the header in the file.
    axis
        Map position (x, y) where the reach's axis crosses the profile (georeferenced files), m, or None.
    """

    reach: str
    name: str
    abscissa: float
    line: int
    points: list[GeoPoint] = field(default_factory=list)
    axis: tuple[float, float] | None = None

    @property
    def bed_level(self) -> float:
        """The lowest level of the profile, m."""
        return min(p.z for p in self.points)

    def minor_bed(self) -> tuple[int, int]:
        """Indices of the first and last point of the minor bed (the run of ``B`` points; all when there is none)."""
        marks = [p.bed == "B" for p in self.points]
        if not any(marks):
            return 0, len(self.points) - 1
        first = marks.index(True)
        last = len(marks) - 1 - marks[::-1].index(True)
        return first, last


@dataclass
class Geometry:
    """The profiles of a geometry file, reach after reach in file order."""

    path: Path
    profiles: list[GeoProfile]

    def reaches(self) -> list[tuple[str, list[GeoProfile]]]:
        """The reaches in file order: (name, profiles)."""
        out: list[tuple[str, list[GeoProfile]]] = []
        for p in self.profiles:
            if not out or out[-1][0] != p.reach:
                out.append((p.reach, []))
            out[-1][1].append(p)
        return out


def read_geometry(path: Path | str) -> Geometry:
    """Read a Mascaret geometry file (``.geo`` or ``.georef``; see the module docstring).

    Raises
    ------
    CaseError
        For a point before the first ``PROFIL`` line, a value that is not a number, a bed mark other than
        ``B`` or ``T``, two separate runs of ``B`` points in a profile, a profile with fewer than two points,
        abscissae that do not increase along a reach, a reach with one profile or a reach whose name comes
        back after another reach; the message names the file and the line.
    """
    path = Path(path)
    profiles: list[GeoProfile] = []
    for line, text in _lines(path, "geometry file"):
        words = text.split()
        if words[0].lower() == "profil":
            if profiles:
                _check_profile(profiles[-1], path)
            if len(words) < 4:
                raise CaseError("a profile header is 'PROFIL <reach> <profile> <abscissa>'; got "
                                f"{len(words) - 1} value(s) after PROFIL", file=str(path), field=f"line {line}")
            abscissa = _number(words[3], path, line, f"abscissa of profile {words[2]!r}")
            axis = None
            upper = [w.upper() for w in words]
            if "AXE" in upper:
                k = upper.index("AXE")
                if len(words) >= k + 3:
                    axis = (_number(words[k + 1], path, line, "x of the axis point"),
                            _number(words[k + 2], path, line, "y of the axis point"))
            profiles.append(GeoProfile(reach=words[1], name=words[2], abscissa=abscissa, line=line, axis=axis))
            continue
        if not profiles:
            raise CaseError("a survey point before the first 'PROFIL <reach> <profile> <abscissa>' line",
                            file=str(path), field=f"line {line}")
        if len(words) < 3:
            raise CaseError(f"a survey point is '<y> <z> <B|T>' (position m, level m, minor or major bed); got "
                            f"{text!r}", file=str(path), field=f"line {line}")
        y = _number(words[0], path, line, f"y of a point of profile {profiles[-1].name!r}")
        z = _number(words[1], path, line, f"z of a point of profile {profiles[-1].name!r}")
        bed = words[2].upper()
        if bed not in ("B", "T"):
            raise CaseError(f"the bed mark of a point of profile {profiles[-1].name!r} is {words[2]!r}: expected B "
                            "(minor bed) or T (major bed)", file=str(path), field=f"line {line}")
        profiles[-1].points.append(GeoPoint(y, z, bed, line))
    if not profiles:
        raise CaseError("no profile: the file has no 'PROFIL <reach> <profile> <abscissa>' line", file=str(path))
    _check_profile(profiles[-1], path)
    geometry = Geometry(path, profiles)
    seen: set[str] = set()
    for name, items in geometry.reaches():
        if name in seen:
            raise CaseError(f"reach {name!r} comes back after another reach: the profiles of a reach must follow "
                            "each other", file=str(path), field=f"line {items[0].line}")
        seen.add(name)
        if len(items) < 2:
            raise CaseError(f"reach {name!r} has one profile; a reach needs at least two", file=str(path),
                            field=f"line {items[0].line}")
        for a, b in itertools.pairwise(items):
            if not b.abscissa > a.abscissa:
                raise CaseError(f"the abscissa of profile {b.name!r} ({b.abscissa:g} m) is not after that of "
                                f"{a.name!r} ({a.abscissa:g} m): abscissae increase along reach {name!r}",
                                file=str(path), field=f"line {b.line}")
    return geometry


def _check_profile(profile: GeoProfile, path: Path) -> None:
    if len(profile.points) < 2:
        raise CaseError(f"profile {profile.name!r} has {len(profile.points)} point(s); a profile needs at least two",
                        file=str(path), field=f"line {profile.line}")
    runs = 0
    previous = "T"
    for p in profile.points:
        if p.bed == "B" and previous != "B":
            runs += 1
            if runs > 1:
                raise CaseError(f"profile {profile.name!r} has two separate runs of minor-bed points (B): the minor "
                                "bed is one stretch between two banks", file=str(path), field=f"line {p.line}")
        previous = p.bed


# -- laws -------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Law:
    """A hydraulic law read from its file.

    Attributes
    ----------
    path
        The file.
    type
        Law type 1-7 (see the module docstring).
    columns
        The columns by name (``time`` in s, ``level`` m, ``discharge`` m³/s, ...), as arrays.
    """

    path: Path
    type: int
    columns: dict[str, np.ndarray]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    @property
    def in_time(self) -> bool:
        """Whether the law is a series in time."""
        return "time" in self.columns


def read_law(path: Path | str, law_type: int) -> Law:
    """Read a Mascaret law file of a type (see the module docstring).

    Raises
    ------
    CaseError
        For a missing time-unit line, a line with too few values or a value that is not a number, times that
        do not increase, a rating whose levels or discharges do not increase; naming the file and the line.
    """
    path = Path(path)
    if law_type not in LAW_COLUMNS:
        raise CaseError(f"law type {law_type} is not one of Mascaret's types 1-7", file=str(path))
    names = LAW_COLUMNS[law_type]
    lines = _lines(path, "law file")
    scale = 1.0
    if "time" in names:
        if not lines:
            raise CaseError("the file is empty: a law in time starts with its time unit (S, M, H or J)", file=str(path))
        line, text = lines[0]
        word = text.split()[0]
        if word[:1].upper() not in _TIME_UNITS or any(c.isdigit() for c in word):
            raise CaseError(f"a law in time starts with a line naming its time unit (S seconds, M minutes, H hours or "
                            f"J days); got {text!r}", file=str(path), field=f"line {line}")
        scale = _TIME_UNITS[word[:1].upper()]
        lines = lines[1:]
    if not lines:
        raise CaseError("the law has no points", file=str(path))
    rows = []
    for line, text in lines:
        words = text.split()
        if len(words) < len(names):
            raise CaseError(f"a point of a {LAW_NAMES[law_type]} law has {len(names)} values "
                            f"({', '.join(names)}); got {len(words)}", file=str(path), field=f"line {line}")
        rows.append([_number(w, path, line, names[i]) for i, w in enumerate(words[:len(names)])])
    data = np.asarray(rows, dtype=float)
    columns = {name: data[:, i].copy() for i, name in enumerate(names)}
    if "time" in columns:
        columns["time"] *= scale
        _increasing(columns["time"], lines, path, "times")
    if law_type in (4, 5):
        if len(rows) < 2:
            raise CaseError("a rating needs at least two points", file=str(path))
        _increasing(columns["level"], lines, path, "levels of the rating")
        _increasing(columns["discharge"], lines, path, "discharges of the rating")
    return Law(path=path, type=law_type, columns=columns)


def _increasing(values: np.ndarray, lines: list[tuple[int, str]], path: Path, what: str) -> None:
    bad = np.flatnonzero(np.diff(values) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise CaseError(f"the {what} must increase strictly: {values[k]:g} follows {values[k - 1]:g}",
                        file=str(path), field=f"line {lines[k][0]}")


# -- stations given with an import -------------------------------------------------------------------------


def read_station_list(path: Path | str) -> list[tuple[str, str, float, int]]:
    """Read a station list: a CSV file with a header ``id,reach,abscissa`` and one station per line.

    ``reach`` is the Mascaret reach's name (as in the geometry file) or its number; ``abscissa`` is the position
    along the reach in m (Mascaret's abscissa). Lines starting with ``#`` are comments.

    Returns
    -------
    list of (id, reach, abscissa, line)

    Raises
    ------
    CaseError
        For a missing column, a line with too few values, an abscissa that is not a number, an id that is not a
        valid station id (letters, digits, ``_``, ``-``) or an id given twice; naming the file and the line.
    """
    import csv
    import io
    import re

    path = Path(path)
    rows = _lines(path, "station list")
    if not rows:
        raise CaseError("the station list is empty: expected a header 'id,reach,abscissa' and one line per station",
                        file=str(path))
    header_line, header = rows[0]
    names = [h.strip().lower() for h in next(csv.reader(io.StringIO(header)))]
    missing = [c for c in ("id", "reach", "abscissa") if c not in names]
    if missing:
        raise CaseError(f"the header names no {', '.join(missing)} column (expected 'id,reach,abscissa'); got "
                        f"{header!r}", file=str(path), field=f"line {header_line}")
    col = {c: names.index(c) for c in ("id", "reach", "abscissa")}
    out: list[tuple[str, str, float, int]] = []
    seen: set[str] = set()
    for line, text in rows[1:]:
        values = [v.strip() for v in next(csv.reader(io.StringIO(text)))]
        if len(values) < len(names):
            raise CaseError(f"expected {len(names)} values ({', '.join(names)}), got {len(values)}", file=str(path),
                            field=f"line {line}")
        sid, reach = values[col["id"]], values[col["reach"]]
        if not re.fullmatch(r"[A-Za-z0-9_\-]{1,64}", sid):
            raise CaseError(f"station id {sid!r}: use 1-64 letters, digits, '_' or '-'", file=str(path),
                            field=f"line {line}")
        if sid in seen:
            raise CaseError(f"station {sid!r} is listed twice", file=str(path), field=f"line {line}")
        seen.add(sid)
        if not reach:
            raise CaseError(f"station {sid!r} names no reach", file=str(path), field=f"line {line}")
        out.append((sid, reach, _number(values[col["abscissa"]], path, line, f"abscissa of station {sid!r}"), line))
    if not out:
        raise CaseError("the station list has a header but no station", file=str(path))
    return out
