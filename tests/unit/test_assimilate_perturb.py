"""AR(1) model-error perturbations: their standard deviation and autocorrelation are the ones asked for."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.assimilate.perturb import ar1_series, multiplicative_factors


def test_ar1_has_the_stationary_sd_and_the_lag_correlation_exp_minus_dt_over_tau():
    rng = np.random.default_rng(1)
    e = ar1_series(rng, 4000, (200,), sigma=0.3, tau_steps=6.0)
    assert e.std() == pytest.approx(0.3, rel=0.02)
    for lag in (1, 6, 12):
        r = np.mean(e[lag:] * e[:-lag]) / e.var()
        assert r == pytest.approx(np.exp(-lag / 6.0), abs=0.02)


def test_ar1_continues_from_a_given_value_and_factors_have_mean_one():
    rng = np.random.default_rng(2)
    e = ar1_series(rng, 1, (100_000,), sigma=0.3, tau_steps=1e12, initial=np.full(100_000, 0.2))
    np.testing.assert_allclose(e[0], 0.2, atol=1e-4)   # τ → ∞: the series keeps its value
    f = multiplicative_factors(ar1_series(rng, 50, (20_000,), sigma=0.3, tau_steps=5.0), 0.3)
    assert f.min() > 0 and f.mean() == pytest.approx(1.0, abs=0.005)


def test_ar1_rejects_a_nonpositive_correlation_time():
    with pytest.raises(ValueError, match="correlation time"):
        ar1_series(np.random.default_rng(0), 3, (2,), sigma=0.1, tau_steps=0.0)
