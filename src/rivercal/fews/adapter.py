"""The Delft-FEWS General Adapter module: one on-line cycle from a PI run file.

FEWS calls ``rivercal fews run_info.xml``; :func:`run_module` then

1. reads the run file (time zero, the files, the ``<properties>`` of :data:`PROPERTIES`);
2. takes the state FEWS handed over — the rivercal store of the previous run (SQLite: estimates,
   alerts, forecasts, the model states of the hot start) — copies it to the state's write location,
   or starts a new one when FEWS exported no state;
3. reads the PI time series FEWS exported: observations at the stations (locationId = station id,
   parameterId = ``h``, ``h_up``, ``h_down`` or ``Q``) go into the store, forcing at boundaries and
   laterals (locationId = boundary or lateral id, parameterId ``Q`` in m³/s, ``h`` in m) replaces the
   case's own series where FEWS has values. Missing values, flags and time zones as PI defines them
   (:func:`rivercal.io.read_pixml`). FEWS's id maps translate its own ids to these;
4. runs one cycle of :class:`rivercal.online.OnlineService`: the calibration window ends at time zero,
   the forecasts (updated parameters, and the fixed DSS) start there;
5. writes the PI time series (forecasts with qualifier ``updated`` or ``dss``; per parameter the
   estimate with flag 0 when accepted, 3 (doubtful) when held, the reason as the event's comment, its σ
   (qualifier ``sigma``) and the value the forecast used (qualifier ``used``), at location
   ``estimatesLocationId``), the PI state description, and the PI diagnostics file.

Every problem goes to the diagnostics file with level 1 (error) — 0 (fatal) for an error in rivercal
itself — and a non-zero exit status (2 bad input, 3 failed model run, 1 otherwise); never a traceback.
"""

from __future__ import annotations

import logging
import math
import shutil
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

import rivercal
from rivercal.errors import CaseError, ModelRunError, RivercalError
from rivercal.fews.pi import (
    DIAG_LEVELS,
    DiagLine,
    RunFile,
    StateLocation,
    diagnostic_file_of,
    read_run_file,
    read_state_description,
    write_diag,
    write_state_description,
)
from rivercal.fews.properties import PROPERTIES, AdapterError, duration, number, prop
from rivercal.io.pixml import EXPECTED_UNITS, PiSeries, read_pixml, read_pixml_series, write_pixml_series
from rivercal.observations import ObservationSet
from rivercal.parameters import shared_quantity

__all__ = ["PROPERTIES", "AdapterError", "FewsOutcome", "run_module"]

log = logging.getLogger(__name__)

_STATE_ID = "rivercal"


@dataclass
class Diagnostics:
    """The lines of the PI diagnostics file, collected while the module runs."""

    lines: list[DiagLine] = field(default_factory=list)

    def add(self, level: str, text: str) -> None:
        """Add a line (``fatal``, ``error``, ``warn``, ``info`` or ``debug``)."""
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


def _config(run: RunFile, model: Any) -> Any:
    """The on-line service configuration from the properties, checked against the case."""
    from rivercal.online.service import OnlineConfig
    from rivercal.optimise import OPTIMISERS

    names = [n.strip() for n in prop(run, "parameters").split(",") if n.strip()]
    known = [p.name for p in model.calibration.parameters]
    unknown = [n for n in names if n not in known]
    if not names or unknown:
        what = f"unknown parameter {unknown[0]!r}" if unknown else "no parameter named"
        raise AdapterError(f"property 'parameters': {what}; the case defines {', '.join(known)}", file=str(run.path),
                           field="properties")
    shared = shared_quantity(model.calibration.parameter(n) for n in names)
    if shared is not None:
        raise AdapterError(f"property 'parameters': {shared[0]} and {shared[1]} both set {shared[2]}; give only one of "
                           "them", file=str(run.path), field="properties")
    algorithm = prop(run, "algorithm")
    if algorithm not in OPTIMISERS:
        raise AdapterError(f"property 'algorithm': unknown optimiser {algorithm!r}; choose one of "
                           f"{', '.join(sorted(OPTIMISERS))}", file=str(run.path), field="properties")
    change: dict[str, float] = {}
    for item in filter(None, (part.strip() for part in prop(run, "maxChange").split(","))):
        name, _, value = item.partition("=")
        try:
            change[name.strip()] = float(value)
        except ValueError:
            change[name.strip()] = math.nan
        if name.strip() not in names or not change[name.strip()] > 0:
            raise AdapterError(f"property 'maxChange': {item!r} must be NAME=VALUE with NAME among the estimated "
                               f"parameters ({', '.join(names)}) and VALUE > 0", file=str(run.path),
                               field="properties")
    workers = number(run, "workers")
    if workers != int(workers):
        raise AdapterError(f"property 'workers': {workers:g} is not a whole number", file=str(run.path),
                           field="properties")
    return OnlineConfig(parameters=tuple(names), window=duration(run, "window"), period=duration(run, "period"),
                        horizon=duration(run, "horizon"), warmup=duration(run, "warmup", allow_zero=True),
                        algorithm=algorithm, deadline_s=number(run, "deadline"), max_change=change,
                        alert_k=number(run, "alertK"), workers=int(workers))


