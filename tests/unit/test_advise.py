"""Gauge advice numerics (rivercal.analysis.advise) against direct computations on synthetic Jacobians."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.analysis import IDENTIFIABLE, NOT_IDENTIFIABLE, analyse_jacobian
from rivercal.analysis.advise import Candidate, LinearWorth, posterior_covariance

NAMES = ("a", "b", "c", "d")


def _woodbury(prior_var: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Posterior covariance by the Kalman (Woodbury) form Σ = C − C Jᵀ (J C Jᵀ + I)⁻¹ J C: another route."""
    c = np.diag(prior_var)
    gain = c @ rows.T @ np.linalg.inv(rows @ c @ rows.T + np.eye(rows.shape[0]))
    return c - gain @ rows @ c


def _problem(seed: int = 0):
    """Base rows see a and b; candidate i sees parameter i (and a little of a); 'ab' sees a and b again."""
    rng = np.random.default_rng(seed)
    base = np.zeros((30, 4))
    base[:, 0] = rng.normal(size=30) * 5.0
    base[:, 1] = rng.normal(size=30) * 3.0
    blocks = {}
    for i, name in enumerate(NAMES):
        b = np.zeros((20, 4))
        b[:, i] = rng.normal(size=20) * (2.0 + i)
        b[:, 0] += rng.normal(size=20) * 0.1
        blocks[f"g{name}"] = b
    blocks["gab"] = np.column_stack([rng.normal(size=20), rng.normal(size=20), np.zeros(20), np.zeros(20)])
    candidates = [Candidate(k, (f"{k}.h",), f"gauge {k}") for k in blocks]
    return base, blocks, candidates


def test_posterior_covariance_equals_the_kalman_form():
    base, blocks, _ = _problem()
    prior_var = np.array([0.5, 2.0, 0.1, 3.0]) ** 2
    rows = np.vstack([base, blocks["gc"]])
    ours = posterior_covariance(rows.T @ rows, prior_var)
    assert np.allclose(ours, _woodbury(prior_var, rows), rtol=1e-9, atol=1e-14)
    # a stack of informations at once gives each one's posterior
    stack = np.array([base.T @ base, rows.T @ rows])
    both = posterior_covariance(stack, prior_var)
    assert np.allclose(both[1], ours, rtol=1e-12)
    assert np.allclose(both[0], _woodbury(prior_var, base), rtol=1e-9, atol=1e-14)


def test_worth_table_matches_brute_force_and_ranks_by_identifiability_then_worth():
    base, blocks, candidates = _problem()
    prior = np.array([0.5, 2.0, 0.1, 3.0])
    lw = LinearWorth(NAMES, base, candidates, blocks, prior)
    table = lw.worth_table()
    v0 = np.diag(_woodbury(prior**2, base))
    for cid, block in blocks.items():
        post = _woodbury(prior**2, np.vstack([base, block]))
        expected = np.mean(1.0 - np.diag(post) / v0)
        assert table.loc[cid, "worth"] == pytest.approx(expected, rel=1e-9)
        for j, n in enumerate(NAMES):
            assert table.loc[cid, f"std:{n}"] == pytest.approx(np.sqrt(post[j, j]), rel=1e-9)
        # the verdict of the set equals the identifiability analysis of the stacked rows
        ident = analyse_jacobian(np.vstack([base, block]), NAMES)
        for n in NAMES:
            assert table.loc[cid, f"verdict:{n}"] == ident.verdict.loc[n, "verdict"]
    # base sees a and b only: a gauge seeing c or d makes three identifiable, the others leave two
    assert set(table.index[:2]) == {"gc", "gd"}
    assert list(table["identifiable"]) == sorted(table["identifiable"], reverse=True)
    assert table.loc["gab", "identifiable"] == 2


def test_assessment_from_the_factor_equals_the_stacked_analysis():
    base, blocks, candidates = _problem(1)
    lw = LinearWorth(NAMES, base, candidates, blocks, np.ones(4), scale=np.array([1.0, 2.0, 0.5, 1.5]))
    small = lw.assess(["gc", "gd"])
    rows = np.vstack([base, blocks["gc"], blocks["gd"]])
    full = analyse_jacobian(rows, NAMES, scale=np.array([1.0, 2.0, 0.5, 1.5]))
    assert np.allclose(small.identifiability.singular_values, full.singular_values, rtol=1e-9)
    assert np.allclose(small.identifiability.covariance, full.covariance, rtol=1e-8)
    assert small.verdicts == {n: full.verdict.loc[n, "verdict"] for n in NAMES}
    assert small.identifiable == 4
    assert small.smallest_singular_value == pytest.approx(full.singular_values[-1], rel=1e-9)


def test_greedy_adds_gauges_until_every_parameter_is_identifiable():
    base, blocks, candidates = _problem()
    lw = LinearWorth(NAMES, base, candidates, blocks, np.ones(4))
    before = lw.assess([])
    assert before.verdicts["c"] == NOT_IDENTIFIABLE and before.verdicts["d"] == NOT_IDENTIFIABLE
    steps = lw.greedy()
    assert {s.candidate for s in steps} == {"gc", "gd"}  # two gauges are enough, and the right two
    assert [s.assessment.identifiable for s in steps] == [3, 4]
    assert all(v == IDENTIFIABLE for v in steps[-1].assessment.verdicts.values())
    assert all(s.worth > 0 for s in steps)
    # a fixed number goes on after every parameter is identifiable, and each pick is worth less than the last
    three = lw.greedy(3)
    assert len(three) == 3 and three[2].worth < three[0].worth


def test_forecast_targets_and_costs():
    base, blocks, candidates = _problem()
    forecast = {"f": np.array([0.0, 0.0, 0.0, 1.0])}  # the forecast depends on d only
    lw = LinearWorth(NAMES, base, candidates, blocks, np.ones(4), forecasts=forecast)
    table = lw.worth_table()
    assert table["worth"].idxmax() == "gd"
    post = _woodbury(np.ones(4), np.vstack([base, blocks["gd"]]))
    assert table.loc["gd", "var:f"] == pytest.approx(post[3, 3], rel=1e-9)
    assert table.loc["gc", "worth"] == pytest.approx(0.0, abs=1e-9)  # c's gauge tells nothing about d
    # with costs, the ranking at equal identifiability is worth per cost
    costly = [Candidate(c.id, c.series, c.name, 100.0 if c.id == "gd" else 1.0) for c in candidates]
    lw2 = LinearWorth(NAMES, base, costly, blocks, np.ones(4))
    t2 = lw2.worth_table()
    assert t2.loc["gd", "worth_per_cost"] == pytest.approx(t2.loc["gd", "worth"] / 100.0)
    assert t2.index[0] == "gc"


def test_bad_input_is_named():
    base, blocks, candidates = _problem()
    with pytest.raises(ValueError, match="appears twice"):
        LinearWorth(NAMES, base, [*candidates, candidates[0]], blocks, np.ones(4))
    with pytest.raises(ValueError, match="no Jacobian rows for candidate 'gx'"):
        LinearWorth(NAMES, base, [Candidate("gx", ("gx.h",))], blocks, np.ones(4))
    with pytest.raises(ValueError, match="prior_std"):
        LinearWorth(NAMES, base, candidates, blocks, np.array([1.0, 0.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="forecast 'z' does not depend"):
        LinearWorth(NAMES, base, candidates, blocks, np.ones(4), forecasts={"z": np.zeros(4)})
