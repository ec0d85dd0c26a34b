"""The Delft-FEWS General Adapter module: one on-line cycle from a PI run file.

FEWS calls ``rivercal fews run_info.xml``; :func:`run_module` then

1. reads the run file (time zero, the files, the ``<properties>`` of :data:`PROPERTIES`);
2. checks, before anything is written: the state's locations (inside the work folder; an existing one a
   rivercal store, never another file), every output location (writable; an existing one a PI file of its
   kind), the case, the inputs, the properties and the times;
3. reads the PI time series FEWS exported: observations at the stations (locationId = station id,
   parameterId = ``h``, ``h_up``, ``h_down`` or ``Q``) go into the store, forcing at boundaries and
   laterals (locationId = boundary or lateral id, parameterId ``Q`` in m³/s, ``h`` in m) and structure
   settings (locationId = structure id, parameterId of :data:`SETTINGS`) replaces the case's own series
   where FEWS has values, unless implausible (:func:`_screen_forcing`). Missing values,
   flags and time zones as PI defines them (:func:`rivercal.io.read_pixml`); cm, mm, l/s, m3/h and m3/min
   converted. FEWS's id maps translate its own ids to these;
4. takes the state FEWS handed over — the rivercal store of the previous run (SQLite: estimates,
   alerts, forecasts, the model states of the hot start) — copies it to the state's write location,
   or starts a new one when FEWS exported no state;
5. runs one cycle of :class:`rivercal.online.OnlineService`: the calibration window ends at time zero,
   the forecasts (updated parameters, and the fixed DSS) start there, every ``timeStep``;
6. writes the PI time series (forecasts with qualifier ``updated`` or ``dss``; per parameter the
   estimate with flag 0 when accepted, 3 (doubtful) when held, the reason as the event's comment, its σ
   (qualifier ``sigma``) and the value the forecast used (qualifier ``used``), at location
   ``estimatesLocationId``), the PI state description, and the PI diagnostics file, each through a
   temporary file and a rename.

Every problem goes to the diagnostics file with level 1 (error) naming the file and the element, property
or series — 0 (fatal) for an error in rivercal itself — and a non-zero exit status (2 bad input, 3 failed
model run, 1 otherwise); never a traceback. Only rivercal's own bad-input errors count as bad input.
"""

from __future__ import annotations

import logging
import math
import shutil
import stat
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

import rivercal
from rivercal.errors import CaseError, FieldProblem, ModelRunError, OptionError, RivercalError
from rivercal.fews.pi import (
    DIAG_LEVELS,
    FIRST_TIME,
    LAST_TIME,
    DiagLine,
    RunFile,
    StateLocation,
    diagnostic_file_of,
    read_run_file,
    read_state_description,
    replace_atomically,
    write_diag,
    write_state_description,
)
from rivercal.fews.properties import PROPERTIES, AdapterError, duration, prop
from rivercal.io.pixml import (
    EXPECTED_UNITS,
    PI_NAMESPACE,
    STANDARD_CONVERSIONS,
    PiSeries,
    read_pixml,
    read_pixml_series,
    unit_factor,
    write_pixml_series,
)
from rivercal.network import MAX_DISCHARGE, MAX_LEVEL
from rivercal.observations import ObservationSet

if TYPE_CHECKING:
    from rivercal.models.contract import Model
    from rivercal.online.config import OnlineConfig
    from rivercal.online.service import CycleOutcome, OnlineService
    from rivercal.store import Run, Store

__all__ = ["PROPERTIES", "AdapterError", "FewsOutcome", "run_module"]

log = logging.getLogger(__name__)

_STATE_ID = "rivercal"
#: The longest diagnostics line, characters (a message quoting a huge value is cut).
_MAX_LINE = 2000
#: A discharge from FEWS may be at most this many times the largest of the case's own series at its boundary.
FORCING_SCALE = 100.0
#: ... and of the other sign by at most this fraction of that largest value, where the case's series keeps one sign.
FORCING_SIGN_TOLERANCE = 0.01
#: A level from FEWS may lie outside the range of the case's own series by max(this, twice that range), m.
FORCING_LEVEL_MARGIN_M = 5.0
_SQLITE_MAGIC = b"SQLite format 3\x00"


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


class _ToDiagnostics(logging.Handler):
    """rivercal's log warnings while the module runs become warning lines of the diagnostics."""

    def __init__(self, diag: Diagnostics):
        super().__init__(logging.WARNING)
        self.diag = diag

    def emit(self, record: logging.LogRecord) -> None:
        self.diag.add("warn", record.getMessage())


@dataclass(frozen=True)
class FewsOutcome:
    """What one module run did.

    Attributes
    ----------
    exit_code
        0 done; 2 bad input; 3 a model run failed; 1 anything else.
    diagnostics
        The lines written to the diagnostics file.
    diag_file
        Where they were written (None when the run file could not name it).
    summary
        JSON-friendly facts: cycle, issue time, status, estimates, files written.
    """

    exit_code: int
    diagnostics: tuple[DiagLine, ...]
    diag_file: Path | None
    summary: dict[str, Any]


#: The run-file property of each field of the on-line configuration that the module sets.
_PROPERTY_OF = {"parameters": "parameters", "window": "window", "period": "period", "horizon": "horizon",
                "warmup": "warmup", "algorithm": "algorithm", "deadline_s": "deadline", "max_change": "maxChange",
                "alert_k": "alertK", "workers": "workers"}


