"""Helpers for the optimisers that drive :mod:`scipy.optimize`.

scipy's minimisers see scaled coordinates u with x = x0 + scale ⊙ u, so that tolerances and initial
simplices/directions are measured in units of the caller's perturbation (or typical magnitude) of each
parameter. Every point scipy asks for is projected into [lb, ub] before it is run (scipy's bounded
Nelder-Mead, Powell, L-BFGS-B and TRF already stay inside; the projection only removes round-off).
A :class:`~rivercal.optimise._core.Stop` raised inside the objective or callback unwinds through scipy
and ends the run with the best point so far.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.optimize import Bounds, OptimizeResult

from rivercal.optimise._core import Run, default_scale, option_vector, project
from rivercal.optimise.jacobian import FiniteDifferences, difference_steps, fd_jacobian


class Scaled:
    """The map u ↦ x = x0 + scale ⊙ u (projected into the box) and the bounds in u."""

    def __init__(self, x0: np.ndarray, scale: np.ndarray, lb: np.ndarray, ub: np.ndarray):
        self.x0, self.scale, self.lb, self.ub = x0, scale, lb, ub
        self.u_lb, self.u_ub = (lb - x0) / scale, (ub - x0) / scale

    def to_x(self, u: np.ndarray) -> np.ndarray:
        """Point in optimiser coordinates (exactly on a bound when u is on or beyond it)."""
        u = np.asarray(u, dtype=float)
        x = project(self.x0 + self.scale * u, self.lb, self.ub)
        return np.where(u <= self.u_lb, self.lb, np.where(u >= self.u_ub, self.ub, x))

    def to_u(self, x: np.ndarray) -> np.ndarray:
        """Scaled coordinates of x."""
        return (x - self.x0) / self.scale

    def bounds(self) -> Bounds:
        """The box in u."""
        return Bounds(self.u_lb, self.u_ub)


def cost_function(run: Run, scaled: Scaled) -> Callable[[np.ndarray], float]:
    """S(x(u)) through the run log."""

    def cost(u: np.ndarray) -> float:
        return run.cost_of(run.evaluate(scaled.to_x(u)))

    return cost


def iteration_callback(run: Run, scaled: Scaled, unit: Callable[[], float] | None = None
                       ) -> Callable[[OptimizeResult], None]:
    """A scipy ``callback(intermediate_result)`` that records the iteration (and may abort the run).

    ``unit()`` is the factor scipy's cost was divided by (see :class:`FDGradient`).
    """

    def callback(intermediate_result: OptimizeResult) -> None:
        factor = 1.0 if unit is None else unit()
        run.iteration(scaled.to_x(intermediate_result.x), float(intermediate_result.fun) * factor)

    return callback


class Differences:
    """The finite-difference steps of one run and its Jacobians through the run log.

    The steps are ``diff_step`` (optimiser units) when given, else rel_step · max(|x_j|, 10⁻³ typical_j).
    With ``noise`` (the residuals' numerical jitter, weighted units) a column whose difference is below
    10 times the noise is taken again with a larger step (see :func:`~rivercal.optimise.fd_jacobian`),
    and that larger step is kept for the rest of the run.
    """

    def __init__(self, run: Run, rel_step: float, diff_step: np.ndarray | None, noise: np.ndarray | None):
        n = run.x0.shape[0]
        self.run, self.rel_step = run, rel_step
        self.typical = default_scale(run.x0, run.lb, run.ub)
        self.fixed = option_vector("diff_step", diff_step, n)
        self.noise = noise
        self.grown = np.zeros(n)

    def steps(self, x: np.ndarray) -> np.ndarray:
        """The step sizes at x."""
        h = self.fixed if self.fixed is not None else difference_steps(x, self.rel_step, self.typical)
        return np.maximum(h, self.grown)

    def jacobian(self, x: np.ndarray) -> FiniteDifferences:
        """r(x) and J(x): x (unless cached) and the p perturbed points as one batch."""
        h = self.steps(x)
        noise = None
        if self.noise is not None:
            if self.run.m is None:
                self.run.evaluate(x)   # the number of residuals, to check the noise against
            if self.noise.shape[0] not in (1, self.run.m):
                raise ValueError(f"options.noise must be a scalar or have one value per residual ({self.run.m}), "
                                 f"got {self.noise.shape[0]}")
            noise = self.noise
        fd = fd_jacobian(self.run.evaluate_many, x, self.run.lb, self.run.ub, h, noise=noise)
        grown = np.abs(fd.steps) > h * (1.0 + 1e-9)
        self.grown[grown] = np.abs(fd.steps[grown])
        return fd


class FDGradient:
    """S(u) and its gradient by forward differences of the residuals (one batch per gradient).

    ∇S = 2 Jᵀ r; the last Jacobian is kept (with its point) for the parameter statistics. With
    ``normalise`` the cost is divided by the 2-norm of its gradient at the first point (in u), so
    that a method whose first trial step is the gradient itself (L-BFGS-B on a box) steps by one
    unit of u, i.e. by the caller's ``x_scale``.
    """

    def __init__(self, run: Run, scaled: Scaled, differences: Differences, *, normalise: bool = False):
        self.run, self.scaled, self.differences = run, scaled, differences
        self.normalise = normalise
        self.unit: float | None = None if normalise else 1.0
        self.last: tuple[np.ndarray, np.ndarray] | None = None

    def residuals_and_jacobian(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """r(x) and J(x); x and its perturbations are one batch."""
        fd = self.differences.jacobian(x)
        self.last = (x.copy(), fd.jacobian)
        return fd.residuals, fd.jacobian

    def __call__(self, u: np.ndarray) -> tuple[float, np.ndarray]:
        """(S, ∇_u S) for scipy's ``jac=True`` (both divided by the normalising unit)."""
        x = self.scaled.to_x(u)
        r, jac = self.residuals_and_jacobian(x)
        grad = 2.0 * (jac.T @ r) * self.scaled.scale
        if self.unit is None:
            norm = float(np.linalg.norm(grad))
            self.unit = norm if np.isfinite(norm) and norm > 0 else 1.0
        return self.run.cost_of(r) / self.unit, grad / self.unit

    def jacobian_at(self, x: np.ndarray) -> np.ndarray | None:
        """The last Jacobian if it was taken at x."""
        if self.last is not None and np.array_equal(self.last[0], x):
            return self.last[1]
        return None


def scipy_status(res: Any, table: dict[int, int], default: int) -> int:
    """Map scipy's status code to ours."""
    return table.get(int(res.status), default)
