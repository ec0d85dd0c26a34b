"""The Jacobian of a calibration problem's weighted residuals (thesis Eq. 2-10), with its rows and columns named.

The differences themselves are :func:`rivercal.optimise.fd_jacobian` (the one finite-difference routine
of rivercal): x and the perturbed points are evaluated as one batch, steps point into the bounds. Here
the step of parameter j is relative to its *scale* d_j, by default its physical range in optimiser units
(ub − lb): h_j = ``rel_step`` · d_j, 1 % by default — 0.013 m for a crest with a 1.3 m range,
0.32 m^(1/3)/s for a Strickler coefficient in 8 … 40. A step relative to |x| would be 10⁻⁵ m for a crest
10 m above datum, far below the numerical noise of a hydrodynamic model.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pandas as pd

from rivercal.analysis._common import Batch, batch_for
from rivercal.optimise import fd_jacobian as fd_differences

__all__ = ["Jacobian", "fd_jacobian", "parameter_scales"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Jacobian:
    """A finite-difference Jacobian of a problem's weighted residuals (thesis Eq. 2-10).

    Attributes
    ----------
    matrix
        ∂r/∂x, shape (m residuals, p parameters); per optimiser unit of each parameter (per m for a crest).
    x
        The point, optimiser units.
    steps
        The signed steps h_j (forward: x_j + h_j; central: the spread x_j + h⁺ − (x_j − h⁻)).
    residuals
        r(x), the weighted residuals at the point.
    names
        Parameter names (columns).
    rows
        The series id of every row.
    scale
        The parameter scales d_j (optimiser units) the steps are relative to.
    scheme
        ``forward`` or ``central``.
    nfev
        Model runs used.
    """

    matrix: np.ndarray
    x: np.ndarray
    steps: np.ndarray
    residuals: np.ndarray
    names: tuple[str, ...]
    rows: tuple[str, ...]
    scale: np.ndarray
    scheme: str
    nfev: int

    def to_frame(self) -> pd.DataFrame:
        """The matrix with a (series, row) index and parameter columns."""
        index = pd.MultiIndex.from_arrays([list(self.rows), _row_numbers(self.rows)], names=["series", "row"])
        return pd.DataFrame(self.matrix, index=index, columns=list(self.names))


def _row_numbers(rows: Sequence[str]) -> list[int]:
    seen: dict[str, int] = {}
    out = []
    for r in rows:
        out.append(seen.get(r, 0))
        seen[r] = out[-1] + 1
    return out


def parameter_scales(problem: Any, scale: Sequence[float] | np.ndarray | None = None) -> np.ndarray:
    """The scales d_j (optimiser units): ``scale`` checked, or the parameter ranges ub − lb."""
    lb, ub = problem.bounds
    if scale is None:
        d = np.asarray(ub, dtype=float) - np.asarray(lb, dtype=float)
    else:
        d = np.asarray(scale, dtype=float).reshape(-1)
    if d.shape != (len(problem.parameters),) or not np.all(np.isfinite(d)) or np.any(d <= 0):
        raise ValueError(f"scale must hold {len(problem.parameters)} positive finite numbers, got {d}")
    return d


def fd_jacobian(problem: Any, x: np.ndarray | None = None, *, rel_step: float = 0.01,
                scale: Sequence[float] | np.ndarray | None = None, scheme: Literal["forward", "central"] = "forward",
                batch: Batch | None = None, workers: int | None = None) -> Jacobian:
    """Finite-difference Jacobian of ``problem.residuals`` at ``x``, all runs as one batch.

    Parameters
    ----------
    problem
        A :class:`~rivercal.problem.CalibrationProblem`.
    x
        The point in optimiser units (default: the initial values, ``problem.x0``).
    rel_step
        Step as a fraction of each parameter's scale: h_j = rel_step · d_j (default 1 %).
    scale
        The scales d_j in optimiser units (default: the parameter ranges ub − lb).
    scheme
        ``forward`` (p + 1 runs) or ``central`` (2p + 1 runs; one-sided where a bound is within a step).
    batch
        A batch evaluator over ``problem.residuals`` (e.g. a shared
        :class:`~rivercal.evaluate.Evaluator`); default: a new one with ``workers`` processes.
    workers
        Worker processes when no ``batch`` is given (None: all cores).

    Raises
    ------
    ValueError
        For a bad step, scale, scheme or a point outside the bounds.
    """
    if not (isinstance(rel_step, int | float) and 0.0 < rel_step <= 0.5):
        raise ValueError(f"rel_step must be in (0, 0.5], got {rel_step!r}")
    if scheme not in ("forward", "central"):
        raise ValueError(f"scheme must be 'forward' or 'central', got {scheme!r}")
    lb, ub = (np.asarray(b, dtype=float) for b in problem.bounds)
    x = np.array(problem.x0 if x is None else x, dtype=float)
    if x.shape != lb.shape or np.any(x < lb) or np.any(x > ub):
        raise ValueError(f"the point {x} lies outside the bounds")
    d = parameter_scales(problem, scale)
    with batch_for(problem, batch, workers) as run:
        fd = fd_differences(lambda points: [np.asarray(r, dtype=float) for r in run(points)], x, lb, ub,
                            rel_step * d, scheme=scheme)
    rows = tuple(s.id for s in problem.observations for _ in range(len(s)))
    log.info("Jacobian of %d residuals and %d parameters from %d runs", fd.residuals.size, x.size, fd.nfev)
    return Jacobian(matrix=fd.jacobian, x=x, steps=fd.steps, residuals=fd.residuals,
                    names=tuple(problem.parameters.names), rows=rows, scale=d, scheme=scheme, nfev=fd.nfev)