# -- inputs ---------------------------------------------------------------------------------------


def _case_source(run: RunFile) -> str:
    text = prop(run, "case")
    folder = Path(text) if Path(text).is_absolute() else run.work_dir / text
    return str(folder) if folder.exists() else text


def _classify(run: RunFile, case: Any, observables: list[str]) -> tuple[dict[Path, dict], dict[str, str]]:
    """Per input file the mapping (locationId, parameterId) -> series id; and forcing series id -> forcing key."""
    network = case.network
    stations = {s.id for s in network.stations}
    kinds = {b.id: ("boundary", b.type) for b in network.boundaries}
    kinds.update({lat.id: ("lateral", "discharge") for lat in network.laterals})
    mappings: dict[Path, dict] = {}
    forcing: dict[str, str] = {}
    problems: list[str] = []
    for path in run.input_series_files:
        mapping = {}
        for pi in read_pixml_series(path):
            series_id = f"{pi.location_id}.{pi.parameter_id}"
            if pi.location_id in stations:
                if series_id not in observables:
                    problems.append(f"{path.name}: {pi.label}: unknown parameter {pi.parameter_id!r} at station "
                                    f"{pi.location_id} (the model simulates "
                                    f"{', '.join(o for o in observables if o.startswith(pi.location_id + '.'))})")
                    continue
            elif pi.location_id in kinds:
                kind, btype = kinds[pi.location_id]
                expected = "h" if btype == "level" else "Q"
                if btype in ("rating", "critical") or pi.parameter_id != expected:
                    problems.append(f"{path.name}: {pi.label}: the {kind} {pi.location_id} ({btype}) takes "
                                    + ("no series" if btype in ("rating", "critical") else f"parameterId {expected!r}"))
                    continue
                forcing[series_id] = f"{kind}:{pi.location_id}"
            else:
                problems.append(f"{path.name}: {pi.label}: unknown location {pi.location_id!r}; the case has stations "
                                f"{', '.join(sorted(stations))} and boundaries/laterals {', '.join(sorted(kinds))}")
                continue
            mapping[(pi.location_id, pi.parameter_id)] = series_id
        mappings[path] = mapping
    if problems:
        raise AdapterError("; ".join(problems), file=str(run.path), field="inputTimeSeriesFile")
    return mappings, forcing


def _inputs(run: RunFile, case: Any, observables: list[str]) -> tuple[list[tuple[str, Any]], dict[str, pd.Series]]:
    """Observation sets by file (source name) and the forcing series FEWS exported (m³/s or m, UTC)."""
    missing = [p for p in run.input_series_files if not p.is_file()]
    if missing:
        raise AdapterError(f"input time-series file {missing[0]} does not exist", file=str(run.path),
                           field="inputTimeSeriesFile")
    mappings, forcing_ids = _classify(run, case, observables)
    observations: list[tuple[str, Any]] = []
    forcing: dict[str, list[pd.Series]] = {}
    for path, mapping in mappings.items():
        if not mapping:
            continue
        obs = read_pixml(path, mapping, unmapped="error")
        kept = [s for s in obs if s.id not in forcing_ids]
        for s in obs:
            if s.id in forcing_ids:
                forcing.setdefault(forcing_ids[s.id], []).append(pd.Series(s.values, index=s.times))
        if kept:
            observations.append((f"fews:{path.name}", ObservationSet(tuple(kept))))
    return observations, {k: pd.concat(v).sort_index() for k, v in forcing.items()}


def _model(case: Any, forcing: Mapping[str, pd.Series]) -> Any:
    """The case's model with FEWS's forcing in place of the case's own where FEWS has values."""
    from rivercal.hydrology.catchments import catchment_forcing
    from rivercal.models import EmbeddedModel

    base = {**case.forcing, **catchment_forcing(case)}
    merged = {}
    for key, series in forcing.items():
        own = base.get(key)
        if own is None:
            merged[key] = series
        else:
            own = own[(own.index < series.index[0]) | (own.index > series.index[-1])]
            merged[key] = pd.concat([own, series]).sort_index()
    return EmbeddedModel(case, forcing={**catchment_forcing(case), **merged})


