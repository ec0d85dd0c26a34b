"""The calibration problem: a model, parameters, observations and a window → weighted residuals.

:class:`CalibrationProblem` turns the optimiser's vector x into model quantities
(:class:`~rivercal.parameters.ParameterSet`), runs any model of the model contract
(:mod:`rivercal.models.contract`)::

    model.simulate(parameters, start, end, state=None) -> (SimulationResult, state)

Parameter targets and fixed quantities must be quantities the model declares settable, and a
parameter's range must keep them inside the bounds the model declares (checked before any run).

over the window (after a warm-up that lets the state adjust to the candidate parameters), and returns
the weighted residuals of thesis Eq. 2-3, r = √W (y − ŷ), so that the cost is S(θ) = Σ rᵀ r:

- W = 1/σ² per series, or thesis Eq. 2-6, W = 1/Δŷ²_max, with Δŷ_max the largest absolute
  difference between the observations and the run at the initial parameters (for series without σ);
- simulated series are interpolated linearly to the observation times (observations between output
  times are not rejected); missing observations were dropped when the series were made.

Observations with outliers or a model with structural error make a few residuals much larger than
the rest; ``loss`` makes the cost robust to them (Huber 1964; a Student-t likelihood, Lange et al. 1989)
by replacing each weighted residual r with r̃ = sign(r) √(2 ρ(r)), so that Σ r̃² = 2 Σ ρ(r) and every
least-squares optimiser minimises the robust cost unchanged:

- ``huber``: ρ(r) = r²/2 for |r| ≤ c, c |r| − c²/2 beyond (c = ``loss_scale``, default 1.345: 95 %
  efficiency under Gaussian errors); r̃ = r inside, √(2c|r| − c²) beyond — like weights 1 inside and
  c/|r| beyond (iteratively reweighted least squares);
- ``student-t``: ρ(r) = (ν c²/2) ln(1 + r²/(ν c²)) with ν = 4 degrees of freedom and c = ``loss_scale``
  (default 1): weights (1 + r²/(ν c²))⁻¹, a large residual barely counts;
- ``l2`` (default): r̃ = r, thesis Eq. 2-3.

c is in units of the weighted residual, i.e. of σ.

A model run that fails (diverges, raises a :class:`~rivercal.errors.ModelRunError`, or returns
non-finite values) follows an explicit policy: ``raise`` re-raises it; ``penalty`` logs it and returns
residuals whose cost is the ``penalty`` value, so that an optimiser steers away from that point.

:func:`calibrate` runs an optimiser of :mod:`rivercal.optimise` on a problem, with its batches on an
:class:`~rivercal.evaluate.Evaluator`, and reports the estimates in physical units. It hands every local
method the parameters' own first perturbations (thesis Eq. 2-8 / 2-9) as its first step, and every
method that differentiates the problem's difference steps and numerical noise (see
:meth:`CalibrationProblem.difference_steps`): a hydrodynamic model iterates each time step only to a
tolerance (the embedded engine's Picard level tolerance, 10⁻⁴ m by default), so a difference of 1.5e-8 of
a parameter, scipy's default, measures that jitter rather than the derivative.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pandas as pd

from rivercal._time import seconds_since, utc
from rivercal.errors import ModelRunError
from rivercal.evaluate import Evaluator
from rivercal.models.contract import Model, check_parameters, spun_up
from rivercal.observations import ObservationSet
from rivercal.optimise import OPTIONS, IterationRecord, OptimiseResult, get_optimiser
from rivercal.parameters import ParameterSet

__all__ = ["LOSSES", "Calibration", "CalibrationProblem", "CostBreakdown", "Model", "calibrate", "problem_evaluator",
           "robust_residuals"]

log = logging.getLogger(__name__)

#: Floor of Δŷ_max in thesis Eq. 2-6 (m or m³/s), so that a series the prior run already fits exactly
#: does not get an infinite weight.
MIN_MAX_DEVIATION = 1e-3

#: Robust costs of :class:`CalibrationProblem` (module docstring) and their default scale c (in σ).
LOSSES = {"l2": None, "huber": 1.345, "student-t": 1.0}
#: Degrees of freedom of the Student-t cost.
STUDENT_T_DOF = 4.0


def robust_residuals(r: np.ndarray, loss: str, scale: float | None = None) -> np.ndarray:
    """Weighted residuals r → r̃ = sign(r) √(2 ρ(r)) of a robust cost (module docstring); ``l2`` returns r.

    Examples
    --------
    >>> robust_residuals(np.array([0.5, -3.0]), "huber", 1.0).round(4).tolist()
    [0.5, -2.2361]
    """
    if loss not in LOSSES:
        raise ValueError(f"unknown loss {loss!r}; choose one of {', '.join(LOSSES)}")
    if loss == "l2":
        return r
    c = float(LOSSES[loss] if scale is None else scale)
    a = np.abs(r)
    if loss == "huber":
        out = np.where(a <= c, a, np.sqrt(np.maximum(2.0 * c * a - c * c, 0.0)))
    else:
        nc2 = STUDENT_T_DOF * c * c
        out = np.sqrt(nc2 * np.log1p(a * a / nc2))
    return np.sign(r) * out


#: First guess of the finite-difference step, as a fraction of a parameter's range (the steps are then
#: checked against the model's noise and enlarged where the difference does not stand 10 times above it).
DIFFERENCE_STEP = 1e-3


@dataclass(frozen=True)
class CostBreakdown:
    """Cost of one parameter vector (thesis Eq. 2-3): total, per series and per station.

    Attributes
    ----------
    total
        S(θ), dimensionless (weighted squared residuals).
    by_series, by_station
        Contributions by series id and by station id.
    """

    total: float
    by_series: dict[str, float]
    by_station: dict[str, float]


class CalibrationProblem:
    """Weighted residuals of a model against observations over a window.

    Parameters
    ----------
    model
        A model of the model contract (e.g. :func:`rivercal.models.load_model`).
    parameters
        The parameters to estimate, in vector order.
    observations
        The observations; only their values inside the window count.
    window
        (start, end) of the calibration window (UTC).
    state
        Model state at ``start - warmup``; None: computed by a run at the initial parameters from the
        model's own start (cold start and spin-up) up to there.
    warmup
        Simulated time before the window that each run lets the state adjust to the candidate
        parameters; its residuals do not count.
    fixed
        Model quantities held at given values during the calibration (e.g. the other parameters of a
        twin experiment).
    on_failure
        ``raise`` or ``penalty`` (see the module docstring).
    penalty
        Cost of a failed run under the ``penalty`` policy.
    noise
        The model's numerical noise in the simulated series (m for levels, m³/s for discharges): the
        size of the jitter a tiny parameter change causes. Default: the ``numerical_noise`` the model
        declares (the embedded engine's Picard level tolerance, SWMM's head tolerance), else unknown
        (None).

    Raises
    ------
    ValueError
        When a series is not simulated by the model, a target is not a settable quantity of the model
        (or a parameter's range leaves its bounds), the window holds no observation, or an option is
        invalid — before any model run.
    """

    def __init__(self, model: Model, parameters: ParameterSet, observations: ObservationSet,
                 window: tuple[Any, Any], *, state: Any = None, warmup: pd.Timedelta | str = "24h",
                 fixed: Mapping[str, float] | None = None, on_failure: Literal["raise", "penalty"] = "raise",
                 penalty: float = 1e8, noise: float | None = None, loss: str = "l2",
                 loss_scale: float | None = None):
        if on_failure not in ("raise", "penalty"):
            raise ValueError(f"on_failure must be 'raise' or 'penalty', got {on_failure!r}")
        if loss not in LOSSES:
            raise ValueError(f"unknown loss {loss!r}; choose one of {', '.join(LOSSES)}")
        if loss_scale is not None and not (math.isfinite(loss_scale) and loss_scale > 0):
            raise ValueError(f"loss_scale must be a positive number (in σ), got {loss_scale!r}")
        self.loss = loss
        self.loss_scale = loss_scale
        if not penalty > 0:
            raise ValueError(f"penalty must be positive, got {penalty}")
        if len(parameters) == 0:
            raise ValueError("no parameters to calibrate")
        self.model = model
        self.parameters = parameters
        self.start, self.end = (utc(window[0]), utc(window[1]))
        if not self.end > self.start:
            raise ValueError(f"the window end {self.end} is not after its start {self.start}")
        self.warmup = pd.Timedelta(warmup)
        self.fixed = dict(fixed or {})
        self.on_failure = on_failure
        self.penalty = float(penalty)
        unknown = [s for s in observations.ids if s not in model.observables]
        if unknown:
            raise ValueError(f"observation series {unknown[0]!r} is not simulated by the model "
                             f"(it simulates: {', '.join(model.observables)})")
        clash = sorted(set(self.fixed) & set(parameters.quantities({})))
        if clash:
            raise ValueError(f"{clash[0]} is both fixed and calibrated")
        check_parameters(model, parameters, self.fixed)
        self.observations = ObservationSet(tuple(s for s in observations.within(self.start, self.end) if len(s)))
        if self.observations.n_values == 0:
            raise ValueError(f"the window {self.start} .. {self.end} holds no observations")
        self.run_start = self.start - self.warmup
        self.noise = _model_noise(model) if noise is None else float(noise)
        if self.noise is not None and not (math.isfinite(self.noise) and self.noise > 0):
            raise ValueError(f"noise must be a positive number (m or m³/s), got {noise!r}")
        self._state = state
        self._sqrt_w: np.ndarray | None = None
        self.n_runs = 0

    # -- vectors ------------------------------------------------------------------------------------

    @property
    def x0(self) -> np.ndarray:
        """Initial optimiser vector."""
        return self.parameters.to_x()

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the optimiser vector."""
        return self.parameters.bounds()

    def quantities(self, x: np.ndarray) -> dict[str, float]:
        """Model quantities for optimiser vector ``x`` (plus the fixed ones)."""
        return {**self.fixed, **self.parameters.quantities(self.parameters.values(x))}

    def difference_steps(self) -> np.ndarray:
        """First finite-difference step per parameter (optimiser units): 10⁻³ of its range.

        (10⁻² of its first perturbation where a bound is infinite.) The optimisers check the differences
        against :meth:`residual_noise` and enlarge a step whose difference does not stand 10 times above
        the noise: 1.3 mm for a crest with a 1.3 m range, 0.03 m^(1/3)/s of a Strickler coefficient in
        8 … 40, where 1.5e-8 of the value (scipy's default) changes the levels far less than the engine's
        tolerance of 10⁻⁴ m.
        """
        lb, ub = self.bounds
        width = np.asarray(ub, dtype=float) - np.asarray(lb, dtype=float)
        return np.where(np.isfinite(width), DIFFERENCE_STEP * width, 0.01 * self.parameters.initial_steps())

    def residual_noise(self) -> np.ndarray | None:
        """The model's noise per weighted residual, √W · :attr:`noise` (None when the noise is unknown)."""
        return None if self.noise is None else self.noise * self.sqrt_weights

    # -- state and weights --------------------------------------------------------------------------

    @property
    def state(self) -> Any:
        """Model state at the start of each run (computed on first use).

        None when the runs start at the model's own start: they cold-start there.
        """
        model_start = getattr(self.model, "start", None)
        if self._state is None and (model_start is None or self.run_start > utc(model_start)):
            log.info("computing the start state at %s with the initial parameters", self.run_start)
            self._state = spun_up(self.model, self.quantities(self.x0), self.run_start)
        return self._state

    def _weights(self, predictions: dict[str, np.ndarray]) -> np.ndarray:
        parts = []
        for s in self.observations:
            if s.sigma is not None:
                w = 1.0 / s.sigma
            else:  # thesis Eq. 2-6 from the prior run
                w = 1.0 / max(float(np.max(np.abs(s.values - predictions[s.id]))), MIN_MAX_DEVIATION)
            parts.append(np.full(len(s), w))
        return np.concatenate(parts)

    @property
    def sqrt_weights(self) -> np.ndarray:
        """√W of every residual (1/σ, or 1/Δŷ_max of thesis Eq. 2-6 from the run at x0)."""
        if self._sqrt_w is None:
            if all(s.sigma is not None for s in self.observations):
                self._sqrt_w = self._weights({})
            else:
                self._sqrt_w = self._weights(self.predictions(self.simulate(self.x0)))
        return self._sqrt_w

    # -- running -------------------------------------------------------------------------------------

    def simulate(self, x: np.ndarray, *, end: pd.Timestamp | None = None) -> Any:
        """Run the model for ``x`` over warm-up and window (or up to ``end``); return the SimulationResult."""
        self.n_runs += 1
        result, _ = self.model.simulate(self.quantities(np.asarray(x, dtype=float)), start=self.run_start,
                                        end=end or self.end, state=self.state)
        return result

    def predictions(self, result: Any) -> dict[str, np.ndarray]:
        """Simulated values at the observation times, by series id (linear interpolation in time)."""
        series = result.series
        at = seconds_since(series.index, self.run_start)
        return {s.id: np.interp(t, at, series[s.id].to_numpy(dtype=float))
                for s, t in zip(self.observations, self._observation_seconds, strict=True)}

    @functools.cached_property
    def _observation_seconds(self) -> list[np.ndarray]:
        """The observation times of each series (s after the run's start), converted once for all runs."""
        return [seconds_since(s.times, self.run_start) for s in self.observations]

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Weighted residuals √W (y − ŷ(x)) (robust ones with a ``loss``), in the order of :attr:`observations`."""
        self.sqrt_weights  # noqa: B018 - the weights' own run comes first
        try:
            return self._weighted(x, self.simulate(x))
        except ModelRunError as exc:
            return self._failed(x, exc)

    def _weighted(self, x: np.ndarray, result: Any) -> np.ndarray:
        pred = self.predictions(result)
        r = np.concatenate([s.values - pred[s.id] for s in self.observations]) * self.sqrt_weights
        if not np.all(np.isfinite(r)):
            raise ModelRunError(f"the model returned non-finite values for {self._describe(x)}")
        return robust_residuals(r, self.loss, self.loss_scale)

    def _failed(self, x: np.ndarray, exc: ModelRunError) -> np.ndarray:
        """The failure policy: re-raise, or residuals whose cost is the penalty."""
        if self.on_failure == "raise":
            raise exc
        log.warning("model run failed for %s (%s); penalty policy: cost %g", self._describe(x), exc, self.penalty)
        size = self.sqrt_weights.size
        return np.full(size, math.sqrt(self.penalty / size))

    @property
    def batched(self) -> bool:
        """Whether :meth:`residuals_batch` runs several points in one call: the model is the embedded engine."""
        from rivercal.engine.simulator import Simulator

        return isinstance(self.model, Simulator) and type(self.model).simulate is Simulator.simulate

    def residuals_batch(self, xs: list[np.ndarray], *, threads: int | None = None) -> list[np.ndarray]:
        """:meth:`residuals` of several points, their model runs in one batched engine call.

        The runs go through :func:`rivercal.engine.ensemble.run_ensemble` on ``threads`` threads (None:
        ``NUMBA_NUM_THREADS``; more than that: that many); each is bit-identical to its single run, so the results equal
        ``[self.residuals(x) for x in xs]``. A point whose run fails is run again alone, so that it follows
        the failure policy with the single run's error, in the order of the points. A model that is not the
        embedded engine runs the points one by one.
        """
        points = [np.asarray(x, dtype=float) for x in xs]
        if not self.batched or len(points) < 2:
            return [self.residuals(x) for x in points]
        import numba

        from rivercal.engine.ensemble import run_ensemble

        self.sqrt_weights  # noqa: B018
        state = self.state
        n = numba.config.NUMBA_NUM_THREADS if threads is None else max(1, min(int(threads),
                                                                              numba.config.NUMBA_NUM_THREADS))
        ens = run_ensemble(self.model, [self.quantities(x) for x in points], self.run_start, self.end,
                           None if state is None else [state] * len(points), n_threads=n, on_failure="report")
        self.n_runs += len(points) - len(ens.failures)
        out = []
        for m, x in enumerate(points):
            if m in ens.failures:
                out.append(self.residuals(x))  # alone: the single run's error and the failure policy
                continue
            try:
                out.append(self._weighted(x, _EnsembleMember(ens.series(m))))
            except ModelRunError as exc:
                out.append(self._failed(x, exc))
        return out

    def cost(self, x: np.ndarray) -> float:
        """S(x) = Σ r² (thesis Eq. 2-3; with a robust ``loss``, 2 Σ ρ(r))."""
        r = self.residuals(x)
        return float(r @ r)

    def cost_breakdown(self, x: np.ndarray) -> CostBreakdown:
        """S(x) in total, per series and per station."""
        r = self.residuals(x)
        by_series, i = {}, 0
        for s in self.observations:
            by_series[s.id] = float(r[i:i + len(s)] @ r[i:i + len(s)])
            i += len(s)
        by_station: dict[str, float] = {}
        for sid, c in by_series.items():
            by_station[sid.rpartition(".")[0]] = by_station.get(sid.rpartition(".")[0], 0.0) + c
        return CostBreakdown(total=float(r @ r), by_series=by_series, by_station=by_station)

    def _describe(self, x: np.ndarray) -> str:
        return ", ".join(f"{k}={v:.6g}" for k, v in self.parameters.values(x).items())

    def __repr__(self) -> str:
        name = getattr(self.model, "name", type(self.model).__name__)
        return (f"CalibrationProblem(model={name!r}, parameters={self.parameters.names}, "
                f"{len(self.observations)} series / {self.observations.n_values} values, "
                f"window {self.start:%Y-%m-%d %H:%M} … {self.end:%Y-%m-%d %H:%M} UTC, "
                f"warmup {self.warmup / pd.Timedelta('1h'):g} h, "
                f"on_failure={self.on_failure!r})")


@dataclass(frozen=True)
class _EnsembleMember:
    """One member's series of a batched run, where :meth:`CalibrationProblem.predictions` reads them."""

    series: pd.DataFrame


def problem_evaluator(problem: CalibrationProblem, workers: Any = None, *, batched: bool = True) -> Evaluator:
    """The :class:`~rivercal.evaluate.Evaluator` of a problem's residuals on ``workers``.

    On the embedded engine and two or more local workers, its batches are batched engine calls on as many
    threads (:meth:`CalibrationProblem.residuals_batch`), unless ``batched`` is False; else local processes,
    this process one by one, or a Dask cluster run the points.
    """
    use = batched and problem.batched
    return Evaluator(problem.residuals, workers=workers, batch=problem.residuals_batch if use else None)


@dataclass(frozen=True)
class Calibration:
    """The outcome of :func:`calibrate`.

    Attributes
    ----------
    result
        The optimiser's :class:`~rivercal.optimise.OptimiseResult` (optimiser coordinates).
    estimates
        Estimated values by parameter name, physical units.
    std
        Standard deviations by name in physical units (thesis Eq. 2-12) for observation errors of the
        weights' σ, where the method gives them.
    std_scaled
        The same scaled by s = √(S/(m − p)), the residual standard deviation the fit shows: right when
        the σ of the weights are right only up to a common factor (e.g. uniform ±a noise weighted as
        σ = a, whose true σ is a/√3).
    initial
        Initial values by name.
    wall_time
        Wall-clock time of the optimisation, s.
    algorithm
        Optimiser name.
    history
        Per iteration (iteration 0: the start point): ``iteration``, ``cost``, ``linear_cost``, ``nfev``
        and the values by name.
    units
        Unit of each parameter, by name (for reports).
    """

    result: OptimiseResult
    estimates: dict[str, float]
    std: dict[str, float]
    initial: dict[str, float]
    wall_time: float
    algorithm: str
    history: list[dict[str, float]] = field(default_factory=list)
    std_scaled: dict[str, float] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """A JSON-friendly summary."""
        r = self.result
        return {
            "algorithm": self.algorithm,
            "estimates": self.estimates,
            "std": self.std,
            "std_scaled": self.std_scaled,
            "initial": self.initial,
            "cost": r.cost,
            "iterations": r.nit,
            "model_runs": r.nfev,
            "wall_s": round(self.wall_time, 3),
            "status": r.status,
            "message": r.message,
            "success": r.success,
            "aborted": r.aborted,
        }

    # -- views -------------------------------------------------------------------------------------

    def __repr__(self) -> str:
        values = ", ".join(f"{n}={v:.6g}" + (f"±{self.std[n]:.2g}" if n in self.std else "")
                           for n, v in self.estimates.items())
        r = self.result
        return (f"Calibration({self.algorithm}, {_outcome(r)}, cost {r.cost:.6g}, {r.nfev} runs, {values})")

    def to_frame(self) -> pd.DataFrame:
        """The estimates as a table, one row per parameter (values in the parameters' units).

        Columns ``estimate``, ``std`` (thesis Eq. 2-12), ``std_scaled``, ``initial`` and ``unit``; NaN where
        the method gives no standard deviation.
        """
        rows = [{"name": n, "estimate": v, "std": self.std.get(n, np.nan), "std_scaled": self.std_scaled.get(n, np.nan),
                 "initial": self.initial.get(n, np.nan), "unit": self.units.get(n, "")}
                for n, v in self.estimates.items()]
        columns = ["name", "estimate", "std", "std_scaled", "initial", "unit"]
        return pd.DataFrame(rows, columns=columns).set_index("name")

    def correlation_frame(self) -> pd.DataFrame | None:
        """The correlation of the estimates (thesis Eq. 2-13), labelled by name; None without it."""
        cor = self.result.correlation
        if cor is None:
            return None
        names = list(self.estimates)
        return pd.DataFrame(np.asarray(cor, dtype=float), index=names, columns=names)

    def history_frame(self) -> pd.DataFrame:
        """:attr:`history` as a table indexed by iteration (cost dimensionless, values in their units)."""
        return pd.DataFrame(self.history).set_index("iteration") if self.history else pd.DataFrame()

    def fit_report(self, *, min_correlation: float = 0.1) -> str:
        """A plain-text report of the fit: method and outcome, cost, runs, estimates with σ, correlations.

        Parameters
        ----------
        min_correlation
            Correlations of a smaller magnitude are left out of the list.

        Returns
        -------
        str
            Lines like those of lmfit's ``fit_report``: ``[[Fit]]`` (method, status and message, cost S of
            thesis Eq. 2-3, iterations, model runs, wall time, residuals), ``[[Estimates]]`` (estimate ± σ
            of thesis Eq. 2-12, the scaled σ, the initial value, the unit) and ``[[Correlations]]`` (Eq. 2-13).
        """
        r = self.result
        start = self.history[0]["cost"] if self.history and self.history[0].get("iteration") == 0 else None
        residuals = r.extra.get("residuals")
        lines = [
            "[[Fit]]",
            f"    method       = {self.algorithm}",
            f"    outcome      = {_outcome(r)} (status {r.status}): {r.message}",
            f"    cost S       = {r.cost:.6g}" + (f" (start: {start:.6g})" if start is not None else ""),
            f"    iterations   = {r.nit}",
            f"    model runs   = {r.nfev}",
            f"    wall time    = {self.wall_time:.3g} s",
        ]
        if residuals is not None:
            m, p = len(residuals), len(self.estimates)
            lines.append(f"    residuals    = {m} (S/(m - p) = {r.cost / (m - p):.4g})" if m > p else
                         f"    residuals    = {m}")
        lines.append("[[Estimates]]")
        width = max(len(n) for n in self.estimates) if self.estimates else 0
        for n, v in self.estimates.items():
            sigma = f" +/- {self.std[n]:.4g}" if n in self.std else " (no σ)"
            scaled = f", scaled σ {self.std_scaled[n]:.4g}" if n in self.std_scaled else ""
            unit = f" {self.units[n]}" if self.units.get(n) else ""
            lines.append(f"    {n + ':':<{width + 1}} {v:.6g}{sigma}{unit} (initial {self.initial.get(n, np.nan):.6g}"
                         f"{scaled})")
        cor = self.correlation_frame()
        if cor is not None and len(cor) > 1:
            pairs = sorted(((a, b, float(cor.loc[a, b])) for i, a in enumerate(cor.index) for b in cor.index[i + 1:]),
                           key=lambda t: -abs(t[2]) if np.isfinite(t[2]) else 0.0)
            shown = [t for t in pairs if not abs(t[2]) < min_correlation]
            lines.append(f"[[Correlations]] (those below {min_correlation:g} in magnitude are not shown)")
            lines += [f"    C({a}, {b}) = {c:+.3f}" for a, b, c in shown] or ["    (none)"]
        return "\n".join(lines)


def calibrate(problem: CalibrationProblem, algorithm: str = "dud", options: Mapping[str, Any] | None = None, *,
              workers: int | None = None, max_nfev: int | None = None, deadline: float | None = None,
              callback: Callable[[IterationRecord], bool | None] | None = None, batched: bool = True,
              **extra: Any) -> Calibration:
    """Run optimiser ``algorithm`` on ``problem``.

    Parameters
    ----------
    problem
        The calibration problem.
    algorithm
        A name of :data:`rivercal.optimise.OPTIMISERS`.
    options
        Options of the algorithm (a dict of its options dataclass fields). Defaults from the problem: the
        first steps of every local method from the parameters' perturbations (thesis Eq. 2-8 / 2-9), the
        difference steps and noise of every method that differentiates, and for DuD and Sparse DuD the
        weak constraint from the parameters' ``prior_std`` around the initial values.
    workers
        Worker processes for batches (None: all cores; 1: serial).
    batched
        On the embedded engine, run each batch as one batched engine call on ``workers`` threads instead of
        worker processes (:func:`problem_evaluator`).
    max_nfev, deadline, callback
        Budget of model runs, wall-clock seconds, abort callback (see :mod:`rivercal.optimise`).
    extra
        Further keyword arguments of the optimiser (e.g. ``restart`` for DuD). Sparse DuD's ``dependency`` may
        also be a map by series and parameter names with a ``rows(problem)`` method (a
        :class:`~rivercal.analysis.dependency.DependencyMap`), turned here into the problem's residual rows.
    """
    optimiser = get_optimiser(algorithm)
    if extra.get("dependency") is not None and optimiser.__name__ != "sparse_dud":
        raise ValueError(f"a dependency map serves Sparse DuD only, not {algorithm!r}")
    if hasattr(extra.get("dependency"), "rows"):
        extra["dependency"] = extra["dependency"].rows(problem)
        log.info("Sparse DuD with a dependency map: at most %d of %d parameters per residual",
                 int(extra["dependency"].sum(axis=1).max()), len(problem.parameters))
    opts = _default_options(problem, OPTIONS[optimiser.__name__], dict(options or {}))
    lb, ub = problem.bounds
    x0 = problem.x0
    problem.state  # noqa: B018 - compute the start state and the weights here, before workers fork
    problem.sqrt_weights  # noqa: B018
    t0 = time.perf_counter()
    with problem_evaluator(problem, workers, batched=batched) as batch:
        result = optimiser(problem.residuals, x0, lb, ub, options=opts, callback=callback, batch=batch,
                           max_nfev=max_nfev, deadline=deadline, **extra)
    wall = time.perf_counter() - t0
    values = problem.parameters.values(result.x)
    std = _physical_std(problem, result.x, result.std)
    std_scaled = _physical_std(problem, result.x, result.extra.get("std_scaled"))
    history = [{"iteration": rec.nit, "cost": rec.cost, "linear_cost": rec.linear_cost, "nfev": rec.nfev,
                **problem.parameters.values(rec.x)} for rec in result.history]
    start_cost = next((c for xe, c in result.evaluations if np.array_equal(xe, x0)), None)
    if start_cost is not None:  # iteration 0: the start point
        history.insert(0, {"iteration": 0, "cost": start_cost, "linear_cost": float("nan"), "nfev": 1,
                           **problem.parameters.values(x0)})
    return Calibration(result=result, estimates=values, std=std, std_scaled=std_scaled,
                       initial=problem.parameters.values(x0), wall_time=wall, algorithm=algorithm, history=history,
                       units={p.name: p.unit for p in problem.parameters})


def _outcome(result: OptimiseResult) -> str:
    """``converged``, ``aborted`` or ``not converged`` (one word or two for reports)."""
    return "converged" if result.success else "aborted" if result.aborted else "not converged"


def _default_options(problem: CalibrationProblem, options_class: type, opts: dict[str, Any]) -> dict[str, Any]:
    """The caller's options plus the problem's defaults, where the method has such an option.

    - ``initial_step`` (DuD, Sparse DuD, Nelder-Mead, Powell) or ``x_scale`` (TRF, BFGS, CG): the
      parameters' first perturbations (thesis Eq. 2-8 / 2-9);
    - ``diff_step`` (TRF, BFGS, CG; unless the caller gives ``rel_step``) or ``jacobian_step`` (DuD's final
      Jacobian): :meth:`CalibrationProblem.difference_steps`; ``noise``: :meth:`CalibrationProblem.residual_noise`;
    - DuD and Sparse DuD: the weak constraint from the parameters' ``prior_std`` around the initial values.
    """
    fields = {f.name for f in dataclasses.fields(options_class)}
    steps = problem.parameters.initial_steps()
    for name in ("initial_step", "x_scale"):
        if name in fields:
            opts.setdefault(name, steps)
    if "diff_step" in fields and "rel_step" not in opts:
        opts.setdefault("diff_step", problem.difference_steps())
    if "jacobian_step" in fields:
        opts.setdefault("jacobian_step", problem.difference_steps())
    noise = problem.residual_noise()
    if "noise" in fields and noise is not None:
        opts.setdefault("noise", noise)
    prior = problem.parameters.prior_std()
    if "prior_std" in fields and prior is not None and "prior_std" not in opts:
        opts["prior_std"] = prior
        opts.setdefault("prior_mean", problem.x0)
    return opts


def _physical_std(problem: CalibrationProblem, x: np.ndarray, std: np.ndarray | None) -> dict[str, float]:
    """Standard deviations by name in physical units (delta method for the ln transform); {} without them."""
    if std is None:
        return {}
    return {p.name: float(math.exp(xv) * sx) if p.transform == "ln" else float(sx)
            for p, xv, sx in zip(problem.parameters, x, std, strict=True)}


def _model_noise(model: Any) -> float | None:
    """The numerical noise the model declares (:mod:`rivercal.models.contract`), None where it declares none."""
    value = getattr(model, "numerical_noise", None)
    if isinstance(value, int | float) and math.isfinite(value) and value > 0:
        return float(value)
    return None
