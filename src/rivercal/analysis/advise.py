"""Where to put the next gauge: identifiability and data worth of candidate gauges (linear first-order analysis).

The reference study (thesis §6-3, "More measurement locations") found that some crest levels of its
network could not be identified from the five stations and proposed choosing further measurement places.
This module answers "which gauge should we add?" from one finite-difference Jacobian of every candidate's
series, without a calibration per candidate.

Notation: x the parameters in optimiser units (p of them), d their scales (default their ranges), J₀ the
Jacobian of the present stations' weighted residuals r = √W (y − ŷ) (thesis Eq. 2-10), J_c that of the
series of candidate gauge c (weighted alike, with the σ a gauge of its kind would have), C_p = diag(σ_p²)
the prior covariance of x (a parameter's ``prior_std``, else a quarter of its range: its bounds taken as
±2σ, the convention of PEST's and pyEMU's linear analysis) and y_f = ∂f/∂x the sensitivity of a forecast
f. For a set S of added gauges:

    F(S) = J₀ᵀJ₀ + Σ_{c ∈ S} J_cᵀJ_c                      (the information of thesis Eq. 2-12)
    Σ(S) = (F(S) + C_p⁻¹)⁻¹                                (posterior covariance; the Schur complement)
    σ_f²(S) = y_fᵀ Σ(S) y_f                                 (forecast variance)

The data worth of candidate c given S is the mean fractional reduction of the variances of the targets,

    worth(c | S) = mean over t of [1 − σ_t²(S ∪ {c}) / σ_t²(S)],

the targets being the chosen forecasts, or the parameters when none is chosen (for a parameter,
y_t is its unit vector). Identifiability uses the data alone: the singular values and vectors of J_D =
J diag(d) of the stacked Jacobian and the verdict per parameter (identifiable, only in combination, not
identifiable) of :mod:`rivercal.analysis.identifiability` (thesis Eq. 2-11 … 2-13; Doherty and Hunt 2009).
They depend on the stacked J only through JᵀJ, so each set is analysed from a p × p factor R with
RᵀR = F(S) (the same singular values, vectors, covariance and correlations), never from the stacked
series.

The choice of K gauges is greedy and re-evaluated after each pick: each step takes the candidate with
the most identifiable parameters, then the largest worth (worth per unit cost where candidates have a
cost). Then an exchange pass (Fedorov's exchange, one gauge at a time) swaps a chosen gauge for one left
out while that raises the set's number of identifiable parameters or, at equal numbers, lowers the
mean fractional variance of the targets. Without K the picks go on until every parameter is
identifiable (or no candidate adds anything), which is then the K the advice says is enough.

Assumptions (docs/explanation/gauge-advice.md): the model is linear in x over the posterior's spread
(first order), the errors of the observations are Gaussian and independent from one output time to the
next with the σ given, and the window's flow conditions are those under which the gauges will measure (a
weir in free flow in the window hides its downstream level's sensitivity to its crest).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import pandas as pd

from rivercal.analysis._worth import Assessment, Candidate, LinearWorth, Step, posterior_covariance
from rivercal.analysis.identifiability import IdentifiabilityOptions
from rivercal.analysis.jacobian import fd_jacobian, parameter_scales

if TYPE_CHECKING:
    from rivercal.models.contract import Model, ModelState
    from rivercal.parameters import ParameterSet

__all__ = [
    "PRIOR_RANGE_SIGMAS",
    "Advice",
    "Assessment",
    "Candidate",
    "LinearWorth",
    "Step",
    "advice_jacobian",
    "advise",
    "model_candidates",
    "posterior_covariance",
    "prior_std",
]

log = logging.getLogger(__name__)

#: A parameter without ``prior_std`` has a prior σ of its range divided by this (bounds at ±2σ), optimiser units.
PRIOR_RANGE_SIGMAS = 4.0


def model_candidates(model: Model, where: str, measure: str) -> list[Candidate]:
    """The places a model offers for a gauge (``points``: every calculation point; ``structures``: either side).

    Asked through the optional capability :class:`~rivercal.models.capabilities.VirtualStations`; ``measure`` is
    ``level``, ``discharge`` or ``both``.

    Raises
    ------
    ValueError
        When the model lacks the capability.
    """
    from rivercal.models.capabilities import VirtualStations

    if not isinstance(model, VirtualStations):
        raise ValueError(f"model {getattr(model, 'name', '?')!r} cannot simulate series at places where it has no "
                         "station (it lacks the optional capability VirtualStations), so it cannot be asked where a "
                         "new gauge would help")
    return [Candidate(loc.id, loc.series, loc.name, None, loc) for loc in model.candidate_locations(where, measure)]


def prior_std(parameters: ParameterSet, scale: np.ndarray | None = None) -> np.ndarray:
    """Prior σ per parameter, optimiser units: its ``prior_std``, else (ub − lb) / :data:`PRIOR_RANGE_SIGMAS`."""
    lb, ub = (np.asarray(b, dtype=float) for b in parameters.bounds())
    default = (ub - lb) / PRIOR_RANGE_SIGMAS
    given = parameters.prior_std()
    if given is None:
        return default
    given = np.asarray(given, dtype=float)
    return np.where(np.isfinite(given), given, default)


@dataclass(frozen=True)
class Advice:
    """Outcome of :func:`advise`.

    Attributes
    ----------
    analysis
        The linear analysis (:class:`LinearWorth`).
    before
        The present stations alone.
    table
        Every candidate added to the present stations (:meth:`LinearWorth.worth_table`).
    steps
        The choice, one gauge at a time.
    after
        The present stations and the chosen gauges (analysed on the stacked series).
    enough
        The number of gauges after which every parameter is identifiable (None: not reached).
    jacobian_runs, wall_s
        Model runs of the Jacobian; wall time of the whole advice, s.
    extra
        Anything else (window, σ, the Jacobian's rows …).
    """

    analysis: LinearWorth
    before: Assessment
    table: pd.DataFrame
    steps: list[Step]
    after: Assessment
    enough: int | None
    jacobian_runs: int
    wall_s: float
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def chosen(self) -> list[str]:
        """The chosen candidates' ids, in order."""
        return [s.candidate for s in self.steps]


# --------------------------------------------------------------------------------------------------
# the Jacobian of every candidate's series, through the model contract
# --------------------------------------------------------------------------------------------------


def advice_jacobian(model: Model, parameters: ParameterSet, window: tuple[pd.Timestamp, pd.Timestamp], *,
                    candidates: Sequence[Candidate], base_series: Sequence[str] | None = None,
                    sigma: Mapping[str, float] | None = None, forecasts: Sequence[str] = (),
                    horizon: pd.Timedelta | str = "48h", warmup: pd.Timedelta | str = "24h",
                    state: ModelState | None = None, rel_step: float = 0.01,
                    scheme: Literal["forward", "central"] = "forward", workers: Any = None) -> dict[str, Any]:
    """One finite-difference Jacobian of the present stations', the candidates' and the forecasts' series.

    The candidates' places are added to the model through its optional capability
    :class:`~rivercal.models.capabilities.VirtualStations` (a candidate whose series the model already
    simulates needs none); then p + 1 runs (2p + 1 central) of the window give every row at once.

    Parameters
    ----------
    model
        A model of the contract.
    parameters
        The :class:`~rivercal.parameters.ParameterSet`; the point is their initial values.
    window
        (start, end) UTC; the runs start ``warmup`` earlier.
    candidates
        The candidates (their ``location`` is passed to ``model.with_stations`` when the model does not
        simulate their series yet).
    base_series
        The present stations' series (default: every level and discharge the model simulates).
    sigma
        σ by series id or quantity (``h``, ``h_up``, ``h_down``, ``Q``), m and m³/s (default
        :data:`rivercal.observations.DEFAULT_SIGMA`).
    forecasts
        Series ids whose mean over ``horizon`` after the window is a forecast.
    horizon, warmup, state
        Forecast horizon; simulated time before the window; model state at ``start − warmup`` (None: a
        spin-up at the parameters' initial values).
    rel_step, scheme, workers
        As for :func:`~rivercal.analysis.jacobian.fd_jacobian`.

    Returns
    -------
    dict
        ``base`` (J₀), ``base_rows``, ``blocks`` (J_c per candidate id), ``forecasts`` (y_f per series id),
        ``scale``, ``nfev``, ``model`` (the model with the candidates' stations), ``state``.

    Raises
    ------
    ValueError
        When a series is not simulated and the model cannot add places, the forecast horizon leaves the
        model's period, or a σ is not positive.
    """
    from rivercal.models.capabilities import VirtualStations
    from rivercal.models.contract import spun_up
    from rivercal.observations import DEFAULT_SIGMA, ObservationSeries, ObservationSet, measurable
    from rivercal.problem import CalibrationProblem

    start, end = window
    warmup = pd.Timedelta(warmup)
    horizon = pd.Timedelta(horizon)
    sig = {**DEFAULT_SIGMA, **dict(sigma or {})}
    for key, value in sig.items():
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ValueError(f"σ of {key} must be a positive number (m or m³/s), got {value!r}")
    base_series = list(base_series) if base_series is not None else measurable(model.observables)
    new = [c for c in candidates if any(s not in model.observables for s in c.series)]
    extended = model
    if new:
        if not isinstance(model, VirtualStations):
            raise ValueError(f"model {getattr(model, 'name', '?')!r} cannot simulate series at places where it has "
                             f"no station (it lacks the optional capability VirtualStations); candidate "
                             f"{new[0].id!r} needs one")
        extended = model.with_stations([c.location for c in new])
    unknown = [s for s in [*base_series, *forecasts] if s not in extended.observables]
    if unknown:
        raise ValueError(f"series {unknown[0]!r} is not simulated by the model")
    if forecasts and end + horizon > extended.end:
        raise ValueError(f"the forecast horizon reaches {end + horizon}, after the end of the model's period "
                         f"({extended.end}); choose an earlier window or a shorter horizon")
    last = end + horizon if forecasts else end
    if state is None and start - warmup > extended.start:
        state = spun_up(model, parameters.quantities({}), start - warmup)
    dt = pd.Timedelta(seconds=float(extended.output_interval))
    inside = pd.date_range(start, end, freq=dt)
    after = pd.date_range(end + dt, last, freq=dt) if forecasts else inside[:0]

    def sigma_of(series_id: str) -> float:
        return float(sig.get(series_id, sig.get(series_id.rpartition(".")[2], 1.0)))

    cand_series = list(dict.fromkeys(s for c in candidates for s in c.series if s not in base_series))
    observed = [*base_series, *cand_series]
    times = {sid: inside for sid in observed}
    for sid in forecasts:  # a forecast is the series' mean over the horizon: rows after the window's end
        times[sid] = times[sid].append(after) if sid in times else after
    obs = ObservationSet(tuple(ObservationSeries(sid, t, np.zeros(t.size), sigma_of(sid)) for sid, t in times.items()))
    problem = CalibrationProblem(extended, parameters, obs, (start, last), state=state, warmup=warmup)
    jac = fd_jacobian(problem, rel_step=rel_step, scheme=scheme, workers=workers)
    rows = np.asarray(jac.rows)
    in_window = np.concatenate([np.asarray(s.times <= end) for s in problem.observations])
    matrix = jac.matrix

    def block(series_ids: Iterable[str]) -> np.ndarray:
        mask = np.isin(rows, list(series_ids)) & in_window
        return matrix[mask]

    base = block(base_series)
    base_rows = tuple(rows[np.isin(rows, base_series) & in_window])
    blocks = {c.id: block(c.series) for c in candidates}
    fc = {}
    for sid in forecasts:  # the rows are −∂ŷ/∂x / σ
        fc[sid] = -sigma_of(sid) * matrix[(rows == sid) & ~in_window].mean(axis=0)
    return {"base": base, "base_rows": base_rows, "blocks": blocks, "forecasts": fc,
            "scale": parameter_scales(problem), "nfev": jac.nfev, "model": extended, "state": problem.state,
            "sigma": {s: sigma_of(s) for s in observed}}


def advise(model: Model, parameters: ParameterSet, window: tuple[pd.Timestamp, pd.Timestamp],
           candidates: Sequence[Candidate], *, add: int | None = None, base_series: Sequence[str] | None = None,
           sigma: Mapping[str, float] | None = None, forecasts: Sequence[str] = (),
           horizon: pd.Timedelta | str = "48h", warmup: pd.Timedelta | str = "24h", state: ModelState | None = None,
           rel_step: float = 0.01, scheme: Literal["forward", "central"] = "forward",
           options: IdentifiabilityOptions | None = None, exchange: bool = True, workers: Any = None,
           progress: Callable[[str], None] | None = None) -> Advice:
    """Where to put the next ``add`` gauges among ``candidates`` (module docstring).

    Parameters
    ----------
    model, parameters, window, candidates, base_series, sigma, forecasts, horizon, warmup, state, rel_step,
    scheme, workers
        As for :func:`advice_jacobian`.
    add
        Gauges to add; None: as many as it takes until every parameter is identifiable (at most p).
    options
        Thresholds of the identifiability verdict.
    exchange
        Improve the greedy choice by one-for-one swaps.
    progress
        Called with a line at each stage.

    Returns
    -------
    Advice
    """
    t0 = time.perf_counter()
    if not candidates:
        raise ValueError("no candidate places: every place of that kind is measured already")
    if add is not None and (isinstance(add, bool) or not isinstance(add, int) or add < 1):
        raise ValueError(f"the number of gauges to add must be a positive integer, got {add!r}")
    say = progress or (lambda _line: None)
    say(f"Jacobian of {len(parameters)} parameters over the series of {len(candidates)} candidates")
    jac = advice_jacobian(model, parameters, window, candidates=candidates, base_series=base_series, sigma=sigma,
                          forecasts=forecasts, horizon=horizon, warmup=warmup, state=state, rel_step=rel_step,
                          scheme=scheme, workers=workers)
    analysis = LinearWorth(parameters.names, jac["base"], candidates, jac["blocks"], prior_std(parameters),
                           scale=jac["scale"], forecasts=jac["forecasts"], options=options,
                           base_rows=jac["base_rows"])
    say("data worth of every candidate")
    before = analysis.assess([], rows=True)
    table = analysis.worth_table()
    say("choosing the gauges")
    steps = analysis.greedy(add, exchange=exchange, progress=say)
    chosen = [s.candidate for s in steps]
    after = analysis.assess(chosen, rows=True)
    p = len(parameters)
    enough = 0 if before.identifiable == p else next(
        (s.number for s in steps if s.assessment.identifiable == p), None)
    wall = time.perf_counter() - t0
    log.info("gauge advice: %d candidates, %d chosen, %d model runs, %.1f s", len(candidates), len(chosen),
             jac["nfev"], wall)
    return Advice(analysis=analysis, before=before, table=table, steps=steps, after=after, enough=enough,
                  jacobian_runs=int(jac["nfev"]), wall_s=wall,
                  extra={"model": jac["model"], "state": jac["state"], "sigma": jac["sigma"],
                         "window": (window[0], window[1])})
