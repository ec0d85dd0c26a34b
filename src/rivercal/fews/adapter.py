"""The Delft-FEWS General Adapter module: one on-line cycle from a PI run file.

FEWS calls ``rivercal fews run_info.xml``; :func:`run_module` then

1. reads the run file (time zero, the files, the ``<properties>`` of :data:`PROPERTIES`);
2. checks, before anything is written: the state's locations (inside the work folder; an existing one a
   rivercal store, never another file), every output location (writable; an existing one a PI file of its
   kind), the case, the inputs, the properties and the times;
3. reads the PI time series FEWS exported: observations at the stations (locationId = station id,
   parameterId = ``h``, ``h_up``, ``h_down`` or ``Q``) go into the store, forcing at boundaries and
   laterals (locationId = boundary or lateral id, parameterId ``Q`` in m³/s, ``h`` in m) and structure
   settings (locationId = structure id, parameterId of ``SETTINGS``) replaces the case's own series
   where FEWS has values, unless implausible. Missing values,
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

The inputs (step 3) are read and screened in :mod:`rivercal.fews._inputs`, the state's and outputs' locations
(steps 2 and 4) checked in :mod:`rivercal.fews._files`.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

import rivercal
from rivercal.errors import CaseError, FieldProblem, ModelRunError, OptionError, RivercalError
from rivercal.fews._files import check_outputs, open_state, output_problem, state_locations
from rivercal.fews._inputs import (
    case_observables,
    case_source,
    forcing_line,
    model_with_forcing,
    own_forcing,
    read_inputs,
    reference_scales,
    screen_forcing,
)
from rivercal.fews.pi import (
    DIAG_LEVELS,
    DiagLine,
    Diagnostics,
    RunFile,
    diagnostic_file_of,
    read_run_file,
    replace_atomically,
    write_diag,
    write_state_description,
)
from rivercal.fews.properties import PROPERTIES, AdapterError, duration, prop
from rivercal.io.pixml import (
    EXPECTED_UNITS,
    PiSeries,
    write_pixml_series,
)
from rivercal.models.load import model_source

if TYPE_CHECKING:
    from rivercal.models.contract import Model
    from rivercal.online.config import OnlineConfig
    from rivercal.online.service import CycleOutcome, OnlineService
    from rivercal.store import Run, Store

__all__ = ["PROPERTIES", "AdapterError", "FewsOutcome", "run_module"]

log = logging.getLogger(__name__)

_STATE_ID = "rivercal"


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
    """time0 and the durations fit the case's period and the forecasts' time step.

    The service's own check of a run's times (:func:`rivercal.online.config.check_schedule`), for the one cycle at
    time0, with the run file's names: the window, warm-up, period and horizon whole numbers of the forecasts' time
    step, the window with its warm-up at least one period (the next run's hot start is taken one period after this
    run's warm-up starts), time0 on the step's grid from the case's start, and the window, warm-up and forecast
    inside the case's period.
    """
    from rivercal.online.config import check_schedule

    names = {key: f"property {_PROPERTY_OF[key]!r}" for key in ("window", "period", "horizon", "warmup")}
    names.update(first="time0", last="time0")
    try:
        check_schedule(model, config, run.time0, run.time0, names=names)
    except ValueError as exc:
        text = str(exc)
        if text.startswith("time0") and "cycles are issued on" in text:
            text += f" (check the run file's timeZone, {run.time_zone:+g} h)"
        raise AdapterError(text, file=str(run.path), field="time0" if text.startswith("time0") else "properties") \
            from None


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
    handed, loc = state_locations(run)
    check_outputs(run, loc)
    for tag, text in run.unread:
        diag.add("warn", f"{run.path}: {tag} {text}: rivercal {'writes' if tag.startswith('output') else 'reads'} "
                         "no such file; ignored")
    for key in sorted(set(run.properties) - set(PROPERTIES)):
        diag.add("warn", f"{run.path}: property {key!r} is not one rivercal reads; ignored (it reads "
                         f"{', '.join(PROPERTIES)})")
    case_folder = case_source(run)
    case = load_case(case_folder)
    diag.add("info", f"rivercal {rivercal.__version__}: case {case.name}, time0 {run.time0:%Y-%m-%d %H:%M} UTC")
    observables = case_observables(case)
    observations, forcing = read_inputs(run, case, observables, diag)
    runoff, own = own_forcing(case)
    screen_forcing(forcing, own, run, reference_scales(case, own))
    model = model_with_forcing(run, case, runoff, own, forcing)
    config = _config(run, model)
    _check_times(run, model, config)
    schemas = _schemas(run)
    if forcing:
        diag.add("info", forcing_line(forcing))
    db = open_state(handed, loc, diag)
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
            service = OnlineService(model, store, name, config, first or run.time0,
                                    source=model_source(case_folder))
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


def _report_cycle(outcome: CycleOutcome, service: OnlineService, diag: Diagnostics) -> None:
    # a unit after each value, none after a dimensionless one ("1.2 ± 0.006", not "1.2 ± 0.006 -")
    units = {p.name: "" if (p.unit or "").strip() in ("", "-", "1") else f" {p.unit}" for p in service.parameters}
    diag.add("info", f"forecast {outcome.cycle} issued at {outcome.issue_time:%Y-%m-%d %H:%M} UTC: {outcome.status}, "
                     f"{outcome.model_runs} model runs, {outcome.wall_s:.1f} s"
                     + ("" if outcome.hot_start else ", cold start (no usable model state at the window's start)"))
    for name, value in outcome.accepted.items():
        std = outcome.std.get(name)
        sigma = f" ± {std:.3g}" if std is not None and math.isfinite(std) else ""
        if name in outcome.held:
            diag.add("warn", f"{name}: estimate {outcome.estimates[name]:.4g}{sigma}{units[name]} held; the forecast "
                             f"uses {value:.4g}{units[name]}: {outcome.held[name]}")
        else:
            diag.add("info", f"{name} = {value:.4g}{sigma}{units[name]} (accepted)")
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
        problem = output_problem(target, "Diag")
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
