"""The on-line parameter estimation service: rolling windows, warm and hot starts, guardrails, forecasts.

Every cycle (thesis §6-2: daily, over the last week of hourly observations) the service

1. takes the observations of the calibration window [t₀ − window, t₀] from the store (values flagged
   as outliers at ingestion stay stored but are left out);
2. starts the optimiser from the last *accepted* estimate (warm start) and the model from the state
   the previous cycle handed over at t₀ − window − warm-up (hot start; a cold spin-up only for the
   first cycle or when no usable state is stored);
3. estimates the parameters inside a box around the warm start (the bound on the change per cycle)
   with a wall-clock deadline, on a robust cost (``loss``, default Huber) — through the transition
   model when a change found earlier still lies in the run (:mod:`rivercal.online.intervention`);
4. applies the guardrails (:mod:`rivercal.online.guardrails`): an aborted or failed calibration keeps
   the last accepted estimate; a parameter the window cannot see is held (identifiability gate); an
   estimate that *jumps* starts the transition estimator on the window, and a transition it finds is
   accepted — the value after the change, with the time of the change stored — and raises one
   ``jump`` alert (without the transition estimator, ``transition=False``, every jump raises one); an
   estimate stopped by the per-cycle bound raises a ``limit`` alert;
5. runs the model with the accepted values through the window to t₀ and forecasts ``horizon`` ahead,
   and forecasts with the fixed parameters of the DSS from the DSS's own state at t₀;
6. scores the earlier cycles' forecasts against the observations that have arrived since, chooses
   the forecast it issues — the updated one while its recent skill is not worse than the DSS's,
   else the DSS's (:mod:`rivercal.online.skill`, do no harm) — and commits everything (status,
   estimates accepted or held with the reason, alerts, transitions, forecasts, the issued one and
   why, the states for the next cycle and the scores) in one transaction.

Forecast forcing: the forecasts use the model's forcing after t₀ as if it were a perfect weather
forecast, for the updated model and the DSS alike, so their difference is the parameters alone.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import pandas as pd

from rivercal._time import utc
from rivercal.analysis.dependency import DependencyMap
from rivercal.errors import ModelRunError
from rivercal.models.contract import Model, ModelState, spun_up
from rivercal.observations import DEFAULT_SIGMA, ObservationSet, measurable
from rivercal.online import guardrails, intervention
from rivercal.online.assimilation import AssimilationConfig, EnsembleFilter
from rivercal.online.config import DEFAULT_RESOLUTION, OnlineConfig, check_schedule, default_resolution
from rivercal.online.metrics import ChangeFacts, figure_scope, run_metrics, score_forecasts
from rivercal.online.skill import ForecastChoice, choose_forecast
from rivercal.online.transition import estimate_transition
from rivercal.parameters import ParameterSet
from rivercal.problem import Calibration, CalibrationProblem, calibrate
from rivercal.store import AlertRecord, BandRecord, CycleRecord, CycleSpec, EstimateRecord, Store, TransitionRecord

__all__ = ["DEFAULT_RESOLUTION", "OPTIMISER_NOTE", "STATE_UPDATING_FAILED", "CycleOutcome", "OnlineConfig",
           "OnlineService", "outcome_words"]

log = logging.getLogger(__name__)

_TOO_RECENT = ": too recent to tell from a passing event"

@dataclass(frozen=True)
class CycleOutcome:
    """What one cycle did (as committed to the store), for progress displays and summaries.

    Costs are S(θ) of thesis Eq. 2-3 (dimensionless); ``estimates`` and ``accepted`` in the parameters'
    units; ``wall_s`` in s. ``transition`` is the change the cycle found or carried (None: none);
    ``issued`` the forecast it issued (``updated`` or ``dss``) and ``issued_reason`` why.
    """

    cycle: int
    issue_time: pd.Timestamp
    status: str
    estimates: dict[str, float]
    accepted: dict[str, float]
    held: dict[str, str]
    std: dict[str, float]
    alerts: tuple[AlertRecord, ...]
    model_runs: int
    wall_s: float
    cost_before: float | None
    cost_after: float | None
    message: str
    hot_start: bool
    transition: TransitionRecord | None = None
    issued: str = "updated"
    issued_reason: str = ""
    bands: Any = None  # with state updating: the ensemble forecast (mean and 90 % band)


@dataclass
class _Estimation:
    """What a cycle's estimation produced (filled by :meth:`OnlineService._estimate`)."""

    estimates: dict[str, float]
    change: TransitionRecord | None
    alerts: list[AlertRecord]
    notes: list[str]
    status: str = "done"
    message: str = ""
    held: dict[str, str] = field(default_factory=dict)
    why: dict[str, str] = field(default_factory=dict)  # why an accepted estimate that jumped was taken anyway
    std: dict[str, float] = field(default_factory=dict)
    model_runs: int = 0
    cost_before: float | None = None
    cost_after: float | None = None


