"""Gridded full search: axes, order, result arrays."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.optimise import grid
from rivercal.optimise.grid import GridOptions, grid_axes


def test_axes_follow_openda_counting():
    axes = grid_axes(GridOptions(ranges=[(0.0, 1.0, 0.3), (-1.0, 1.0, 0.5)]), np.array([0.0, -1.0]),
                     np.array([1.0, 1.0]))
    np.testing.assert_allclose(axes[0], [0.0, 0.3, 0.6, 0.9])   # ⌊(max − min)/step⌋ + 1 points
    np.testing.assert_allclose(axes[1], [-1.0, -0.5, 0.0, 0.5, 1.0])


def test_odometer_order_and_cost_array():
    def fun(x):
        return np.array([x[0] - 0.5, 2.0 * (x[1] - 1.0)])

    res = grid(fun, [0.0, 0.0], [0.0, 0.0], [1.0, 2.0], options={"ranges": [(0, 1, 0.5), (0, 2, 1.0)], "chunk_size": 4})
    xs = [x for x, _ in res.evaluations[1:]]   # x0 first, then the grid
    np.testing.assert_array_equal(xs[:4], [[0, 0], [0.5, 0], [1, 0], [0, 1]])   # first parameter fastest
    np.testing.assert_array_equal(res.x, [0.5, 1.0])
    costs = res.extra["grid_costs"]
    assert costs.shape == (3, 3) and costs[1, 1] == 0.0 and costs[2, 0] == pytest.approx(0.25 + 4.0)
    assert res.nit == 3   # chunks of 4 (+ x0 in the first)


def test_default_axes_from_bounds():
    res = grid(lambda x: x - 0.3, [0.0], [0.0], [1.0], options={"points_per_axis": 11})
    assert res.extra["grid_axes"][0].size == 11 and res.x[0] == pytest.approx(0.3)


def test_range_outside_bounds_and_size_guard():
    with pytest.raises(ValueError, match=r"ranges\[0\]"):
        grid(lambda x: x, [0.0], [0.0], [1.0], options={"ranges": [(-1.0, 1.0, 0.5)]})
    with pytest.raises(ValueError, match="max_points"):
        grid(lambda x: x, [0.0, 0.0], 0.0, 1.0, options={"points_per_axis": 1000, "max_points": 1000})
    with pytest.raises(ValueError, match="rows"):
        grid(lambda x: x, [0.0, 0.0], 0.0, 1.0, options={"ranges": [(0.0, 1.0, 0.5)]})
    with pytest.raises(ValueError, match="triples"):
        GridOptions(ranges=[(0.0, 1.0)])


def test_abort_leaves_nan_where_not_evaluated():
    res = grid(lambda x: x, [0.0, 0.0], 0.0, 1.0, options={"points_per_axis": 5, "chunk_size": 5}, max_nfev=8)
    assert res.aborted and np.count_nonzero(np.isfinite(res.extra["grid_costs"])) == 7