def _config(run: RunFile, model: Model) -> OnlineConfig:
    """The on-line service configuration from the properties, checked against the model.

    The checks are the configuration's own (:meth:`OnlineConfig.from_options
    <rivercal.online.config.OnlineConfig.from_options>`), as for the command line; a problem names the property.
    """
    from rivercal.online.config import OnlineConfig, OnlineConfigError

    values: dict[str, Any] = {field: prop(run, key) for field, key in _PROPERTY_OF.items() if field != "workers"}
    values["max_change"] = values["max_change"] or None
    values["output_interval_s"] = _time_step(run, model)
    try:
        return OnlineConfig.from_options(model, **values, workers=_workers(run))
    except OnlineConfigError as exc:
        key = _PROPERTY_OF.get(exc.field, exc.field)
        raise AdapterError(exc.describe(f"property {key!r}"), file=str(run.path), field="properties") from None


def _time_step(run: RunFile, model: Model) -> float:
    """The ``timeStep`` property, s: a positive duration, a whole multiple of the model's own time step."""
    text = duration(run, "timeStep")
    step = pd.Timedelta(text).total_seconds()
    dt = float(model.dt)
    if abs(step / dt - round(step / dt)) > 1e-9:
        low = max(1, math.floor(step / dt)) * dt
        raise AdapterError(f"property 'timeStep': {text!r} ({step:g} s) is not a whole multiple of the model's time "
                           f"step ({dt:g} s); e.g. {low:g} s or {low + dt:g} s", file=str(run.path),
                           field="properties")
    return step


def _workers(run: RunFile) -> int:
    """The ``workers`` property: a whole number from 1 to the cores this process may use."""
    from rivercal.evaluate import default_workers

    text, cores = prop(run, "workers"), default_workers()
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value == int(value) and 1 <= value <= cores):
        raise AdapterError(f"property 'workers': {text[:40]!r} must be a whole number from 1 to {cores} (the cores "
                           "available to rivercal on this machine)", file=str(run.path), field="properties")
    return int(value)


# -- inputs ---------------------------------------------------------------------------------------


def _case_source(run: RunFile) -> str:
    text = prop(run, "case")
    folder = Path(text) if Path(text).is_absolute() else run.work_dir / text
    return str(folder) if _what(folder) != "missing" else text


#: Structure settings FEWS may give, by parameterId (D-Flow FM's keywords, as ``rivercal import dhydro`` names the
#: columns of a case's ``settings.csv``): (network table, the structure's series field, forcing prefix, quantity).
#: A crest or gate level is in m (as ``h``), a pump capacity in m³/s (as ``Q``).
SETTINGS = {"crestLevel": ("weirs", "crest_series", "crest", "h"),
            "gateLowerEdgeLevel": ("orifices", "gate_series", "gate", "h"),
            "capacity": ("pumps", "capacity_series", "capacity", "Q")}
_SETTING_OF = {"weirs": "weir", "orifices": "orifice", "pumps": "pump"}


def _settable(network: Any) -> tuple[dict[tuple[str, str], str], dict[tuple[str, str], str]]:
    """The structure settings FEWS may give, and those it may not.

    Returns (structure id, parameterId) -> forcing key where the case has a series for the setting, and
    (structure id, parameterId) -> what the structure is (``weir``) where its setting is a constant.
    """
    series, constant = {}, {}
    for parameter, (table, name, prefix, _) in SETTINGS.items():
        for item in getattr(network, table):
            if getattr(item, name) is not None:
                series[(item.id, parameter)] = f"{prefix}:{item.id}"
            else:
                constant[(item.id, parameter)] = _SETTING_OF[table]
    return series, constant


def _classify(run: RunFile, case: Any, observables: list[str]) -> tuple[dict[Path, dict], dict[str, str]]:
    """Per input file the mapping (locationId, parameterId) -> series id; and forcing series id -> forcing key.

    Every series is checked here, all problems at once: a known location and parameter, a unit rivercal knows (a
    standard one is converted: cm, mm to m; l/s, m3/h, m3/min to m³/s), times rivercal can handle. A series is an
    observation when its location is a station that simulates the parameter; forcing when its location is a
    boundary or lateral (``h`` or ``Q``), or a structure whose setting follows a series in the case
    (:data:`SETTINGS`). A forcing series gets the id ``<forcing key>.<h or Q>`` (``lateral:L1.Q``), which no
    station's series has.
    """
    network = case.network
    stations = {s.id for s in network.stations}
    kinds = {b.id: ("boundary", b.type) for b in network.boundaries}
    kinds.update({lat.id: ("lateral", "discharge") for lat in network.laterals})
    settings, constant = _settable(network)
    mappings: dict[Path, dict] = {}
    forcing: dict[str, str] = {}
    problems: list[str] = []
    for path in run.input_series_files:
        mapping = {}
        for pi in read_pixml_series(path):
            where = f"{path}: {pi.label}"
            loc, par = pi.location_id, pi.parameter_id
            if (loc, par) in settings:
                key = settings[(loc, par)]
                quantity = SETTINGS[par][3]
            elif (loc, par) in constant:
                problems.append(f"{where}: the {constant[(loc, par)]} {loc} has a constant {par} in the case; only a "
                                f"structure whose {par} follows a series in the case takes one from FEWS (as the "
                                "import writes for a setting of real-time control)")
                continue
            elif loc in stations:
                if f"{loc}.{par}" not in observables:
                    own = [o.rpartition(".")[2] for o in observables if o.rpartition(".")[0] == loc]
                    takes = [p for (i, p) in [*settings, *constant] if i == loc]
                    problems.append(f"{where}: unknown parameter {par!r} at station {loc} (the model simulates "
                                    f"{', '.join(own)}" + (f"; the structure takes {', '.join(takes)}" if takes else "")
                                    + ")")
                    continue
                key, quantity = None, par
            elif loc in kinds:
                kind, btype = kinds[loc]
                expected = "h" if btype == "level" else "Q"
                if btype in ("rating", "critical") or par != expected:
                    problems.append(f"{where}: the {kind} {loc} ({btype}) takes "
                                    + ("no series" if btype in ("rating", "critical") else f"parameterId {expected!r}"))
                    continue
                key, quantity = f"{kind}:{loc}", expected
            else:
                structures = sorted({i for i, _ in [*settings, *constant]} - stations)
                problems.append(f"{where}: unknown location {loc!r}; the case has stations {_some(stations)}, "
                                f"boundaries and laterals {_some(kinds)}"
                                + (f" and structures {_some(structures)}" if structures else ""))
                continue
            if pi.units is not None and unit_factor(pi.units, quantity, STANDARD_CONVERSIONS) is None:
                unit = EXPECTED_UNITS[quantity]
                problems.append(f"{where}: unit {pi.units[:40]!r}, where parameterId {par} is in {unit}; "
                                "rivercal converts cm and mm to m, and l/s, m3/h and m3/min to m3/s; give the series "
                                "in one of these or let FEWS convert it on export (unit conversions of the General "
                                "Adapter's export)")
                continue
            if len(pi.times) and not (FIRST_TIME <= pi.times.min() and pi.times.max() <= LAST_TIME):
                odd = pi.times.min() if pi.times.min() < FIRST_TIME else pi.times.max()
                problems.append(f"{where}: an event at {odd:%Y-%m-%d %H:%M} UTC lies outside the years "
                                f"{FIRST_TIME.year}-{LAST_TIME.year} that rivercal handles")
                continue
            series_id = f"{loc}.{par}" if key is None else f"{key}.{quantity}"
            if key is not None:
                forcing[series_id] = key
            mapping[(loc, par)] = series_id
        mappings[path] = mapping
    if problems:
        more = f" (and {len(problems) - 5} more)" if len(problems) > 5 else ""
        raise AdapterError("; ".join(problems[:5]) + more, file=str(run.path), field="inputTimeSeriesFile")
    return mappings, forcing


