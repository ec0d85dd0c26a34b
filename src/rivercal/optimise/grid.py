"""Gridded full search: every point of a regular grid, evaluated in batches.

Each parameter gets the axis min, min + step, ..., up to max (⌊(max − min)/step⌋ + 1 points, as OpenDA's
GriddedFullSearch); the grid is the Cartesian product in odometer order (first parameter fastest). x0 is
evaluated first (it validates the problem and competes for the best point), then the grid in chunks of
``chunk_size`` points, each one ``batch``. The callback is called after every chunk.

Status codes (``TERMINATION_MESSAGES``): 1 every grid point evaluated; 0 / −1 / −2 budget, callback,
deadline (``extra["grid_costs"]`` then holds NaN where no run was made).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rivercal.optimise._core import (
    Batch,
    Callback,
    Fun,
    Run,
    Stop,
    check_int,
    coerce_options,
    require_finite_bounds,
    validate_controls,
    validate_problem,
)
from rivercal.optimise.result import COMMON_MESSAGES, OptimiseResult

__all__ = ["TERMINATION_MESSAGES", "GridOptions", "grid", "grid_axes"]

STATUS_DONE = 1

TERMINATION_MESSAGES: dict[int, str] = {
    **COMMON_MESSAGES,
    STATUS_DONE: "Every grid point was evaluated.",
}


@dataclass(frozen=True, slots=True)
class GridOptions:
    """Options of :func:`grid`.

    Attributes
    ----------
    ranges
        ``(min, max, step)`` per parameter, inside [lb, ub]. Default: ``points_per_axis`` equally spaced
        points from lb to ub (finite bounds needed).
    points_per_axis
        Points per axis when ``ranges`` is None (11).
    chunk_size
        Points per batch (1000).
    max_points
        Refuse grids larger than this (1 000 000).
    """

    ranges: Any = None
    points_per_axis: int = 11
    chunk_size: int = 1000
    max_points: int = 1_000_000

    def __post_init__(self) -> None:
        check_int("points_per_axis", self.points_per_axis, 2)
        check_int("chunk_size", self.chunk_size, 1)
        check_int("max_points", self.max_points, 1)
        if self.ranges is not None:
            ranges = np.array(self.ranges, dtype=float, ndmin=2)
            if ranges.ndim != 2 or ranges.shape[1] != 3 or not np.all(np.isfinite(ranges)):
                raise ValueError(f"ranges must be a sequence of (min, max, step) triples, got {self.ranges!r}")
            if np.any(ranges[:, 2] <= 0) or np.any(ranges[:, 1] < ranges[:, 0]):
                raise ValueError("ranges: each step must be positive and each max >= min")
            ranges.setflags(write=False)
            object.__setattr__(self, "ranges", ranges)


def grid_axes(opts: GridOptions, lb: np.ndarray, ub: np.ndarray) -> tuple[np.ndarray, ...]:
    """The grid values per parameter."""
    n = lb.shape[0]
    if opts.ranges is None:
        require_finite_bounds("grid without options.ranges", lb, ub)
        return tuple(np.linspace(lb[j], ub[j], opts.points_per_axis) for j in range(n))
    if opts.ranges.shape[0] != n:
        raise ValueError(f"options.ranges has {opts.ranges.shape[0]} rows, x0 has {n} parameters")
    axes = []
    for j, (low, high, step) in enumerate(opts.ranges):
        if low < lb[j] or high > ub[j]:
            raise ValueError(f"options.ranges[{j}] = ({low}, {high}) is outside [lb, ub] = [{lb[j]}, {ub[j]}]")
        count = int(np.floor((high - low) / step * (1 + 1e-12) + 1e-9)) + 1
        axes.append(np.minimum(low + step * np.arange(count), high))
    return tuple(axes)


def _keep_partial(run: Run, costs: np.ndarray, start: int, partial: list[np.ndarray | None]) -> None:
    """Store the costs of the points of an interrupted batch that were run."""
    for i, r in enumerate(partial):
        if r is not None:
            costs[start + i] = run.cost_of(r)


def grid(fun: Fun, x0: Any, lb: Any, ub: Any, *, options: GridOptions | dict | None = None,
         callback: Callback | None = None, batch: Batch | None = None, max_nfev: int | None = None,
         deadline: float | None = None) -> OptimiseResult:
    """Evaluate S(x) = Σ r(x)² on a regular grid and return the best point.

    Parameters
    ----------
    fun, x0, lb, ub, callback, batch, max_nfev, deadline
        See :func:`rivercal.optimise.dud.dud`.
    options
        :class:`GridOptions` or a dict.

    Returns
    -------
    OptimiseResult
        ``extra["grid_axes"]`` (tuple of axis values) and ``extra["grid_costs"]`` (array of shape
        (len(axis_0), ..., len(axis_p−1)), NaN where not evaluated).
    """
    x0, lb, ub = validate_problem(x0, lb, ub)
    validate_controls(max_nfev, deadline, callback, batch, fun)
    opts = coerce_options(options, GridOptions)
    axes = grid_axes(opts, lb, ub)
    shape = tuple(a.size for a in axes)
    total = int(np.prod(shape, dtype=float))
    if total > opts.max_points:
        raise ValueError(f"the grid has {total} points, more than options.max_points={opts.max_points}")
    mesh = np.meshgrid(*axes, indexing="ij")
    points = np.stack([g.ravel(order="F") for g in mesh], axis=1)
    costs = np.full(total, np.nan)
    run = Run(fun, batch, x0, lb, ub, max_nfev=max_nfev, deadline=deadline, callback=callback)
    try:
        for start in range(0, total, opts.chunk_size):
            chunk = list(points[start:start + opts.chunk_size])
            lead = [x0] if start == 0 else []
            try:
                residuals = run.evaluate_many(lead + chunk)[len(lead):]
            except Stop as stop:
                _keep_partial(run, costs, start, (stop.partial or [])[len(lead):])
                raise
            costs[start:start + len(chunk)] = [run.cost_of(r) for r in residuals]
            run.iteration(run.best_x, run.best_cost)
        status = STATUS_DONE
    except Stop as stop:
        status = stop.status
    extra = {"grid_axes": axes, "grid_costs": costs.reshape(shape, order="F")}
    return run.result(status, TERMINATION_MESSAGES, "grid", extra=extra)
