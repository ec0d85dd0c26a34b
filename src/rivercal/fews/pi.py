"""The PI files of a Delft-FEWS General Adapter run besides time series: run file, state, diagnostics.

Schemas ``pi_run.xsd``, ``pi_state.xsd`` and ``pi_diag.xsd``.

Before a module runs, the General Adapter writes a *run file* (``<Run>``) that names everything the
module needs: time zero, the run's start and end, the PI time-series files it exported, the state it
exported, the files it will import afterwards, and free ``<properties>``. After the run it imports the
time series, the state description (``<State>``: where the new state files are) and the diagnostics
(``<Diag>``: one ``<line level=… description=…/>`` per message; 0 fatal, 1 error, 2 warning, 3 info,
4 debug).

Dates in a PI file are local to its ``<timeZone>`` (hours ahead of UTC); this module converts them to
UTC on reading and back on writing. Files are parsed with :mod:`defusedxml` (no DTDs or entities).
"""

from __future__ import annotations

import math
import os
import re
import uuid
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import defusedxml
import defusedxml.ElementTree as SafeET
import pandas as pd

from rivercal.errors import CaseError
from rivercal.io.pixml import PI_NAMESPACE

__all__ = ["DIAG_LEVELS", "FIRST_TIME", "LAST_TIME", "DiagLine", "RunFile", "StateLocation", "read_run_file",
           "read_state_description", "replace_atomically", "write_diag", "write_state_description"]

_XSI = "http://www.w3.org/2001/XMLSchema-instance"
_SCHEMAS = "http://fews.wldelft.nl/schemas/version1.0/pi-schemas"
#: PI diagnostics levels by name (pi_diag.xsd): lower is more severe.
DIAG_LEVELS = {"fatal": 0, "error": 1, "warn": 2, "info": 3, "debug": 4}
#: The earliest and latest times rivercal handles (UTC): its time axes count nanoseconds in 64 bits.
FIRST_TIME = pd.Timestamp("1678-01-01T00:00:00Z")
LAST_TIME = pd.Timestamp("2261-12-31T23:59:59Z")
_DATE = re.compile(r"\d{4}-\d{2}-\d{2}")
#: The longest diagnostics line, characters (a message quoting a huge value is cut).
_MAX_LINE = 2000
_TIME = re.compile(r"\d{2}:\d{2}(:\d{2}(\.\d{1,9})?)?")


class PiFileError(CaseError):
    """A PI run or state file cannot be used; the message names the file and the element."""


def _q(tag: str) -> str:
    return f"{{{PI_NAMESPACE}}}{tag}"


def _parse(path: Path, root_tag: str) -> ET.Element:
    if not path.is_file():
        raise PiFileError("no such file", file=str(path))
    try:
        root = SafeET.parse(str(path), forbid_dtd=True, forbid_entities=True, forbid_external=True).getroot()
    except defusedxml.DefusedXmlException as exc:
        raise PiFileError(f"refused to parse: the file declares a DTD or entities ({type(exc).__name__})",
                          file=str(path)) from None
    except SafeET.ParseError as exc:
        raise PiFileError(f"not well-formed XML ({exc})", file=str(path)) from None
    except OSError as exc:
        raise PiFileError(f"cannot read the file ({exc.strerror or exc})", file=str(path)) from None
    if root.tag != _q(root_tag):
        raise PiFileError(f"not a PI <{root_tag}> file: the root element is {root.tag!r} (expected <{root_tag}> in "
                          f"the namespace {PI_NAMESPACE})", file=str(path))
    return root


def _zone(root: ET.Element, path: Path, required: bool) -> float:
    node = root.find(_q("timeZone"))
    if node is None or not (node.text or "").strip():
        if required:
            raise PiFileError("no <timeZone>", file=str(path), field="timeZone")
        return 0.0
    try:
        hours = float(node.text)
    except ValueError:
        raise PiFileError(f"{node.text.strip()!r} is not a time zone (hours ahead of UTC, e.g. 1.0)", file=str(path),
                          field="timeZone") from None
    if not (math.isfinite(hours) and -12.0 <= hours <= 14.0):
        raise PiFileError(f"{hours:g} h is not a time-zone offset (-12 to 14 h)", file=str(path), field="timeZone")
    return hours


