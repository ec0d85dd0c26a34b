"""DuD: every stopping rule on its own, the OpenDA quirks that are fixed, restart, statistics."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rivercal.optimise import DudOptions, DudState, dud
from rivercal.optimise.dud import TERMINATION_MESSAGES, DenseSecant
from tests.optimise.problems import COST_LINEAR, X_LINEAR, A, linear, rosenbrock

T = np.linspace(0.0, 3.0, 30)
Y = 2.0 * np.exp(-1.3 * T) + 0.02 * np.random.default_rng(7).standard_normal(T.size)


def decay(x):
    """Exponential decay fitted to noisy data: nonlinear, non-zero residual at the optimum."""
    return Y - x[0] * np.exp(-x[1] * T)


def only(**rules):
    """Options with every tolerance off except the ones given, no confirmation round, the secant Jacobian."""
    base = {"abs_tol": 0.0, "rel_tol": 0.0, "rel_tol_linear": 0.0, "negligible_cost": 0.0, "max_outer": 200,
            "confirm_convergence": False, "final_jacobian": "secant"}
    return {**base, **rules}


DOF = T.size - 2   # residual rows minus parameters of ``decay``


def accepted_drops(res):
    """(previous cost, new cost, linear cost) for the iterations that lowered the cost."""
    costs = [res.evaluations[0][1]] + [r.cost for r in res.history]
    costs[0] = min(c for _, c in res.evaluations[:3])  # the best of the initial set (p + 1 = 3 points)
    return [(a, b, r.linear_cost) for a, b, r in zip(costs[:-1], costs[1:], res.history, strict=True) if b < a]


def test_defaults_are_thesis_table_4_3():
    opts = DudOptions()
    assert (opts.max_outer, opts.max_inner, opts.abs_tol, opts.rel_tol, opts.rel_tol_linear, opts.max_rel_step) == \
        (20, 5, 1e-3, 1e-4, 1e-4, 10.0)


def test_t1_cost_change_in_units_of_the_residual_variance():
    """T1: the drop of the last iteration is at most abs_tol · s², s² = S/(m − p)."""
    res = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], options=only(abs_tol=1e-1))
    assert res.status == 1 and res.message == TERMINATION_MESSAGES[1] and res.success
    drops = accepted_drops(res)
    assert drops[-1][0] - drops[-1][1] <= 1e-1 * drops[-1][1] / DOF


def test_t2_relative_cost_change():
    res = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], options=only(rel_tol=1e-2))
    assert res.status == 2 and res.message == TERMINATION_MESSAGES[2]
    drops = accepted_drops(res)
    assert drops[-1][0] - drops[-1][1] <= 1e-2 * drops[-1][1]


def test_t3_relative_linearised_cost_change():
    res = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], options=only(rel_tol_linear=1e-2))
    assert res.status == 3 and res.message == TERMINATION_MESSAGES[3]
    drops = accepted_drops(res)
    assert (drops[-1][0] - drops[-1][2]) <= 1e-2 * drops[-1][0]
    assert all(a - lin > 1e-2 * a for a, _, lin in drops[:-1])


def test_max_outer_iterations():
    res = dud(rosenbrock, [-1.2, 1.0], -2.0, 2.0, options=only(max_outer=3))
    assert res.status == -3 and res.nit == 3 and not res.success and not res.aborted


def test_max_inner_bounds_the_line_search():
    def penalty(x):   # the secant step always overshoots into a penalty region beyond x = 1
        return np.array([x[0] - 2.0 + (10.0 if x[0] > 1.0 else 0.0)])

    for max_inner in (2, 5):
        res = dud(penalty, [0.0], [-5.0], [5.0], options=only(max_inner=max_inner), )
        per_iteration = np.diff([0, *[r.nfev for r in res.history]])
        assert max(per_iteration[1:]) <= max_inner + 1 + 1   # trials + (re-)initialisation runs (p = 1)


def test_no_t1_right_after_a_shortened_step(monkeypatch):
    """A step the line search had to shorten never ends the run by T1 or T2; the set is refreshed instead."""
    import rivercal.optimise._dud_engine as engine

    seen = []

    def spy(opts, step, step_cost):
        seen.append((step, engine_rules(opts, step, step_cost)))
        return seen[-1][1]

    engine_rules = engine.rivercal_rules
    monkeypatch.setattr(engine, "rivercal_rules", spy)

    def penalty(x):
        return np.array([x[0] - 2.0 + (10.0 if x[0] > 1.0 else 0.0)])

    res = dud(penalty, [0.0], [-5.0], [5.0], options=only(abs_tol=1e6, rel_tol=1e6))
    # initial set {0, 0.1}; the secant step 1.9 is capped at max_rel_step × 0.1 = 1: the trial at t = 1
    # (x = 1.1) is penalised, t = ½ (x = 0.6) is accepted. T1 and T2 (which would always fire) do not:
    first, (status, refresh) = seen[0]
    assert first.shortened and first.s_new == pytest.approx(1.96) and status is None and refresh
    assert res.extra["n_reinit"] >= 1
    # the run ends at the first step taken in full
    last, (status, _) = seen[-1]
    assert not last.shortened and status == 1 and res.status == 1
    assert all(step.shortened for step, _ in seen[:-1])


def test_failed_line_search_on_fresh_set_ends_the_run():
    def penalty(x):
        return np.array([x[0] - 2.0 + (10.0 if x[0] > 1.0 else 0.0)])

    res = dud(penalty, [0.0], [-5.0], [5.0], options=only())
    assert res.status == 5 and res.success
    assert 0.95 < res.x[0] <= 1.0
    state = res.extra["state"]
    assert np.max(state.costs) < 2.0   # the failed trials (cost ≥ 64) never entered the set (OpenDA quirk)
    assert res.extra["n_reinit"] >= 1


def test_no_predicted_decrease_when_started_at_the_optimum():
    res = dud(linear, X_LINEAR, -10.0, 10.0)   # DFO-LS issue 24: a warm start at the optimum
    assert res.status == 4 and res.success
    np.testing.assert_array_equal(res.x, X_LINEAR)
    # initial set + one re-initialisation + the final Jacobian at the best point (the set was re-initialised);
    # no trial step, and no Gauss-Newton step (the fresh Jacobian predicts no decrease either)
    assert res.nfev == (3 + 1) + 3 + 3
    assert res.cost == pytest.approx(COST_LINEAR)


def test_zero_cost():
    res = dud(lambda x: A @ (x - X_LINEAR), np.zeros(3), -10.0, 10.0, options=only())
    assert res.status == 6 and res.cost == 0.0
    np.testing.assert_allclose(res.x, X_LINEAR, atol=1e-12)


def test_a_negligible_cost_ends_the_run_at_once():
    """A warm start at the answer of a zero-residual problem: no run is spent confirming it."""
    start = X_LINEAR + 1e-6
    res = dud(lambda x: A @ (x - X_LINEAR), start, -10.0, 10.0)
    assert res.status == 7 and res.success and res.nit == 0 and res.nfev == 4  # x0 and its p perturbations
    # S_h: the smallest cost change of one initial perturbation h_j = 0.1 |x_j|
    step_cost = min(float(np.sum((A[:, j] * 0.1 * abs(start[j])) ** 2)) for j in range(3))
    assert res.extra["state"].step_cost == pytest.approx(step_cost, rel=1e-6)
    assert res.cost <= 1e-6 * step_cost
    far = dud(lambda x: A @ (x - X_LINEAR), np.zeros(3) + 0.5, -10.0, 10.0)
    assert far.status in (6, 7) and far.nfev < 12
    np.testing.assert_allclose(far.x, X_LINEAR, atol=1e-3 * 0.05)


def test_confirmation_round_reinitialises_before_stopping():
    plain = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], options=only(rel_tol=1e-6))
    confirmed = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], options={**only(rel_tol=1e-6),
                                                                         "confirm_convergence": True})
    assert plain.status == confirmed.status == 2
    assert confirmed.extra["n_reinit"] > plain.extra["n_reinit"]
    assert confirmed.cost <= plain.cost


def test_start_at_a_bound_is_perturbed_inwards():
    sizes, points = [], []

    def batch(xs):
        sizes.append(len(xs))
        points.extend(xs)
        return [rosenbrock(x) for x in xs]

    res = dud(rosenbrock, [2.0, -2.0], -2.0, 2.0, batch=batch, options={"initial_step": [0.5, 0.5]})
    assert sizes[0] == 3   # the p + 1 initial runs are one batch
    initial = np.array(points[:3])
    np.testing.assert_array_equal(initial[1], [1.5, -2.0])
    np.testing.assert_array_equal(initial[2], [2.0, -1.5])
    assert res.cost < 1e-6


def test_initial_step_larger_than_the_range():
    lb, ub = np.array([0.0, -2.5, 0.0]), np.array([1.5, 0.0, 1.0])
    res = dud(linear, [0.5, -0.5, 0.2], lb, ub, options={"initial_step": [10.0] * 3, "rel_tol": 1e-12})
    # no room for the full step on either side: step to the farther bound
    np.testing.assert_array_equal([res.evaluations[j + 1][0][j] for j in range(3)], [1.5, -2.5, 1.0])
    np.testing.assert_allclose(res.x, X_LINEAR, atol=1e-8)


@pytest.mark.parametrize("stop_at", [1, 3, 5, 7, 10, 16, 23])
def test_restart_after_max_nfev_reproduces_the_uninterrupted_run(stop_at):
    opts = {"abs_tol": 0.0, "rel_tol": 1e-12, "max_outer": 100}
    full = dud(rosenbrock, [-1.2, 1.0], -2.0, 2.0, options=opts)
    part = dud(rosenbrock, [-1.2, 1.0], -2.0, 2.0, options=opts, max_nfev=stop_at)
    assert part.aborted and part.nfev == stop_at
    rest = dud(rosenbrock, [-1.2, 1.0], -2.0, 2.0, options=opts, restart=part.extra["state"])
    np.testing.assert_array_equal(rest.x, full.x)
    assert (rest.nfev, rest.nit, rest.status, rest.cost) == (full.nfev, full.nit, full.status, full.cost)
    assert [c for _, c in rest.evaluations] == [c for _, c in full.evaluations]


def test_restart_chain_and_callback_abort():
    opts = {"abs_tol": 0.0, "rel_tol": 1e-12, "max_outer": 100}
    full = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], options=opts)
    res = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], options=opts, callback=lambda r: r.nit == 2)
    assert res.status == -1
    res = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], options=opts, restart=res.extra["state"], max_nfev=9)
    res = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], options=opts, restart=res.extra["state"])
    np.testing.assert_array_equal(res.x, full.x)
    assert res.nfev == full.nfev


def test_restart_after_convergence_continues_with_new_options():
    first = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], options=only(rel_tol=1e-1))
    more = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], options=only(rel_tol=1e-10),
               restart=first.extra["state"])
    assert more.nit > first.nit and more.cost < first.cost


def test_restart_validation():
    res = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], max_nfev=5)
    with pytest.raises(TypeError, match="DudState"):
        dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], restart={"points": None})
    with pytest.raises(ValueError, match="parameters"):
        dud(linear, np.zeros(3), -10.0, 10.0, restart=res.extra["state"])
    with pytest.raises(ValueError, match="outside the bounds"):
        dud(decay, [1.0, 1.0], [0.0, 0.0], [1.05, 1.05], restart=res.extra["state"])


def test_degenerate_set_is_reinitialised():
    x = np.array([[1.0, 1.0], [1.1, 1.1], [1.2, 1.2 + 1e-12]])    # collinear interpolation set
    residuals = np.array([decay(p) for p in x])
    costs = np.sum(residuals**2, axis=1)
    order = np.argsort(costs)
    state = DudState(method="dud", x0=x[0], initial_step=np.array([0.1, 0.1]), points=x[order],
                     residuals=residuals[order], costs=costs[order], nit=0, nfev=3, n_reinit=0, fresh=False,
                     history=(), evaluations=tuple((p, c) for p, c in zip(x, costs, strict=True)))
    assert DenseSecant(1e7).jacobian(state.points, state.residuals) is None
    res = dud(decay, [1.0, 1.0], [0.0, 0.0], [10.0, 10.0], restart=state, options={"rel_tol": 1e-10})
    assert res.extra["n_reinit"] >= 1 and res.success
    np.testing.assert_allclose(res.x, [2.0, 1.3], atol=0.1)


def test_prior_is_a_weak_constraint():
    res = dud(lambda x: np.array([x[0] - 1.0]), [0.2], [-5.0], [5.0],
              options={"prior_mean": [0.0], "prior_std": [1.0], "abs_tol": 0.0, "rel_tol": 1e-14})
    assert res.x[0] == pytest.approx(0.5, abs=1e-8)
    assert res.cost == pytest.approx(0.5)    # (x − 1)² + x² at x = ½
    assert res.std[0] == pytest.approx(np.sqrt(0.5), rel=1e-6)   # posterior σ with J = [1, 1]ᵀ
    np.testing.assert_allclose(res.extra["residuals"], [-0.5, 0.5], atol=1e-8)


def test_std_and_correlation_follow_eq_2_12_and_2_13():
    res = dud(linear, np.zeros(3), -10.0, 10.0, options={"abs_tol": 0.0, "rel_tol": 1e-14})
    cov = np.linalg.inv(A.T @ A)
    std = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(res.std, std, rtol=1e-6)
    np.testing.assert_allclose(res.correlation, cov / np.outer(std, std), rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(res.jac, A, rtol=1e-6, atol=1e-9)
    s2 = COST_LINEAR / (A.shape[0] - A.shape[1])
    np.testing.assert_allclose(res.extra["std_scaled"], std * np.sqrt(s2), rtol=1e-6)


def test_parallel_line_search_gives_the_same_iterates():
    opts = {"abs_tol": 0.0, "rel_tol": 1e-10, "max_outer": 100}
    serial = dud(rosenbrock, [-1.2, 1.0], -2.0, 2.0, options=opts)
    sizes = []

    def batch(xs):
        sizes.append(len(xs))
        return [rosenbrock(x) for x in xs]

    parallel = dud(rosenbrock, [-1.2, 1.0], -2.0, 2.0, options={**opts, "parallel_line_search": True}, batch=batch)
    assert [r.cost for r in parallel.history] == [r.cost for r in serial.history]
    assert parallel.nfev >= serial.nfev and max(sizes) >= 3


@pytest.mark.parametrize(("options", "message"), [
    ({"max_outer": -1}, "max_outer must be an integer >= 0"),
    ({"abs_tol": -1.0}, "abs_tol must be a finite number >= 0"),
    ({"shortening_factor": 1.0}, "shortening_factor"),
    ({"prior_mean": [0.0, 0.0]}, "prior_mean and prior_std must be given together"),
    ({"initial_step": [0.1, -0.1]}, "initial_step must be a 1-D array of positive"),
    ({"initial_step": [0.1, 0.1, 0.1]}, "options.initial_step must have length 2"),
    ({"prior_mean": [0.0] * 3, "prior_std": [1.0] * 3}, "options.prior_mean must have length 2"),
    ({"confirm_convergence": 1}, "confirm_convergence must be a bool"),
    ({"max_outr": 3}, "did you mean 'max_outer'"),
])
def test_option_validation(options, message):
    with pytest.raises(ValueError, match=message):
        dud(rosenbrock, [-1.2, 1.0], -2.0, 2.0, options=options)


def test_options_are_frozen_and_arrays_read_only():
    opts = DudOptions(initial_step=[0.1, 0.2])
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.max_outer = 3  # type: ignore[misc]
    with pytest.raises(ValueError):
        opts.initial_step[0] = 1.0