def _some(ids: Any, shown: int = 8) -> str:
    """Up to ``shown`` ids (sorted) and how many more: an imported model has hundreds of stations."""
    ids = sorted(ids)
    more = f" ... ({len(ids) - shown} more)" if len(ids) > shown else ""
    return (", ".join(ids[:shown]) or "none") + more


@dataclass(frozen=True)
class _Forcing:
    """A forcing series FEWS exported: the case's key (``boundary:ID``), values (m³/s or m, UTC), its source."""

    key: str
    quantity: str
    series: pd.Series
    source: str


def _inputs(run: RunFile, case: Any, observables: list[str],
            diag: Diagnostics) -> tuple[list[tuple[str, Any]], list[_Forcing]]:
    """Observation sets by file (source name) and the forcing series FEWS exported (m³/s or m, UTC)."""
    for path in run.input_series_files:
        what = _what(path)
        if what != "file":
            raise AdapterError(f"input time-series file {path} {_WHAT[what] if what in _WHAT else what}",
                               file=str(run.path), field="inputTimeSeriesFile")
    mappings, forcing_ids = _classify(run, case, observables)
    observations: list[tuple[str, Any]] = []
    forcing: list[_Forcing] = []
    for path, mapping in mappings.items():
        if not mapping:
            continue
        obs = read_pixml(path, mapping, unmapped="error", conversions=STANDARD_CONVERSIONS)
        kept = [s for s in obs if s.id not in forcing_ids]
        exported = {series_id: pair for pair, series_id in mapping.items()}
        for s in obs:
            if s.id not in forcing_ids:
                continue
            loc, par = exported[s.id]
            source = f"{path}: series locationId={loc} parameterId={par}"
            if s.n_missing:
                diag.add("info", f"{source}: {s.n_missing} missing or unreliable forcing values dropped")
            if len(s):
                forcing.append(_Forcing(forcing_ids[s.id], s.quantity, pd.Series(s.values, index=s.times), source))
            else:
                diag.add("warn", f"{source}: no usable value; the case's own {forcing_ids[s.id]} is used")
        if kept:
            observations.append((f"fews:{path.name}", ObservationSet(tuple(kept))))
    return observations, forcing


def _own_forcing(case: Any) -> tuple[dict[str, pd.Series], dict[str, pd.Series]]:
    """The runoff of the case's catchments, and all its own forcing series with that runoff (m³/s or m, UTC)."""
    from rivercal.hydrology.catchments import catchment_forcing

    runoff = catchment_forcing(case)
    return runoff, {**case.forcing, **runoff}


def _reference_scales(case: Any, own: Mapping[str, pd.Series]) -> dict[str, float]:
    """The magnitude (m³/s) below which a discharge at each lateral or pump is never called implausible.

    A lateral: the largest discharge of any of the case's laterals. An imported model's lateral series are one
    run's (a coupled week of a rainfall-runoff model): the same lateral's largest value there may be a
    thousandth of what the next shower brings (in the Dellen model, half of the laterals vary more than
    76-fold within its own week, and one in four more than 1600-fold). A pump: its capacity in the case, which
    real-time control may have kept at zero for the whole of the case's own series.
    """
    lateral_keys = [key for key in own if key.startswith("lateral:")]
    largest = max((float(np.nanmax(np.abs(own[key].to_numpy(dtype=float)))) for key in lateral_keys
                   if own[key].notna().any()), default=0.0)
    scales = dict.fromkeys(lateral_keys, largest)
    scales.update({f"lateral:{lat.id}": largest for lat in case.network.laterals})
    scales.update({f"capacity:{p.id}": float(p.capacity) for p in case.network.pumps})
    return scales


