"""The sparse LDLᵀ solver against numpy's dense solve, on trees and on looped graphs."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.engine.kernels.solver import ldl_solve
from rivercal.engine.plan import elimination_order


def _random_system(n: int, pairs: list[tuple[int, int]], seed: int):
    rng = np.random.default_rng(seed)
    sym = elimination_order(n, pairs)
    off = np.zeros(sym.n_edges)
    dense = np.zeros((n, n))
    for i, j in pairs:
        c = rng.uniform(0.5, 5.0)
        off[sym.edge_of[(min(i, j), max(i, j))]] -= c
        dense[i, j] -= c
        dense[j, i] -= c
    diag = -dense.sum(axis=1) + rng.uniform(0.01, 1.0, n)  # storage keeps it SPD
    dense[np.diag_indices(n)] = diag
    rhs = rng.normal(size=n)
    return sym, diag, off, rhs, dense


def _tree(n: int, seed: int) -> list[tuple[int, int]]:
    rng = np.random.default_rng(seed)
    return [(int(rng.integers(0, i)), i) for i in range(1, n)]


@pytest.mark.parametrize("compiled", [True, False], ids=["numba", "py_func"])
@pytest.mark.parametrize("graph", ["chain", "tree", "loops"])
def test_ldl_matches_dense_solve(compiled: bool, graph: str) -> None:
    n = 60
    pairs = {"chain": [(i, i + 1) for i in range(n - 1)], "tree": _tree(n, 1)}.get(graph)
    if pairs is None:
        pairs = [*_tree(n, 2), (3, 40), (10, 55), (0, 59), (20, 21)]
    sym, diag, off, rhs, dense = _random_system(n, pairs, seed=7)
    expected = np.linalg.solve(dense, rhs)
    solve = ldl_solve if compiled else ldl_solve.py_func
    x = rhs.copy()
    solve(sym.order, sym.cptr, sym.cedge, sym.cother, sym.uptr, sym.ue1, sym.ue2, sym.utgt,
          diag.copy(), off.copy(), np.zeros(sym.n_edges), x)
    np.testing.assert_allclose(x, expected, rtol=1e-10, atol=1e-12)


def test_tree_has_no_fill_and_loops_do() -> None:
    assert elimination_order(100, _tree(100, 3)).fill == 0
    # a ring of 10: eliminating one point joins its two neighbours until the ring closes
    ring = [(i, (i + 1) % 10) for i in range(10)]
    sym = elimination_order(10, ring)
    assert sym.fill > 0
    assert sym.n_edges == 10 + sym.fill


def test_packed_schedule_is_bit_identical_to_the_csr_solve() -> None:
    from rivercal.engine.kernels.solver import ldl_solve_packed
    from rivercal.engine.plan import solver_schedule

    rng = np.random.default_rng(0)
    tree = [(int(rng.integers(0, i)), i) for i in range(1, 60)]
    graphs = {
        "chain": [(i, i + 1) for i in range(59)],
        "loops": [*tree, (3, 40), (10, 55), (0, 59), (20, 21)],
        "grid": [(i * 6 + j, i * 6 + j + 1) for i in range(6) for j in range(5)]
        + [(i * 6 + j, (i + 1) * 6 + j) for i in range(5) for j in range(6)],
        "big grid": [(i * 12 + j, i * 12 + j + 1) for i in range(12) for j in range(11)]
        + [(i * 12 + j, (i + 1) * 12 + j) for i in range(11) for j in range(12)],
        "ring with trees": [(i, (i + 1) % 90) for i in range(90)]
        + [(int(rng.integers(0, i)), i) for i in range(90, 200)],
    }
    for seed, pairs in enumerate(graphs.values()):
        sym, diag, off, rhs, _ = _random_system(1 + max(max(p) for p in pairs), pairs, seed)
        x, y = rhs.copy(), rhs.copy()
        ldl_solve_packed(solver_schedule(sym), sym.cptr, sym.cedge, sym.cother, sym.uptr, sym.ue1, sym.ue2, sym.utgt,
                         diag.copy(), off.copy(), np.zeros(sym.n_edges), x)
        ldl_solve(sym.order, sym.cptr, sym.cedge, sym.cother, sym.uptr, sym.ue1, sym.ue2, sym.utgt, diag.copy(),
                  off.copy(), np.zeros(sym.n_edges), y)
        assert np.array_equal(x, y)


def test_a_loop_is_eliminated_in_rounds_that_the_solver_runs_side_by_side() -> None:
    """On a ring every point has two neighbours: eliminated one after the other, each elimination would wait for
    the one before (a chain of the ring's length, as many solver steps as points). The order eliminates it in
    rounds of points that share no entry, and the four-lane schedule runs each round side by side."""
    from rivercal.engine.kernels.codes import SCHED_LANES, SCHED_WIDTH
    from rivercal.engine.plan import solver_schedule

    n = 120
    sym = elimination_order(n, [(i, (i + 1) % n) for i in range(n)])
    assert sym.fill == n - 3  # a ring's fill whatever the order
    steps = solver_schedule(sym).size // (SCHED_LANES * SCHED_WIDTH)
    assert steps < n / 2
