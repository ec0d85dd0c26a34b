"""Calibration algorithms over ``fun(x) -> residuals``; this package knows nothing of rivers.

Every optimiser has the signature (scipy-like)::

    name(fun, x0, lb, ub, *, options=None, callback=None, batch=None, max_nfev=None, deadline=None)
        -> OptimiseResult

- ``fun(x)`` returns the vector of *weighted* residuals r; the cost is S = Σ r² (thesis Eq. 2-3 with the
  weights folded in). x, lb, ub are 1-D arrays in the optimiser's coordinates; no point outside
  [lb, ub] is ever evaluated. A NaN or infinite residual raises :class:`NonFiniteResidualsError`;
  exceptions from ``fun`` propagate unchanged.
- ``options`` is the algorithm's frozen options dataclass (e.g. :class:`DudOptions`) or a dict of its
  fields (unknown keys raise ValueError).
- ``batch(list_of_x) -> list_of_r`` evaluates independent points, possibly in parallel (default: a
  serial map over ``fun``). A batch may also offer ``batch.within(list_of_x, deadline, keep=i)``, the
  results of the runs done by ``deadline`` (a ``time.monotonic`` time) and None for the others, with
  point ``i`` run whatever the time (:meth:`rivercal.evaluate.Evaluator.within` and the default do).
- ``callback(record)`` is called after every iteration with an :class:`IterationRecord`; returning True
  aborts. ``max_nfev`` caps the number of model runs (a batch that does not fit is cut to the runs
  that do); ``deadline`` (wall-clock seconds from the call) is checked before every evaluation or batch,
  and inside a batch that offers ``within``: no run starts after it. A run already going is not
  interrupted, and x0 is always evaluated (which validates the problem). All three end the run with
  ``aborted=True`` and the best point so far.

Algorithms (one module each): :func:`dud`, :func:`sparse_dud`, :func:`trf`, :func:`sce_ua`, :func:`dds`,
:func:`nelder_mead`, :func:`powell`, :func:`cg`, :func:`bfgs`, :func:`grid`, :func:`glue`; by name through
:data:`OPTIMISERS` / :func:`get_optimiser`. Every local method takes its first step from the caller's
perturbation of each parameter (``initial_step`` or ``x_scale``; default 10 % of |x0|).

The one finite-difference Jacobian and covariance (:mod:`rivercal.optimise.jacobian`):
:func:`fd_jacobian` (forward or central differences in one batch, steps checked against the function's
noise) and :func:`covariance` / :func:`parameter_statistics` (thesis Eq. 2-12/2-13). :func:`fd_jacobian_of`
wraps the first for a plain ``fun`` (e.g. the standard deviations of a result of a method without a
Jacobian).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from rivercal.optimise._core import default_scale, start_first, until_deadline, validate_problem
from rivercal.optimise.bfgs import BfgsOptions, bfgs
from rivercal.optimise.cg import CgOptions, cg
from rivercal.optimise.dds import DdsOptions, dds
from rivercal.optimise.dud import DudOptions, DudState, dud
from rivercal.optimise.glue import GlueOptions, glue
from rivercal.optimise.grid import GridOptions, grid
from rivercal.optimise.jacobian import (
    Covariance,
    FiniteDifferences,
    covariance,
    difference_steps,
    fd_jacobian,
    parameter_statistics,
)
from rivercal.optimise.nelder_mead import NelderMeadOptions, nelder_mead
from rivercal.optimise.powell import PowellOptions, powell
from rivercal.optimise.registry import OPTIMISERS, OPTIONS, get_optimiser
from rivercal.optimise.result import IterationRecord, NonFiniteResidualsError, OptimiseResult
from rivercal.optimise.sce_ua import SceOptions, sce_ua
from rivercal.optimise.sparse_dud import SparseDudOptions, sparse_dud
from rivercal.optimise.trf import TrfOptions, trf

__all__ = [
    "OPTIMISERS",
    "OPTIONS",
    "BfgsOptions",
    "CgOptions",
    "Covariance",
    "DdsOptions",
    "DudOptions",
    "DudState",
    "FiniteDifferences",
    "GlueOptions",
    "GridOptions",
    "IterationRecord",
    "NelderMeadOptions",
    "NonFiniteResidualsError",
    "OptimiseResult",
    "PowellOptions",
    "SceOptions",
    "SparseDudOptions",
    "TrfOptions",
    "bfgs",
    "cg",
    "covariance",
    "dds",
    "difference_steps",
    "dud",
    "fd_jacobian",
    "fd_jacobian_of",
    "get_optimiser",
    "glue",
    "grid",
    "nelder_mead",
    "parameter_statistics",
    "powell",
    "sce_ua",
    "sparse_dud",
    "start_first",
    "trf",
    "until_deadline",
]


def fd_jacobian_of(fun: Callable[[np.ndarray], Any], x: Any, lb: Any, ub: Any, *, rel_step: float = 1e-6,
                   steps: Any = None, scheme: str = "forward",
                   batch: Callable[[list[np.ndarray]], Any] | None = None) -> np.ndarray:
    """Finite-difference Jacobian of ``fun`` at ``x`` (one batch), steps pointing into [lb, ub].

    ``steps`` (optimiser units) defaults to rel_step · max(|x_j|, 10⁻³ typical_j). With
    :func:`parameter_statistics` it gives ``std``/``correlation`` for the result of a method without a
    Jacobian (SCE-UA, DDS, Nelder-Mead, Powell, grid, GLUE).
    """
    x, lb, ub = validate_problem(x, lb, ub)
    h = difference_steps(x, rel_step, default_scale(x, lb, ub)) if steps is None else steps
    evaluate = batch if batch is not None else (lambda points: [np.asarray(fun(p), dtype=float) for p in points])
    return fd_jacobian(evaluate, x, lb, ub, h, scheme=scheme).jacobian
