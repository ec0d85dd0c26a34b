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

from rivercal.optimise._core import Run, fd_jacobian, project


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


def iteration_callback(run: Run, scaled: Scaled) -> Callable[[OptimizeResult], None]:
    """A scipy ``callback(intermediate_result)`` that records the iteration (and may abort the run)."""

    def callback(intermediate_result: OptimizeResult) -> None:
        run.iteration(scaled.to_x(intermediate_result.x), float(intermediate_result.fun))

    return callback


class FDGradient:
    """S(u) and its gradient by forward differences of the residuals (one batch per gradient).

    ∇S = 2 Jᵀ r; the last Jacobian is kept (with its point) for the parameter statistics.
    """

    def __init__(self, run: Run, scaled: Scaled, rel_step: float, typical: np.ndarray):
        self.run, self.scaled, self.rel_step, self.typical = run, scaled, rel_step, typical
        self.last: tuple[np.ndarray, np.ndarray] | None = None

    def residuals_and_jacobian(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """r(x) and J(x); x and its perturbations are one batch."""
        r, jac = fd_jacobian(self.run, x, self.rel_step, self.typical)
        self.last = (x.copy(), jac)
        return r, jac

    def __call__(self, u: np.ndarray) -> tuple[float, np.ndarray]:
        """(S, ∇_u S) for scipy's ``jac=True``."""
        x = self.scaled.to_x(u)
        r, jac = self.residuals_and_jacobian(x)
        return self.run.cost_of(r), 2.0 * (jac.T @ r) * self.scaled.scale

    def jacobian_at(self, x: np.ndarray) -> np.ndarray | None:
        """The last Jacobian if it was taken at x."""
        if self.last is not None and np.array_equal(self.last[0], x):
            return self.last[1]
        return None


def scipy_status(res: Any, table: dict[int, int], default: int) -> int:
    """Map scipy's status code to ours."""
    return table.get(int(res.status), default)
