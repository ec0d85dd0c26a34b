"""SCE-UA: seeding, batched complexes, each stopping rule."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.optimise import sce_ua
from rivercal.optimise.sce_ua import TERMINATION_MESSAGES
from tests.optimise.problems import ROSEN_LB, ROSEN_START, ROSEN_UB, rosenbrock


def rastrigin(x):
    """Residual form of Rastrigin's function (many local minima, global minimum 0 at 0)."""
    return np.sqrt(10.0 + x**2 - 10.0 * np.cos(2 * np.pi * x))


def test_global_minimum_among_many_local_ones():
    res = sce_ua(rastrigin, [3.2, -2.1], [-5.12] * 2, [5.12] * 2,
                 options={"seed": 11, "n_complexes": 8, "peps": 1e-8, "pcento": 0.0, "kstop": 10}, max_nfev=20000)
    np.testing.assert_allclose(res.x, [0.0, 0.0], atol=1e-4)
    assert res.success


def test_seed_none_is_reported_and_reproducible():
    first = sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, max_nfev=300)
    again = sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, max_nfev=300, options={"seed": first.extra["seed"]})
    assert [c for _, c in first.evaluations] == [c for _, c in again.evaluations]
    other = sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, max_nfev=300, options={"seed": 12345})
    assert [c for _, c in first.evaluations] != [c for _, c in other.evaluations]


def test_complexes_evolve_as_batches():
    sizes = []

    def batch(xs):
        sizes.append(len(xs))
        return [rosenbrock(x) for x in xs]

    res = sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, batch=batch, max_nfev=2000,
                 options={"seed": 1, "n_complexes": 6})
    assert sizes[0] == 6 * 5                  # the initial population (p·m, m = 2n + 1)
    assert sizes[1] == 6                      # one reflection per complex
    assert max(sizes[1:]) == 6 and sum(sizes) == res.nfev
    assert res.extra["population"].shape == (30, 2) and res.extra["n_complexes"] == 6


def test_batched_evolution_does_not_depend_on_batch():
    serial = sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, max_nfev=500, options={"seed": 4})
    parallel = sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, max_nfev=500, options={"seed": 4},
                      batch=lambda xs: [rosenbrock(x) for x in reversed(xs)][::-1])
    np.testing.assert_array_equal(serial.x, parallel.x)


def test_stop_on_no_improvement():
    res = sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB,
                 options={"seed": 2, "kstop": 3, "pcento": 50.0, "peps": 0.0})
    assert res.status == 1 and res.message == TERMINATION_MESSAGES[1]
    best = [r.cost for r in res.history]
    assert (best[-4] - best[-1]) * 100 / np.mean(best[-4:]) < 50.0


def test_stop_on_parameter_convergence():
    res = sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB,
                 options={"seed": 2, "pcento": 0.0, "kstop": 1000, "peps": 1e-3})
    assert res.status == 2 and res.message == TERMINATION_MESSAGES[2]
    pop = res.extra["population"]
    spread = (pop.max(axis=0) - pop.min(axis=0)) / (ROSEN_UB - ROSEN_LB)
    assert np.exp(np.mean(np.log(spread))) < 1e-3


def test_stop_on_max_loops():
    res = sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, options={"seed": 2, "max_loops": 3})
    assert res.status == -3 and res.nit == 3


def test_initial_box():
    res = sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, max_nfev=10,
                 options={"seed": 2, "init_lb": [-1.3, 0.9], "init_ub": [-1.1, 1.1]})
    xs = np.array([x for x, _ in res.evaluations])
    assert np.all(xs >= [-1.3, 0.9]) and np.all(xs <= [-1.1, 1.1])
    with pytest.raises(ValueError, match="init_lb < init_ub"):
        sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, options={"init_lb": [-3.0, 0.0], "init_ub": [0.0, 1.0]})


def test_subcomplex_larger_than_complex_is_rejected():
    with pytest.raises(ValueError, match="points_per_subcomplex"):
        sce_ua(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, options={"points_per_complex": 3,
                                                                    "points_per_subcomplex": 4})
