""":func:`calibrate`: an optimiser of :mod:`rivercal.optimise` on a problem, its batches on an evaluator.

It reports the estimates in physical units. It hands every local method the parameters' own first
perturbations (thesis Eq. 2-8 / 2-9) as its first step, and every method that differentiates the problem's
difference steps and numerical noise (see :meth:`CalibrationProblem.difference_steps
<rivercal.problem.CalibrationProblem.difference_steps>`): a hydrodynamic model iterates each time step only to
a tolerance (the embedded engine's Picard level tolerance, 10⁻⁴ m by default), so a difference of 1.5e-8 of a
parameter, scipy's default, measures that jitter rather than the derivative.

:func:`problem_evaluator` is the :class:`~rivercal.evaluate.Evaluator` of a problem: on a model with batch runs
(:class:`~rivercal.models.capabilities.BatchRuns`, the embedded engine) a batch of points is one batched call of
the model on threads; else worker processes, this process or a Dask cluster run the points.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from rivercal.evaluate import Evaluator, Workers
from rivercal.optimise import OPTIONS, IterationRecord, get_optimiser
from rivercal.problem.outcome import Calibration
from rivercal.problem.residuals import CalibrationProblem

__all__ = ["calibrate", "problem_evaluator"]

log = logging.getLogger(__name__)


def problem_evaluator(problem: CalibrationProblem, workers: Workers = None, *, batched: bool = True) -> Evaluator:
    """The :class:`~rivercal.evaluate.Evaluator` of a problem's residuals on ``workers``.

    On a model with batch runs (the embedded engine) and two or more local workers, its batches are batched
    calls of the model on as many threads (:meth:`CalibrationProblem.residuals_batch`), unless ``batched`` is
    False; else local processes, this process one by one, or a Dask cluster run the points.
    """
    use = batched and problem.batched
    return Evaluator(problem.residuals, workers=workers, batch=problem.residuals_batch if use else None)


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
        On a model with batch runs (the embedded engine), run each batch as one batched call on ``workers``
        threads instead of worker processes (:func:`problem_evaluator`).
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
