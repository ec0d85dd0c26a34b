"""Sparse DuD: the dependency map, fewer runs on separable problems, exact restart."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.optimise import dud, sparse_dud
from rivercal.optimise.sparse_dud import Dependency

N = 8
T = np.linspace(0.0, 2.0, 6)
TRUE = np.linspace(0.5, 2.0, N)


def stations(x):
    """Eight 'stations' of six residuals each; station i depends on parameter i (and i − 1)."""
    rows = []
    for i in range(N):
        neighbour = 0.2 * x[i - 1] if i else 0.0
        rows.append(np.exp(-x[i] * T) + neighbour - np.exp(-TRUE[i] * T) - (0.2 * TRUE[i - 1] if i else 0.0))
    return np.concatenate(rows)


DEPENDENCY = {range(6 * i, 6 * i + 6): ([i - 1, i] if i else [0]) for i in range(N)}
TIGHT = {"abs_tol": 0.0, "rel_tol": 1e-14, "rel_tol_linear": 0.0, "negligible_cost": 0.0, "max_outer": 200}


def test_sparse_needs_far_fewer_runs_than_dud():
    sizes = []

    def batch(xs):
        sizes.append(len(xs))
        return [stations(x) for x in xs]

    x0 = np.ones(N)
    sparse = sparse_dud(stations, x0, 0.01, 5.0, dependency=DEPENDENCY, options=TIGHT, batch=batch)
    dense = dud(stations, x0, 0.01, 5.0, options=TIGHT)
    np.testing.assert_allclose(sparse.x, TRUE, rtol=1e-6)
    np.testing.assert_allclose(dense.x, TRUE, rtol=1e-6)
    assert sizes[0] == 4            # k = 2 parameters per row: x0 + k + 1 directions, one batch
    assert sparse.nfev < dense.nfev / 2
    jac = sparse.jac
    assert jac.shape == (6 * N, N) and np.count_nonzero(jac[:6, 1:]) == 0   # block-sparse


@pytest.mark.parametrize("form", ["mapping", "pairs", "matrix"])
def test_dependency_forms_agree(form):
    if form == "mapping":
        spec = DEPENDENCY
    elif form == "pairs":
        spec = [(slice(6 * i, 6 * i + 6), [i - 1, i] if i else [0]) for i in range(N)]
    else:
        spec = np.zeros((6 * N, N), dtype=bool)
        for rows, cols in DEPENDENCY.items():
            spec[np.ix_(list(rows), cols)] = True
    res = sparse_dud(stations, np.ones(N), 0.01, 5.0, dependency=spec, options=TIGHT)
    np.testing.assert_allclose(res.x, TRUE, rtol=1e-6)
    blocks = Dependency(spec, N).bind(6 * N)
    assert len(blocks) == N


@pytest.mark.parametrize(("spec", "message"), [
    ({range(0, 40): [0, 1], range(40, 48): [9]}, "parameter indices must be in 0..7"),
    ({range(0, 40): list(range(7)), range(40, 48): [0]}, r"parameter\(s\) \[7\] influence no residual"),
    ({range(0, 40): list(range(8))}, "are not covered"),
    ({range(0, 41): list(range(8)), range(40, 48): [0]}, "appears in more than one group"),
    ({range(0, 60): list(range(8))}, "outside 0..47"),
    (np.ones((47, 8), dtype=bool), "dependency has 47 rows"),
    (np.ones((48, 7), dtype=bool), r"shape \(m, 8\)"),
    ("rows", "dependency must be None"),
])
def test_dependency_errors(spec, message):
    with pytest.raises((ValueError, TypeError), match=message):
        sparse_dud(stations, np.ones(N), 0.01, 5.0, dependency=spec)


def test_n_directions_below_k_is_rejected():
    with pytest.raises(ValueError, match="n_directions=1 is below 2"):
        sparse_dud(stations, np.ones(N), 0.01, 5.0, dependency=DEPENDENCY, options={"n_directions": 1})


def test_corner_start_is_not_degenerate():
    res = sparse_dud(stations, np.full(N, 0.01), 0.01, 5.0, dependency=DEPENDENCY, options=TIGHT)
    np.testing.assert_allclose(res.x, TRUE, rtol=1e-6)


@pytest.mark.parametrize("stop_at", [2, 6, 11])
def test_restart_reproduces_the_uninterrupted_run(stop_at):
    full = sparse_dud(stations, np.ones(N), 0.01, 5.0, dependency=DEPENDENCY, options=TIGHT)
    part = sparse_dud(stations, np.ones(N), 0.01, 5.0, dependency=DEPENDENCY, options=TIGHT, max_nfev=stop_at)
    rest = sparse_dud(stations, np.ones(N), 0.01, 5.0, dependency=DEPENDENCY, options=TIGHT,
                      restart=part.extra["state"])
    np.testing.assert_array_equal(rest.x, full.x)
    assert rest.nfev == full.nfev


def test_prior_rows_are_exact():
    res = sparse_dud(lambda x: x - 1.0, [0.2, 0.3], -5.0, 5.0, dependency={0: [0], 1: [1]},
                     options={**TIGHT, "prior_mean": 0.0, "prior_std": 1.0})
    np.testing.assert_allclose(res.x, [0.5, 0.5], atol=1e-8)
    np.testing.assert_allclose(res.jac[2:], np.eye(2))


def _analytic_jacobian(x):
    """∂r/∂x of :func:`stations`: −T e^{−x_i T} on station i's rows, 0.2 on station i + 1's rows."""
    jac = np.zeros((6 * N, N))
    for i in range(N):
        jac[6 * i:6 * i + 6, i] = -T * np.exp(-x[i] * T)
        if i + 1 < N:
            jac[6 * i + 6:6 * i + 12, i] = 0.2
    return jac


@pytest.mark.parametrize(("dependency", "final_batch"), [(DEPENDENCY, 6), (None, N)])
def test_the_fresh_jacobian_takes_the_cheaper_way(dependency, final_batch):
    """k = 2 of p = 8: central differences along 3 mixed directions (6 runs); a dense map: p forward runs."""
    sizes = []

    def batch(xs):
        sizes.append(len(xs))
        return [stations(x) for x in xs]

    res = sparse_dud(stations, np.ones(N), 0.01, 5.0, dependency=dependency, batch=batch,
                     options={**TIGHT, "final_jacobian": "fresh", "jacobian_step": 1e-6})
    np.testing.assert_allclose(res.x, TRUE, rtol=1e-6)
    assert final_batch in sizes[1:] and (2 * N) not in sizes[1:]  # never 2 p runs for one Jacobian
    np.testing.assert_allclose(res.jac, _analytic_jacobian(res.x), atol=1e-5)
