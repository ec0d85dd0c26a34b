"""Conjugate gradients: the three variants, the active set at bounds."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.optimise import cg
from tests.optimise.problems import X_LINEAR, linear, rosenbrock

SCALES = np.array([1.0, 2.0, 4.0])


def quadratic(x):
    return SCALES * (x - 1.0)


@pytest.mark.parametrize("method", ["fletcher-reeves", "polak-ribiere", "steepest-descent"])
def test_variants_converge_on_a_quadratic(method):
    res = cg(quadratic, np.zeros(3), -5.0, 5.0, options={"method": method, "max_iter": 2000, "x_scale": [1, 1, 1]})
    np.testing.assert_allclose(res.x, 1.0, atol=1e-6)
    assert res.success and res.extra["cg_method"] == method


def test_conjugacy_beats_steepest_descent():
    runs = {m: cg(rosenbrock, [-1.2, 1.0], -2.0, 2.0, options={"method": m, "max_iter": 100})
            for m in ("polak-ribiere", "fletcher-reeves", "steepest-descent")}
    assert runs["polak-ribiere"].success and runs["polak-ribiere"].cost < 1e-12
    assert runs["fletcher-reeves"].success and runs["fletcher-reeves"].cost < 1e-12
    assert runs["steepest-descent"].status == -3 and runs["steepest-descent"].cost > 1e-6


def test_linear_problem_with_active_bound():
    res = cg(linear, [0.5, -0.5, 0.2], [-3.0, -1.0, -3.0], [3.0, 3.0, 3.0])
    assert res.x[1] == -1.0    # the bound is active: the free optimum has x[1] = −2
    assert res.success
    res = cg(linear, [0.5, -0.5, 0.2], -3.0, 3.0)
    np.testing.assert_allclose(res.x, X_LINEAR, atol=1e-6)


def test_unknown_variant():
    with pytest.raises(ValueError, match="method must be one of"):
        cg(linear, np.zeros(3), -3.0, 3.0, options={"method": "hestenes-stiefel"})