def _screen_forcing(forcing: list[_Forcing], own: Mapping[str, pd.Series], run: RunFile,
                    scales: Mapping[str, float] | None = None) -> None:
    """Refuse forcing FEWS exported that cannot be meant: far outside what the case itself has there.

    FEWS's values replace the case's own. A discharge more than :data:`FORCING_SCALE` times the largest of the
    case's own series there (at a lateral or pump, at least its ``scales`` value: :func:`_reference_scales`), or
    at a discharge boundary of the other sign where the case's series never changes sign (beyond
    :data:`FORCING_SIGN_TOLERANCE` of that largest value), or a negative pump capacity, is a unit or
    sign-convention error (l/s for m³/s, outflow counted positive), not a forecast; so is a level (a level
    boundary, a crest or a gate) more than max(:data:`FORCING_LEVEL_MARGIN_M`, twice the range of the case's own
    levels) outside that range. A lateral may take either sign (drainage and extraction, evaporation in a
    rainfall-runoff model's output). Either is an error naming the file, the series and the first such value.
    """
    scales = scales or {}
    for f in forcing:
        values = f.series.to_numpy(dtype=float)
        level = f.quantity == "h"
        unit = "m" if level else "m³/s"
        kind = f.key.partition(":")[0]
        ref = own.get(f.key)
        ref_values = ref.to_numpy(dtype=float) if ref is not None else np.array([])
        ref_values = ref_values[np.isfinite(ref_values)]
        if not ref_values.size:
            low, high = (-MAX_LEVEL, MAX_LEVEL) if level else (-MAX_DISCHARGE, MAX_DISCHARGE)
            why = f"the largest magnitude rivercal accepts for a {'level' if level else 'discharge'}"
        elif level:
            a, b = float(ref_values.min()), float(ref_values.max())
            margin = max(FORCING_LEVEL_MARGIN_M, 2.0 * (b - a))
            low, high = max(a - margin, -MAX_LEVEL), min(b + margin, MAX_LEVEL)
            why = (f"the case's own levels there span {a:.3g} .. {b:.3g} m; a level this far outside is a datum or "
                   "unit error")
        else:
            a, b = float(ref_values.min()), float(ref_values.max())
            floor = float(scales.get(f.key, 0.0))
            largest = max(abs(a), abs(b), floor)
            scale = FORCING_SCALE * largest if largest > 0 else 1.0
            tolerance = FORCING_SIGN_TOLERANCE * largest
            if kind == "boundary":
                low = -tolerance if a >= 0 else -scale
                high = tolerance if b <= 0 else scale
            else:
                low, high = (0.0 if kind == "capacity" else -scale), scale
            low, high = max(low, -MAX_DISCHARGE), min(high, MAX_DISCHARGE)
            own_words = f"the case's own series there spans {a:.3g} .. {b:.3g} m³/s"
            if kind == "lateral":
                own_words += f", its laterals reach {floor:.3g} m³/s"
            elif kind == "capacity":
                own_words += f", the pump's capacity is {floor:.3g} m³/s"
            why = (f"{own_words}; a discharge {FORCING_SCALE:g} times larger"
                   + (", or of the other sign," if kind == "boundary" else
                      ", or a negative capacity," if kind == "capacity" else "")
                   + " is a unit or sign-convention error")
        bad = np.flatnonzero((values < low) | (values > high))
        if bad.size:
            i = int(bad[0])
            raise AdapterError(f"{f.source}: forcing {values[i]:.6g} {unit} at {f.series.index[i]:%Y-%m-%d %H:%M} UTC "
                               f"({bad.size} such values) lies outside the plausible range {low:.4g} .. {high:.4g} "
                               f"{unit} for {f.key} ({why})", file=str(run.path), field="inputTimeSeriesFile")


def _model(run: RunFile, case: Any, runoff: Mapping[str, pd.Series], own: Mapping[str, pd.Series],
           forcing: list[_Forcing]) -> Any:
    """The case's model with FEWS's forcing in place of the case's own where FEWS has values."""
    from rivercal.models import EmbeddedModel

    grouped: dict[str, list[pd.Series]] = {}
    for f in forcing:
        grouped.setdefault(f.key, []).append(f.series)
    merged = {}
    for key, parts in grouped.items():
        series = pd.concat(parts).sort_index()
        if series.index.has_duplicates:
            first = series.index[series.index.duplicated()][0]
            raise AdapterError(f"forcing {key}: time {first:%Y-%m-%d %H:%M} UTC occurs in more than one exported "
                               "series", file=str(run.path), field="inputTimeSeriesFile")
        mine = own.get(key)
        if mine is None:
            merged[key] = series
        else:
            mine = mine[(mine.index < series.index[0]) | (mine.index > series.index[-1])]
            merged[key] = pd.concat([mine, series]).sort_index()
    return EmbeddedModel(case, forcing={**runoff, **merged})


# -- state ----------------------------------------------------------------------------------------


def _inside_work(path: Path, run: RunFile, file: Path, field: str) -> Path:
    """``path`` (symbolic links followed), refused unless it lies inside the module's work folder."""
    try:
        resolved, work = path.resolve(), run.work_dir.resolve()
    except (OSError, RuntimeError) as exc:  # a loop of symbolic links
        raise AdapterError(f"state location {path} cannot be resolved ({exc})", file=str(file), field=field) from None
    if resolved == work:
        raise AdapterError(f"state location {path} is the module's work folder itself; rivercal's state is one file in "
                           "it", file=str(file), field=field)
    if not resolved.is_relative_to(work):
        raise AdapterError(f"state location {path} lies outside the module's work folder {work}; rivercal reads and "
                           "writes its state only inside the work folder (the run file's workDir)", file=str(file),
                           field=field)
    return resolved


