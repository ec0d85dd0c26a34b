"""GLUE: likelihoods, behavioural sets, weighted quantiles, prediction bounds."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.optimise import glue
from rivercal.optimise.glue import weighted_quantiles

T = np.linspace(0.0, 2.0, 20)
NOISE = 0.05 * np.random.default_rng(1).standard_normal(T.size)
Y = 1.5 * np.exp(-0.8 * T) + NOISE


def fun(x):
    return (Y - x[0] * np.exp(-x[1] * T)) / 0.05


def test_weighted_quantiles():
    values = np.arange(1.0, 6.0)
    np.testing.assert_allclose(weighted_quantiles(values, np.ones(5), (0.5,)), [3.0])
    np.testing.assert_allclose(weighted_quantiles(values, np.array([0, 0, 0, 0, 1.0]), (0.05, 0.95)), [5.0, 5.0])
    out = weighted_quantiles(np.arange(6.0).reshape(3, 2), np.ones(3), (0.5,))
    np.testing.assert_allclose(out, [[2.0, 3.0]])


@pytest.mark.parametrize("likelihood", ["exp", "gaussian", "inverse"])
def test_quantiles_bracket_the_truth(likelihood):
    res = glue(fun, [1.0, 1.0], [0.5, 0.2], [2.5, 2.0],
               options={"seed": 2, "n_samples": 3000, "likelihood": likelihood, "behavioural_fraction": 0.05})
    q = res.extra["quantiles"]
    assert np.all(q[0.05] <= [1.5, 0.8]) and np.all(q[0.95] >= [1.5, 0.8])
    assert np.all(q[0.05] <= q[0.5]) and np.all(q[0.5] <= q[0.95])
    w = res.extra["weights"]
    assert w.sum() == pytest.approx(1.0) and np.all(w[~res.extra["behavioural"]] == 0)
    assert res.extra["samples"].shape == (3000, 2) and res.nfev == 3001


def test_threshold_nse_and_prediction_bounds():
    reference = float(np.sum(((Y - Y.mean()) / 0.05) ** 2))
    res = glue(fun, [1.0, 1.0], [0.5, 0.2], [2.5, 2.0], predictions=lambda x: x[0] * np.exp(-x[1] * T),
               options={"seed": 2, "n_samples": 2000, "likelihood": "nse", "reference_cost": reference,
                        "threshold": 0.9})
    like = res.extra["likelihood"]
    assert np.all(like[res.extra["behavioural"]] >= 0.9) and np.all(like[~res.extra["behavioural"]] < 0.9)
    low, high = res.extra["prediction_quantiles"][0.05], res.extra["prediction_quantiles"][0.95]
    truth = 1.5 * np.exp(-0.8 * T)
    assert low.shape == T.shape and np.mean((low <= truth) & (truth <= high)) > 0.8


def test_callable_likelihood():
    res = glue(fun, [1.0, 1.0], [0.5, 0.2], [2.5, 2.0],
               options={"seed": 2, "n_samples": 500, "likelihood": lambda r: 1.0 / (1.0 + r @ r)})
    assert res.extra["behavioural"].sum() == 50


def test_nse_needs_reference_cost():
    with pytest.raises(ValueError, match="reference_cost"):
        glue(fun, [1.0, 1.0], [0.5, 0.2], [2.5, 2.0], options={"likelihood": "nse"})
    with pytest.raises(ValueError, match="likelihood must be one of"):
        glue(fun, [1.0, 1.0], [0.5, 0.2], [2.5, 2.0], options={"likelihood": "nash"})


def test_aborted_run_still_has_statistics():
    res = glue(fun, [1.0, 1.0], [0.5, 0.2], [2.5, 2.0], options={"seed": 2, "n_samples": 1000, "chunk_size": 100},
               max_nfev=250)
    assert res.aborted and np.count_nonzero(np.isfinite(res.extra["costs"])) == 249
    assert "quantiles" in res.extra
