"""Levenberg-Marquardt-type trust-region least squares: :func:`scipy.optimize.least_squares` (``"trf"``).

The Trust Region Reflective method handles the bounds natively and keeps its iterates strictly inside.
The Jacobian is a forward-difference Jacobian whose p perturbed runs go out as ONE ``batch`` (passed to
scipy as ``jac=``), with steps relative to |x_j| (see ``fd_steps``) that point into the box at a bound.
The Jacobian at the solution gives ``std``/``correlation``.

Status codes (``TERMINATION_MESSAGES``), as scipy's: 1 ``gtol``, 2 ``ftol``, 3 ``xtol``, 4 ``ftol`` and
``xtol``; −3 scipy's iteration budget (``max_iter`` evaluations of the step) is used up; 0 / −1 / −2
budget, callback, deadline.

References
----------
Branch, M. A., Coleman, T. F. & Li, Y. (1999). A subspace, interior, and conjugate gradient method for
large-scale bound-constrained minimization problems. SIAM Journal on Scientific Computing 21(1), 1-23.
Moré, J. J. (1978). The Levenberg-Marquardt algorithm: implementation and theory. Lecture Notes in
Mathematics 630, 105-116.
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
    default_scale,
    fd_jacobian,
    option_vector,
    optional_array,
    project,
    validate_controls,
    validate_problem,
)
from rivercal.optimise.result import COMMON_MESSAGES, STATUS_MAX_ITER, OptimiseResult

__all__ = ["TERMINATION_MESSAGES", "LmOptions", "lm"]

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_MAX_ITER: "scipy's iteration budget (max_iter trial steps) is used up.",
    1: "gtol: the first-order optimality measure is small.",
    2: "ftol: the relative reduction of the cost is small.",
    3: "xtol: the relative step is small.",
    4: "ftol and xtol are both satisfied.",
}


@dataclass(frozen=True, slots=True)
class LmOptions:
    """Options of :func:`lm`.

    Attributes
    ----------
    ftol, xtol, gtol
        scipy's tolerances (1e-10 each; scipy's default is 1e-8).
    x_scale
        ``"jac"`` (scale by the Jacobian's column norms, default), or typical magnitudes per parameter.
    rel_step
        Relative forward-difference step (1.49e-8 ≈ √eps).
    max_iter
        Cap on scipy's own count of residual evaluations (trial steps, not Jacobian runs); default 100 p.
    """

    ftol: float = 1e-10
    xtol: float = 1e-10
    gtol: float = 1e-10
    x_scale: Any = "jac"
    rel_step: float = 1.4901161193847656e-08
    max_iter: int | None = None

    def __post_init__(self) -> None:
        for name in ("ftol", "xtol", "gtol"):
            check_real(name, getattr(self, name))
        if not (isinstance(self.x_scale, str) and self.x_scale == "jac"):
            optional_array(self, "x_scale", positive=True)
        check_real("rel_step", self.rel_step, 1e-14, maximum=0.5)
        if self.max_iter is not None:
            check_int("max_iter", self.max_iter, 1)


def lm(fun: Fun, x0: Any, lb: Any, ub: Any, *, options: LmOptions | dict | None = None,
       callback: Callback | None = None, batch: Batch | None = None, max_nfev: int | None = None,
       deadline: float | None = None) -> OptimiseResult:
    """Minimise S(x) = Σ r(x)² with scipy's bounded trust-region least squares and a batched Jacobian.

    Parameters
    ----------
    fun, x0, lb, ub, callback, batch, max_nfev, deadline
        See :func:`rivercal.optimise.dud.dud`.
    options
        :class:`LmOptions` or a dict.

    Returns
    -------
    OptimiseResult
        ``jac`` is the forward-difference Jacobian at ``x``.
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    opts = coerce_options(options, LmOptions)
    n = x0.shape[0]
    typical = default_scale(x0, lb, ub)
    x_scale = opts.x_scale if isinstance(opts.x_scale, str) else option_vector("x_scale", opts.x_scale, n)
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback)
    last: dict[str, Any] = {}

    def residuals(x: np.ndarray) -> np.ndarray:
        return run.evaluate(project(x, lb, ub))

    def jacobian(x: np.ndarray) -> np.ndarray:
        x = project(x, lb, ub)
        _, jac = fd_jacobian(run, x, opts.rel_step, typical)
        last["x"], last["jac"] = x, jac
        return jac

    def iteration(intermediate_result: OptimizeResult) -> None:
        run.iteration(project(intermediate_result.x, lb, ub), 2.0 * float(intermediate_result.cost))

    try:
        res = least_squares(residuals, x0, jac=jacobian, bounds=(lb, ub), method="trf", x_scale=x_scale,
                            ftol=opts.ftol, xtol=opts.xtol, gtol=opts.gtol, max_nfev=opts.max_iter or 100 * n,
                            callback=iteration)
        status = STATUS_MAX_ITER if res.status == 0 else int(res.status)
    except Stop as stop:
        status = stop.status
    jac = last["jac"] if "jac" in last and np.array_equal(last["x"], run.best_x) else None
    return run.result(status, TERMINATION_MESSAGES, "lm", jac=jac)
