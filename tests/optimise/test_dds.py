"""DDS: the budget, the neighbourhood schedule, parallel candidates, reflection."""

from __future__ import annotations

import numpy as np

from rivercal.optimise import dds
from rivercal.optimise.dds import _perturb
from tests.optimise.problems import ROSEN_LB, ROSEN_START, ROSEN_UB, rosenbrock


def test_budget_is_used_and_the_search_narrows():
    res = dds(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, options={"seed": 5, "max_evaluations": 400})
    assert res.status == 1 and res.nfev == 400 and not res.aborted
    xs = np.array([x for x, _ in res.evaluations])
    moved = np.count_nonzero(np.diff(xs, axis=0) != 0, axis=1)
    assert moved[:20].mean() > moved[-100:].mean()   # P(i) = 1 − ln i / ln m shrinks the neighbourhood


def test_parallel_candidates():
    sizes = []

    def batch(xs):
        sizes.append(len(xs))
        return [rosenbrock(x) for x in xs]

    res = dds(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, batch=batch,
              options={"seed": 5, "max_evaluations": 203, "candidates": 8})
    assert res.nfev == 203 and sizes[1] == 8 and sizes[-1] == 202 % 8
    assert res.nit == len(sizes) - 1


def test_reflection_stays_inside():
    rng = np.random.default_rng(0)
    lb, ub = np.zeros(3), np.ones(3)
    for _ in range(2000):
        x = _perturb(rng, rng.uniform(lb, ub), lb, ub, 2.0, 1.0)
        assert np.all(x >= lb) and np.all(x <= ub)
