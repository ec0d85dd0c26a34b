"""Result objects shared by every optimiser.

:class:`OptimiseResult` follows the shape of :class:`scipy.optimize.OptimizeResult` (``x``, ``nfev``,
``nit``, ``status``, ``message``, ``success``) but is a frozen dataclass, carries the full evaluation log
and, where the algorithm has a Jacobian (exact, finite-difference or secant), the parameter standard
deviations and correlations of thesis Eq. 2-12/2-13.

Status codes
------------
Every algorithm module defines its own ``TERMINATION_MESSAGES`` table. The non-positive codes are shared
(:data:`COMMON_MESSAGES`); positive codes mean the algorithm converged or finished its design
(``success = status > 0``, as in scipy):

====== ==========================================================================================
status meaning
====== ==========================================================================================
  0    the evaluation budget ``max_nfev`` was used up (``aborted=True``)
 -1    the callback returned True (``aborted=True``)
 -2    the wall-clock ``deadline`` passed (``aborted=True``)
 -3    the iteration limit of the algorithm's options was reached (not converged, not aborted)
 -4    the underlying scipy routine stopped abnormally (e.g. no progress in its line search)
====== ==========================================================================================
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rivercal.errors import RivercalError

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "ABORT_STATUSES",
    "COMMON_MESSAGES",
    "STATUS_ABNORMAL",
    "STATUS_CALLBACK",
    "STATUS_DEADLINE",
    "STATUS_MAX_ITER",
    "STATUS_MAX_NFEV",
    "IterationRecord",
    "NonFiniteResidualsError",
    "OptimiseResult",
]

STATUS_MAX_NFEV = 0
STATUS_CALLBACK = -1
STATUS_DEADLINE = -2
STATUS_MAX_ITER = -3
STATUS_ABNORMAL = -4

#: Statuses after which ``aborted`` is True: the run was cut short from outside the algorithm.
ABORT_STATUSES = frozenset({STATUS_MAX_NFEV, STATUS_CALLBACK, STATUS_DEADLINE})

COMMON_MESSAGES: dict[int, str] = {
    STATUS_MAX_NFEV: "The maximum number of function evaluations (max_nfev) is exceeded.",
    STATUS_CALLBACK: "The callback requested to stop (returned True).",
    STATUS_DEADLINE: "The wall-clock deadline passed.",
    STATUS_MAX_ITER: "The maximum number of iterations is reached.",
}


class NonFiniteResidualsError(RivercalError, ValueError):
    """``fun`` returned a residual vector with NaN or infinite entries.

    An optimiser never turns such a vector into a cost. A caller that wants failed model runs to count
    as bad points must return a finite penalty itself (the "penalty" failure policy of the evaluation
    layer).
    """


@dataclass(frozen=True, slots=True)
class IterationRecord:
    """One iteration as reported to the callback and stored in ``OptimiseResult.history``.

    Attributes
    ----------
    nit
        Iteration number, starting at 1.
    x
        The best point after the iteration (optimiser coordinates).
    cost
        Its cost S = Σ r².
    linear_cost
        The cost the algorithm's linear (secant or Jacobian) model predicted for the step taken in this
        iteration; NaN for methods without such a model.
    nfev
        Function evaluations used so far.
    """

    nit: int
    x: np.ndarray
    cost: float
    linear_cost: float
    nfev: int


@dataclass(frozen=True)
class OptimiseResult:
    """What every optimiser returns.

    Attributes
    ----------
    x
        The best point found (the lowest cost of all evaluations), optimiser coordinates.
    cost
        Its cost S = Σ r² (thesis Eq. 2-3 with the weights folded into the residuals).
    nfev
        Number of model runs (calls of ``fun`` or points passed to ``batch``).
    nit
        Number of iterations (algorithm specific: outer iterations, shuffling loops, ...).
    status
        Termination code; see the algorithm module's ``TERMINATION_MESSAGES``.
    message
        Text of ``status``.
    success
        ``status > 0``: the algorithm converged or completed its design.
    aborted
        The run was cut short by ``max_nfev``, ``deadline`` or the callback; ``x`` is the best point so far.
    history
        One :class:`IterationRecord` per iteration.
    evaluations
        ``(x, cost)`` of every evaluation, in the order they were run.
    std
        Parameter standard deviations √diag(cov) with cov = (JᵀJ)⁻¹ (thesis Eq. 2-12), or None when the
        method has no Jacobian or JᵀJ is singular. Exact (to first order) for properly weighted residuals
        r = (y − ŷ)/σ; ``extra["std_scaled"]`` gives the version scaled by s² = S/(m − p).
    correlation
        cor(i, j) = cov_ij / √(cov_ii cov_jj) (thesis Eq. 2-13), or None.
    jac
        The Jacobian (m × p) behind ``std``: finite-difference, scipy's, or DuD's secant approximation.
    method
        Name of the algorithm (key of ``rivercal.optimise.OPTIMISERS``).
    extra
        Algorithm-specific results. Every method sets ``"residuals"`` (the residual vector at ``x``);
        methods with a Jacobian add ``"covariance"`` and ``"std_scaled"``.
    """

    x: np.ndarray
    cost: float
    nfev: int
    nit: int
    status: int
    message: str
    success: bool
    aborted: bool
    history: tuple[IterationRecord, ...]
    evaluations: tuple[tuple[np.ndarray, float], ...]
    std: np.ndarray | None
    correlation: np.ndarray | None
    jac: np.ndarray | None
    method: str
    extra: dict[str, Any] = field(default_factory=dict)

    def __repr__(self) -> str:
        x = np.array2string(np.asarray(self.x), precision=6, separator=", ")
        return (
            f"OptimiseResult(method={self.method!r}, status={self.status}, success={self.success}, "
            f"aborted={self.aborted}, cost={self.cost:.6g}, nfev={self.nfev}, nit={self.nit}, x={x})"
        )

    def to_frame(self, names: list[str] | None = None) -> pd.DataFrame:
        """The best point as a table: ``x`` and ``std`` (optimiser coordinates; NaN without ``std``).

        Parameters
        ----------
        names
            Row labels (default ``x0``, ``x1``, ...).

        Examples
        --------
        >>> from rivercal.optimise import dud
        >>> t = np.linspace(0.0, 1.0, 20)
        >>> res = dud(lambda x: 2.0 * np.exp(-1.5 * t) - x[0] * np.exp(-x[1] * t), [1.0, 1.0], [0, 0], [10, 10])
        >>> res.to_frame(["a", "k"]).round(3)  # std for residuals of σ = 1
                     x    std
        parameter
        a          2.0  0.572
        k          1.5  0.801
        """
        import pandas as pd

        x = np.atleast_1d(np.asarray(self.x, dtype=float))
        labels = list(names) if names is not None else [f"x{i}" for i in range(x.size)]
        std = np.full(x.size, np.nan) if self.std is None else np.asarray(self.std, dtype=float)
        return pd.DataFrame({"x": x, "std": std}, index=pd.Index(labels, name="parameter"))