def outcome_words(result: Any) -> str:
    """How a cycle's calibration ended, in words, with the optimiser's own message and status in brackets.

    The pages for people (the report's tables, the dashboard) show the words and leave out the bracket
    (:data:`OPTIMISER_NOTE`); the store, its exports and the JSON keep both.
    """
    from rivercal.optimise.result import STATUS_CALLBACK, STATUS_DEADLINE, STATUS_MAX_ITER, STATUS_MAX_NFEV

    status = getattr(result, "status", None)
    if getattr(result, "success", False):
        words = "converged"
    elif status == STATUS_DEADLINE:
        words = "stopped at the deadline before converging"
    elif status == STATUS_MAX_NFEV:
        words = "stopped at the cap on model runs before converging"
    elif status == STATUS_MAX_ITER:
        words = "stopped after the most iterations the optimiser allows"
    elif status == STATUS_CALLBACK:
        words = "stopped on request before converging"
    else:
        words = "did not converge"
    return f"{words} [optimiser: {getattr(result, 'message', '')} (status {status})]"


#: How a stored cycle message says that the cycle's state updating failed (its forecast is the parameters' own).
STATE_UPDATING_FAILED = "state updating failed"

#: The optimiser's own words in a stored cycle message (see :func:`outcome_words`), for pages to leave out.
OPTIMISER_NOTE = r"\s*\[optimiser: [^\]]*\]"


