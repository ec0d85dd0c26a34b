"""L-BFGS-B through :func:`scipy.optimize.minimize` with a parallel finite-difference gradient.

The gradient of S = Σ r² is 2 Jᵀ r with J the forward-difference Jacobian of the residuals: the point
and its p perturbations go out as ONE ``batch`` per gradient (scipy's own finite differences would run
them one by one). scipy works in coordinates scaled by ``x_scale``. Bounds are native to L-BFGS-B.
OpenDA's BFGS always ends up in its limited-memory variant (reference note §4); this is that method,
done by scipy. The last Jacobian gives ``std``/``correlation``.

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
    default_scale,
    option_vector,
    optional_array,
    validate_controls,
    validate_problem,
)
from rivercal.optimise._scipy import FDGradient, Scaled, iteration_callback
from rivercal.optimise.result import COMMON_MESSAGES, STATUS_ABNORMAL, STATUS_MAX_ITER, OptimiseResult

__all__ = ["TERMINATION_MESSAGES", "BfgsOptions", "bfgs"]

STATUS_CONVERGED = 1

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_CONVERGED: "Converged: the relative reduction of the cost is within ftol or the projected gradient "
                      "within gtol.",
    STATUS_MAX_ITER: "The maximum number of iterations (max_iter) is reached.",
    STATUS_ABNORMAL: "L-BFGS-B stopped abnormally (no progress in the line search; often a noisy gradient: "
                     "raise rel_step).",
}


@dataclass(frozen=True, slots=True)
class BfgsOptions:
    """Options of :func:`bfgs`.

    Attributes
    ----------
    max_iter
        Maximum number of iterations (15000, scipy's default).
    ftol
        Stop when (S_k − S_{k+1}) / max(|S_k|, |S_{k+1}|, 1) ≤ ftol (scipy's rule; 1e-12).
    gtol
        Stop when the largest projected gradient component (scaled coordinates) is ≤ gtol (1e-10).
    maxcor
        Number of correction pairs of the limited-memory matrix (10).
    rel_step
        Relative forward-difference step (1.49e-8 ≈ √eps).
    x_scale
        Typical magnitude per parameter (default |x0|, see ``default_scale``).
    """

    max_iter: int = 15000
    ftol: float = 1e-12
    gtol: float = 1e-10
    maxcor: int = 10
    rel_step: float = 1.4901161193847656e-08
    x_scale: Any = None

    def __post_init__(self) -> None:
        check_int("max_iter", self.max_iter, 1)
        check_int("maxcor", self.maxcor, 1)
        check_real("ftol", self.ftol)
        check_real("gtol", self.gtol)
        check_real("rel_step", self.rel_step, 1e-14, maximum=0.5)
        optional_array(self, "x_scale", positive=True)


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
    typical = default_scale(x0, lb, ub)
    scale = option_vector("x_scale", opts.x_scale, n)
    scale = typical if scale is None else scale
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback)
    scaled = Scaled(x0, scale, lb, ub)
    gradient = FDGradient(run, scaled, opts.rel_step, typical)
    try:
        res = minimize(gradient, np.zeros(n), jac=True, method="L-BFGS-B", bounds=scaled.bounds(),
                       callback=iteration_callback(run, scaled),
                       options={"maxiter": opts.max_iter, "maxfun": np.iinfo(np.int32).max, "ftol": opts.ftol,
                                "gtol": opts.gtol, "maxcor": opts.maxcor})
        status = {0: STATUS_CONVERGED, 1: STATUS_MAX_ITER}.get(int(res.status), STATUS_ABNORMAL)
    except Stop as stop:
        status = stop.status
    return run.result(status, TERMINATION_MESSAGES, "bfgs", jac=gradient.jacobian_at(run.best_x))