def _is_store(path: Path) -> bool:
    """Whether a regular file starts as a rivercal store does (SQLite header, rivercal's application id)."""
    from rivercal.store.schema import APPLICATION_ID

    with path.open("rb") as f:
        head = f.read(100)
    return len(head) == 100 and head.startswith(_SQLITE_MAGIC) and int.from_bytes(head[68:72], "big") == APPLICATION_ID


def _check_store(path: Path, file: Path, field: str, role: str) -> None:
    """Refuse ``path`` unless it is a regular file holding a rivercal store (read, never written)."""
    what = _what(path)
    if what != "file":
        raise AdapterError(f"{role} {path} {_WHAT.get(what, what)}", file=str(file), field=field)
    try:
        ok = _is_store(path)
    except OSError as exc:
        raise AdapterError(f"{role} {path} cannot be read ({exc.strerror or exc})", file=str(file),
                           field=field) from None
    if not ok:
        raise AdapterError(f"{role} {path} is not a rivercal store (an SQLite file that rivercal wrote); rivercal "
                           "neither reads nor replaces any other file", file=str(file), field=field)


#: How messages say what :func:`_what` found.
_WHAT = {"missing": "does not exist", "not a file": "exists but is not a file"}


def _what(path: Path) -> str:
    """``file``, ``missing``, ``not a file`` (a folder, a FIFO, a device), or why ``path`` cannot be used."""
    try:
        mode = path.stat().st_mode
    except (FileNotFoundError, NotADirectoryError):
        try:
            return "is a symbolic link to nothing" if path.is_symlink() else "missing"
        except OSError as exc:
            return f"cannot be used ({exc.strerror or exc})"
    except (OSError, ValueError) as exc:  # a loop of links, a name too long, no permission
        return f"cannot be used ({getattr(exc, 'strerror', None) or exc})"
    return "file" if stat.S_ISREG(mode) else "not a file"


def _exists(path: Path) -> bool:
    return _what(path) != "missing"


def _state_locations(run: RunFile) -> tuple[Path | None, StateLocation]:
    """(the state file FEWS handed over or None, where this run writes the state), both checked.

    Both lie inside the work folder; each that exists is a rivercal store. Nothing is opened for writing here.
    """
    if len(run.input_state_files) > 1:
        raise AdapterError(f"{len(run.input_state_files)} state descriptions; rivercal's state is one file, described "
                           "once", file=str(run.path), field="inputStateDescriptionFile")
    for description in run.input_state_files:
        what = _what(description)
        if what != "file":
            raise AdapterError(f"input state description {description} {_WHAT.get(what, what)}", file=str(run.path),
                               field="inputStateDescriptionFile")
        _, locations = read_state_description(description, run.work_dir)
        if len(locations) > 1:
            raise AdapterError(f"{len(locations)} state locations; rivercal's state is one file", file=str(description),
                               field="stateLoc")
        loc = locations[0]
        if loc.type != "file":
            raise AdapterError(f"state location {loc.read} is a {loc.type}; rivercal's state is one file",
                               file=str(description), field="stateLoc")
        read = _inside_work(loc.read, run, description, "stateLoc/readLocation")
        write = _inside_work(loc.write, run, description, "stateLoc/writeLocation")
        if _exists(loc.read):
            _check_store(loc.read, description, "stateLoc/readLocation", "the state handed over")
        if write != read and _exists(loc.write):
            _check_store(loc.write, description, "stateLoc/writeLocation", "the state's write location")
        return (loc.read if _exists(loc.read) else None), loc
    text = prop(run, "stateFile")
    default = run.work_dir / text
    _inside_work(default, run, run.path, "properties/stateFile")
    if _exists(default):
        _check_store(default, run.path, "properties/stateFile", "the state file")
    return (default if _exists(default) else None), StateLocation(default, default)


def _open_state(handed: Path | None, loc: StateLocation, diag: Diagnostics) -> Path:
    """Copy the handed-over store to the write location (a new store when there is none); both checked before."""
    loc.write.parent.mkdir(parents=True, exist_ok=True)
    sidecars = [Path(f"{loc.write}{suffix}") for suffix in ("-wal", "-shm")]
    if handed is None:
        for path in [loc.write, *sidecars]:  # an earlier store there (checked): FEWS asked for a cold start
            path.unlink(missing_ok=True)
        diag.add("info", f"no state handed over: a new state (store) at {loc.write}; the model starts cold")
    elif handed.resolve() != loc.write.resolve():
        for path in sidecars:  # the journal of an earlier store there must not meet the copy
            path.unlink(missing_ok=True)
        replace_atomically(loc.write, lambda part: shutil.copyfile(handed, part))
    return loc.write


def _check_outputs(run: RunFile, loc: StateLocation) -> None:
    """Before anything is written: every output location can be written and replaces no file of another kind.

    An existing output file must be a PI file of its kind (the output of an earlier run) or empty; no output may
    be an input, the state, or another output.
    """
    outputs = [("outputDiagnosticFile", run.output_diagnostic_file, "Diag")]
    if run.output_state_file is not None:
        outputs.append(("outputStateDescriptionFile", run.output_state_file, "State"))
    outputs += [("outputTimeSeriesFile", f, "TimeSeries") for f in run.output_series_files[:2]]
    taken = {_resolved(p): what for p, what in [(run.path, "the run file"), (loc.read, "the state handed over"),
                                               (loc.write, "the state's write location"),
                                               *[(p, "an input state description") for p in run.input_state_files],
                                               *[(p, "an input time-series file") for p in run.input_series_files]]}
    for tag, path, root in outputs:
        key = _resolved(path)
        if key in taken:
            raise AdapterError(f"{path} is also {taken[key]}", file=str(run.path), field=tag)
        taken[key] = f"the {tag}"
        problem = _output_problem(path, root)
        if problem:
            raise AdapterError(problem, file=str(run.path), field=tag)


