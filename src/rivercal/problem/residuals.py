"""The calibration problem: a model, parameters, observations and a window → weighted residuals.

:class:`CalibrationProblem` turns the optimiser's vector x into model quantities
(:class:`~rivercal.parameters.ParameterSet`), runs any model of the model contract
(:mod:`rivercal.models.contract`)::

    model.simulate(parameters, start, end, state=None) -> (SimulationResult, state)

over the window (after a warm-up that lets the state adjust to the candidate parameters), and returns
the weighted residuals of thesis Eq. 2-3, r = √W (y − ŷ), so that the cost is S(θ) = Σ rᵀ r:

- W = 1/σ² per series, or thesis Eq. 2-6, W = 1/Δŷ²_max, with Δŷ_max the largest absolute
  difference between the observations and the run at the initial parameters (for series without σ);
- simulated series are interpolated linearly to the observation times (observations between output
  times are not rejected); missing observations were dropped when the series were made;
- a robust ``loss`` (:mod:`rivercal.problem.loss`) replaces each weighted residual.

Parameter targets and fixed quantities must be quantities the model declares settable, and a
parameter's range must keep them inside the bounds the model declares (checked before any run).

A model run that fails (diverges, raises a :class:`~rivercal.errors.ModelRunError`, or returns
non-finite values) follows an explicit policy: ``raise`` re-raises it; ``penalty`` logs it and returns
residuals whose cost is the ``penalty`` value, so that an optimiser steers away from that point.

A model with batch runs (:class:`~rivercal.models.capabilities.BatchRuns`; the embedded engine) runs several
points in one call (:meth:`CalibrationProblem.residuals_batch`).
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pandas as pd

from rivercal._time import seconds_since, utc
from rivercal.errors import ModelRunError
from rivercal.models.capabilities import BatchRuns
from rivercal.models.contract import Model, ModelState, check_parameters, spun_up
from rivercal.observations import ObservationSet
from rivercal.parameters import ParameterSet
from rivercal.problem.loss import LOSSES, robust_residuals
from rivercal.results import SimulationResult

__all__ = ["DIFFERENCE_STEP", "MIN_MAX_DEVIATION", "CalibrationProblem", "CostBreakdown"]

log = logging.getLogger(__name__)

#: Floor of Δŷ_max in thesis Eq. 2-6 (m or m³/s), so that a series the prior run already fits exactly
#: does not get an infinite weight.
MIN_MAX_DEVIATION = 1e-3

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
                 window: tuple[Any, Any], *, state: ModelState | None = None, warmup: pd.Timedelta | str = "24h",
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
    def state(self) -> ModelState | None:
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

    def simulate(self, x: np.ndarray, *, end: pd.Timestamp | None = None) -> SimulationResult:
        """Run the model for ``x`` over warm-up and window (or up to ``end``); return the SimulationResult."""
        self.n_runs += 1
        result, _ = self.model.simulate(self.quantities(np.asarray(x, dtype=float)), start=self.run_start,
                                        end=end or self.end, state=self.state)
        return result

    def predictions(self, result: SimulationResult | _EnsembleMember) -> dict[str, np.ndarray]:
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

    def _weighted(self, x: np.ndarray, result: SimulationResult | _EnsembleMember) -> np.ndarray:
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
        """Whether :meth:`residuals_batch` runs several points in one call: the model has batch runs."""
        return isinstance(self.model, BatchRuns)

    def residuals_batch(self, xs: list[np.ndarray], *, threads: int | None = None) -> list[np.ndarray]:
        """:meth:`residuals` of several points, their model runs in one batched call of the model.

        The runs go through the model's :meth:`~rivercal.models.capabilities.BatchRuns.run_batch` on ``threads``
        threads (None: all the model offers); each is its single run, so the results equal
        ``[self.residuals(x) for x in xs]``. A point whose run fails is run again alone, so that it follows
        the failure policy with the single run's error, in the order of the points. A model without batch
        runs runs the points one by one.
        """
        points = [np.asarray(x, dtype=float) for x in xs]
        if not self.batched or len(points) < 2:
            return [self.residuals(x) for x in points]
        self.sqrt_weights  # noqa: B018
        state = self.state
        runs = self.model.run_batch([self.quantities(x) for x in points], self.run_start, self.end,
                                    None if state is None else [state] * len(points), threads=threads,
                                    on_failure="report")
        self.n_runs += len(points) - len(runs.failures)
        out = []
        for m, x in enumerate(points):
            if m in runs.failures:
                out.append(self.residuals(x))  # alone: the single run's error and the failure policy
                continue
            try:
                out.append(self._weighted(x, _EnsembleMember(runs.series(m))))
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


def _model_noise(model: Model) -> float | None:
    """The numerical noise the model declares (:mod:`rivercal.models.contract`), None where it declares none."""
    value = getattr(model, "numerical_noise", None)
    if isinstance(value, int | float) and math.isfinite(value) and value > 0:
        return float(value)
    return None
