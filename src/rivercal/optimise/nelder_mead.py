"""Nelder-Mead simplex through :func:`scipy.optimize.minimize` (bounded).

The initial simplex is {x0, x0 + s_j e_j} with s_j = ±``initial_step`` pointing into the box (OpenDA's
Simplex starts from {p0, p0 + l_i}; a start at a bound is perturbed inwards instead of collapsing the
simplex). scipy works in coordinates scaled by ``initial_step``, so ``xatol`` is in units of it.

Status codes (``TERMINATION_MESSAGES``): 1 converged (``xatol`` and ``fatol``); −3 ``max_iter``;
0 / −1 / −2 budget, callback, deadline (see :mod:`rivercal.optimise.result`).

References
----------
Nelder, J. A. & Mead, R. (1965). A simplex method for function minimization. The Computer Journal 7(4),
308-313. Gao, F. & Han, L. (2012). Implementing the Nelder-Mead simplex algorithm with adaptive parameters.
Computational Optimization and Applications 51, 259-277 (``adaptive=True``).
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
from rivercal.optimise._scipy import Scaled, cost_function, iteration_callback
from rivercal.optimise.jacobian import inward_steps
from rivercal.optimise.result import COMMON_MESSAGES, STATUS_MAX_ITER, OptimiseResult

__all__ = ["TERMINATION_MESSAGES", "NelderMeadOptions", "nelder_mead"]

STATUS_CONVERGED = 1

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_CONVERGED: "The simplex converged: its spread is within xatol (units of initial_step) and its costs "
                      "within fatol.",
    STATUS_MAX_ITER: "The maximum number of iterations (max_iter) is reached.",
}


@dataclass(frozen=True, slots=True)
class NelderMeadOptions:
    """Options of :func:`nelder_mead`.

    Attributes
    ----------
    max_iter
        Maximum number of simplex iterations (default 200 p).
    xatol
        Convergence when the simplex vertices lie within ``xatol`` of the best one, in units of
        ``initial_step`` (1e-4).
    fatol
        ... and their costs within ``fatol`` of the best cost (absolute, 1e-8).
    adaptive
        Dimension-dependent coefficients (Gao & Han 2012).
    initial_step
        Edge lengths of the initial simplex per parameter (default: 10 % of |x0|).
    """

    max_iter: int | None = None
    xatol: float = 1e-4
    fatol: float = 1e-8
    adaptive: bool = False
    initial_step: Any = None

    def __post_init__(self) -> None:
        if self.max_iter is not None:
            check_int("max_iter", self.max_iter, 1)
        check_real("xatol", self.xatol)
        check_real("fatol", self.fatol)
        if not isinstance(self.adaptive, bool):
            raise ValueError(f"adaptive must be a bool, got {self.adaptive!r}")
        optional_array(self, "initial_step", positive=True)


def nelder_mead(fun: Fun, x0: Any, lb: Any, ub: Any, *, options: NelderMeadOptions | dict | None = None,
                callback: Callback | None = None, batch: Batch | None = None, max_nfev: int | None = None,
                deadline: float | None = None) -> OptimiseResult:
    """Minimise S(x) = Σ r(x)² with the bounded Nelder-Mead simplex method.

    Parameters
    ----------
    fun, x0, lb, ub, callback, batch, max_nfev, deadline
        See :func:`rivercal.optimise.dud.dud`. The initial simplex goes out as one ``batch``.
    options
        :class:`NelderMeadOptions` or a dict.

    Returns
    -------
    OptimiseResult
        Without Jacobian (``std``, ``correlation`` and ``jac`` are None).
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    opts = coerce_options(options, NelderMeadOptions)
    n = x0.shape[0]
    h = option_vector("initial_step", opts.initial_step, n)
    h = default_initial_step(x0, lb, ub) if h is None else h
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback)
    scaled = Scaled(x0, h, lb, ub)
    simplex = np.vstack([np.zeros(n), np.diag(inward_steps(x0, h, lb, ub) / h)])
    try:
        run.evaluate_many([scaled.to_x(u) for u in simplex])
        res = minimize(cost_function(run, scaled), np.zeros(n), method="Nelder-Mead", bounds=scaled.bounds(),
                       callback=iteration_callback(run, scaled),
                       options={"maxiter": opts.max_iter or 200 * n, "maxfev": np.iinfo(np.int64).max,
                                "xatol": opts.xatol, "fatol": opts.fatol, "adaptive": opts.adaptive,
                                "initial_simplex": simplex})
        status = STATUS_CONVERGED if res.status == 0 else STATUS_MAX_ITER
    except Stop as stop:
        status = stop.status
    return run.result(status, TERMINATION_MESSAGES, "nelder_mead")
