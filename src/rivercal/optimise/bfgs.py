"""L-BFGS-B through :func:`scipy.optimize.minimize` with a parallel finite-difference gradient.

The gradient of S = Σ r² is 2 Jᵀ r with J the forward-difference Jacobian of the residuals: the point
and its p perturbations go out as ONE ``batch`` per gradient (scipy's own finite differences would run
them one by one). Bounds are native to L-BFGS-B. OpenDA's BFGS always ends up in its limited-memory
variant (reference note §4); this is that method, done by scipy. The last Jacobian gives
``std``/``correlation``.

The problem is scaled so that the first trial step has the size the caller expects: scipy works in
coordinates u with x = x0 + ``x_scale`` ⊙ u, and on the cost divided by the 2-norm of its gradient at x0
(in u). L-BFGS-B's first trial point on a box is x0 minus the gradient itself; unscaled, that is a step
of the gradient's length in the parameters' units and lands on a corner of the box (x = [0, 1.3e5]
from [8, 1.57] on a damped oscillator). Scaled, it is one ``x_scale`` along the steepest descent.
Dividing the cost by a constant changes neither the minimiser nor scipy's relative ``ftol`` rule, and
makes both tolerances independent of the scale of the weights.

Status codes (``TERMINATION_MESSAGES``): 1 converged (scipy's ``ftol`` on the relative cost reduction or
``gtol`` on the projected gradient); −3 ``max_iter``; −4 abnormal termination in the line search;
0 / −1 / −2 budget, callback, deadline.

References
----------
Byrd, R. H., Lu, P., Nocedal, J. & Zhu, C. (1995). A limited memory algorithm for bound constrained
optimization. SIAM Journal on Scientific Computing 16(5), 1190-1208.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import minimize

from rivercal.optimise._core import (
    Batch,
    Callback,
    Fun,
    Run,
    Stop,
    check_int,
    check_real,
    coerce_options,
    default_initial_step,
    option_vector,
    optional_array,
    validate_controls,
    validate_problem,
)
from rivercal.optimise._scipy import Differences, FDGradient, Scaled, iteration_callback
from rivercal.optimise.result import COMMON_MESSAGES, STATUS_ABNORMAL, STATUS_MAX_ITER, OptimiseResult

__all__ = ["TERMINATION_MESSAGES", "BfgsOptions", "bfgs"]

STATUS_CONVERGED = 1

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_CONVERGED: "Converged: the relative reduction of the cost is within ftol or the projected gradient "
                      "within gtol.",
    STATUS_MAX_ITER: "The maximum number of iterations (max_iter) is reached.",
    STATUS_ABNORMAL: "L-BFGS-B stopped abnormally (no progress in the line search; often a noisy gradient: "
                     "raise rel_step or give the function's noise).",
}


@dataclass(frozen=True, slots=True)
class BfgsOptions:
    """Options of :func:`bfgs`.

    Attributes
    ----------
    max_iter
        Maximum number of iterations (15000, scipy's default).
    ftol
        Stop when (S_k − S_{k+1}) / max(|S_k|, |S_{k+1}|, g₀) ≤ ftol, g₀ the norm of the gradient at x0 in
        units of ``x_scale`` (scipy's rule on the normalised cost; 1e-12).
    gtol
        Stop when the largest projected gradient component is ≤ gtol times the gradient norm at x0
        (1e-10).
    maxcor
        Number of correction pairs of the limited-memory matrix (10).
    rel_step, diff_step, noise
        The forward differences (see ``_scipy.Differences``): steps ``diff_step`` per parameter (optimiser
        units), else ``rel_step`` (1.49e-8 ≈ √eps) relative to |x|; checked against ``noise``, the
        residuals' numerical jitter (weighted units), when given.
    x_scale
        The size of the first trial step per parameter, and the unit of scipy's coordinates (default:
        10 % of |x0|, the default initial step of every method).
    """

    max_iter: int = 15000
    ftol: float = 1e-12
    gtol: float = 1e-10
    maxcor: int = 10
    rel_step: float = 1.4901161193847656e-08
    diff_step: Any = None
    noise: Any = None
    x_scale: Any = None

    def __post_init__(self) -> None:
        check_int("max_iter", self.max_iter, 1)
        check_int("maxcor", self.maxcor, 1)
        check_real("ftol", self.ftol)
        check_real("gtol", self.gtol)
        check_real("rel_step", self.rel_step, 1e-14, maximum=0.5)
        for name in ("diff_step", "noise", "x_scale"):
            optional_array(self, name, positive=True)


def bfgs(fun: Fun, x0: Any, lb: Any, ub: Any, *, options: BfgsOptions | dict | None = None,
         callback: Callback | None = None, batch: Batch | None = None, max_nfev: int | None = None,
         deadline: float | None = None) -> OptimiseResult:
    """Minimise S(x) = Σ r(x)² with L-BFGS-B and batched finite-difference gradients.

    Parameters
    ----------
    fun, x0, lb, ub, callback, batch, max_nfev, deadline
        See :func:`rivercal.optimise.dud.dud`.
    options
        :class:`BfgsOptions` or a dict.

    Returns
    -------
    OptimiseResult
        ``jac`` is the forward-difference Jacobian at ``x`` (when the last gradient was taken there).
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    opts = coerce_options(options, BfgsOptions)
    n = x0.shape[0]
    scale = option_vector("x_scale", opts.x_scale, n)
    scale = default_initial_step(x0, lb, ub) if scale is None else scale
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback)
    scaled = Scaled(x0, scale, lb, ub)
    gradient = FDGradient(run, scaled, Differences(run, opts.rel_step, opts.diff_step, opts.noise), normalise=True)
    try:
        res = minimize(gradient, np.zeros(n), jac=True, method="L-BFGS-B", bounds=scaled.bounds(),
                       callback=iteration_callback(run, scaled, lambda: gradient.unit or 1.0),
                       options={"maxiter": opts.max_iter, "maxfun": np.iinfo(np.int32).max, "ftol": opts.ftol,
                                "gtol": opts.gtol, "maxcor": opts.maxcor})
        status = {0: STATUS_CONVERGED, 1: STATUS_MAX_ITER}.get(int(res.status), STATUS_ABNORMAL)
    except Stop as stop:
        status = stop.status
    return run.result(status, TERMINATION_MESSAGES, "bfgs", jac=gradient.jacobian_at(run.best_x))
