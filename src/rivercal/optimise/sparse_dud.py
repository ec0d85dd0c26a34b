"""Sparse DuD: DuD with a dependency map, so that fewer than p + 1 runs build the secant model.

In a river network a water-level station depends on only a few parameters (the friction of its own
reach, the crest of the weir downstream). Given which residual rows depend on which parameters, Sparse
DuD needs only k + 1 directions, k the largest number of parameters any row depends on, instead of p:
every initial run perturbs *all* parameters at once (random combinations ±½, ±1 of ``initial_step``), and
each block of the Jacobian (the rows of one dependency pattern × their parameters) is fitted by least
squares over all stored secants (OpenDA's SparseDud, reference note §2). Differences from OpenDA:

- each block is fitted by an orthogonal least-squares solve (``numpy.linalg.lstsq``), not the normal
  equations, with the secants weighted by 1/distance from the best point so that near points dominate;
- ``max_rel_step`` caps the step relative to the set's spread per parameter (OpenDA caps the absolute
  step in δ);
- the direction weights (±½ or ±1 per parameter, pointing into the box) come from a seeded generator
  and are redrawn until every block is well-conditioned; the generator's state is part of the restart state;
- the fresh Jacobian at the end (see ``DudOptions.final_jacobian``) comes from central differences along
  n_dir mixed directions (2 n_dir runs): a forward difference along a direction that moves every parameter
  carries the curvature of the strongly seen parameters into the column of a weakly seen one; where p
  forward differences along the axes take no more runs (p ≤ 2 n_dir), from those, as DuD's;
- everything else (line search, stopping rules, re-initialisation, restart, statuses) is DuD's,
  see :mod:`rivercal.optimise.dud`.

The status table is DuD's (``TERMINATION_MESSAGES``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rivercal.optimise._core import (
    Batch,
    Callback,
    Fun,
    Run,
    check_int,
    coerce_options,
    project,
    validate_controls,
    validate_problem,
)
from rivercal.optimise._dud_engine import default_steps, run_dud, validate_restart
from rivercal.optimise._dud_options import TERMINATION_MESSAGES, DudOptions, DudState
from rivercal.optimise.jacobian import fd_jacobian
from rivercal.optimise.result import OptimiseResult

__all__ = ["TERMINATION_MESSAGES", "Dependency", "SparseDudOptions", "sparse_dud"]

_DRAWS = 200


@dataclass(frozen=True, slots=True)
class SparseDudOptions(DudOptions):
    """Options of :func:`sparse_dud`: those of :class:`~rivercal.optimise.dud.DudOptions` and two more.

    Attributes
    ----------
    n_directions
        Number of perturbed points per (re-)initialisation; default min(p, k + 1) with k the largest
        number of parameters one residual row depends on (one secant more than the largest block needs).
    seed
        Seed of the generator of the direction weights.
    """

    n_directions: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        DudOptions.__post_init__(self)
        if self.n_directions is not None:
            check_int("n_directions", self.n_directions, 1)
        check_int("seed", self.seed)


class Dependency:
    """Which residual rows depend on which parameters.

    Parameters
    ----------
    spec
        None (every row on every parameter); a boolean ``numpy.ndarray`` (m, p); a mapping ``{rows: parameters}``
        whose keys are an int, a ``range`` or a tuple of row indices and whose values are parameter
        indices; or a sequence of ``(rows, parameters)`` pairs (rows may then also be a ``slice``).
        Row groups must not overlap, must cover every row, and every parameter must appear.
    n
        Number of parameters.
    """

    def __init__(self, spec: Any, n: int):
        self.n = n
        self.matrix: np.ndarray | None = None
        self.pairs: list[tuple[Any, np.ndarray]] = []
        if spec is None:
            self.patterns = [np.arange(n)]
        elif isinstance(spec, np.ndarray):
            self.matrix = self._matrix(spec)
            self.patterns = [np.flatnonzero(row) for row in np.unique(self.matrix, axis=0) if row.any()]
        else:
            if not isinstance(spec, Mapping | Sequence) or isinstance(spec, str | bytes):
                raise TypeError(f"dependency must be None, a boolean ndarray, a mapping or a sequence of pairs, "
                                f"got {type(spec).__name__}")
            items = spec.items() if isinstance(spec, Mapping) else spec
            for item in items:
                rows, params = item
                self.pairs.append((rows, self._params(params)))
            if not self.pairs:
                raise ValueError("dependency is empty")
            self.patterns = [p for p in {tuple(p): p for _, p in self.pairs}.values()]
            used = np.zeros(n, dtype=bool)
            for _, p in self.pairs:
                used[p] = True
            self._check_all_used(used)
        self.k = max(len(p) for p in self.patterns)

    def _matrix(self, spec: Any) -> np.ndarray:
        matrix = np.asarray(spec)
        if matrix.ndim != 2 or matrix.shape[1] != self.n:
            raise ValueError(f"dependency must have shape (m, {self.n}), got {matrix.shape}")
        if matrix.dtype != bool and not np.all(np.isin(matrix, (0, 1))):
            raise ValueError("dependency matrix must be boolean (or 0/1)")
        matrix = matrix.astype(bool)
        self._check_all_used(matrix.any(axis=0))
        return matrix

    def _params(self, params: Any) -> np.ndarray:
        idx = np.unique(np.atleast_1d(np.asarray(params, dtype=int)))
        if idx.size == 0 or idx[0] < 0 or idx[-1] >= self.n:
            raise ValueError(f"dependency: parameter indices must be in 0..{self.n - 1}, got {params!r}")
        return idx

    @staticmethod
    def _check_all_used(used: np.ndarray) -> None:
        if not used.all():
            raise ValueError(f"dependency: parameter(s) {np.flatnonzero(~used).tolist()} influence no residual")

    def bind(self, m: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """The (rows, parameters) blocks for m residual rows (one per dependency pattern)."""
        matrix = self.matrix if self.matrix is not None else self._matrix_from_pairs(m)
        if matrix.shape[0] != m:
            raise ValueError(f"dependency has {matrix.shape[0]} rows, fun returned {m} residuals")
        patterns, inverse = np.unique(matrix, axis=0, return_inverse=True)
        inverse = np.asarray(inverse).reshape(-1)
        return [(np.flatnonzero(inverse == g), np.flatnonzero(p)) for g, p in enumerate(patterns) if p.any()]

    def _matrix_from_pairs(self, m: int) -> np.ndarray:
        if not self.pairs:
            return np.ones((m, self.n), dtype=bool)
        matrix = np.zeros((m, self.n), dtype=bool)
        covered = np.zeros(m, dtype=int)
        for rows, params in self.pairs:
            idx = np.arange(m)[rows] if isinstance(rows, slice) else np.atleast_1d(np.asarray(rows, dtype=int))
            if idx.size and (idx.min() < 0 or idx.max() >= m):
                raise ValueError(f"dependency: rows {rows!r} are outside 0..{m - 1}")
            covered[idx] += 1
            matrix[np.ix_(idx, params)] = True
        if np.any(covered > 1):
            raise ValueError(f"dependency: row {int(np.flatnonzero(covered > 1)[0])} appears in more than one group")
        if np.any(covered == 0):
            missing = np.flatnonzero(covered == 0)
            raise ValueError(f"dependency: rows {missing[:10].tolist()} ({missing.size} in all) are not covered")
        return matrix


class SparseSecant:
    """Sparse DuD's secant model: mixed perturbations and block-wise least-squares Jacobians."""

    def __init__(self, dependency: Dependency, n_directions: int, seed: int, h0: np.ndarray,
                 max_condition: float, prior_std: np.ndarray | None):
        self.dependency, self.n_dir, self.h0 = dependency, n_directions, h0
        self.max_condition, self.prior_std = max_condition, prior_std
        self.rng = np.random.default_rng(seed)
        self.blocks: list[tuple[np.ndarray, np.ndarray]] | None = None

    def _steps(self, x: np.ndarray, h: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray:
        """One draw of n_dir steps: random weights in {±½, ±1} times h, flipped where they leave the box."""
        weights = self.rng.choice((-1.0, -0.5, 0.5, 1.0), size=(self.n_dir, self.dependency.n))
        steps = weights * h
        room = np.where(ub - x >= x - lb, ub - x, lb - x)
        for step, weight in zip(steps, weights, strict=True):
            out = (x + step < lb) | (x + step > ub)
            step[out] = -step[out]
            out = (x + step < lb) | (x + step > ub)
            step[out] = room[out] * np.abs(weight[out])
        return steps

    def initial_points(self, x: np.ndarray, h: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> list[np.ndarray]:
        """Points x + w_i ⊙ h, w_i random in {±½, ±1}: the best-conditioned of many draws.

        Components that would leave the box point the other way; the two magnitudes keep the directions
        independent even in a corner of the box, where every component must point inwards.
        """
        best, best_cond = None, np.inf
        for _ in range(_DRAWS):
            steps = self._steps(x, h, lb, ub)
            cond = max(_cond(steps[:, cols] / h[cols]) for cols in self.dependency.patterns)
            if cond < best_cond:
                best, best_cond = steps, cond
            if cond <= 10.0:
                break
        return [project(x + step, lb, ub) for step in best]

    def jacobian(self, points: np.ndarray, residuals: np.ndarray) -> np.ndarray | None:
        """Fit every block by weighted least squares over the secants; None if a block is degenerate."""
        n_obs = residuals.shape[1] - (0 if self.prior_std is None else self.prior_std.shape[0])
        if self.blocks is None:
            self.blocks = self.dependency.bind(n_obs)
        d_x = points[1:] - points[0]
        d_r = residuals[1:] - residuals[0]
        weight = 1.0 / np.maximum(np.linalg.norm(d_x / self.h0, axis=1), 1e-300)
        jac = np.zeros((residuals.shape[1], points.shape[1]))
        for rows, cols in self.blocks:
            lhs = d_x[:, cols] * weight[:, None]
            if _cond(lhs) > self.max_condition:
                return None
            sol = np.linalg.lstsq(lhs, d_r[:, rows] * weight[:, None], rcond=None)[0]
            jac[np.ix_(rows, cols)] = sol.T
        if self.prior_std is not None:
            jac[n_obs:, :] = np.diag(1.0 / self.prior_std)
        return jac

    def step_size(self, points: np.ndarray, delta: np.ndarray) -> float:
        """max_j |δ_j| / spread_j."""
        extent = np.max(np.abs(points[1:] - points[0]), axis=0)
        return float(np.max(np.abs(delta) / np.where(extent > 0, extent, self.h0)))

    def fresh_jacobian(self, run: Run, x: np.ndarray, r: np.ndarray, h: np.ndarray,
                       noise: np.ndarray | None) -> np.ndarray | None:
        """A fresh Jacobian at ``x`` in one batch, by whichever of two ways takes fewer runs.

        - 2 n_dir < p: the block Jacobian from n_dir mixed directions of size ``h``, by central differences.
          Every mixed direction moves all parameters, so a forward difference carries the curvature of the
          strongly seen parameters into the column of a weakly seen one (8 % on a damped oscillator); the
          central difference (r(x + d) − r(x − d))/2 cancels it.
        - otherwise (a dense map, or k close to p): DuD's forward differences along the axes, p runs, every
          column measured on its own and the weak dependencies the map leaves out included.
        """
        if run.lb.size <= 2 * self.n_dir:
            return fd_jacobian(run.evaluate_many, x, run.lb, run.ub, h, r0=r, noise=noise).jacobian
        plus = self.initial_points(x, h, run.lb, run.ub)  # inside the box: the steps point inwards
        minus = [x - (p - x) for p in plus]
        if any(np.any(m < run.lb) or np.any(m > run.ub) for m in minus):
            residuals = run.evaluate_many(plus)   # a bound within a step: one-sided (the steps point inwards)
            return self.jacobian(np.array([x, *plus]), np.array([r, *residuals]))
        residuals = run.evaluate_many(plus + minus)
        half = [r + 0.5 * (rp - rm) for rp, rm in zip(residuals[: len(plus)], residuals[len(plus):], strict=True)]
        return self.jacobian(np.array([x, *plus]), np.array([r, *half]))

    def get_state(self) -> Any:
        """The generator state (so a restart draws the same directions)."""
        return self.rng.bit_generator.state

    def set_state(self, state: Any) -> None:
        """Restore :meth:`get_state`."""
        if state is not None:
            self.rng.bit_generator.state = state


def _cond(block: np.ndarray) -> float:
    """Condition number after scaling the columns to unit length (inf if rank-deficient)."""
    norms = np.linalg.norm(block, axis=0)
    if block.shape[0] < block.shape[1] or np.any(norms == 0.0):
        return np.inf
    cond = np.linalg.cond(block / norms)
    return float(cond) if np.isfinite(cond) else np.inf


def sparse_dud(fun: Fun, x0: Any, lb: Any, ub: Any, *, dependency: Any = None,
               options: SparseDudOptions | dict | None = None, callback: Callback | None = None,
               batch: Batch | None = None, max_nfev: int | None = None, deadline: float | None = None,
               restart: DudState | None = None) -> OptimiseResult:
    """Minimise S(x) = Σ r(x)² with Sparse DuD.

    Parameters
    ----------
    fun, x0, lb, ub, options, callback, batch, max_nfev, deadline, restart
        As for :func:`~rivercal.optimise.dud.dud` (options: :class:`SparseDudOptions`).
    dependency
        Which residual rows depend on which parameters (see :class:`Dependency`); None means dense,
        which makes Sparse DuD a DuD with mixed perturbation directions.

    Returns
    -------
    OptimiseResult
        As for DuD; ``jac`` is the fitted block-sparse Jacobian.

    Examples
    --------
    >>> import numpy as np
    >>> fun = lambda x: np.array([x[0] - 1, 2 * (x[1] - 2), x[2] - 3, x[2] + x[0] - 4])
    >>> res = sparse_dud(fun, [0, 0, 0], -10, 10, dependency={0: [0], 1: [1], (2, 3): [0, 2]})
    >>> np.round(res.x, 6)
    array([1., 2., 3.])
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    opts = coerce_options(options, SparseDudOptions)
    n = x0.shape[0]
    dep = Dependency(dependency, n)
    n_dir = opts.n_directions if opts.n_directions is not None else min(n, dep.k + 1)
    if not dep.k <= n_dir:
        raise ValueError(f"options.n_directions={n_dir} is below {dep.k}, the largest number of parameters "
                         "one residual depends on")
    if restart is not None:
        restart = validate_restart(restart, "sparse_dud", n)
    h0 = restart.initial_step if restart is not None else default_steps(opts, x0, lb, ub)
    prior_std = None
    if opts.prior_std is not None:
        prior_std = np.full(n, opts.prior_std[0]) if opts.prior_std.shape[0] == 1 else opts.prior_std
    model = SparseSecant(dep, n_dir, opts.seed, h0, opts.max_condition, prior_std)
    return run_dud("sparse_dud", fun, x0, lb, ub, opts=opts, model=model, h0=h0, callback=callback,
                   batch=batch, max_nfev=max_nfev, deadline=deadline, restart=restart)
