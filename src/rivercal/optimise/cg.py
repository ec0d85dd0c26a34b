"""Nonlinear conjugate gradients with bounds: Fletcher-Reeves, Polak-Ribière (PR+) or steepest descent.

scipy's ``CG`` is Polak-Ribière only and ignores bounds, so this is rivercal's own, in the three
variants OpenDA offers (reference note §4):

- the gradient ∇S = 2 Jᵀ r comes from a forward-difference Jacobian of the residuals, the point and its
  p perturbations going out as ONE ``batch``; the last Jacobian gives ``std``/``correlation``;
- bounds by an active set: components at a bound whose gradient points outwards are frozen, the search
  direction is built from the projected gradient, and the line search runs over the feasible segment;
- the line search is Brent's bounded method (:func:`scipy.optimize.minimize_scalar`) on
  [0, min(t_max, 4 t_GN, t_cap)] (plus the end point t_max itself when the minimum lies there), with
  t_GN = −(Jd)ᵀr / ‖Jd‖² the minimiser of the linearised cost along d (a least-squares problem knows
  its own curvature; OpenDA brackets from a fixed start value instead) and t_cap the step that moves a
  parameter by ``max_step`` units of ``x_scale``: a linearisation far from its point must not send the
  search across the box (the next iteration continues from the end of the segment if the cost says so);
- β = ‖g_k‖²/‖g_{k−1}‖² (FR) or max(0, g_kᵀ(g_k − g_{k−1})/‖g_{k−1}‖²) (PR+); the direction restarts
  as steepest descent every ``restart_every`` iterations, when it is not a descent direction, and once
  after a line search that found no decrease;
- everything runs in coordinates scaled by ``x_scale`` (default: 10 % of |x0|, the initial step of
  every method).

Status codes (``TERMINATION_MESSAGES``): 1 ``ftol``, 2 ``gtol``, 3 ``xtol``, 4 no decrease along the
steepest-descent direction; −3 ``max_iter``; 0 / −1 / −2 budget, callback, deadline.

References
----------
Fletcher, R. & Reeves, C. M. (1964). Function minimization by conjugate gradients. The Computer Journal
7(2), 149-154. Polak, E. & Ribière, G. (1969). Note sur la convergence de méthodes de directions
conjuguées. ESAIM: M2AN 3(R1), 35-43. Gilbert, J. C. & Nocedal, J. (1992). Global convergence properties of
conjugate gradient methods for optimization. SIAM Journal on Optimization 2(1), 21-42 (PR+).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

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
from rivercal.optimise._scipy import Differences, FDGradient, Scaled
from rivercal.optimise.result import COMMON_MESSAGES, STATUS_MAX_ITER, OptimiseResult

__all__ = ["METHODS", "TERMINATION_MESSAGES", "CgOptions", "cg"]

METHODS = ("fletcher-reeves", "polak-ribiere", "steepest-descent")

STATUS_FTOL = 1
STATUS_GTOL = 2
STATUS_XTOL = 3
STATUS_NO_DESCENT = 4

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_MAX_ITER: "The maximum number of iterations (max_iter) is reached.",
    STATUS_FTOL: "ftol: the relative decrease of the cost in the last iteration is small.",
    STATUS_GTOL: "gtol: the projected gradient is small relative to ‖r‖ and the Jacobian.",
    STATUS_XTOL: "xtol: the last step is small relative to x (scaled coordinates).",
    STATUS_NO_DESCENT: "The line search found no decrease along the steepest-descent direction.",
}


@dataclass(frozen=True, slots=True)
class CgOptions:
    """Options of :func:`cg`.

    Attributes
    ----------
    method
        ``"polak-ribiere"`` (PR+, default), ``"fletcher-reeves"`` or ``"steepest-descent"``.
    max_iter
        Maximum number of iterations (200, OpenDA's default).
    ftol
        Stop when an iteration lowers the cost by at most ``ftol`` × cost (1e-12).
    gtol
        Stop when ‖projected gradient‖∞ ≤ gtol · 2‖r‖ · max_j ‖J_j‖ (scaled coordinates; 1e-10).
    xtol
        Stop when ‖Δu‖ ≤ xtol (xtol + ‖u‖), u the scaled coordinates (1e-12).
    rel_step, diff_step, noise
        The forward differences (see ``_scipy.Differences``): steps ``diff_step`` per parameter (optimiser
        units), else ``rel_step`` (1.49e-8 ≈ √eps) relative to |x|; checked against ``noise``, the
        residuals' numerical jitter (weighted units), when given.
    x_scale
        Unit of the scaled coordinates per parameter (default: 10 % of |x0|).
    max_step
        Longest move of one parameter in one line search, in units of ``x_scale`` (10).
    line_search_maxiter
        Maximum number of cost evaluations of one Brent line search (30).
    restart_every
        Restart with steepest descent every this many iterations (default p).
    """

    method: str = "polak-ribiere"
    max_iter: int = 200
    ftol: float = 1e-12
    gtol: float = 1e-10
    xtol: float = 1e-12
    rel_step: float = 1.4901161193847656e-08
    diff_step: Any = None
    noise: Any = None
    x_scale: Any = None
    max_step: float = 10.0
    line_search_maxiter: int = 30
    restart_every: int | None = None

    def __post_init__(self) -> None:
        check_choice("method", self.method, METHODS)
        check_int("max_iter", self.max_iter, 1)
        check_int("line_search_maxiter", self.line_search_maxiter, 1)
        if self.restart_every is not None:
            check_int("restart_every", self.restart_every, 1)
        for name in ("ftol", "gtol", "xtol"):
            check_real(name, getattr(self, name))
        check_real("rel_step", self.rel_step, 1e-14, maximum=0.5)
        check_real("max_step", self.max_step, strict=True)
        for name in ("diff_step", "noise", "x_scale"):
            optional_array(self, name, positive=True)


class _ConjugateGradient:
    """State of one CG run in scaled coordinates u (x = x0 + scale ⊙ u)."""

    def __init__(self, run: Run, scaled: Scaled, gradient: FDGradient, opts: CgOptions):
        self.run, self.scaled, self.gradient, self.opts = run, scaled, gradient, opts
        bounds = scaled.bounds()
        self.lo, self.hi = bounds.lb, bounds.ub
        self.restart_every = opts.restart_every or run.x0.shape[0]
        self.u = np.zeros(run.x0.shape[0])
        self.update(self.u)

    def update(self, u: np.ndarray) -> None:
        """Residuals, Jacobian, cost and projected gradient at u."""
        self.u = u
        self.x = self.scaled.to_x(u)
        self.r, jac = self.gradient.residuals_and_jacobian(self.x)
        self.jac_u = jac * self.scaled.scale
        self.cost = self.run.cost_of(self.r)
        g = 2.0 * self.jac_u.T @ self.r
        frozen = ((self.u <= self.lo) & (g > 0)) | ((self.u >= self.hi) & (g < 0))
        self.g = np.where(frozen, 0.0, g)

    def gradient_small(self) -> bool:
        """The gtol test (scale-free)."""
        ref = 2.0 * np.linalg.norm(self.r) * np.max(np.linalg.norm(self.jac_u, axis=0))
        return bool(np.max(np.abs(self.g)) <= self.opts.gtol * ref)

    def direction(self, k: int, d_prev: np.ndarray | None, g_prev: np.ndarray | None) -> np.ndarray:
        """FR / PR+ / SD direction, restarted when needed."""
        d = -self.g
        if d_prev is None or self.opts.method == "steepest-descent" or k % self.restart_every == 0:
            return d
        gg = float(g_prev @ g_prev)
        if self.opts.method == "fletcher-reeves":
            beta = float(self.g @ self.g) / gg
        else:
            beta = max(0.0, float(self.g @ (self.g - g_prev)) / gg)
        d = d + beta * np.where(self.g == 0.0, 0.0, d_prev)
        return d if float(d @ self.g) < 0 else -self.g

    def line_search(self, d: np.ndarray) -> tuple[np.ndarray, float]:
        """Brent's bounded search on [0, min(t_max, 4 t_GN, t_cap)]; the best point seen and its cost."""
        with np.errstate(divide="ignore", invalid="ignore"):
            limits = np.where(d > 0, (self.hi - self.u) / d, np.where(d < 0, (self.lo - self.u) / d, np.inf))
        target = np.where(d > 0, self.hi, self.lo)
        t_max = float(np.min(limits))
        a = self.jac_u @ d
        t_gn = -float(a @ self.r) / float(a @ a) if float(a @ a) > 0 else t_max
        longest = float(np.max(np.abs(d)))
        t_cap = self.opts.max_step / longest if longest > 0 else np.inf
        t_hi = min(t_max, 4.0 * t_gn) if np.isfinite(t_gn) and t_gn > 0 else t_max
        t_hi = min(t_hi, t_cap)

        def phi(t: float) -> float:
            u = np.clip(self.u + t * d, self.lo, self.hi)
            u = np.where(t >= limits, target, u)    # a component that reaches its bound sits exactly on it
            cost = self.run.cost_of(self.run.evaluate(self.scaled.to_x(u)))
            if cost < best[1]:
                best[:] = [u, cost, t]
            return cost

        best = [self.u, self.cost, 0.0]
        if np.isfinite(t_hi) and t_hi > 0:
            minimize_scalar(phi, bounds=(0.0, t_hi), method="bounded",
                            options={"xatol": 1e-6 * t_hi, "maxiter": self.opts.line_search_maxiter})
            if t_hi == t_max and best[2] > (1.0 - 1e-3) * t_max:
                phi(t_max)    # Brent never evaluates the end point: try the bound itself
        return best[0], best[1]

    def solve(self) -> int:
        """Iterate until a stopping rule fires."""
        d_prev = g_prev = None
        k = 0
        while True:
            if self.gradient_small():
                return STATUS_GTOL
            if self.run.nit >= self.opts.max_iter:
                return STATUS_MAX_ITER
            d = self.direction(k, d_prev, g_prev)
            u_new, cost_new = self.line_search(d)
            if not cost_new < self.cost:
                if d_prev is None or np.array_equal(d, -self.g):
                    return STATUS_NO_DESCENT
                d_prev = None
                k = 0
                continue
            cost_old, u_old = self.cost, self.u
            g_prev, d_prev = self.g, d
            self.update(u_new)
            k += 1
            self.run.iteration(self.x, self.cost)
            if cost_old - self.cost <= self.opts.ftol * self.cost:
                return STATUS_FTOL
            if np.linalg.norm(u_new - u_old) <= self.opts.xtol * (self.opts.xtol + np.linalg.norm(u_new)):
                return STATUS_XTOL


def cg(fun: Fun, x0: Any, lb: Any, ub: Any, *, options: CgOptions | dict | None = None,
       callback: Callback | None = None, batch: Batch | None = None, max_nfev: int | None = None,
       deadline: float | None = None) -> OptimiseResult:
    """Minimise S(x) = Σ r(x)² by nonlinear conjugate gradients with bounds.

    Parameters
    ----------
    fun, x0, lb, ub, callback, batch, max_nfev, deadline
        See :func:`rivercal.optimise.dud.dud`.
    options
        :class:`CgOptions` or a dict (``method`` selects FR, PR+ or steepest descent).

    Returns
    -------
    OptimiseResult
        ``jac`` is the forward-difference Jacobian at ``x``; ``extra["cg_method"]`` the variant.
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    opts = coerce_options(options, CgOptions)
    scale = option_vector("x_scale", opts.x_scale, x0.shape[0])
    scaled = Scaled(x0, default_initial_step(x0, lb, ub) if scale is None else scale, lb, ub)
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback)
    gradient = FDGradient(run, scaled, Differences(run, opts.rel_step, opts.diff_step, opts.noise))
    try:
        status = _ConjugateGradient(run, scaled, gradient, opts).solve()
    except Stop as stop:
        status = stop.status
    return run.result(status, TERMINATION_MESSAGES, "cg", jac=gradient.jacobian_at(run.best_x),
                      extra={"cg_method": opts.method})