def _output_problem(path: Path, root: str) -> str | None:
    """Why the PI file ``path`` (root element ``root``) cannot be written, or None; creates the folder of a new one."""
    try:
        what = _what(path)
        if what != "missing":
            if what != "file":
                return f"{path} {_WHAT.get(what, what)}"
            if not _is_pi(path, root):
                return (f"{path} exists and is not a PI <{root}> file; rivercal replaces only the output of an earlier "
                        "run")
            with path.open("ab"):
                pass
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            with path.open("xb"):
                pass
            path.unlink()
    except OSError as exc:
        return f"{path} cannot be written ({exc.strerror or exc})"
    return None


def _resolved(path: Path) -> Path:
    try:
        return path.resolve()
    except (OSError, RuntimeError):
        return path.absolute()


def _is_pi(path: Path, root: str) -> bool:
    """Whether a file is empty or its root element is the PI element ``root`` (only its start is read)."""
    import defusedxml
    import defusedxml.ElementTree as SafeET

    with path.open("rb") as f:  # not the size: files of /proc say 0 and are not empty
        if not f.read(1):
            return True
    try:
        for _, element in SafeET.iterparse(str(path), events=("start",), forbid_dtd=True):
            return bool(element.tag == f"{{{PI_NAMESPACE}}}{root}")
    except (SafeET.ParseError, defusedxml.DefusedXmlException, OSError, UnicodeError):
        return False
    return False


# -- outputs --------------------------------------------------------------------------------------


def _forecast_series(store: Store, run: Run, cycle: int) -> list[PiSeries]:
    fc = store.forecasts(run, cycle=cycle)
    out = []
    for (kind, series_id), part in fc.groupby(["kind", "series"], sort=True):
        station, _, quantity = str(series_id).rpartition(".")
        values = part["value"].to_numpy(float)
        out.append(PiSeries(station, quantity, (str(kind),), "instantaneous", EXPECTED_UNITS.get(quantity, "-"),
                            math.nan, pd.DatetimeIndex(part["time"]), values, np.zeros(len(values), dtype=int)))
    return out


def _estimate_series(store: Store, run: Run, cycle: int, used: Mapping[str, float], location: str,
                     t0: pd.Timestamp) -> list[PiSeries]:
    est = store.estimates(run)
    est = est[est["cycle"] == cycle]
    times = pd.DatetimeIndex([t0])
    out = []
    for r in est.itertuples():
        held = not r.accepted
        out.append(PiSeries(location, r.parameter, (), "instantaneous", r.unit, math.nan, times,
                            np.array([r.value]), np.array([3 if held else 0]), ((r.reason or "") if held else "",)))
        std = float(r.std) if r.std is not None and math.isfinite(r.std) else math.nan
        out.append(PiSeries(location, r.parameter, ("sigma",), "instantaneous", r.unit, math.nan, times,
                            np.array([std]), np.array([0 if math.isfinite(std) else -1])))
        out.append(PiSeries(location, r.parameter, ("used",), "instantaneous", r.unit, math.nan, times,
                            np.array([float(used[r.parameter])]), np.array([0])))
    return out


# -- the module -----------------------------------------------------------------------------------


def _check_times(run: RunFile, model: Model, config: OnlineConfig) -> None:
    """time0 and the durations fit the case's period and the forecasts' time step (seconds: no overflow).

    The service runs the model from ``time0 - window - warmup``, takes the state for the next run's hot start
    one ``period`` later, and forecasts ``horizon`` ahead, all on the grid of the forecasts' time step from the
    case's start.
    """
    t0 = run.time0
    step = float(config.output_interval_s)
    seconds = {key: pd.Timedelta(getattr(config, key)).total_seconds() for key in ("window", "warmup", "horizon",
                                                                                   "period")}
    for key, value in seconds.items():
        if abs(value / step - round(value / step)) > 1e-9:
            raise AdapterError(f"property {key!r}: {getattr(config, key)!r} is not a whole number of the forecasts' "
                               f"time step ({step:g} s)", file=str(run.path), field="properties")
    if seconds["period"] > seconds["window"] + seconds["warmup"]:
        raise AdapterError(f"property 'period': {config.period!r} is longer than the window and warm-up "
                           f"({config.window} + {config.warmup}); the next run's hot start is taken one period after "
                           "this run's warm-up starts, so it must lie before time0", file=str(run.path),
                           field="properties")
    after_start, before_end = t0.timestamp() - model.start.timestamp(), model.end.timestamp() - t0.timestamp()
    if seconds["window"] + seconds["warmup"] > after_start:
        raise AdapterError(f"time0 {t0:%Y-%m-%d %H:%M} UTC: the window ({config.window}) and warm-up "
                           f"({config.warmup}) before it need the model from before the case starts "
                           f"({model.start:%Y-%m-%d %H:%M} UTC)", file=str(run.path), field="time0")
    if seconds["horizon"] > before_end:
        raise AdapterError(f"time0 {t0:%Y-%m-%d %H:%M} UTC: the forecast ({config.horizon}) runs past the end of the "
                           f"case ({model.end:%Y-%m-%d %H:%M} UTC)", file=str(run.path), field="time0")
    if abs(after_start / step - round(after_start / step)) > 1e-9:
        raise AdapterError(f"time0 {t0:%Y-%m-%d %H:%M:%S} UTC is not on the forecasts' time step ({step:g} s from the "
                           f"case's start, {model.start:%Y-%m-%d %H:%M} UTC); check the run file's timeZone "
                           f"({run.time_zone:+g} h)", file=str(run.path), field="time0")