class OnlineService:
    """Runs the cycles of one stored run of the on-line service.

    Parameters
    ----------
    model
        A model of the model contract (:mod:`rivercal.models.contract`), e.g. of
        :func:`rivercal.models.load_model`: its calibration setup names the parameters (with units), its
        ``save_state``/``load_state`` carry the hot starts through the store.
    store
        The open store.
    run_name
        Name of the run in the store (created if new; a restart resumes it).
    config
        The service configuration.
    first_issue
        Issue time of cycle 0 (UTC).
    meta
        Further facts stored with the run's configuration (e.g. the twin scenario that produced the
        observations), so that a report can find them and a restart with other facts is refused.
    assimilation
        State updating (:class:`~rivercal.online.assimilation.AssimilationConfig`; None: parameters only).
    take_over
        Compute an unfinished cycle even when the store names a live process as its owner
        (:meth:`rivercal.store.Store.begin_cycle`): only when no other service runs this run.
    source
        Where the model lies (its case folder or ``model.toml``, absolute), recorded with a new run as
        ``model_source`` so that a report or the dashboard can open the model without being told; the store names
        the model by its name, which need not be a folder (an imported model's name is its model file's).

    Raises
    ------
    ValueError
        For an unknown parameter or series, or times that do not fit the model
        (:func:`~rivercal.online.config.check_schedule`: the window, cycle, horizon or warm-up not whole
        output intervals, a first window that starts before the model's period).
    StoreError
        If the run exists with another model or configuration.
    """

    def __init__(self, model: Model, store: Store, run_name: str, config: OnlineConfig, first_issue: Any,
                 meta: Mapping[str, Any] | None = None, assimilation: AssimilationConfig | None = None,
                 take_over: bool = False, source: str | None = None):
        self.model = model
        self.take_over = take_over
        #: Told what a cycle does now (the command line's progress display: a cycle of a large model with
        #: state updating takes minutes); None: nothing is said.
        self.on_stage: Callable[[str], None] | None = None
        self.store = store
        self.config = config
        self.schedule = config.schedule(first_issue)
        config.check_model(model)  # the one check of a configuration against a model (rivercal.online.config)
        known = {p.name: p for p in model.calibration.parameters}
        self.parameters = ParameterSet(known[n] for n in config.parameters)
        self.series = list(config.series) if config.series is not None else measurable(model.observables)
        missing = [s for s in self.series if s not in model.observables]
        if missing:
            raise ValueError(f"online: series {missing[0]!r} is not simulated by the model")
        self.window = pd.Timedelta(config.window)
        self.period = pd.Timedelta(config.period)
        self.horizon = pd.Timedelta(config.horizon)
        self.warmup = pd.Timedelta(config.warmup)
        check_schedule(model, config, self.schedule.first_issue)
        setup = model.calibration  # e.g. the case's stopping rules are DuD's (thesis Table 4-3)
        case_options = setup.options if config.algorithm == setup.algorithm else {}
        self.options = dict(config.options if config.options is not None else case_options)
        self.dependency = None
        if config.dependency is not None:
            self.dependency = DependencyMap.from_csv(config.dependency, config.dependency_threshold)
        stored = {**config.stored(), "first_issue": self.schedule.first_issue.isoformat(), "meta": dict(meta or {})}
        self.facts = ChangeFacts.from_meta(meta)  # a twin's change, for the run metrics
        self.filter: EnsembleFilter | None = None  # state updating, for modes 'states' and 'both'
        self.assimilate = "parameters" if assimilation is None else assimilation.mode
        if assimilation is not None and assimilation.mode != "parameters":
            self.filter = EnsembleFilter(model, assimilation, self.series, config.sigma, workers=config.workers)
            stored["assimilation"] = assimilation.stored()
        if source is not None:
            stored["model_source"] = source
        self.run = store.ensure_run(run_name, model.name, stored)

    # -- helpers -----------------------------------------------------------------------------------

    def _stage(self, text: str) -> None:
        """Say what the cycle does now (:attr:`on_stage`)."""
        if self.on_stage is not None:
            self.on_stage(text)

    def resolution(self, name: str) -> float:
        """The resolution of a parameter (its unit; see :class:`OnlineConfig`)."""
        p = self.parameters[name]
        if name in self.config.resolution:
            return float(self.config.resolution[name])
        return default_resolution(p)

    def data_period(self, last_issue: Any) -> tuple[pd.Timestamp, pd.Timestamp]:
        """The period (UTC) whose observations the cycles up to ``last_issue`` use.

        From the first window's start (first issue − window − warm-up) to the last issue plus the
        forecast horizon, so that every forecast can be scored; but not past the end of the model's period.
        """
        start = self.schedule.first_issue - self.window - self.warmup
        return start, min(utc(last_issue) + self.horizon, self.model.end)

    def warm_start(self) -> dict[str, float]:
        """The last accepted value of each parameter, else its initial value (physical units)."""
        last = self.store.last_accepted(self.run)
        return {p.name: float(last.get(p.name, p.initial)) for p in self.parameters}

    def _box(self, warm: Mapping[str, float]) -> ParameterSet:
        """The parameters with the warm start as initial value and the per-cycle change box as bounds."""
        out = []
        for p in self.parameters:
            lo, hi = p.min, p.max
            if p.name in self.config.max_change:
                step = self.config.max_change[p.name]
                lo, hi = max(p.min, warm[p.name] - step), min(p.max, warm[p.name] + step)
            out.append(p.model_copy(update={"initial": warm[p.name], "min": lo, "max": hi}))
        return ParameterSet(out)

    def _state(self, name: str, at: pd.Timestamp, quantities: Mapping[str, float]) -> tuple[ModelState, bool]:
        """The stored state ``name`` if it is at ``at``; else a cold spin-up to ``at`` (returns hot=False)."""
        stored = self.store.model_state(self.run, name)
        if stored is not None:
            when, fmt, data = stored
            if when == at:
                try:
                    return self.model.load_state(data, fmt), True
                except ValueError as exc:
                    log.warning("stored %s state unusable (%s); spinning the model up again", name, exc)
            else:
                log.warning("stored %s state is at %s, the cycle needs %s; spinning the model up again", name, when,
                            at)
        state = spun_up(self.model, dict(quantities), at)
        return state, False

    def _quantities(self, values: Mapping[str, float], change: TransitionRecord | None = None,
                    at: pd.Timestamp | None = None) -> dict[str, float]:
        """Model quantities of parameter values (the value before a change that lies after ``at``)."""
        if change is not None and at is not None and change.time > at:
            values = {**values, change.parameter: change.before}
        return {**self.config.dss, **self.parameters.quantities(values)}

    # -- one cycle ---------------------------------------------------------------------------------

    def next_cycle(self, now: Any | None = None) -> CycleSpec | None:
        """The cycle due next (the first unfinished, else the next by the schedule), or None if not due."""
        return self.store.next_cycle(self.run, self.schedule, now=now)

    def run_cycle(self, spec: CycleSpec) -> CycleOutcome:
        """Compute cycle ``spec`` and commit it (see the module docstring)."""
        t_wall = time.perf_counter()
        spec = self.store.begin_cycle(self.run, spec, take_over=self.take_over)
        t0 = spec.issue_time
        run_start = spec.window_start - self.warmup
        warm = self.warm_start()
        change = intervention.active_transition(self.store, self.run, run_start, spec.window_end)
        obs = self.store.observations(self.series, spec.window_start, spec.window_end,
                                      sources=list(self.config.sources) if self.config.sources else None,
                                      sigma=self.config.sigma if self.config.sigma is not None else DEFAULT_SIGMA)
        state, hot = self._state("updated", run_start, self._quantities(warm, change, run_start))
        thin = guardrails.data_alerts(obs, self.window, self.config.output_interval_s, self.config.min_coverage,
                                      store=self.store, first=spec.cycle == 0)
        est = _Estimation(estimates=dict(warm), change=change, alerts=thin, notes=self._flag_note(spec))
        if obs.n_values == 0:
            est.status = "failed"
            est.message = f"no observations in the window {spec.window_start} .. {spec.window_end}"
            est.held = dict.fromkeys(warm, "no observations in the window; the last accepted estimate is kept")
        elif self.filter is not None and self.filter.config.mode == "states":
            est.message = "state updating only: the parameters stay as they are"
        else:
            self._stage(f"cycle {spec.cycle} {t0:%Y-%m-%d %H:%M}: estimating the parameters")
            self._estimate(est, spec, warm, state, obs, first=not self.store.last_accepted(self.run))
        held, estimates = est.held, est.estimates
        accepted = {n: (warm[n] if n in held else estimates[n]) for n in warm}
        change = est.change
        if change is not None:
            after = accepted[change.parameter]
            change = (replace(change, after=after) if change.found_cycle == spec.cycle
                      else intervention.carried(change, after))
        alerts = [*est.alerts, *guardrails.limit_alerts(self.parameters, warm, estimates, self.config.max_change)]
        self._stage(f"cycle {spec.cycle} {t0:%Y-%m-%d %H:%M}: forecasting")
        forecasts, states = self._forecasts(spec, run_start, state, accepted, change)
        bands = ensemble = None
        if self.filter is not None:
            from rivercal.online.assimilation import assimilation_cycle

            try:
                bands, ensemble, analyses = assimilation_cycle(self, spec, run_start, state, accepted)
            except ModelRunError as exc:  # the cycle goes on with the parameters' forecast; the next starts anew
                log.warning("cycle %d: state updating failed (%s); the parameters' forecast is issued", spec.cycle,
                            exc)
                est.message += f"; {STATE_UPDATING_FAILED} ({exc}): the parameters' forecast is issued"
            else:
                forecasts["updated"] = bands.mean
                est.message += f"; {analyses} state analyses of {self.filter.config.members} members"
        records = tuple(
            EstimateRecord(parameter=n, value=float(estimates[n]), unit=self.parameters[n].unit or "-",
                           std=float(est.std[n]) if n in est.std and math.isfinite(est.std[n]) else None,
                           accepted=n not in held, reason=held.get(n, est.why.get(n)))
            for n in warm)
        scores = self._scores(list(range(max(0, spec.cycle - self._cycles_per_horizon()), spec.cycle)))
        choice = self._choose(spec, scores, change)
        wall = time.perf_counter() - t_wall
        notes = [*est.notes, *([] if hot else ["cold start (no stored state)"])]
        self.store.commit_cycle(self.run, CycleRecord(
            spec.cycle, spec.window_start, spec.window_end, t0, status=est.status, algorithm=self.config.algorithm,
            model_runs=est.model_runs, wall_time_s=wall, cost_before=est.cost_before, cost_after=est.cost_after,
            message="; ".join([est.message, *notes]) if notes else est.message, estimates=records,
            alerts=tuple(alerts), forecasts=forecasts, states=states, scores=scores,
            transitions=(change,) if change is not None else (), issued=choice.issued, issued_reason=choice.reason,
            skill_updated=choice.rmse_updated, skill_dss=choice.rmse_dss, ensemble=ensemble,
            bands=None if bands is None else BandRecord(bands.low, bands.high, probability=0.9)))
        self.store.put_metrics(self.run, spec.cycle, self.metrics())
        log.info("cycle %d (%s): %s, %s in %.1f s, %d runs; issued %s", spec.cycle, t0, est.status,
                 ", ".join(f"{k}={v:.4g}" for k, v in accepted.items()), wall, est.model_runs, choice.issued)
        return CycleOutcome(cycle=spec.cycle, issue_time=t0, status=est.status, estimates=estimates,
                            accepted=accepted, held=held, std=est.std, alerts=tuple(alerts), model_runs=est.model_runs,
                            wall_s=wall, cost_before=est.cost_before, cost_after=est.cost_after, message=est.message,
                            hot_start=hot, transition=change, issued=choice.issued, issued_reason=choice.reason,
                            bands=bands)

    def _estimate(self, est: _Estimation, spec: CycleSpec, warm: Mapping[str, float], state: ModelState | None,
                  obs: ObservationSet, *,
                  first: bool) -> None:
        """Calibrate, gate, test for jumps and look for a transition; fills ``est``."""
        try:
            problem, cal = self._calibrate(spec, warm, state, obs, est.change)
        except ModelRunError as exc:
            est.status, est.message = "failed", f"a model run failed and the policy is 'raise': {exc}"
            est.held = dict.fromkeys(warm, "the calibration failed; the last accepted estimate is kept")
            return
        est.model_runs = cal.result.nfev
        if cal.result.aborted:
            est.status = "aborted"
            est.message = (f"{outcome_words(cal.result)} after {cal.result.nfev} model runs; the last accepted "
                           "estimate is kept")
            est.held = dict.fromkeys(warm, est.message)
            return
        est.held, extra = self._gate(problem, cal)
        est.model_runs += extra
        earlier = guardrails.accepted_at(self.store, self.run, spec.window_start)
        moved = {} if first else guardrails.jumps(warm, {n: cal.estimates[n] for n in warm}, cal.std_scaled or cal.std,
                                                  est.held,
                                                  {n: self.resolution(n) for n in warm}, self.config.alert_k,
                                                  earlier=earlier)
        if est.change is not None:
            moved.pop(est.change.parameter, None)  # the carried change is being refined, not a new jump
        if moved and est.change is None and self.config.transition:
            # every parameter that jumped, the largest jump first, until one holds a transition: under model
            # error one parameter's estimate wanders (an effective value) while another's made the change
            found, recent, verdicts = None, None, {}
            for name in sorted(moved, key=lambda n: -moved[n]):
                found, runs, why = self._search(spec, warm, state, obs, name, moved[name])
                est.model_runs += runs
                est.notes.append(why)
                verdicts[name] = why.split("transition estimate: ", 1)[-1]
                recent = why if recent is None and why.endswith(_TOO_RECENT) else recent
                if found is not None:
                    break
            if found is None and recent is not None:
                # a one-value fit over a window that may end in a change is neither value: keep the last
                # accepted estimate until the next cycle can tell
                est.held = dict.fromkeys(warm, f"{recent}; the last accepted estimate is kept until the next cycle")
            elif found is None:
                # no transition: the jump is the window's one-value fit moving (under model error an effective
                # value wanders with the events in the window); it is accepted, and the estimate says why
                for name, k in moved.items():
                    if name not in est.held:
                        verdict = f" ({verdicts[name]})" if name in verdicts else ""
                        est.why[name] = (f"jumped ({k:.0f} σ; last accepted {warm[name]:.4g}), and the transition "
                                         f"estimator found no change inside the window{verdict}, so the window's "
                                         "one-value fit is accepted (no alert: a jump alone is no intervention)")
            if found is not None:
                est.change = found
                retried = self._retry(spec, {**warm, found.parameter: found.after}, state, obs, found)
                if retried is not None:
                    problem, cal = retried
                    est.model_runs += cal.result.nfev
                    est.held, extra = self._gate(problem, cal)
                    est.model_runs += extra
                name = found.parameter
                est.alerts.append(guardrails.jump_alert(
                    name, self.parameters[name].unit, found.before, cal.estimates.get(name, found.after), moved[name],
                    spec, f"at about {found.time:%Y-%m-%d %H:%M} (the transition fit lowers the cost by "
                          f"{1 - found.cost_transition / found.cost_single:.0%})"))
            moved = {}
        elif moved and self.config.transition:
            # one change is followed at a time; another parameter's jump meanwhile is noted, not alerted: only
            # the transition test may call a jump an intervention
            est.notes.append(", ".join(f"{n} jumped ({k:.0f} σ)" for n, k in moved.items())
                             + f" while the change of {est.change.parameter} is followed: no transition search")
            for name, k in moved.items():
                if name not in est.held:
                    est.why[name] = (f"jumped ({k:.0f} σ; last accepted {warm[name]:.4g}) while the change of "
                                     f"{est.change.parameter} is followed: accepted without a transition search")
            moved = {}
        for n, k in moved.items():  # without the transition estimator every jump alerts
            est.alerts.append(guardrails.jump_alert(n, self.parameters[n].unit, warm[n], cal.estimates[n], k, spec,
                                                    "(a one-value fit over the window)"))
        est.cost_after = cal.result.cost
        est.cost_before = cal.history[0]["cost"] if cal.history and cal.history[0]["iteration"] == 0 else None
        est.estimates = {n: float(cal.estimates.get(n, warm[n])) for n in warm}
        est.std = dict(cal.std)
        est.message = outcome_words(cal.result)

    def _flag_note(self, spec: CycleSpec) -> list[str]:
        """A note on the values flagged as outliers in the window (stored, left out)."""
        counts = self.store.flag_counts(self.series, spec.window_start, spec.window_end)
        n = int(counts.loc[counts["flag"] != "ok", "n"].sum()) if len(counts) else 0
        return [f"{n} value{'s' if n != 1 else ''} flagged as outlier{'s' if n != 1 else ''} left out"] if n else []

    def _calibrate(self, spec: CycleSpec, warm: Mapping[str, float], state: ModelState | None, obs: ObservationSet,
                   change: TransitionRecord | None) -> tuple[CalibrationProblem, Calibration]:
        """The cycle's calibration, on the transition model when a change lies in the run."""
        run_start = spec.window_start - self.warmup
        box = self._box(warm)
        model: Model = self.model
        fixed = dict(self.config.dss)
        if change is not None:
            model = intervention.transition_model(self.model, self.parameters[change.parameter], run_start)
            fixed.update(intervention.fixed_transition(model, change))
            box = intervention.after_parameters(box, change.parameter)
        fixed = {k: v for k, v in fixed.items() if k not in box.quantities(warm)}
        problem = CalibrationProblem(model, box, obs, (spec.window_start, spec.window_end), state=state,
                                     warmup=self.warmup, fixed=fixed, on_failure=self.config.on_failure,
                                     loss=self.config.loss, loss_scale=self.config.loss_scale)
        extra = {"dependency": self.dependency} if self.dependency is not None else {}
        cal = calibrate(problem, self.config.algorithm, self.options, workers=self.config.workers,
                        deadline=self.config.deadline_s, **extra)
        return problem, cal

    def _retry(self, spec: CycleSpec, warm: Mapping[str, float], state: ModelState | None, obs: ObservationSet,
               change: TransitionRecord) -> tuple[CalibrationProblem, Calibration] | None:
        """The cycle's calibration again, with the change just found (None if it failed or was aborted)."""
        try:
            problem, cal = self._calibrate(spec, warm, state, obs, change)
        except ModelRunError as exc:
            log.warning("the calibration with the transition failed (%s); the one-value estimates are kept", exc)
            return None
        return None if cal.result.aborted else (problem, cal)

    def _search(self, spec: CycleSpec, warm: Mapping[str, float], state: ModelState | None, obs: ObservationSet,
                name: str,
                k: float) -> tuple[TransitionRecord | None, int, str]:
        """Run the transition estimator on ``name`` (it jumped by ``k`` σ); the change if the window holds one."""
        p = self.parameters[name]
        # the search looks at the warm-up's observations too (the state at its start comes from the values
        # before): a change just before a short window's start has no value before it inside the window
        run_start = spec.window_start - self.warmup
        if self.warmup > pd.Timedelta(0):
            obs = self.store.observations(self.series, run_start, spec.window_end,
                                          sources=list(self.config.sources) if self.config.sources else None,
                                          sigma=self.config.sigma if self.config.sigma is not None else DEFAULT_SIGMA)
        others = {k: v for k, v in warm.items() if k != name}
        fixed = {**self.config.dss, **ParameterSet(q for q in self.parameters if q.name != name).quantities(others)}
        fixed = {k: v for k, v in fixed.items() if k not in p.quantities(warm[name])}
        try:
            est = estimate_transition(self.model, p.model_copy(update={"initial": warm[name]}), obs,
                                      (run_start, spec.window_end), state=state, warmup="0h",
                                      fixed=fixed, algorithm=self.config.algorithm, options=self.options,
                                      workers=self.config.workers, alpha=self.config.transition_alpha,
                                      min_reduction=self.config.transition_min_reduction, loss=self.config.loss,
                                      loss_scale=self.config.loss_scale)
        except (ModelRunError, ValueError) as exc:
            return None, 0, f"{name} jumped ({k:.0f} σ); the transition estimator failed: {exc}"
        words = f"{name} jumped ({k:.0f} σ); transition estimate: {est.test.reason}"
        after_h = (spec.window_end - est.time) / pd.Timedelta("1h")
        if not est.test.transition or abs(est.after - est.before) <= self.resolution(name):
            if est.test.transition:
                words += f" but before and after differ by less than the resolution {self.resolution(name):g}"
            return None, est.model_runs, words
        need_h = min(self.config.transition_min_after_h, 0.5 * self.window / pd.Timedelta("1h"))
        if after_h < need_h:
            shown = math.floor(after_h * 10.0) / 10.0  # rounded down: never printed as the threshold it missed
            words += (f" at {est.time:%Y-%m-%d %H:%M}, but only {shown:g} h of the window follow it (fewer than "
                      f"{need_h:g} h){_TOO_RECENT}")
            return None, est.model_runs, words
        found = TransitionRecord(parameter=name, time=est.time.floor("s"), before=est.before, after=est.after,
                                 unit=p.unit or "-", found_cycle=spec.cycle, cost_single=est.test.cost_single,
                                 cost_transition=est.test.cost_transition, p_value=est.test.p_value)
        return found, est.model_runs, words

    def _choose(self, spec: CycleSpec, fresh: pd.DataFrame | None, change: TransitionRecord | None) -> ForecastChoice:
        """The forecast to issue (:mod:`rivercal.online.skill`) from the stored scores and this cycle's.

        With a change in the run, only the forecasts from the cycle that found it on count.
        """
        if self.config.skill_cycles == 0:
            return ForecastChoice("updated", "the updated parameters' forecast (no skill comparison)", None, None, ())
        stored = self.store.scores(self.run)
        if fresh is not None and len(fresh):
            stored = pd.concat([stored[~stored["cycle"].isin(fresh["cycle"].unique())], fresh], ignore_index=True)
        since = None
        if change is not None:
            since = (change.found_cycle, f"cycle {change.found_cycle} found that {change.parameter} changed from "
                                         f"{change.before:.4g} to {change.after:.4g} {change.unit} at about "
                                         f"{change.time:%Y-%m-%d %H:%M}")
        return choose_forecast(stored, spec.cycle, cycles=self.config.skill_cycles, lead_h=self.config.skill_lead_h,
                               tolerance=self.config.skill_tolerance, since=since)

    def _scores(self, cycles: list[int]) -> pd.DataFrame | None:
        """Scores of the forecasts of earlier cycles against the observations stored so far (None: none)."""
        fc = self.store.forecasts(self.run)
        fc = fc[fc["cycle"].isin(cycles)]
        if fc.empty:
            return None
        observed = self.store.observation_table(sorted(fc["series"].unique()), fc["time"].min(), fc["time"].max(),
                                                sources=self.config.sources)
        return score_forecasts(fc, observed)

    def _cycles_per_horizon(self) -> int:
        return math.ceil(self.horizon / self.period) + 1

    def _gate(self, problem: CalibrationProblem, cal: Calibration) -> tuple[dict[str, str], int]:
        """The identifiability gate (:func:`rivercal.online.guardrails.gate`) under the service's settings."""
        names = problem.parameters.names
        return guardrails.gate(problem, cal.result, {n: self.resolution(n) for n in names},
                               {n: self.parameters[n].unit for n in names}, gate_sv=self.config.gate_sv,
                               gate_index=self.config.gate_index, algorithm=self.config.algorithm,
                               workers=self.config.workers)

    def _forecasts(self, spec: CycleSpec, run_start: pd.Timestamp, state: ModelState | None,
                   accepted: Mapping[str, float],
                   change: TransitionRecord | None) -> tuple[dict[str, pd.DataFrame], dict[str, tuple]]:
        """Run the accepted model to t₀ and on to the horizon, and the DSS from its own state at t₀.

        With a change in the run, the run to t₀ switches from the value before to the accepted value after
        at the estimated time of the change.
        """
        t0 = spec.issue_time
        interval = self.config.output_interval_s
        q = self._quantities(accepted)
        model: Model = self.model
        if change is not None:
            model = intervention.transition_model(self.model, self.parameters[change.parameter], run_start)
            q = intervention.transition_quantities(model, q, change, accepted[change.parameter])
        next_start = run_start + self.period
        _, s_next = model.simulate(q, start=run_start, end=next_start, state=state, output_interval=interval)
        s_t0 = s_next  # a window and warm-up of one cycle start the next cycle's run at t0 itself
        if t0 > next_start:
            _, s_t0 = model.simulate(q, start=next_start, end=t0, state=s_next, output_interval=interval)
        updated, _ = model.simulate(q, start=t0, end=t0 + self.horizon, state=s_t0, output_interval=interval)
        dss_q = dict(self.config.dss)
        dss_state, _ = self._state("dss", t0 - self.period, dss_q)
        _, dss_t0 = self.model.simulate(dss_q, start=t0 - self.period, end=t0, state=dss_state,
                                        output_interval=interval)
        dss, _ = self.model.simulate(dss_q, start=t0, end=t0 + self.horizon, state=dss_t0, output_interval=interval)
        forecasts = {"updated": updated.series[self.series], "dss": dss.series[self.series]}
        fmt = self.model.state_format
        states = {"updated": (next_start, fmt, self.model.save_state(s_next)),
                  "dss": (t0, fmt, self.model.save_state(dss_t0))}
        return forecasts, states

    def cycle_at(self, issue_time: Any) -> CycleSpec:
        """The cycle issued at ``issue_time`` (UTC): the unfinished cycle, which must be at that time, else the next.

        For a caller that runs one cycle at a time at times it chooses (the Delft-FEWS module, its time zero);
        a replay follows the schedule instead (:meth:`replay`).

        Raises
        ------
        ValueError
            When an unfinished cycle is issued at another time, ``issue_time`` is not after the last cycle, or
            the window holds no observations of the used series.
        """
        t0 = utc(issue_time)
        cycles = self.store.cycles(self.run)
        unfinished = self.store.first_unfinished(self.run)
        if unfinished is not None and unfinished.issue_time != t0:
            raise ValueError(f"the store holds an unfinished cycle issued at {unfinished.issue_time:%Y-%m-%d %H:%M} "
                             f"UTC, not at {t0:%Y-%m-%d %H:%M} UTC")
        if unfinished is None and len(cycles) and t0 <= cycles["issue_time"].max():
            raise ValueError(f"the issue time {t0:%Y-%m-%d %H:%M} UTC is not after the last cycle's "
                             f"({cycles['issue_time'].max():%Y-%m-%d %H:%M} UTC)")
        spec = CycleSpec(unfinished.cycle if unfinished is not None else len(cycles), t0 - self.window, t0, t0)
        window = self.store.observations(self.series, spec.window_start, spec.window_end,
                                         sources=list(self.config.sources) if self.config.sources else None)
        if window.n_values == 0:
            raise ValueError(f"no observations of {', '.join(self.series)} in the window "
                             f"{spec.window_start:%Y-%m-%d %H:%M} – {spec.window_end:%Y-%m-%d %H:%M} UTC")
        return spec

    def close(self) -> None:
        """Stop the worker processes of state updating, if any were started (the store stays open)."""
        if self.filter is not None:
            self.filter.close()

    def metrics(self) -> dict[str, Any]:
        """The run metrics as of the last finished cycle (:func:`rivercal.online.metrics.run_metrics`).

        With ``forecast_scope`` (:func:`rivercal.online.metrics.figure_scope`): which cycles the forecast
        figures cover, so that every page that shows them can say so.
        """
        out = run_metrics(self.store, self.run, self.series, sources=self.config.sources, facts=self.facts)
        return {**out, "forecast_scope": figure_scope(self.store, self.run, facts=self.facts)}

    # -- many cycles --------------------------------------------------------------------------------

    def replay(self, until: Any, *, progress: Callable[[CycleOutcome], None] | None = None,
               max_cycles: int | None = None) -> list[CycleOutcome]:
        """Run every cycle whose issue time is at or before ``until`` (UTC), as fast as possible.

        A restart resumes at the first unfinished cycle; finished cycles are not computed again.
        """
        until = utc(until)
        done: list[CycleOutcome] = []
        while max_cycles is None or len(done) < max_cycles:
            spec = self.next_cycle(now=until)
            if spec is None:
                break
            done.append(self.run_cycle(spec))
            if progress is not None:
                progress(done[-1])
        return done

    def latest_observation(self) -> pd.Timestamp | None:
        """The time of the newest stored observation of the used series (None when there is none).

        A cycle is due when the newest data reach its issue time; a station that stopped reporting
        does not stop the service (the cycle raises a ``data`` alert instead).
        """
        table = self.store.availability(self.series)
        return None if table.empty else pd.Timestamp(table["last"].max())
