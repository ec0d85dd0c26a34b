"""The Delft-FEWS module's inputs: the PI time series FEWS exported, sorted into observations and forcing.

An observation is a series at a station that simulates its parameter; forcing is a series at a boundary or
lateral, or a structure setting that follows a series in the case (:data:`SETTINGS`). Forcing replaces the
case's own series where FEWS has values, unless it is implausible (:func:`screen_forcing`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from rivercal.fews._files import PATH_KIND_WORDS, path_kind
from rivercal.fews.pi import FIRST_TIME, LAST_TIME, Diagnostics, RunFile
from rivercal.fews.properties import AdapterError, prop
from rivercal.io.pixml import EXPECTED_UNITS, STANDARD_CONVERSIONS, read_pixml, read_pixml_series, unit_factor
from rivercal.network import MAX_DISCHARGE, MAX_LEVEL
from rivercal.observations import ObservationSet

if TYPE_CHECKING:
    from rivercal.case import Case
    from rivercal.network import Network

#: A discharge from FEWS may be at most this many times the largest of the case's own series at its boundary.
FORCING_SCALE = 100.0
#: ... and of the other sign by at most this fraction of that largest value, where the case's series keeps one sign.
FORCING_SIGN_TOLERANCE = 0.01
#: A level from FEWS may lie outside the range of the case's own series by max(this, twice that range), m.
FORCING_LEVEL_MARGIN_M = 5.0


def case_source(run: RunFile) -> str:
    text = prop(run, "case")
    folder = Path(text) if Path(text).is_absolute() else run.work_dir / text
    return str(folder) if path_kind(folder) != "missing" else text


#: Structure settings FEWS may give, by parameterId (D-Flow FM's keywords, as ``rivercal import dhydro`` names the
#: columns of a case's ``settings.csv``): (network table, the structure's series field, forcing prefix, quantity).
#: A crest or gate level is in m (as ``h``), a pump capacity in m³/s (as ``Q``).
SETTINGS = {"crestLevel": ("weirs", "crest_series", "crest", "h"),
            "gateLowerEdgeLevel": ("orifices", "gate_series", "gate", "h"),
            "capacity": ("pumps", "capacity_series", "capacity", "Q")}
_SETTING_OF = {"weirs": "weir", "orifices": "orifice", "pumps": "pump"}


def _settable(network: Network) -> tuple[dict[tuple[str, str], str], dict[tuple[str, str], str]]:
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


def _classify(run: RunFile, case: Case, observables: list[str]) -> tuple[dict[Path, dict], dict[str, str]]:
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
class Forcing:
    """A forcing series FEWS exported: the case's key (``boundary:ID``), values (m³/s or m, UTC), its source."""

    key: str
    quantity: str
    series: pd.Series
    source: str


def read_inputs(run: RunFile, case: Case, observables: list[str],
            diag: Diagnostics) -> tuple[list[tuple[str, Any]], list[Forcing]]:
    """Observation sets by file (source name) and the forcing series FEWS exported (m³/s or m, UTC)."""
    for path in run.input_series_files:
        what = path_kind(path)
        if what != "file":
            raise AdapterError(f"input time-series file {path} {PATH_KIND_WORDS.get(what, what)}",
                               file=str(run.path), field="inputTimeSeriesFile")
    mappings, forcing_ids = _classify(run, case, observables)
    observations: list[tuple[str, Any]] = []
    forcing: list[Forcing] = []
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
                forcing.append(Forcing(forcing_ids[s.id], s.quantity, pd.Series(s.values, index=s.times), source))
            else:
                diag.add("warn", f"{source}: no usable value; the case's own {forcing_ids[s.id]} is used")
        if kept:
            observations.append((f"fews:{path.name}", ObservationSet(tuple(kept))))
    return observations, forcing


def own_forcing(case: Case) -> tuple[dict[str, pd.Series], dict[str, pd.Series]]:
    """The runoff of the case's catchments, and all its own forcing series with that runoff (m³/s or m, UTC)."""
    from rivercal.hydrology.catchments import catchment_forcing

    runoff = catchment_forcing(case)
    return runoff, {**case.forcing, **runoff}


def reference_scales(case: Case, own: Mapping[str, pd.Series]) -> dict[str, float]:
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


def screen_forcing(forcing: list[Forcing], own: Mapping[str, pd.Series], run: RunFile,
                    scales: Mapping[str, float] | None = None) -> None:
    """Refuse forcing FEWS exported that cannot be meant: far outside what the case itself has there.

    FEWS's values replace the case's own. A discharge more than :data:`FORCING_SCALE` times the largest of the
    case's own series there (at a lateral or pump, at least its ``scales`` value: :func:`reference_scales`), or
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


def model_with_forcing(run: RunFile, case: Case, runoff: Mapping[str, pd.Series], own: Mapping[str, pd.Series],
           forcing: list[Forcing]) -> Any:
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


def forcing_line(forcing: list[Forcing], shown: int = 8) -> str:
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


def case_observables(case: Case) -> list[str]:
    """The series the case's model simulates (its stations' observables), without compiling it."""
    return [o for s in case.network.stations for o in s.observables]