def _schemas(run: RunFile) -> dict[str, Any]:
    """The PI schemas of ``piSchemaDir`` (relative to the work folder) by file name; none without the property."""
    text = prop(run, "piSchemaDir")
    if not text:
        return {}
    try:
        import xmlschema
    except ImportError:
        raise AdapterError("property 'piSchemaDir' needs the xmlschema package (pip install 'rivercal[fews]')",
                           file=str(run.path), field="properties") from None
    folder = run.work_dir / text
    schemas = {}
    for name in ("pi_timeseries.xsd", "pi_state.xsd"):
        path = folder / name
        if not path.is_file():
            raise AdapterError(f"property 'piSchemaDir': no {name} in {folder}", file=str(run.path), field="properties")
        try:
            schemas[name] = xmlschema.XMLSchema(str(path))
        except Exception as exc:  # xmlschema raises many kinds for a file that is no schema
            raise AdapterError(f"property 'piSchemaDir': {path} is not a usable XML schema ({type(exc).__name__}: "
                               f"{str(exc)[:300]})", file=str(run.path), field="properties") from None
    return schemas


def _cycle(run: RunFile, diag: Diagnostics) -> dict[str, Any]:
    """Everything between reading the run file and writing the diagnostics; raises on a problem.

    Everything that can be checked is checked before the state is touched: the state locations, every output
    location, the case, the inputs, the properties and the times.
    """
    from rivercal.case import load_case
    from rivercal.online.service import OnlineService
    from rivercal.store import Store, StoreError

    t_start = time.perf_counter()
    handed, loc = _state_locations(run)
    _check_outputs(run, loc)
    for tag, text in run.unread:
        diag.add("warn", f"{run.path}: {tag} {text}: rivercal {'writes' if tag.startswith('output') else 'reads'} "
                         "no such file; ignored")
    for key in sorted(set(run.properties) - set(PROPERTIES)):
        diag.add("warn", f"{run.path}: property {key!r} is not one rivercal reads; ignored (it reads "
                         f"{', '.join(PROPERTIES)})")
    case = load_case(_case_source(run))
    diag.add("info", f"rivercal {rivercal.__version__}: case {case.name}, time0 {run.time0:%Y-%m-%d %H:%M} UTC")
    observables = _observables(case)
    observations, forcing = _inputs(run, case, observables, diag)
    runoff, own = _own_forcing(case)
    _screen_forcing(forcing, own, run, _reference_scales(case, own))
    model = _model(run, case, runoff, own, forcing)
    config = _config(run, model)
    _check_times(run, model, config)
    schemas = _schemas(run)
    if forcing:
        diag.add("info", _forcing_line(forcing))
    db = _open_state(handed, loc, diag)
    name = prop(run, "run")
    try:
        store_cm = Store(db)
    except StoreError as exc:
        raise AdapterError(f"the state cannot be used as a rivercal store: {exc}", file=str(db),
                           field="state") from None
    with store_cm as store:
        for source, obs in observations:
            result = store.ingest(obs, source=source, on_conflict="replace")
            diag.add("info", f"{source}: {result.inserted} new observations ({obs.n_missing} missing or unreliable "
                             "values dropped)")
        stored = store.get_run(name)
        first = stored.config.get("first_issue") if stored is not None else None
        try:
            service = OnlineService(model, store, name, config, first or run.time0)
        except ValueError as exc:
            raise AdapterError(str(exc), file=str(run.path), field="properties") from None
        try:
            spec = service.cycle_at(run.time0)  # the service's own choice of the cycle, as in a replay
        except ValueError as exc:
            text = str(exc)
            if text.startswith("no observations"):
                raise AdapterError(f"{text} (neither in the exported time series nor in the state)",
                                   file=str(run.path), field="inputTimeSeriesFile") from None
            if "unfinished" in text:
                raise AdapterError(text, file=str(db), field="state") from None
            raise AdapterError(f"time0: {text}; FEWS must hand over an older state, or use another run name",
                               file=str(run.path), field="time0") from None
        outcome = service.run_cycle(spec)
        _report_cycle(outcome, service, diag)
        files = _write_outputs(run, store, service, outcome, case.name)
    if run.output_state_file is not None:
        write_state_description(run.output_state_file, _STATE_ID, run.time0, [loc], time_zone=run.time_zone,
                                name=f"rivercal store of run {name}", comment=f"forecast {outcome.cycle}")
        files.append(str(run.output_state_file))
    _check_schemas(run, schemas, [Path(f) for f in files], diag)
    diag.add("info", f"done in {time.perf_counter() - t_start:.1f} s")
    return {"cycle": outcome.cycle, "issue_time": run.time0.isoformat(), "status": outcome.status,
            "estimates": outcome.estimates, "accepted": outcome.accepted, "held": outcome.held,
            "model_runs": outcome.model_runs, "state": str(db), "files": files}


def _forcing_line(forcing: list[_Forcing], shown: int = 8) -> str:
    """What FEWS's forcing replaced: every key, or (an imported model has a hundred laterals) counts by kind."""
    keys = sorted({f.key for f in forcing})
    if len(keys) <= shown:
        return f"forcing from FEWS at {', '.join(keys)}"
    kinds: dict[str, list[str]] = {}
    for key in keys:
        kind, _, ident = key.partition(":")
        kinds.setdefault(kind, []).append(ident)
    parts = [f"{len(ids)} {kind} series ({', '.join(ids[:3])}{', ...' if len(ids) > 3 else ''})"
             for kind, ids in kinds.items()]
    return f"forcing from FEWS at {len(keys)} places: {'; '.join(parts)}"


