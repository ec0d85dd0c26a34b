"""Powell's conjugate-direction method through :func:`scipy.optimize.minimize` (bounded).

The initial direction set is the columns of diag(``initial_step``) (OpenDA's Powell starts from the
columns of L, the prior standard deviations), realised by running scipy in coordinates scaled by
``initial_step``. Two ways to keep to the bounds (``line_search``):

- ``"projected"`` (default): scipy's unbounded Powell on the projected cost S(clip(x)) · (1 + ‖d‖²), d the
  distance of x beyond the box in units of ``initial_step``; each line search brackets from the current
  point like OpenDA's, and every point run is inside the box. The factor makes the cost rise beyond a
  bound: on the flat S(clip(x)) alone, a bracket that overshoots a bound settles anywhere on the plateau
  and Powell can stop at the bound (the default case's Wc with its 0.1 perturbation: Wc = 1, FA off by
  0.5);
- ``"bounded"``: scipy's bounded Powell, whose line searches run Brent's bounded method over the whole
  feasible segment of the line. With bounds much wider than the region of interest that search lands
  far away (1 of the 19 NIST problems solved from start 1, against 15 with ``"projected"``).

Status codes (``TERMINATION_MESSAGES``): 1 converged (``ftol``/``xtol``); −3 ``max_iter``; −4 scipy
stopped abnormally; 0 / −1 / −2 budget, callback, deadline.

References
----------
Powell, M. J. D. (1964). An efficient method for finding the minimum of a function of several variables
without calculating derivatives. The Computer Journal 7(2), 155-162.
"""

from __future__ import annotations

from collections.abc import Callable
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
    check_choice,
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
from rivercal.optimise.result import COMMON_MESSAGES, STATUS_ABNORMAL, STATUS_MAX_ITER, OptimiseResult

__all__ = ["TERMINATION_MESSAGES", "PowellOptions", "powell"]

STATUS_CONVERGED = 1

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_CONVERGED: "Converged: the relative cost decrease of an iteration is within ftol "
                      "(or the line searches within xtol).",
    STATUS_MAX_ITER: "The maximum number of iterations (max_iter) is reached.",
    STATUS_ABNORMAL: "scipy's Powell stopped abnormally.",
}


@dataclass(frozen=True, slots=True)
class PowellOptions:
    """Options of :func:`powell`.

    Attributes
    ----------
    max_iter
        Maximum number of iterations (sweeps over the direction set; default 1000 p).
    xtol
        Tolerance of the line searches, in units of ``initial_step`` (1e-4).
    ftol
        Relative decrease of the cost in one iteration below which the run stops (1e-8).
    initial_step
        Lengths of the initial directions per parameter (default: 10 % of |x0|).
    line_search
        ``"projected"`` or ``"bounded"`` (see the module docstring).
    """

    max_iter: int | None = None
    xtol: float = 1e-4
    ftol: float = 1e-8
    initial_step: Any = None
    line_search: str = "projected"

    def __post_init__(self) -> None:
        if self.max_iter is not None:
            check_int("max_iter", self.max_iter, 1)
        check_real("xtol", self.xtol, strict=True)
        check_real("ftol", self.ftol)
        optional_array(self, "initial_step", positive=True)
        check_choice("line_search", self.line_search, ("projected", "bounded"))


def powell(fun: Fun, x0: Any, lb: Any, ub: Any, *, options: PowellOptions | dict | None = None,
           callback: Callback | None = None, batch: Batch | None = None, max_nfev: int | None = None,
           deadline: float | None = None) -> OptimiseResult:
    """Minimise S(x) = Σ r(x)² with Powell's method (scipy, bounded).

    Parameters
    ----------
    fun, x0, lb, ub, callback, batch, max_nfev, deadline
        See :func:`rivercal.optimise.dud.dud`. Powell's line searches are sequential; ``batch`` is not used
        for more than one point at a time.
    options
        :class:`PowellOptions` or a dict.

    Returns
    -------
    OptimiseResult
        Without Jacobian (``std``, ``correlation`` and ``jac`` are None).
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    opts = coerce_options(options, PowellOptions)
    n = x0.shape[0]
    h = option_vector("initial_step", opts.initial_step, n)
    h = default_initial_step(x0, lb, ub) if h is None else h
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback)
    scaled = Scaled(x0, h, lb, ub)
    try:
        bounded = opts.line_search == "bounded"
        cost = cost_function(run, scaled) if bounded else _beyond_rises(cost_function(run, scaled), scaled)
        res = minimize(cost, np.zeros(n), method="Powell", bounds=scaled.bounds() if bounded else None,
                       callback=iteration_callback(run, scaled),
                       options={"maxiter": opts.max_iter or 1000 * n, "maxfev": np.iinfo(np.int64).max,
                                "xtol": opts.xtol, "ftol": opts.ftol, "direc": np.eye(n)})
        status = {0: STATUS_CONVERGED, 2: STATUS_MAX_ITER}.get(int(res.status), STATUS_ABNORMAL)
    except Stop as stop:
        status = stop.status
    return run.result(status, TERMINATION_MESSAGES, "powell")


def _beyond_rises(cost: Callable[[np.ndarray], float], scaled: Scaled) -> Callable[[np.ndarray], float]:
    """S(clip(x)) · (1 + ‖d‖²) with d the distance beyond the box in scaled units (0 inside)."""
    lo, hi = scaled.u_lb, scaled.u_ub

    def projected(u: np.ndarray) -> float:
        d = u - np.clip(u, lo, hi)
        return cost(u) * (1.0 + float(d @ d))

    return projected