def _datetime(node: ET.Element | None, zone_h: float, path: Path, tag: str) -> pd.Timestamp:
    if node is None:
        raise PiFileError(f"no <{tag}>", file=str(path), field=tag)
    date, time = (node.get("date") or "").strip(), (node.get("time") or "").strip()
    local: Any = pd.NaT
    if _DATE.fullmatch(date) and _TIME.fullmatch(time):
        try:
            local = pd.Timestamp(f"{date}T{time}")
        except ValueError:
            local = pd.NaT
    if pd.isna(local):
        raise PiFileError(f"date {date[:40]!r} time {time[:40]!r} is not a date and time (YYYY-MM-DD, HH:MM:SS)",
                          file=str(path), field=tag)
    utc = (local - pd.Timedelta(hours=zone_h)).tz_localize("UTC")  # microseconds: no overflow for years 1-9999
    if not FIRST_TIME <= utc <= LAST_TIME:
        raise PiFileError(f"{date} {time} (time zone {zone_h:+g} h) lies outside the years "
                          f"{FIRST_TIME.year}-{LAST_TIME.year} that rivercal handles", file=str(path), field=tag)
    return utc


def _local(time: pd.Timestamp, zone_h: float) -> dict[str, str]:
    t = (time.tz_convert("UTC") + pd.Timedelta(hours=zone_h)).tz_localize(None)
    return {"date": t.strftime("%Y-%m-%d"), "time": t.strftime("%H:%M:%S")}


def _resolve(text: str, base: Path) -> Path:
    path = Path(text.strip())
    return path if path.is_absolute() else base / path


@dataclass(frozen=True)
class RunFile:
    """A PI run file as read (times in UTC, paths resolved against the work folder).

    Attributes
    ----------
    path
        The run file.
    time_zone
        Hours ahead of UTC of the exported PI files and of the files the module writes.
    start, end, time0
        Start and end of the run and the forecast's time zero (UTC).
    work_dir
        The module's work folder (a relative one is taken relative to the run file's folder).
    input_state_files, input_series_files
        State descriptions and time-series files the General Adapter exported.
    output_diagnostic_file, output_state_file, output_series_files
        Where the module writes its diagnostics, state description and time series.
    properties
        The ``<properties>``: key -> value as text (dates as ISO 8601 UTC).
    log_level
        The run file's ``logLevel`` (``info`` when absent).
    unread
        (element, text) of the files the run file names that the module neither reads nor writes
        (:data:`UNUSED_ELEMENTS`).
    """

    path: Path
    time_zone: float
    start: pd.Timestamp
    end: pd.Timestamp
    time0: pd.Timestamp
    work_dir: Path
    output_diagnostic_file: Path
    input_state_files: tuple[Path, ...] = ()
    input_series_files: tuple[Path, ...] = ()
    output_state_file: Path | None = None
    output_series_files: tuple[Path, ...] = ()
    properties: Mapping[str, str] = field(default_factory=dict)
    log_level: str = "info"
    unread: tuple[tuple[str, str], ...] = ()


#: Run-file elements naming files the module neither reads nor writes (reported as warnings).
UNUSED_ELEMENTS = ("inputParameterFile", "inputMapStackFile", "inputNetcdfFile", "inputLongitudinalProfilesFile",
                   "inputRatingCurveFile", "outputMapStackFile", "outputNetcdfFile", "outputLongitudinalProfilesFile",
                   "outputCsvModuleRunTableFile")


def diagnostic_file_of(path: str | Path) -> Path | None:
    """The run file's ``outputDiagnosticFile`` if the file can be read that far, else None."""
    try:
        root = _parse(Path(path), "Run")
    except PiFileError:
        return None
    node, work = root.find(_q("outputDiagnosticFile")), root.find(_q("workDir"))
    if node is None or not (node.text or "").strip():
        return None
    base = Path(path).resolve().parent
    if work is not None and (work.text or "").strip():
        base = _resolve(work.text, base)
    if Path(node.text.strip()).is_absolute():
        return Path(node.text.strip())
    return _resolve(node.text, base) if _is_dir(base) else None  # never below a work folder that is not one


def _is_dir(path: Path) -> bool:
    try:
        return path.is_dir()
    except (OSError, ValueError):
        return False