def _check_schemas(run: RunFile, schemas: Mapping[str, Any], files: list[Path], diag: Diagnostics) -> None:
    """Check the written PI files against the schemas of ``piSchemaDir`` (if given); a problem is an error."""
    if not schemas:
        return
    for path in files:
        name = "pi_state.xsd" if path == run.output_state_file else "pi_timeseries.xsd"
        errors = [f"{e.path}: {e.reason}" for e in schemas[name].iter_errors(str(path))]
        if errors:
            raise RivercalError(f"{path} does not validate against {name}: {errors[0]}")
    diag.add("info", f"{len(files)} written files validate against the PI schemas in {prop(run, 'piSchemaDir')}")


def _observables(case: Any) -> list[str]:
    """The series the case's model simulates (its stations' observables), without compiling it."""
    return [o for s in case.network.stations for o in s.observables]


def _report_cycle(outcome: CycleOutcome, service: OnlineService, diag: Diagnostics) -> None:
    units = {p.name: p.unit for p in service.parameters}
    diag.add("info", f"forecast {outcome.cycle} issued at {outcome.issue_time:%Y-%m-%d %H:%M} UTC: {outcome.status}, "
                     f"{outcome.model_runs} model runs, {outcome.wall_s:.1f} s"
                     + ("" if outcome.hot_start else ", cold start (no usable model state at the window's start)"))
    for name, value in outcome.accepted.items():
        std = outcome.std.get(name)
        sigma = f" ± {std:.3g}" if std is not None and math.isfinite(std) else ""
        if name in outcome.held:
            diag.add("warn", f"{name}: estimate {outcome.estimates[name]:.4g}{sigma} {units[name]} held; the forecast "
                             f"uses {value:.4g} {units[name]}: {outcome.held[name]}")
        else:
            diag.add("info", f"{name} = {value:.4g}{sigma} {units[name]} (accepted)")
    if outcome.status in ("failed", "aborted"):
        diag.add("warn", f"the calibration {outcome.status} ({outcome.message}); the forecast uses the last accepted "
                         "estimates")
    for alert in outcome.alerts:
        diag.add("warn", f"alert ({alert.kind}): {alert.message}")


def _write_outputs(run: RunFile, store: Store, service: OnlineService, outcome: CycleOutcome,
                   case_name: str) -> list[str]:
    files = list(run.output_series_files)
    if not files:
        return []
    location = prop(run, "estimatesLocationId") or case_name
    forecasts = _forecast_series(store, service.run, outcome.cycle)
    estimates = _estimate_series(store, service.run, outcome.cycle, outcome.accepted, location, outcome.issue_time)
    parts = [forecasts + estimates] if len(files) == 1 else [forecasts, estimates]
    for path, series in zip(files, parts, strict=False):
        path.parent.mkdir(parents=True, exist_ok=True)
        replace_atomically(path, lambda part, series=series: write_pixml_series(
            part, series, time_zone=run.time_zone, forecast_date=run.time0))
    for extra in files[2:]:
        log.warning("outputTimeSeriesFile %s: rivercal writes forecasts to the first and estimates to the second "
                    "file only", extra)
    return [str(f) for f in files[:2]]


#: Errors that are bad input: a file, a field, a property or an option named in the message.
_BAD_INPUT = (CaseError, FieldProblem, OptionError)


def run_module(run_file: str | Path) -> FewsOutcome:
    """Run the module on a PI run file; never raises (see the module docstring).

    Returns
    -------
    FewsOutcome
        The exit status, the diagnostics lines and where they were written, and a summary.
    """
    diag = Diagnostics()
    handler = _ToDiagnostics(diag)
    logger = logging.getLogger("rivercal")
    logger.addHandler(handler)
    summary: dict[str, Any] = {}
    code = 0
    run: RunFile | None = None
    try:
        run = read_run_file(run_file)
        summary = _cycle(run, diag)
    except ModelRunError as exc:
        diag.add("error", f"a model run failed: {exc}")
        code = 3
    except _BAD_INPUT as exc:  # a file, a property, a series, the state
        diag.add("error", str(exc))
        code = 2
    except RivercalError as exc:
        diag.add("error", str(exc))
        code = 1
    except OSError as exc:
        diag.add("error", f"{exc.filename or ''}: {exc.strerror or exc}".lstrip(": "))
        code = 1
    except Exception as exc:  # an error in rivercal itself: fatal, with its type, never a traceback
        log.debug("internal error", exc_info=True)
        diag.add("fatal", f"internal error in rivercal: {type(exc).__name__}: {exc} (please report it)")
        code = 1
    finally:
        logger.removeHandler(handler)
    if code == 0 and diag.worst <= DIAG_LEVELS["error"]:
        code = 1
    target = run.output_diagnostic_file if run is not None else diagnostic_file_of(run_file)
    if target is not None:
        problem = _output_problem(target, "Diag")
        if problem is None:
            try:
                write_diag(target, diag.lines)
            except OSError as exc:
                problem = f"cannot write the diagnostics file {target}: {exc.strerror or exc}"
        if problem is not None:
            if not any(problem in line.text for line in diag.lines):
                diag.add("error", f"outputDiagnosticFile: {problem}")
            target, code = None, code or 2
    return FewsOutcome(code, tuple(diag.lines), target, summary)
