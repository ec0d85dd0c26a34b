"""The on-line service over a replay or a watched folder, with its summary and report.

Observations reach the store from a twin scenario of thesis chapter 5, from files (CSV or Delft-FEWS
PI-XML), or from a folder that is watched; every value is screened for spikes at ingestion
(:class:`~rivercal.observations.ScreenRule`) and stored with its flag, and gaps are recorded. A file is
first checked against the model (:mod:`rivercal.online.screening`): a series the model does not simulate,
or one whose values mostly lie outside what the model makes plausible there (a unit, a datum), refuses
the file before anything of it is stored; a few implausible values are stored flagged as outliers. The
service then runs every cycle that is due. A restart with the same store and run resumes at the first
unfinished cycle.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from rivercal._time import utc
from rivercal.observations import ObservationSet, ScreenRule
from rivercal.workflows.progress import NO_PROGRESS, Progress

if TYPE_CHECKING:
    from rivercal.models.contract import Model
    from rivercal.online.assimilation import AssimilationConfig
    from rivercal.online.config import OnlineConfig
    from rivercal.online.screening import PlausibleRange
    from rivercal.online.service import CycleOutcome, OnlineService
    from rivercal.store import IngestResult, Store
    from rivercal.twin.realism import Realism

__all__ = ["format_value", "ingest_file", "online_summary", "read_observation_file", "run_online"]

log = logging.getLogger(__name__)


def read_observation_file(path: str | Path) -> ObservationSet:
    """Observations from a CSV file or a Delft-FEWS PI-XML file (by its suffix).

    Raises
    ------
    CaseError
        For a file that cannot be read or holds bad values (named, with the line). A message quotes the
        file's text; a long run of it (a 100 kB column name) is cut to its start and its length.
    """
    from rivercal.errors import CaseError
    from rivercal.io import read_observations_csv, read_pixml

    path = Path(path)
    try:
        if path.suffix.lower() == ".xml":
            return read_pixml(path)
        if path.suffix.lower() == ".csv":
            return read_observations_csv(path)
    except CaseError as exc:
        reason, field = _cut(exc.reason), _cut(exc.field) if exc.field else exc.field
        if (reason, field) == (exc.reason, exc.field):
            raise
        raise type(exc)(reason, file=exc.file, field=field) from None
    raise CaseError("expected a .csv or a PI-XML .xml file", file=str(path))


#: Longest run of text without a blank that a message quotes as it is, characters.
_LONGEST_WORD = 200


def _cut(text: str) -> str:
    """``text`` with every run of more than :data:`_LONGEST_WORD` characters without a blank cut short."""
    import re

    return re.sub(r"\S{" + str(_LONGEST_WORD + 1) + ",}",
                  lambda m: f"{m.group(0)[:60]}… ({len(m.group(0))} characters)", text)


def run_online(model: Model, db: str | Path, run: str, config: OnlineConfig, first: pd.Timestamp,
               last: pd.Timestamp, *, scenario: str | None = None, noise: str = "none", seed: int = 0,
               realism: str | Realism | None = None, observations: Sequence[tuple[str, ObservationSet]] = (),
               follow: str | Path | None = None, poll: float = 10.0,
               max_cycles: int | None = None, report: str | Path | None = None,
               progress: Progress = NO_PROGRESS, assimilation: AssimilationConfig | None = None,
               rain_error: float = 0.0,
               take_over: bool = False, source: str | None = None) -> dict[str, Any]:
    """Run the cycles issued from ``first`` to ``last`` and return the summary (:func:`online_summary`).

    Parameters
    ----------
    model
        A loaded model (:func:`rivercal.model.load_model`).
    db
        The store: an SQLite file (created if missing) or a ``postgresql://`` URL.
    run
        The run's name in the store; a run that exists resumes (with the same configuration only).
    config
        The :class:`~rivercal.online.service.OnlineConfig`.
    first, last
        Issue times (UTC) of the first and the last cycle.
    scenario, noise, seed
        Twin observations of a practical scenario of thesis chapter 5, with noise.
    realism
        Realism level of the twin (:mod:`rivercal.twin.realism`: a name, a TOML file or a
        :class:`~rivercal.twin.realism.Realism`); None: the identical twin (with ``noise``).
    observations
        (source name, :class:`~rivercal.observations.ObservationSet`) pairs to ingest.
    follow, poll
        Watch this folder for new CSV / PI-XML files, looking every ``poll`` s, and run each cycle when
        its data are in; stops after ``last`` or on Ctrl-C (finished cycles stay stored).
    max_cycles
        Stop after this many cycles.
    report
        Folder for the HTML report and the exports (None: no report).
    progress
        Where to say what happens: one step per cycle, a note per finished cycle.
    assimilation
        State updating (:class:`~rivercal.online.assimilation.AssimilationConfig`; None: parameters only).
    rain_error
        Twin only: σ of the multiplicative error of the truth's inflows and laterals against the model's
        (:func:`rivercal.twin.forcing_error.rain_error_model`; 0.3: about 30 %).
    take_over
        Resume a cycle whose recorded owner looks alive (:meth:`rivercal.store.Store.begin_cycle`).
    source
        Where the model lies, recorded with a new run (:class:`~rivercal.online.service.OnlineService`).

    Raises
    ------
    CaseError
        For an observation file (``observations``) with a series the model does not simulate or with values
        mostly outside their plausible range (:mod:`rivercal.online.screening`); nothing is stored then. A
        file in the ``follow`` folder with such a problem is reported and skipped instead.
    """
    from rivercal.online.service import OnlineService
    from rivercal.store import FINAL_STATUSES, Store, is_url

    t_start = time.perf_counter()
    truth_series = None
    meta: dict[str, Any] = {"scenario": scenario, "noise": noise, "seed": seed} if scenario else {}
    if scenario:
        from rivercal.twin.practical import SCENARIOS

        meta["truth"] = SCENARIOS[scenario].facts()  # for the run metrics the service stores
    level = None
    if scenario and realism is not None:
        from rivercal.twin.realism import get_realism

        level = get_realism(realism)
        if not level.ideal:  # an ideal level is the identical twin: its runs keep the meta of before
            meta["realism"] = level.summary()
    if scenario and rain_error:
        meta["rain_error"] = rain_error
    ranges: dict[str, PlausibleRange] = {}
    if observations or follow is not None:
        ranges = _screen_deliveries(model, config, first, last, observations, progress)
    if not is_url(db):
        Path(db).parent.mkdir(parents=True, exist_ok=True)
    from rivercal.evaluate import DaskCluster

    if isinstance(config.workers, DaskCluster):  # every cycle's problem then refers to the model on the workers
        config.workers.share(model)
    with Store(db) as store:
        service = OnlineService(model, store, run, config, first, meta=meta, assimilation=assimilation,
                                take_over=take_over, source=source)
        service.on_stage = progress.stage
        if scenario is not None:
            from rivercal.twin.practical import practical_truth

            progress.stage(f"{scenario}: running the truth")
            truth_model = model
            if rain_error:
                from rivercal.twin.forcing_error import rain_error_model

                truth_model = rain_error_model(model, rain_error, seed)
            truth = practical_truth(truth_model, scenario, *service.data_period(last), noise=noise, seed=seed,
                                    series=service.series, realism=level)
            store.ingest(truth.observations, source=f"twin:{scenario}", screen=ScreenRule())
            truth_series = truth.series
        for source, obs in observations:
            store.ingest(obs, source=source, screen=ScreenRule(),
                         plausible={sid: r.bounds() for sid, r in ranges.items()})
        finished = int(store.cycles(service.run)["status"].isin(FINAL_STATUSES).sum())
        total = int((last - service.schedule.first_issue) // service.period) + 1
        if max_cycles is not None:
            total = min(total, finished + max_cycles)
        outcomes: list[CycleOutcome] = []
        units = {p.name: p.unit for p in model.calibration.parameters}

        def on_cycle(o: CycleOutcome) -> None:
            outcomes.append(o)
            values = ", ".join(f"{k} {format_value(v, units.get(k, ''))}" + ("*" if k in o.held else "")
                               for k, v in o.accepted.items())
            progress.step(finished + len(outcomes), max(total, finished + len(outcomes)),
                          f"cycles (last: {o.issue_time:%Y-%m-%d %H:%M}, {o.status})")
            progress.note(f"cycle {o.cycle:>3} {o.issue_time:%Y-%m-%d %H:%M}  {o.status:<7} {values}  "
                          f"{o.model_runs} runs {o.wall_s:.1f} s"
                          + "".join(f"\n    {a.kind}: {a.message}" for a in o.alerts))

        progress.step(finished, total, "cycles")
        if follow is None:
            service.replay(last, progress=on_cycle, max_cycles=max_cycles)
        else:
            _follow(service, store, Path(follow), last, poll, on_cycle, max_cycles, progress, ranges)
        if scenario is not None:
            _store_twin_fields(model, store, service, progress)
        service.close()
        summary = online_summary(store, service, outcomes, time.perf_counter() - t_start, truth=truth_series)
        if report is not None:
            from rivercal.report.online import write_online_report

            progress.stage("writing the report")
            summary["files"] = write_online_report(store, service.run.name, report, model=model)
    return summary


def ingest_file(store: Store, path: str | Path, model: Model, ranges: dict[str, PlausibleRange],
                progress: Progress = NO_PROGRESS) -> IngestResult:
    """Read, check and store one delivered observation file, as ``--follow`` does with each new file.

    Parameters
    ----------
    store
        The open store.
    path
        A CSV or PI-XML file; its name is the values' source in the store.
    model
        The model whose series the file must hold.
    ranges
        The plausible range of each series (:func:`rivercal.online.screening.plausible_ranges`).
    progress
        Where notes on values stored as outliers go (they are logged too).

    Returns
    -------
    IngestResult
        What :meth:`rivercal.store.Store.ingest` stored.

    Raises
    ------
    CaseError
        Naming the file and the series (and line) of the problem; nothing of the file is stored then.
    """
    from rivercal.online.screening import check_delivery, check_series

    path = Path(path)
    delivery = read_observation_file(path)
    check_series(delivery, model.observables, path.name, model.name)
    _outlier_notes(check_delivery(delivery, path.name, ranges), path.name, progress)
    return store.ingest(delivery, source=path.name, screen=ScreenRule(),
                        plausible={sid: r.bounds() for sid, r in ranges.items()})


def _screen_deliveries(model: Model, config: OnlineConfig, first: pd.Timestamp, last: pd.Timestamp,
                       observations: Sequence[tuple[str, ObservationSet]],
                       progress: Progress) -> dict[str, PlausibleRange]:
    """Check the given files against the model; the plausible range of each series (for the files to come too).

    The series of every file are checked first (no model run); then the model runs the data period once
    (:func:`rivercal.online.screening.plausible_ranges`) and every file's values are checked against it.
    """
    from rivercal.observations import measurable
    from rivercal.online.screening import check_delivery, check_series, data_end, plausible_ranges

    for source, obs in observations:
        check_series(obs, model.observables, source, model.name)
    progress.stage("checking the observations against the model's own levels")
    start = first - pd.Timedelta(config.window) - pd.Timedelta(config.warmup)
    ranges = plausible_ranges(model, measurable(model.observables), start, data_end(model, config, first, last),
                              config.dss, config.output_interval_s)
    for source, obs in observations:
        _outlier_notes(check_delivery(obs, source, ranges), source, progress)
    return ranges


#: A file with values outside their plausible range in more series than this is summarised in one line.
OUTLIER_LINES = 5


def _outlier_notes(notes: list[str], source: str, progress: Progress) -> None:
    """Say which series of a file hold values outside their plausible range: each, or a summary of many.

    Each note goes to the log (``--verbose`` shows it); the progress shows each of a few, or one line for many,
    so that a file of hundreds of series (every structure of an imported model) does not fill the screen.
    """
    for note in notes:
        log.info("%s", note)
    if len(notes) <= OUTLIER_LINES:
        for note in notes:
            progress.note(note)
        return
    progress.note(f"{source}: {len(notes)} series hold values outside their plausible range (stored as outliers, "
                  f"left out); the first: {notes[0].removeprefix(source + ': ')}; --verbose lists every one")


def _follow(service: OnlineService, store: Store, folder: Path, last: pd.Timestamp, poll: float,
            on_cycle: Callable[[CycleOutcome], None], max_cycles: int | None, progress: Progress,
            ranges: dict[str, PlausibleRange]) -> None:
    """Ingest new files from ``folder`` and run each cycle when the newest data reach its issue time.

    A file that cannot be read, names a series the model does not simulate or holds mostly implausible
    values (:mod:`rivercal.online.screening`) is reported and skipped; ``ranges`` are the plausible ranges.
    """
    seen: dict[Path, tuple[float, int]] = {}
    done = 0
    try:
        while True:
            for path in sorted(folder.iterdir()):
                if path.suffix.lower() not in (".csv", ".xml") or not path.is_file():
                    continue
                stamp = (path.stat().st_mtime, path.stat().st_size)
                if seen.get(path) == stamp:
                    continue
                try:
                    ingest_file(store, path, service.model, ranges, progress)
                except ValueError as exc:  # a bad file (CaseError) is reported and skipped; the service goes on
                    log.warning("skipped %s: %s", path.name, exc)
                    progress.note(f"skipped {path.name}: {exc}")
                seen[path] = stamp
            newest = service.latest_observation()
            while newest is not None and (max_cycles is None or done < max_cycles):
                spec = service.next_cycle(now=min(newest, last))
                if spec is None:
                    break
                on_cycle(service.run_cycle(spec))
                done += 1
            nxt = service.next_cycle()
            if nxt is None or nxt.issue_time > last or (max_cycles is not None and done >= max_cycles):
                return
            progress.stage(f"waiting for observations up to {nxt.issue_time:%Y-%m-%d %H:%M} in {folder}")
            time.sleep(poll)
    except KeyboardInterrupt:
        progress.note("stopped; the store holds every finished cycle, a restart resumes after the last one")


def online_summary(store: Store, service: OnlineService, outcomes: Sequence[CycleOutcome], wall: float,
                   truth: pd.DataFrame | None = None) -> dict[str, Any]:
    """JSON-friendly summary of a run: cycles, estimates, alerts and the run metrics (updated vs DSS).

    ``state_updating_failed`` lists the cycles whose state updating failed (their forecast is the parameters'
    own). ``cycles_done_now`` counts the cycles this call computed, ``cycles_succeeded_now`` those of them that
    ended ``done`` (not failed or aborted), ``status_now`` counts them by status and ``first_message_now`` is
    the message of the first that did not end ``done``.

    The metrics are those the service stored with the run's last cycle (:mod:`rivercal.online.metrics`):
    ``forecast_errors``, the headline figures (``forecast_mae_ratio``, ``time_to_correct_cycles``,
    ``jump_alerts``, ``fallbacks`` …), ``forecast_mae_by_lead`` and, with state updating, ``band_coverage_90``.
    For a twin the error by lead is measured against its noise-free ``truth`` instead of the observations
    (:func:`rivercal.online.metrics.mae_by_lead`). ``wall_s`` in s; estimates in the parameters' units.
    """
    from rivercal.online.metrics import mae_by_lead
    from rivercal.online.service import STATE_UPDATING_FAILED

    cycles = store.cycles(service.run)
    est = store.estimates(service.run)
    flags = store.flag_counts(service.series)
    alerts = store.alerts(service.run)
    metrics = store.metrics(service.run) or service.metrics()
    if truth is not None:
        metrics = {**metrics, "forecast_mae_by_lead": mae_by_lead(store, service.run, service.series, truth)}
    return {
        "run": service.run.name,
        "case": service.model.name,
        "db": str(store.path),
        "assimilate": service.assimilate,
        "cycles_done_now": len(outcomes),
        "cycles_succeeded_now": sum(o.status == "done" for o in outcomes),
        "status_now": {k: sum(o.status == k for o in outcomes) for k in sorted({o.status for o in outcomes})},
        "first_message_now": next((o.message for o in outcomes if o.status != "done"), None),
        "cycles": len(cycles),
        "status": cycles["status"].value_counts().to_dict(),
        "state_updating_failed": [int(c) for c, m in zip(cycles["cycle"], cycles["message"], strict=True)
                                  if STATE_UPDATING_FAILED in str(m or "")] if len(cycles) else [],
        "wall_s": round(wall, 2),
        "units": {p.name: p.unit for p in service.parameters},
        "cycle_wall_s_median": float(cycles["wall_time_s"].median()) if len(cycles) else None,
        "model_runs_median": float(cycles["model_runs"].median()) if len(cycles) else None,
        "estimates": [
            {"cycle": int(c), "issue_time": g["issue_time"].iloc[0].isoformat(),
             **{r.parameter: float(r.value) for r in g.itertuples()},
             "held": [r.parameter for r in g.itertuples() if not r.accepted]}
            for c, g in est.groupby("cycle")],
        "alerts": [{"cycle": int(r.cycle), "kind": r.kind, "parameter": r.parameter, "message": r.message}
                   for r in alerts.itertuples()],
        "observations_flagged": {str(k): int(v) for k, v in flags.groupby("flag")["n"].sum().items()},
        **metrics,
    }


def _store_twin_fields(model: Model, store: Store, service: OnlineService, progress: Progress) -> None:
    """The twin's levels at every point of the truth, the DSS and rivercal, kept with the run for its report.

    Only for a model with snapshots; nothing when the cycles end at the end of the model's period.
    """
    from rivercal.models.capabilities import has_capability
    from rivercal.twin.fields import store_twin_fields, twin_fields

    cycles = store.cycles(service.run)
    if cycles.empty or not has_capability(model, "snapshots"):
        return
    start = cycles["issue_time"].min()
    end = min(cycles["issue_time"].max() + service.period, utc(model.end))
    if not end > start:
        return
    progress.stage("running the truth, the DSS and rivercal at every point for the report")
    store_twin_fields(store, service.run, twin_fields(model, store, service.run, start, end))


def format_value(value: float, unit: str) -> str:
    """A parameter value to the precision that matters: 0.1 mm for levels, 0.01 for the rest."""
    return f"{value:.4f}" if unit in ("m", "m AD") else f"{value:.2f}"