def read_run_file(path: str | Path) -> RunFile:
    """Read a PI run file (``pi_run.xsd``).

    Raises
    ------
    PiFileError
        Naming the file and the element: missing or malformed file, another root element, a bad time zone
        or date, or a missing required element.
    """
    path = Path(path)
    root = _parse(path, "Run")
    zone = _zone(root, path, required=True)

    def texts(tag: str) -> list[str]:
        return [n.text.strip() for n in root.findall(_q(tag)) if n.text and n.text.strip()]

    work_text = texts("workDir")
    if not work_text:
        raise PiFileError("no <workDir>", file=str(path), field="workDir")
    work = _resolve(work_text[0], path.resolve().parent)
    if not _is_dir(work):
        raise PiFileError(f"the work folder {work} is not an existing folder (FEWS creates it before it starts the "
                          "module)", file=str(path), field="workDir")
    diag = texts("outputDiagnosticFile")
    if not diag:
        raise PiFileError("no <outputDiagnosticFile>", file=str(path), field="outputDiagnosticFile")
    props: dict[str, str] = {}
    node = root.find(_q("properties"))
    for prop in list(node) if node is not None else []:
        kind = prop.tag.rpartition("}")[2]
        if kind == "description":
            continue
        key = (prop.get("key") or "").strip()
        if not key:
            raise PiFileError(f"a <{kind}> property has no key", file=str(path), field="properties")
        if key in props:
            raise PiFileError(f"property {key!r} is given more than once", file=str(path), field="properties")
        if kind == "dateTime":
            props[key] = _datetime(prop, zone, path, f"properties/{key}").isoformat()
        else:
            props[key] = (prop.get("value") or "").strip()
    state_out = texts("outputStateDescriptionFile")
    level = texts("logLevel")
    time0 = _datetime(root.find(_q("time0")), zone, path, "time0")  # first: the time that matters most
    run = RunFile(path=path, time_zone=zone,
                  start=_datetime(root.find(_q("startDateTime")), zone, path, "startDateTime"),
                  end=_datetime(root.find(_q("endDateTime")), zone, path, "endDateTime"), time0=time0,
                  work_dir=work, output_diagnostic_file=_resolve(diag[0], work),
                  input_state_files=tuple(_resolve(t, work) for t in texts("inputStateDescriptionFile")),
                  input_series_files=tuple(_resolve(t, work) for t in texts("inputTimeSeriesFile")),
                  output_state_file=_resolve(state_out[0], work) if state_out else None,
                  output_series_files=tuple(_resolve(t, work) for t in texts("outputTimeSeriesFile")),
                  properties=props, log_level=level[0] if level else "info",
                  unread=tuple((tag, text) for tag in UNUSED_ELEMENTS for text in texts(tag)))
    if not run.start <= run.time0 <= run.end:
        raise PiFileError(f"time0 {run.time0:%Y-%m-%d %H:%M} UTC is not between startDateTime "
                          f"{run.start:%Y-%m-%d %H:%M} and endDateTime {run.end:%Y-%m-%d %H:%M} UTC", file=str(path),
                          field="time0")
    return run


@dataclass(frozen=True)
class StateLocation:
    """One ``<stateLoc>``: where FEWS puts a state file before the run and where the module writes it."""

    read: Path
    write: Path
    type: str = "file"


def read_state_description(path: str | Path, work_dir: Path) -> tuple[pd.Timestamp | None, tuple[StateLocation, ...]]:
    """The state time (UTC, None when absent) and the state locations of a PI state description.

    Raises
    ------
    PiFileError
        For a missing or malformed file, or a ``<stateLoc>`` without read or write location.
    """
    path = Path(path)
    root = _parse(path, "State")
    zone = _zone(root, path, required=False)
    node = root.find(_q("dateTime"))
    when = _datetime(node, zone, path, "dateTime") if node is not None else None
    locations = []
    for k, loc in enumerate(root.findall(_q("stateLoc")), 1):
        read, write = loc.find(_q("readLocation")), loc.find(_q("writeLocation"))
        if read is None or write is None or not (read.text or "").strip() or not (write.text or "").strip():
            raise PiFileError(f"<stateLoc> number {k} needs a readLocation and a writeLocation", file=str(path),
                              field="stateLoc")
        locations.append(StateLocation(_resolve(read.text, work_dir), _resolve(write.text, work_dir),
                                       loc.get("type") or "file"))
    if not locations:
        raise PiFileError("no <stateLoc>", file=str(path), field="stateLoc")
    return when, tuple(locations)


