"""The on-line parameter estimation service: rolling windows, warm and hot starts, guardrails, forecasts.

Every cycle (thesis §6-2: daily, over the last week of hourly observations) the service

1. takes the observations of the calibration window [t₀ − window, t₀] from the store;
2. starts the optimiser from the last *accepted* estimate (warm start) and the model from the state
   the previous cycle handed over at t₀ − window − warm-up (hot start; a cold spin-up only for the
   first cycle or when no usable state is stored);
3. estimates the parameters inside a box around the warm start (the bound on the change per cycle)
   with a wall-clock deadline;
4. applies the guardrails: an aborted or failed calibration keeps the last accepted estimate; a
   parameter the window cannot see is held (identifiability gate, below); an estimate that moved by
   more than ``alert_k`` standard deviations *and* more than its alert floor raises a ``jump`` alert
   (a probable intervention: mowing, a lowered weir); an estimate stopped by the per-cycle bound
   raises a ``limit`` alert;
5. runs the model with the accepted values through the window to t₀ and forecasts ``horizon`` ahead,
   and forecasts with the fixed parameters of the DSS from the DSS's own state at t₀;
6. scores the earlier cycles' forecasts against the observations that have arrived since, and commits
   everything — status, estimates (accepted or held, with the reason), alerts, forecasts, the states
   for the next cycle and those scores — in one transaction.

Identifiability gate
    The final Jacobian J of the weighted residuals (the DuD secant matrix, or the optimiser's
    finite-difference Jacobian) is scaled column-wise by each parameter's *resolution* d (the
    smallest change that matters to the operator: 0.5 m^(1/3)/s of friction, 1 cm of crest). A
    singular value s_j of J·diag(d) is the square root of the cost increase when the parameters move
    by their resolutions along singular vector j; directions with s_j < ``gate_sv`` (default 1: less
    than one σ in the whole window) are unseen. A parameter whose identifiability index (Doherty and
    Hunt 2009) over the seen directions is below ``gate_index`` is held at its previous value and the
    estimate is stored as not accepted, with the reason. Holding it does not spoil the others: by
    construction their cost hardly depends on it.

Forecast forcing: the forecasts use the model's forcing after t₀ as if it were a perfect weather
forecast, for the updated model and the DSS alike, so their difference is the parameters alone.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, replace
from typing import Any, Literal

import numpy as np
import pandas as pd

from rivercal._time import utc
from rivercal.analysis.forecast import score_forecasts
from rivercal.analysis.identifiability import IdentifiabilityOptions, analyse_jacobian, fd_jacobian
from rivercal.errors import ModelRunError
from rivercal.evaluate import Workers
from rivercal.observations import DEFAULT_SIGMA
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from rivercal.store import AlertRecord, CycleRecord, CycleSpec, EstimateRecord, Schedule, Store

__all__ = ["CycleOutcome", "OnlineConfig", "OnlineService"]

log = logging.getLogger(__name__)

#: Resolution d of the identifiability gate and alert floor for the parameters of the packaged cases,
#: by unit (the smallest change that matters in operation).
DEFAULT_RESOLUTION = {"m^(1/3)/s": 0.5, "m AD": 0.01, "m": 0.01, "-": 0.01}


@dataclass(frozen=True)
class OnlineConfig:
    """How the service runs; stored with the run, so a restart with another configuration is refused.

    Attributes
    ----------
    parameters
        Names of the model's parameters to estimate (default global friction and the crest shift).
    window, period, horizon
        Calibration window length, time between cycles and forecast horizon (thesis §6-2: 7 d, 1 d;
        48 h).
    warmup
        Simulated time before each window that lets the state adjust to a candidate (its residuals do
        not count).
    algorithm, options
        Optimiser and its options (default: the model's, e.g. the case's ``[calibration]``).
    deadline_s
        Wall-clock limit of one calibration, s; on expiry the cycle is ``aborted`` and the last
        accepted estimate is kept.
    max_change
        Per parameter, the largest change per cycle (the optimiser's box around the warm start), in
        the parameter's unit; missing: its whole range.
    resolution
        Per parameter, the smallest change that matters (identifiability gate scale and alert floor);
        missing: from :data:`DEFAULT_RESOLUTION` by unit, else 1 % of the range.
    gate_sv, gate_index
        Identifiability gate thresholds (module docstring); ``gate_sv = 0`` disables the gate.
    alert_k
        A change larger than ``alert_k`` standard deviations (and than the resolution) raises an alert.
    series
        Observed series to use (default: every series the model simulates).
    sources
        Observation sources in priority order (default all).
    sigma
        σ per quantity or series id (default :data:`~rivercal.observations.DEFAULT_SIGMA`).
    min_coverage
        A window whose observations cover less than this share of the hourly values raises a
        ``data`` alert; with none at all the cycle fails (and keeps the last estimate).
    output_interval_s
        Interval of the stored forecasts, s.
    dss
        Model quantities of the DSS (default: the model as it is).
    on_failure
        Failed model run inside a calibration: ``penalty`` (logged; the optimiser steers away) or
        ``raise`` (the cycle fails and keeps the last estimate).
    workers
        Worker processes of one calibration (None: all cores), or a :class:`~rivercal.evaluate.DaskCluster`.
    """

    parameters: tuple[str, ...] = ("FA", "Wd")
    window: str = "7D"
    period: str = "1D"
    horizon: str = "48h"
    warmup: str = "24h"
    algorithm: str = "dud"
    options: dict[str, Any] | None = None
    deadline_s: float | None = 60.0
    max_change: dict[str, float] = field(default_factory=dict)
    resolution: dict[str, float] = field(default_factory=dict)
    gate_sv: float = 1.0
    gate_index: float = 0.5
    alert_k: float = 3.0
    series: tuple[str, ...] | None = None
    sources: tuple[str, ...] | None = None
    sigma: dict[str, float] | None = None
    min_coverage: float = 0.8
    output_interval_s: float = 3600.0
    dss: dict[str, float] = field(default_factory=dict)
    on_failure: Literal["raise", "penalty"] = "penalty"
    workers: Workers = None

    def __post_init__(self) -> None:
        for name in ("window", "period", "horizon"):
            if not pd.Timedelta(getattr(self, name)) > pd.Timedelta(0):
                raise ValueError(f"online {name} must be positive, got {getattr(self, name)!r}")
        if pd.Timedelta(self.warmup) < pd.Timedelta(0):
            raise ValueError(f"online warmup must not be negative, got {self.warmup!r}")
        if not self.parameters:
            raise ValueError("online: give at least one parameter to estimate")
        if self.deadline_s is not None and not self.deadline_s > 0:
            raise ValueError(f"online deadline_s must be positive, got {self.deadline_s}")
        for name, value in {**self.max_change, **self.resolution}.items():
            if not value > 0:
                raise ValueError(f"online: the change bound or resolution of {name} must be positive, got {value}")
        if not self.alert_k > 0 or self.gate_sv < 0 or not 0 < self.gate_index <= 1:
            raise ValueError("online: alert_k must be > 0, gate_sv >= 0 and gate_index in (0, 1]")
        if not 0 <= self.min_coverage <= 1:
            raise ValueError(f"online min_coverage must be in [0, 1], got {self.min_coverage}")
        if self.on_failure not in ("raise", "penalty"):
            raise ValueError(f"online on_failure must be 'raise' or 'penalty', got {self.on_failure!r}")

    def schedule(self, first_issue: Any) -> Schedule:
        """The cycle schedule whose cycle 0 is issued at ``first_issue``."""
        return Schedule(first_issue=first_issue, period=pd.Timedelta(self.period), window=pd.Timedelta(self.window),
                        horizon=pd.Timedelta(self.horizon))

    def stored(self) -> dict[str, Any]:
        """The configuration as stored with the run (JSON types; the worker count is not part of it)."""
        out = asdict(replace(self, workers=None))  # the workers may be a Dask cluster, which is not copied
        out.pop("workers")
        out["parameters"] = list(self.parameters)
        out["series"] = list(self.series) if self.series is not None else None
        out["sources"] = list(self.sources) if self.sources is not None else None
        return out


@dataclass(frozen=True)
class CycleOutcome:
    """What one cycle did (as committed to the store), for progress displays and summaries.

    Costs are S(θ) of thesis Eq. 2-3 (dimensionless); ``estimates`` and ``accepted`` in the parameters'
    units; ``wall_s`` in s.
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

    Raises
    ------
    ValueError
        For an unknown parameter or series, or a first window that starts before the model's period.
    StoreError
        If the run exists with another model or configuration.
    """

    def __init__(self, model: Any, store: Store, run_name: str, config: OnlineConfig, first_issue: Any,
                 meta: Mapping[str, Any] | None = None):
        self.model = model
        self.store = store
        self.config = config
        self.schedule = config.schedule(first_issue)
        known = {p.name: p for p in model.calibration.parameters}
        unknown = [n for n in config.parameters if n not in known]
        if unknown:
            raise ValueError(f"online: unknown parameter {unknown[0]!r}; model {model.name!r} defines "
                             f"{', '.join(known) or 'none'}")
        self.parameters = ParameterSet(known[n] for n in config.parameters)
        for name in [*config.max_change, *config.resolution]:
            if name not in self.parameters.names:
                raise ValueError(f"online: {name!r} has a change bound or resolution but is not estimated")
        self.series = list(config.series) if config.series is not None else list(model.observables)
        missing = [s for s in self.series if s not in model.observables]
        if missing:
            raise ValueError(f"online: series {missing[0]!r} is not simulated by the model")
        self.window = pd.Timedelta(config.window)
        self.period = pd.Timedelta(config.period)
        self.horizon = pd.Timedelta(config.horizon)
        self.warmup = pd.Timedelta(config.warmup)
        first_run = self.schedule.first_issue - self.window - self.warmup
        if first_run < model.start:
            raise ValueError(f"online: the first window needs the model from {first_run}, before the model's period "
                             f"starts ({model.start}); issue the first cycle later")
        setup = model.calibration  # e.g. the case's stopping rules are DuD's (thesis Table 4-3)
        case_options = setup.options if config.algorithm == setup.algorithm else {}
        self.options = dict(config.options if config.options is not None else case_options)
        stored = {**config.stored(), "first_issue": self.schedule.first_issue.isoformat(), "meta": dict(meta or {})}
        self.run = store.ensure_run(run_name, model.name, stored)

    # -- helpers -----------------------------------------------------------------------------------

    def resolution(self, name: str) -> float:
        """The resolution of a parameter (its unit; see :class:`OnlineConfig`)."""
        p = self.parameters[name]
        if name in self.config.resolution:
            return float(self.config.resolution[name])
        return DEFAULT_RESOLUTION.get(p.unit, 0.01 * (p.max - p.min))

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

    def _state(self, name: str, at: pd.Timestamp, quantities: Mapping[str, float]) -> tuple[Any, bool]:
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
        _, state = self.model.simulate(dict(quantities), end=at)
        return state, False

    def _quantities(self, values: Mapping[str, float]) -> dict[str, float]:
        return {**self.config.dss, **self.parameters.quantities(values)}

    # -- one cycle ---------------------------------------------------------------------------------

    def next_cycle(self, now: Any | None = None) -> CycleSpec | None:
        """The cycle due next (the first unfinished, else the next by the schedule), or None if not due."""
        return self.store.next_cycle(self.run, self.schedule, now=now)

    def run_cycle(self, spec: CycleSpec) -> CycleOutcome:
        """Compute cycle ``spec`` and commit it (see the module docstring)."""
        t_wall = time.perf_counter()
        spec = self.store.begin_cycle(self.run, spec)
        t0 = spec.issue_time
        run_start = spec.window_start - self.warmup
        warm = self.warm_start()
        obs = self.store.observations(self.series, spec.window_start, spec.window_end,
                                      sources=list(self.config.sources) if self.config.sources else None,
                                      sigma=self.config.sigma if self.config.sigma is not None else DEFAULT_SIGMA)
        alerts: list[AlertRecord] = []
        expected = int(self.window / pd.Timedelta(seconds=self.config.output_interval_s)) + 1
        coverage = {s.id: len(s) / expected for s in obs}
        thin = {k: v for k, v in coverage.items() if v < self.config.min_coverage}
        if thin:
            alerts.append(AlertRecord("data", "observations cover less than "
                                      f"{self.config.min_coverage:.0%} of the window at "
                                      + ", ".join(f"{k} ({v:.0%})" for k, v in sorted(thin.items()))))
        state, hot = self._state("updated", run_start, self._quantities(warm))
        status, message, cal = "done", "", None
        estimates, std, alert_std = dict(warm), {}, {}
        held: dict[str, str] = {}
        cost_before = cost_after = None
        model_runs = 0
        if obs.n_values == 0:
            status, message = "failed", f"no observations in the window {spec.window_start} .. {spec.window_end}"
            held = dict.fromkeys(warm, "no observations in the window; the last accepted estimate is kept")
        else:
            box = self._box(warm)
            estimated = box.quantities(warm)
            fixed = {k: v for k, v in self.config.dss.items() if k not in estimated}
            problem = CalibrationProblem(self.model, box, obs, (spec.window_start, spec.window_end), state=state,
                                         warmup=self.warmup, fixed=fixed, on_failure=self.config.on_failure)
            try:
                cal = calibrate(problem, self.config.algorithm, self.options, workers=self.config.workers,
                                deadline=self.config.deadline_s)
            except ModelRunError as exc:
                status, message = "failed", f"a model run failed and the policy is 'raise': {exc}"
                held = dict.fromkeys(warm, "the calibration failed; the last accepted estimate is kept")
            if cal is not None:
                r = cal.result
                model_runs = r.nfev
                cost_after = r.cost
                cost_before = cal.history[0]["cost"] if cal.history and cal.history[0]["iteration"] == 0 else None
                estimates, std = dict(cal.estimates), dict(cal.std)
                alert_std = dict(cal.std_scaled)   # σ from the fit's own residual variance, not the weights' σ
                message = r.message
                if r.aborted:
                    status = "aborted"
                    message = f"{r.message} after {r.nfev} model runs; the last accepted estimate is kept"
                    held = dict.fromkeys(warm, message)
                else:
                    held, extra = self._gate(problem, r)
                    model_runs += extra
        accepted = {n: (warm[n] if n in held else estimates[n]) for n in warm}
        alerts += self._alerts(warm, accepted, estimates, alert_std, held, spec)
        forecasts, states = self._forecasts(spec, run_start, state, accepted)
        records = tuple(
            EstimateRecord(parameter=n, value=float(estimates[n]), unit=self.parameters[n].unit or "-",
                           std=float(std[n]) if n in std and math.isfinite(std[n]) else None,
                           accepted=n not in held, reason=held.get(n))
            for n in warm)
        scored = [c for c in range(max(0, spec.cycle - self._cycles_per_horizon()), spec.cycle)]
        wall = time.perf_counter() - t_wall
        self.store.commit_cycle(self.run, CycleRecord(
            spec.cycle, spec.window_start, spec.window_end, t0, status=status, algorithm=self.config.algorithm,
            model_runs=model_runs, wall_time_s=wall, cost_before=cost_before, cost_after=cost_after,
            message=message + ("" if hot else "; cold start (no stored state)"), estimates=records,
            alerts=tuple(alerts), forecasts=forecasts, states=states, scores=self._scores(scored)))
        log.info("cycle %d (%s): %s, %s in %.1f s, %d runs", spec.cycle, t0, status,
                 ", ".join(f"{k}={v:.4g}" for k, v in accepted.items()), wall, model_runs)
        return CycleOutcome(cycle=spec.cycle, issue_time=t0, status=status, estimates=estimates, accepted=accepted,
                            held=held, std=std, alerts=tuple(alerts), model_runs=model_runs, wall_s=wall,
                            cost_before=cost_before, cost_after=cost_after, message=message, hot_start=hot)

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

    def _gate(self, problem: CalibrationProblem, result: Any) -> tuple[dict[str, str], int]:
        """Parameters the window cannot see, with the reason (module docstring); and the model runs it took.

        The Jacobian is the optimiser's (DuD's secant one); when it has none, a forward-difference one at
        the estimate (p + 1 runs in one batch).
        """
        if self.config.gate_sv <= 0:
            return {}, 0
        jac, extra = result.jac, 0
        if jac is None or not np.all(np.isfinite(jac)):
            # e.g. DuD's secant set degenerated: a gate that is skipped would accept anything, so measure it
            log.info("no usable Jacobian from %s; finite differences at the estimate", self.config.algorithm)
            try:
                fd = fd_jacobian(problem, np.asarray(result.x, dtype=float), workers=self.config.workers)
            except ModelRunError as exc:
                reason = f"the identifiability gate could not run ({exc}); held at its last accepted value"
                return dict.fromkeys(problem.parameters.names, reason), 0
            jac, extra = fd.matrix, fd.nfev
        names = problem.parameters.names
        scale = np.array([self.resolution(n) for n in names])
        seen = int(np.count_nonzero(np.linalg.svd(jac * scale, compute_uv=False) >= self.config.gate_sv))
        ident = analyse_jacobian(jac, names, scale=scale, options=IdentifiabilityOptions(k=seen))
        held = {}
        for i, n in enumerate(names):
            if ident.index[i] < self.config.gate_index:
                held[n] = (f"this window cannot see {n}: identifiability index {ident.index[i]:.2f} < "
                           f"{self.config.gate_index:g} over the {seen} direction(s) whose singular value reaches "
                           f"{self.config.gate_sv:g} (a change of {self.resolution(n):g} {self.parameters[n].unit} "
                           f"moves the cost by less than that); held at its last accepted value")
        return held, extra

    def _alerts(self, warm: Mapping[str, float], accepted: Mapping[str, float], estimates: Mapping[str, float],
                std: Mapping[str, float], held: Mapping[str, str], spec: CycleSpec) -> list[AlertRecord]:
        out = []
        for p in self.parameters:
            n = p.name
            if n not in held:
                change = accepted[n] - warm[n]
                sigma = std.get(n, math.nan)
                k = abs(change) / sigma if sigma and math.isfinite(sigma) and sigma > 0 else math.inf
                if abs(change) > self.resolution(n) and k > self.config.alert_k:
                    out.append(AlertRecord(
                        "jump", f"{n} changed from {warm[n]:.4g} to {accepted[n]:.4g} {p.unit} ({change:+.3g}, "
                        + (f"{k:.0f} σ" if math.isfinite(k) else "σ unknown")
                        + f") in the window {spec.window_start:%Y-%m-%d %H:%M} – {spec.window_end:%Y-%m-%d %H:%M}: "
                        "a probable intervention (mowing, a changed weir setting)",
                        parameter=n, magnitude=k if math.isfinite(k) else None))
            if n in self.config.max_change:
                step = self.config.max_change[n]
                at_box = abs(abs(estimates[n] - warm[n]) - step) <= 1e-6 * max(1.0, step)
                inside = p.min < estimates[n] < p.max
                if at_box and inside:
                    out.append(AlertRecord(
                        "limit", f"{n} stopped at the per-cycle change bound ±{step:g} {p.unit}; the true change may "
                        "be larger and the next cycles will continue", parameter=n))
        return out

    def _forecasts(self, spec: CycleSpec, run_start: pd.Timestamp, state: Any,
                   accepted: Mapping[str, float]) -> tuple[dict[str, pd.DataFrame], dict[str, tuple]]:
        """Run the accepted model to t₀ and on to the horizon, and the DSS from its own state at t₀."""
        t0 = spec.issue_time
        interval = self.config.output_interval_s
        q = self._quantities(accepted)
        next_start = run_start + self.period
        _, s_next = self.model.simulate(q, start=run_start, end=next_start, state=state, output_interval=interval)
        _, s_t0 = self.model.simulate(q, start=next_start, end=t0, state=s_next, output_interval=interval)
        updated, _ = self.model.simulate(q, start=t0, end=t0 + self.horizon, state=s_t0, output_interval=interval)
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