# -- state ----------------------------------------------------------------------------------------


def _state_locations(run: RunFile) -> tuple[Path | None, StateLocation]:
    """(the state file FEWS handed over or None, where this run writes the state)."""
    for description in run.input_state_files:
        if not description.is_file():
            raise AdapterError(f"input state description {description} does not exist", file=str(run.path),
                               field="inputStateDescriptionFile")
        _, locations = read_state_description(description, run.work_dir)
        loc = locations[0]
        if loc.type != "file":
            raise AdapterError(f"state location {loc.read} is a {loc.type}; rivercal's state is one file",
                               file=str(description), field="stateLoc")
        return (loc.read if loc.read.is_file() else None), loc
    default = run.work_dir / prop(run, "stateFile")
    return (default if default.is_file() else None), StateLocation(default, default)


def _open_state(handed: Path | None, loc: StateLocation, diag: Diagnostics) -> Path:
    """Copy the handed-over state to the write location (a new store when there is none)."""
    loc.write.parent.mkdir(parents=True, exist_ok=True)
    if handed is None:
        for suffix in ("", "-wal", "-shm"):
            Path(f"{loc.write}{suffix}").unlink(missing_ok=True)
        diag.add("info", f"no state handed over: a new state (store) at {loc.write}; the model starts cold")
    elif handed.resolve() != loc.write.resolve():
        shutil.copyfile(handed, loc.write)
        for suffix in ("-wal", "-shm"):
            Path(f"{loc.write}{suffix}").unlink(missing_ok=True)
    return loc.write


# -- outputs --------------------------------------------------------------------------------------


def _forecast_series(store: Any, run: Any, cycle: int) -> list[PiSeries]:
    fc = store.forecasts(run, cycle=cycle)
    out = []
    for (kind, series_id), part in fc.groupby(["kind", "series"], sort=True):
        station, _, quantity = str(series_id).rpartition(".")
        values = part["value"].to_numpy(float)
        out.append(PiSeries(station, quantity, (str(kind),), "instantaneous", EXPECTED_UNITS.get(quantity, "-"),
                            math.nan, pd.DatetimeIndex(part["time"]), values, np.zeros(len(values), dtype=int)))
    return out