def _root(tag: str, schema: str, version: str = "1.2") -> ET.Element:
    ET.register_namespace("", PI_NAMESPACE)
    ET.register_namespace("xsi", _XSI)
    return ET.Element(_q(tag), {f"{{{_XSI}}}schemaLocation": f"{PI_NAMESPACE} {_SCHEMAS}/{schema}",
                                "version": version})


def _write(root: ET.Element, path: Path) -> Path:
    ET.indent(root, space="  ")
    path.parent.mkdir(parents=True, exist_ok=True)
    replace_atomically(path, lambda part: ET.ElementTree(root).write(part, encoding="UTF-8", xml_declaration=True))
    return path


def replace_atomically(path: Path, write: Any) -> None:
    """Write ``path`` through ``write(temporary_path)`` and rename: a killed run leaves the old file or the new one.

    The temporary file is created by ``write`` itself, so the file gets the permissions of any file the process
    writes (the umask's: readable by Delft-FEWS running as another user where the umask allows it), not the
    owner-only ones of a file :func:`tempfile.mkstemp` creates.
    """
    part = path.with_name(f".{path.name}.{uuid.uuid4().hex}.part")
    try:
        write(part)
        os.replace(part, path)
    finally:
        part.unlink(missing_ok=True)


def write_state_description(path: str | Path, state_id: str, time: pd.Timestamp, locations: Sequence[StateLocation],
                            *, time_zone: float = 0.0, name: str | None = None, comment: str | None = None) -> Path:
    """Write a PI state description (``pi_state.xsd``): the state ``state_id`` valid at ``time`` (UTC)."""
    root = _root("State", "pi_state.xsd")
    ET.SubElement(root, _q("stateId")).text = state_id
    if name:
        ET.SubElement(root, _q("stateName")).text = name
    ET.SubElement(root, _q("timeZone")).text = f"{time_zone:.1f}"
    ET.SubElement(root, _q("dateTime"), _local(time, time_zone))
    for loc in locations:
        node = ET.SubElement(root, _q("stateLoc"), type=loc.type)
        ET.SubElement(node, _q("readLocation")).text = str(loc.read)
        ET.SubElement(node, _q("writeLocation")).text = str(loc.write)
    if comment:
        ET.SubElement(root, _q("comment")).text = comment
    return _write(root, Path(path))


@dataclass(frozen=True)
class DiagLine:
    """One diagnostics message: its PI level (0 fatal … 4 debug) and text."""

    level: int
    text: str


@dataclass
class Diagnostics:
    """The lines of the PI diagnostics file, collected while the module runs."""

    lines: list[DiagLine] = field(default_factory=list)

    def add(self, level: str, text: str) -> None:
        """Add a line (``fatal``, ``error``, ``warn``, ``info`` or ``debug``); a very long text is cut."""
        text = str(text)
        if len(text) > _MAX_LINE:
            text = f"{text[:_MAX_LINE]} ... ({len(text) - _MAX_LINE} more characters)"
        self.lines.append(DiagLine(DIAG_LEVELS[level], text))

    @property
    def worst(self) -> int:
        """The most severe level (lowest number), 3 (info) when there is nothing worse."""
        return min((line.level for line in self.lines), default=DIAG_LEVELS["info"])


def write_diag(path: str | Path, lines: Sequence[DiagLine], *, comment: str | None = None) -> Path:
    """Write a PI diagnostics file (``pi_diag.xsd``; at least one line, as the schema demands)."""
    root = _root("Diag", "pi_diag.xsd")
    for line in lines or [DiagLine(DIAG_LEVELS["info"], "rivercal: nothing to report")]:
        ET.SubElement(root, _q("line"), level=str(int(line.level)), description=_clean_text(line.text))
    if comment:
        ET.SubElement(root, _q("comment")).text = _clean_text(comment)
    return _write(root, Path(path))


def _clean_text(text: Any) -> str:
    """Text XML 1.0 in UTF-8 can hold.

    Control characters other than tab and newline are dropped; lone surrogates (from file names that are not
    UTF-8) and the non-characters U+FFFE and U+FFFF become U+FFFD.
    """
    return "".join(ch if ch in "\t\n" or (32 <= ord(ch) < 0xD800) or (0xE000 <= ord(ch) < 0xFFFE) or ord(ch) > 0xFFFF
                   else "\ufffd" for ch in str(text) if ch in "\t\n" or ord(ch) >= 32)
