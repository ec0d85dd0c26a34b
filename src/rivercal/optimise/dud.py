"""DuD: derivative-free Gauss-Newton by secant interpolation (Ralston & Jennrich 1978).

DuD keeps p + 1 evaluated points, interpolates the residual vector linearly through them (the secant
Jacobian J = A P⁻¹, with P the point differences and A the residual differences relative to the best
point), takes the Gauss-Newton step of that linear model, and backtracks along it until the cost drops;
the new point replaces the worst one (thesis §2-2-3). It is the algorithm of the reference study and of
OpenDA, run here as OpenDA runs it (reference note §1) with the stopping rules of thesis Table 4-3, but
without OpenDA's quirks:

- a parameter that starts at or near a bound is perturbed inwards (never clipped onto x0);
- bounds enter the step as a bounded linear least-squares problem (:func:`scipy.optimize.lsq_linear`,
  BVLS) on the secant system, not as an active-set QP on a rescaled normal matrix;
- a failed line search never puts a worse point into the set: the set is re-initialised around the best
  point with smaller perturbations (one parallel batch), and a second failure on the fresh set ends the
  run (status 5);
- the set is also re-initialised when it degenerates (ill-conditioned secant matrix), the remedy the
  OpenDA maintainers recommend by hand;
- every stopping rule is invariant to a common scale of the weights (T1 measures the drop of the cost
  in units of the residual variance s² = S/(m − p), the near-zero-cost rule against the cost change of
  one initial perturbation), and T1/T2 never fire right after a line search that shortened its step:
  such a step re-initialises the set instead when it gained what would have fired them (and, with
  ``stall_ratio``, when it gained little of what the secant model predicted for it);
  OpenDA's own rules are available as ``stopping="openda"`` (see :class:`DudOptions`);
- ``std`` and ``correlation`` come from a fresh finite-difference Jacobian at the end when the secant
  one has aged (p more runs, then one Gauss-Newton step with it);
- the p + 1 initial runs go out as one ``batch``; ``max_nfev`` caps the total number of runs;
- the run can be saved and continued exactly (``extra["state"]``, ``restart=``).

Status codes (``TERMINATION_MESSAGES``)
---------------------------------------
====== =====================================================================================
  1    T1: the last iteration lowered the cost by at most ``abs_tol`` × s²
  2    T2: ... by at most ``rel_tol`` × cost
  3    T3: the linearised cost predicted a relative decrease of at most ``rel_tol_linear``
  4    no predicted decrease from a fresh interpolation set (stationary point)
  5    line search failed on a fresh interpolation set (local minimum to model resolution)
  6    the cost is zero
  7    the cost is at most ``negligible_cost`` × the cost change of one initial perturbation
  0    ``max_nfev`` used up;  −1 callback;  −2 deadline;  −3 ``max_outer`` reached
 −4    the interpolation set stays degenerate
====== =====================================================================================

References
----------
Ralston, M. L. & Jennrich, R. I. (1978). Dud, a derivative-free algorithm for nonlinear least squares.
Technometrics 20(1), 7-14.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rivercal.optimise._core import (
    Batch,
    Callback,
    Fun,
    Run,
    coerce_options,
    project,
    validate_controls,
    validate_problem,
)
from rivercal.optimise._dud_engine import default_steps, run_dud, validate_restart
from rivercal.optimise._dud_options import TERMINATION_MESSAGES, DudOptions, DudState
from rivercal.optimise.jacobian import fd_jacobian, inward_steps
from rivercal.optimise.result import OptimiseResult

__all__ = ["TERMINATION_MESSAGES", "DudOptions", "DudState", "dud"]


class DenseSecant:
    """DuD's secant model: coordinate perturbations and J = A P⁻¹ through p + 1 points."""

    def __init__(self, max_condition: float):
        self.max_condition = max_condition

    def initial_points(self, x: np.ndarray, h: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> list[np.ndarray]:
        """Points x + s_j e_j with s_j = ±h_j pointing into the box (thesis Eq. 2-8)."""
        steps = inward_steps(x, h, lb, ub)
        points = []
        for j, s in enumerate(steps):
            p = x.copy()
            p[j] += s
            points.append(project(p, lb, ub))
        return points

    def jacobian(self, points: np.ndarray, residuals: np.ndarray) -> np.ndarray | None:
        """J with J P = A, or None when P is (nearly) singular after scaling."""
        p_mat = (points[1:] - points[0]).T
        a_mat = (residuals[1:] - residuals[0]).T
        extent = np.max(np.abs(p_mat), axis=1)
        if np.any(extent < np.finfo(float).tiny):  # zero or subnormal: no usable secant in that direction
            return None
        scaled = p_mat / extent[:, None]
        scaled /= np.linalg.norm(scaled, axis=0)
        cond = np.linalg.cond(scaled)
        if not np.isfinite(cond) or cond > self.max_condition:
            return None
        try:
            return np.linalg.solve(p_mat.T, a_mat.T).T
        except np.linalg.LinAlgError:
            return None

    def step_size(self, points: np.ndarray, delta: np.ndarray) -> float:
        """‖α‖∞ with δ = Pα: the step in units of the secant spread."""
        p_mat = (points[1:] - points[0]).T
        return float(np.max(np.abs(np.linalg.solve(p_mat, delta))))

    def fresh_jacobian(self, run: Run, x: np.ndarray, r: np.ndarray, h: np.ndarray,
                       noise: np.ndarray | None) -> np.ndarray:
        """Forward differences with steps ``h`` pointing into the box (p runs, one batch; noise-checked)."""
        return fd_jacobian(run.evaluate_many, x, run.lb, run.ub, h, r0=r, noise=noise).jacobian

    def get_state(self) -> Any:
        """DuD's model has no state."""
        return None

    def set_state(self, state: Any) -> None:
        """Nothing to restore."""


def dud(fun: Fun, x0: Any, lb: Any, ub: Any, *, options: DudOptions | dict | None = None,
        callback: Callback | None = None, batch: Batch | None = None, max_nfev: int | None = None,
        deadline: float | None = None, restart: DudState | None = None) -> OptimiseResult:
    """Minimise S(x) = Σ r(x)² with DuD.

    Parameters
    ----------
    fun
        ``fun(x) -> r``: the weighted residuals at x (1-D array).
    x0, lb, ub
        Start and bounds (1-D, optimiser coordinates; scalar bounds broadcast; ±inf allowed).
    options
        :class:`DudOptions` or a dict of its fields.
    callback
        Called after every outer iteration with an :class:`~rivercal.optimise.IterationRecord`;
        returning True aborts the run.
    batch
        ``batch(list_of_x) -> list_of_r`` evaluating independent points, possibly in parallel
        (the initial set, re-initialisations, and with ``parallel_line_search`` the trial steps).
    max_nfev
        Cap on the total number of model runs (including the runs of a restarted state).
    deadline
        Wall-clock seconds from the call after which the run stops with the best point.
    restart
        A :class:`DudState` from ``result.extra["state"]`` to continue; ``x0`` is then only validated,
        the run continues from the state's interpolation set (and start point).

    Returns
    -------
    OptimiseResult
        ``jac`` is the final Jacobian (see ``DudOptions.final_jacobian``: the secant one, J = A P⁻¹, or a
        fresh finite-difference one); ``std``/``correlation`` follow from cov = (JᵀJ)⁻¹ (thesis
        Eq. 2-12/2-13). ``extra`` holds ``state``, ``n_reinit``, ``initial_step`` and
        ``final_jacobian_nfev`` (the runs spent on the final Jacobian and its Gauss-Newton step).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 1, 20)
    >>> y = 2.0 * np.exp(-1.5 * t)
    >>> res = dud(lambda x: y - x[0] * np.exp(-x[1] * t), [1.0, 1.0], [0, 0], [10, 10],
    ...           options={"abs_tol": 0, "rel_tol": 1e-12})
    >>> res.success, np.round(res.x, 4)
    (True, array([2. , 1.5]))
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    opts = coerce_options(options, DudOptions)
    if restart is not None:
        restart = validate_restart(restart, "dud", x0.shape[0])
    h0 = restart.initial_step if restart is not None else default_steps(opts, x0, lb, ub)
    return run_dud("dud", fun, x0, lb, ub, opts=opts, model=DenseSecant(opts.max_condition), h0=h0,
                   callback=callback, batch=batch, max_nfev=max_nfev, deadline=deadline, restart=restart)