def _estimate_series(store: Any, run: Any, cycle: int, used: Mapping[str, float], location: str,
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


def _check_times(run: RunFile, model: Any, config: Any) -> None:
    t0 = run.time0
    if t0.value % 1_000_000_000:
        raise AdapterError(f"time0 {t0.isoformat()} has a fraction of a second", file=str(run.path), field="time0")
    first = t0 - pd.Timedelta(config.window) - pd.Timedelta(config.warmup)
    if first < model.start:
        raise AdapterError(f"time0 {t0:%Y-%m-%d %H:%M} UTC: the window ({config.window}) and warm-up "
                           f"({config.warmup}) need the model from {first:%Y-%m-%d %H:%M}, before the case starts "
                           f"({model.start:%Y-%m-%d %H:%M})", file=str(run.path), field="time0")
    if t0 + pd.Timedelta(config.horizon) > model.end:
        raise AdapterError(f"time0 {t0:%Y-%m-%d %H:%M} UTC: the forecast ({config.horizon}) runs past the end of the "
                           f"case ({model.end:%Y-%m-%d %H:%M})", file=str(run.path), field="time0")


def _cycle(run: RunFile, diag: Diagnostics) -> dict[str, Any]:
    """Everything between reading the run file and writing the diagnostics; raises on a problem."""
    from rivercal.case import load_case
    from rivercal.online.service import OnlineService
    from rivercal.store import CycleSpec, Store

    t_start = time.perf_counter()
    case = load_case(_case_source(run))
    diag.add("info", f"rivercal {rivercal.__version__}: case {case.name}, time0 {run.time0:%Y-%m-%d %H:%M} UTC")
    observables = _observables(case)
    observations, forcing = _inputs(run, case, observables)
    model = _model(case, forcing)
    config = _config(run, model)
    _check_times(run, model, config)
    if forcing:
        diag.add("info", f"forcing from FEWS at {', '.join(sorted(forcing))}")
    handed, loc = _state_locations(run)
    db = _open_state(handed, loc, diag)
    name = prop(run, "run")
    with Store(db) as store:
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
        cycles = store.cycles(service.run)
        unfinished = store.first_unfinished(service.run)
        if unfinished is not None and unfinished.issue_time != run.time0:
            raise AdapterError(f"the state holds an unfinished forecast issued at "
                               f"{unfinished.issue_time:%Y-%m-%d %H:%M} UTC, not at time0", file=str(db), field="state")
        if unfinished is None and len(cycles) and run.time0 <= cycles["issue_time"].max():
            raise AdapterError(f"time0 {run.time0:%Y-%m-%d %H:%M} UTC is not after the last forecast in the state "
                               f"({cycles['issue_time'].max():%Y-%m-%d %H:%M} UTC); FEWS must hand over an older "
                               "state, or use another run name", file=str(run.path), field="time0")
        index = unfinished.cycle if unfinished is not None else len(cycles)
        spec = CycleSpec(index, run.time0 - service.window, run.time0, run.time0)
        window = store.observations(service.series, spec.window_start, spec.window_end)
        if window.n_values == 0:
            raise AdapterError(f"no observations of {', '.join(service.series)} in the window "
                               f"{spec.window_start:%Y-%m-%d %H:%M} – {spec.window_end:%Y-%m-%d %H:%M} UTC (neither in "
                               "the exported time series nor in the state)", file=str(run.path),
                               field="inputTimeSeriesFile")
        outcome = service.run_cycle(spec)
        _report_cycle(outcome, service, diag)
        files = _write_outputs(run, store, service, outcome, case.name)
    if run.output_state_file is not None:
        write_state_description(run.output_state_file, _STATE_ID, run.time0, [loc], time_zone=run.time_zone,
                                name=f"rivercal store of run {name}", comment=f"forecast {outcome.cycle}")
        files.append(str(run.output_state_file))
    _check_schemas(run, [Path(f) for f in files], diag)
    diag.add("info", f"done in {time.perf_counter() - t_start:.1f} s")
    return {"cycle": outcome.cycle, "issue_time": run.time0.isoformat(), "status": outcome.status,
            "estimates": outcome.estimates, "accepted": outcome.accepted, "held": outcome.held,
            "model_runs": outcome.model_runs, "state": str(db), "files": files}


def _check_schemas(run: RunFile, files: list[Path], diag: Diagnostics) -> None:
    """Check the written PI files against the schemas of ``piSchemaDir`` (if given); a problem is an error."""
    folder = prop(run, "piSchemaDir")
    if not folder:
        return
    try:
        import xmlschema
    except ImportError:
        raise AdapterError("property 'piSchemaDir' needs the xmlschema package (pip install 'rivercal[fews]')",
                           file=str(run.path), field="properties") from None
    for path in files:
        name = "pi_state.xsd" if path == run.output_state_file else "pi_timeseries.xsd"
        schema = Path(folder) / name
        if not schema.is_file():
            raise AdapterError(f"property 'piSchemaDir': no {name} in {folder}", file=str(run.path), field="properties")
        errors = [f"{e.path}: {e.reason}" for e in xmlschema.XMLSchema(str(schema)).iter_errors(str(path))]
        if errors:
            raise RivercalError(f"{path} does not validate against {name}: {errors[0]}")
    diag.add("info", f"{len(files)} written files validate against the PI schemas in {folder}")


def _observables(case: Any) -> list[str]:
    """The series the case's model simulates (its stations' observables), without compiling it."""
    return [o for s in case.network.stations for o in s.observables]


def _report_cycle(outcome: Any, service: Any, diag: Diagnostics) -> None:
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


def _write_outputs(run: RunFile, store: Any, service: Any, outcome: Any, case_name: str) -> list[str]:
    files = list(run.output_series_files)
    if not files:
        return []
    for f in files:
        f.parent.mkdir(parents=True, exist_ok=True)
    location = prop(run, "estimatesLocationId") or case_name
    forecasts = _forecast_series(store, service.run, outcome.cycle)
    estimates = _estimate_series(store, service.run, outcome.cycle, outcome.accepted, location, outcome.issue_time)
    if len(files) == 1:
        write_pixml_series(files[0], forecasts + estimates, time_zone=run.time_zone, forecast_date=run.time0)
        return [str(files[0])]
    write_pixml_series(files[0], forecasts, time_zone=run.time_zone, forecast_date=run.time0)
    write_pixml_series(files[1], estimates, time_zone=run.time_zone, forecast_date=run.time0)
    for extra in files[2:]:
        log.warning("outputTimeSeriesFile %s: rivercal writes forecasts to the first and estimates to the second "
                    "file only", extra)
    return [str(f) for f in files[:2]]


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
    except (CaseError, ValueError) as exc:  # bad input: a file, a property, a series, the state
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
        try:
            write_diag(target, diag.lines)
        except OSError as exc:
            diag.add("error", f"cannot write the diagnostics file {target}: {exc.strerror or exc}")
            target, code = None, code or 1
    return FewsOutcome(code, tuple(diag.lines), target, summary)

