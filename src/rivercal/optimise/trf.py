"""Trust-region reflective least squares: :func:`scipy.optimize.least_squares` with ``method="trf"``.

This is scipy's Trust Region Reflective method (Branch, Coleman & Li 1999), a trust-region
Gauss-Newton method for bounded problems; it is *not* Levenberg-Marquardt (the name this optimiser had
before), although it solves the same trust-region subproblem for an unbounded problem. It handles the
bounds natively and keeps its iterates strictly inside.

- scipy works in coordinates u with x = x0 + ``x_scale`` ⊙ u (default: the initial step of every
  method, 10 % of |x0|), and its own scaling is chosen so that the first trust region is one
  ``x_scale`` around x0 (see ``_first_step_scale``): the first trial step has the size the caller
  expects, and later ones grow only where the cost agrees with the model;
- the Jacobian is a forward-difference Jacobian whose p perturbed runs go out as ONE ``batch`` (passed to
  scipy as ``jac=``), with steps ``diff_step`` (or relative to |x_j|) that point into the box at a bound,
  checked against the function's ``noise`` when it is given;
- the Jacobian at the solution gives ``std``/``correlation``.

Status codes (``TERMINATION_MESSAGES``), as scipy's: 1 ``gtol``, 2 ``ftol``, 3 ``xtol``, 4 ``ftol`` and
``xtol``; −3 scipy's iteration budget (``max_iter`` evaluations of the step) is used up; 0 / −1 / −2
budget, callback, deadline.

References
----------
Branch, M. A., Coleman, T. F. & Li, Y. (1999). A subspace, interior, and conjugate gradient method for
large-scale bound-constrained minimization problems. SIAM Journal on Scientific Computing 21(1), 1-23.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import OptimizeResult, least_squares

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
from rivercal.optimise._scipy import Differences, Scaled
from rivercal.optimise.result import COMMON_MESSAGES, STATUS_MAX_ITER, OptimiseResult

__all__ = ["TERMINATION_MESSAGES", "TrfOptions", "trf"]

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_MAX_ITER: "scipy's iteration budget (max_iter trial steps) is used up.",
    1: "gtol: the first-order optimality measure is small.",
    2: "ftol: the relative reduction of the cost is small.",
    3: "xtol: the relative step is small.",
    4: "ftol and xtol are both satisfied.",
}


@dataclass(frozen=True, slots=True)
class TrfOptions:
    """Options of :func:`trf`.

    Attributes
    ----------
    ftol, xtol, gtol
        scipy's tolerances (1e-10 each; scipy's default is 1e-8). ``xtol`` is relative to ‖u‖ in the
        scaled coordinates.
    x_scale
        Unit of the scaled coordinates per parameter: the first trust region is one unit (default: 10 %
        of |x0|); or ``"jac"``: scipy's scaling by the Jacobian's column norms on top of that.
    rel_step, diff_step, noise
        The forward differences (see ``_scipy.Differences``): steps ``diff_step`` per parameter (optimiser
        units), else ``rel_step`` (1.49e-8 ≈ √eps) relative to |x|; checked against ``noise``, the
        residuals' numerical jitter (weighted units), when given.
    max_iter
        Cap on scipy's own count of residual evaluations (trial steps, not Jacobian runs); default 100 p.
    """

    ftol: float = 1e-10
    xtol: float = 1e-10
    gtol: float = 1e-10
    x_scale: Any = None
    rel_step: float = 1.4901161193847656e-08
    diff_step: Any = None
    noise: Any = None
    max_iter: int | None = None

    def __post_init__(self) -> None:
        for name in ("ftol", "xtol", "gtol"):
            check_real(name, getattr(self, name))
        if not (isinstance(self.x_scale, str) and self.x_scale == "jac"):
            optional_array(self, "x_scale", positive=True)
        check_real("rel_step", self.rel_step, 1e-14, maximum=0.5)
        for name in ("diff_step", "noise"):
            optional_array(self, name, positive=True)
        if self.max_iter is not None:
            check_int("max_iter", self.max_iter, 1)


def trf(fun: Fun, x0: Any, lb: Any, ub: Any, *, options: TrfOptions | dict | None = None,
        callback: Callback | None = None, batch: Batch | None = None, max_nfev: int | None = None,
        deadline: float | None = None) -> OptimiseResult:
    """Minimise S(x) = Σ r(x)² with scipy's trust-region reflective method and a batched Jacobian.

    Parameters
    ----------
    fun, x0, lb, ub, callback, batch, max_nfev, deadline
        See :func:`rivercal.optimise.dud.dud`.
    options
        :class:`TrfOptions` or a dict.

    Returns
    -------
    OptimiseResult
        ``jac`` is the forward-difference Jacobian at ``x``.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0, 1, 20)
    >>> y = 2.0 * np.exp(-1.5 * t)
    >>> res = trf(lambda x: y - x[0] * np.exp(-x[1] * t), [1.0, 1.0], [0, 0], [10, 10])
    >>> np.round(res.x, 6)
    array([2. , 1.5])
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    opts = coerce_options(options, TrfOptions)
    n = x0.shape[0]
    jac_scaling = isinstance(opts.x_scale, str)
    scale = None if jac_scaling else option_vector("x_scale", opts.x_scale, n)
    scaled = Scaled(x0, default_initial_step(x0, lb, ub) if scale is None else scale, lb, ub)
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback)
    differences = Differences(run, opts.rel_step, opts.diff_step, opts.noise)
    last: dict[str, Any] = {}

    def residuals(u: np.ndarray) -> np.ndarray:
        return run.evaluate(scaled.to_x(u))

    def jacobian(u: np.ndarray) -> np.ndarray:
        x = scaled.to_x(u)
        jac = differences.jacobian(x).jacobian
        last["x"], last["jac"] = x, jac
        return jac * scaled.scale

    def iteration(intermediate_result: OptimizeResult) -> None:
        run.iteration(scaled.to_x(intermediate_result.x), 2.0 * float(intermediate_result.cost))

    bounds = scaled.bounds()
    try:
        x_scale = "jac" if jac_scaling else _first_step_scale(residuals(np.zeros(n)), jacobian(np.zeros(n)), bounds)
        res = least_squares(residuals, np.zeros(n), jac=jacobian, bounds=(bounds.lb, bounds.ub), method="trf",
                            x_scale=x_scale, ftol=opts.ftol, xtol=opts.xtol, gtol=opts.gtol,
                            max_nfev=opts.max_iter or 100 * n, callback=iteration)
        status = STATUS_MAX_ITER if res.status == 0 else int(res.status)
    except Stop as stop:
        status = stop.status
    jac = last["jac"] if "jac" in last and np.array_equal(last["x"], run.best_x) else None
    return run.result(status, TERMINATION_MESSAGES, "trf", jac=jac)


def _first_step_scale(r0: np.ndarray, jac: np.ndarray, bounds: Any) -> np.ndarray:
    """The ``x_scale`` for scipy (in u) that makes TRF's first trust region one unit of u around x0.

    TRF scales variable j by √v_j·x_scale_j, with v_j its distance (in units of x_scale_j) to the bound
    its steepest-descent direction heads for, 1 when that bound is infinite (Coleman & Li). Its first trust
    region has radius 1 in those scaled variables, so a bound 10⁴ units away allows a first step of 100
    units. With x_scale_j = 1/v_j at x0 the scaling is 1 there: the first step is at most one ``x_scale``
    (the caller's initial step) per parameter, and later steps grow only as the trust region does.
    """
    g = jac.T @ r0
    distance = np.where(g < 0, bounds.ub, np.where(g > 0, -bounds.lb, np.inf))   # u = 0 at x0
    return np.where(np.isfinite(distance) & (distance > 0), 1.0 / np.where(distance > 0, distance, 1.0), 1.0)
