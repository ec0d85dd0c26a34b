"""Transition estimation (thesis §6-3): a parameter as value-before, value-after and transition time.

A single value per calibration window averages a sudden change (mowing, a lowered weir) that happens
inside the window: the estimate matches neither the value before nor the value after. Thesis §6-3
proposes to discretise the parameter into three: the value before the transition, the value after it,
and the time of the transition. :func:`estimate_transition` does that with the unchanged calibration
core, in three pieces along their seams:

- the model adapter :class:`~rivercal.models.transition.TransitionModel` (the value jumps at τ; the
  calibration problem sees three quantities of the adapter);
- the search (:mod:`rivercal.online.transition_search`): a start for the three-value fit from the
  residuals of the one-value fit, and the test whether the window holds a transition;
- the estimator here: one-value fit, start, three-value fit, test.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pandas as pd

from rivercal.models.contract import Model, ModelState
from rivercal.models.transition import AFTER, BEFORE, TIME, TransitionModel
from rivercal.observations import ObservationSet
from rivercal.online.transition_search import TransitionTest, effective_size, transition_start, transition_test
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import Calibration, CalibrationProblem, calibrate

__all__ = [
    "AFTER",
    "BEFORE",
    "TIME",
    "TransitionEstimate",
    "TransitionModel",
    "TransitionTest",
    "estimate_transition",
    "transition_start",
    "transition_test",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TransitionEstimate:
    """Outcome of :func:`estimate_transition`.

    Attributes
    ----------
    single
        The one-value calibration over the window (the "average value" of thesis §6-3).
    transition
        The three-value calibration (estimates ``<name>_before``, ``<name>_after``, ``<name>_time``).
    before, after
        Estimated values before and after the transition (the parameter's unit).
    time
        Estimated transition time (UTC).
    tau
        The same as h since the window start.
    test
        The verdict of :func:`transition_test`.
    model_runs
        Model runs of both calibrations (plus the one that re-weights S₁, if needed).
    wall_time
        Wall-clock time of both calibrations, s.
    """

    single: Calibration
    transition: Calibration
    before: float
    after: float
    time: pd.Timestamp
    tau: float
    test: TransitionTest
    model_runs: int
    wall_time: float

    def summary(self) -> dict[str, Any]:
        """A JSON-friendly summary."""
        return {"transition": self.test.transition, "reason": self.test.reason, "before": self.before,
                "after": self.after, "time": self.time.isoformat(), "tau_h": self.tau,
                "single": next(iter(self.single.estimates.values())), "cost_single": self.test.cost_single,
                "cost_transition": self.test.cost_transition, "p_value": self.test.p_value,
                "n_effective": self.test.n_effective,
                "model_runs": self.model_runs, "wall_s": round(self.wall_time, 3)}


def estimate_transition(model: Model, parameter: Parameter, observations: ObservationSet, window: tuple[Any, Any], *,
                        state: ModelState | None = None, warmup: pd.Timedelta | str = "24h",
                        fixed: Mapping[str, float] | None = None,
                        initial: Mapping[str, float] | None = None, algorithm: str = "dud",
                        options: Mapping[str, Any] | None = None, workers: int | None = 1,
                        max_nfev: int | None = None, smoothing: Literal["substep", "none"] = "substep",
                        alpha: float = 1e-3, min_reduction: float = 0.25, min_gain: float = 1.0, loss: str = "l2",
                        loss_scale: float | None = None, correlated: bool = True) -> TransitionEstimate:
    """Fit one value and (before, after, τ) of ``parameter`` over ``window``, and test for a transition.

    The on-line service calls this when the per-cycle estimate jumps: one-value fit, a start for the
    three-value fit from its residuals (:func:`transition_start`), the three-value fit through
    :class:`TransitionModel` with the unchanged calibration core, and :func:`transition_test`.

    Parameters
    ----------
    model
        A model of the model contract (see :class:`TransitionModel`).
    parameter
        The parameter that may have changed (bounds, transform, first step); its ``initial`` starts the
        one-value fit (in the on-line service: the last accepted estimate).
    observations, window, state, warmup, fixed
        As for :class:`~rivercal.problem.CalibrationProblem`; the state (computed once when None) is
        shared by both fits.
    initial
        Initial ``before``, ``after`` (parameter unit) and ``time`` (h since the window start) of the
        three-value fit; those not given come from :func:`transition_start` (one extra model run).
    algorithm, options, workers
        As for :func:`~rivercal.problem.calibrate`.
    max_nfev
        Budget of model runs of each of the two calibrations.
    smoothing
        See :class:`TransitionModel`.
    alpha, min_reduction, min_gain
        The rule of :func:`transition_test`.
    loss, loss_scale
        The cost of both fits (:class:`~rivercal.problem.CalibrationProblem`).
    correlated
        Weigh the F-test by the number of independent residuals that the three-value fit's residuals are
        worth (:func:`~rivercal.online.transition_search.effective_size`); False: take them as independent.
    """
    initial = dict(initial or {})
    unknown = sorted(set(initial) - {"before", "after", "time"})
    if unknown:
        raise ValueError(f"initial: unknown key {unknown[0]!r}; use 'before', 'after' (parameter unit) and 'time' (h)")
    single_problem = CalibrationProblem(model, ParameterSet([parameter]), observations, window, state=state,
                                        warmup=warmup, fixed=fixed, loss=loss, loss_scale=loss_scale)
    t0 = time.perf_counter()
    single = calibrate(single_problem, algorithm, options, workers=workers, max_nfev=max_nfev)
    s = single.estimates[parameter.name]
    runs = single.result.nfev
    if not {"before", "after", "time"} <= set(initial):
        initial = {**transition_start(single_problem, single), **initial}
        runs += 1
    tm = TransitionModel(model, parameter, reference=single_problem.start, smoothing=smoothing)
    params = tm.parameter_set(window, before=initial["before"], after=initial["after"], time=initial["time"])
    problem = CalibrationProblem(tm, params, observations, window, state=single_problem.state, warmup=warmup,
                                 fixed=fixed, loss=loss, loss_scale=loss_scale)
    transition = calibrate(problem, algorithm, options, workers=workers, max_nfev=max_nfev)
    runs += transition.result.nfev
    if all(o.sigma is not None for o in problem.observations):  # 1/σ weights: both costs on one scale
        cost_single = single.result.cost
    else:  # thesis Eq. 2-6 weights depend on each problem's first run: re-evaluate S₁ in the second problem
        cost_single = problem.cost(params.to_x({params.names[0]: s, params.names[1]: s}))
        runs += 1
    wall = time.perf_counter() - t0
    est = transition.estimates
    before, after, tau = (est[p.name] for p in params)
    n = problem.observations.n_values
    n_eff = None
    if correlated:
        r3 = transition.result.extra.get("residuals")
        r3 = np.asarray(r3 if r3 is not None else problem.residuals(transition.result.x))[:n]
        n_eff = effective_size(r3, [len(o) for o in problem.observations])
    test = transition_test(cost_single, transition.result.cost, n, alpha=alpha,
                           min_reduction=min_reduction, min_gain=min_gain, n_effective=n_eff)
    log.info("transition of %s in %s .. %s: %s", parameter.name, problem.start, problem.end, test.reason)
    return TransitionEstimate(single=single, transition=transition, before=before, after=after,
                              time=tm.time_of(tau), tau=tau, test=test, model_runs=runs, wall_time=wall)
