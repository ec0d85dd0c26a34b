"""The behaviour every optimiser shares (scipy-style: written once, run for each method)."""

from __future__ import annotations

import dataclasses
import time

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from rivercal.optimise import OPTIMISERS, IterationRecord, NonFiniteResidualsError, OptimiseResult, get_optimiser
from tests.optimise.problems import (
    COST_LINEAR,
    GRID_ROSEN,
    LINEAR_LB,
    LINEAR_START,
    LINEAR_UB,
    ROSEN_LB,
    ROSEN_START,
    ROSEN_UB,
    SETTINGS,
    X_LINEAR,
    A,
    B,
    linear,
    rosenbrock,
)

METHODS = list(OPTIMISERS)
LOCAL = ("dud", "sparse_dud", "trf", "bfgs", "cg")


def options(method: str, *, rosen: bool = False, **overrides) -> dict:
    opts = dict(SETTINGS[method].options)
    if method == "grid" and rosen:
        opts = dict(GRID_ROSEN)
    opts.update(overrides)
    return opts


def call(method, fun, x0, lb, ub, *, rosen=False, opts=None, **kwargs) -> OptimiseResult:
    kwargs.setdefault("max_nfev", SETTINGS[method].max_nfev)
    return get_optimiser(method)(fun, x0, lb, ub, options=opts if opts is not None else options(method, rosen=rosen),
                                 **kwargs)


def test_every_method_has_a_setting():
    assert set(SETTINGS) == set(METHODS)


@pytest.mark.parametrize("method", METHODS)
class TestBehaviour:
    def test_linear_least_squares(self, method):
        res = call(method, linear, LINEAR_START, LINEAR_LB, LINEAR_UB)
        tol = SETTINGS[method].linear_tol
        if method == "glue":  # a sampler: the truth must lie inside its 5-95 % band
            assert np.all(res.extra["quantiles"][0.05] <= X_LINEAR + tol)
            assert np.all(res.extra["quantiles"][0.95] >= X_LINEAR - tol)
        else:
            np.testing.assert_allclose(res.x, X_LINEAR, atol=tol, rtol=0)
        assert res.success and not res.aborted, res.message
        assert res.cost >= COST_LINEAR - 1e-12
        if tol <= 1e-5:
            assert res.cost == pytest.approx(COST_LINEAR, rel=1e-6)

    def test_rosenbrock(self, method):
        res = call(method, rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True)
        tol = SETTINGS[method].rosen_tol
        start_cost = float(np.sum(rosenbrock(ROSEN_START) ** 2))
        if tol is None:
            assert res.cost < 0.05 * start_cost
        else:
            np.testing.assert_allclose(res.x, [1.0, 1.0], atol=tol, rtol=0)
        assert res.success, res.message

    def test_bounds_never_violated(self, method):
        lb, ub = np.array([0.0, -1.0, 0.0]), np.array([0.8, 1.0, 1.0])   # excludes the free optimum
        seen = []

        def fun(x):
            assert np.all(x >= lb) and np.all(x <= ub), f"evaluated outside the bounds: {x}"
            seen.append(x.copy())
            return linear(x)

        opts = options(method, ranges=[(0.0, 0.8, 0.1), (-1.0, 1.0, 0.25), (0.0, 1.0, 0.25)]) \
            if method == "grid" else None
        res = call(method, fun, lb.copy(), lb, ub, opts=opts)   # start in a corner, on the bounds
        assert len(seen) == res.nfev > 1
        assert np.all(res.x >= lb) and np.all(res.x <= ub)
        if method in LOCAL:
            expected = lsq_linear(A, B, bounds=(lb, ub)).x
            np.testing.assert_allclose(res.x, expected, atol=1e-5)

    def test_callback_abort(self, method):
        records: list[IterationRecord] = []

        def callback(record):
            records.append(record)
            return record.nit >= 2

        opts = options(method, rosen=True, chunk_size=40) if SETTINGS[method].chunked else None
        res = call(method, rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True, opts=opts, callback=callback)
        assert res.status == -1 and res.aborted and not res.success
        assert res.nit == 2 and len(res.history) == 2 and [r.nit for r in records] == [1, 2]
        assert records[-1].nfev <= res.nfev
        best = min(res.evaluations, key=lambda e: e[1])
        assert res.cost == best[1]
        np.testing.assert_array_equal(res.x, best[0])

    def test_max_nfev(self, method):
        res = call(method, rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True, max_nfev=12)
        assert res.nfev == 12 == len(res.evaluations)
        assert res.status == 0 and res.aborted and not res.success
        assert res.message == get_module(method).TERMINATION_MESSAGES[0]
        assert res.cost == min(c for _, c in res.evaluations)

    def test_deadline(self, method):
        def slow(x):
            time.sleep(0.002)
            return rosenbrock(x)

        opts = options(method, rosen=True, chunk_size=10) if SETTINGS[method].chunked else None
        start = time.monotonic()
        res = call(method, slow, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True, opts=opts, deadline=0.05)
        assert res.status == -2 and res.aborted
        assert time.monotonic() - start < 1.5
        assert res.nfev >= 1 and np.isfinite(res.cost)

    def test_nan_at_x0_raises(self, method):
        with pytest.raises(NonFiniteResidualsError, match="initial point"):
            call(method, lambda x: np.full(2, np.nan), ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True)

    def test_nan_is_never_used_as_a_cost(self, method):
        def fun(x):
            return np.array([np.nan, 1.0]) if x[0] > 0.9 else rosenbrock(x)

        with pytest.raises(ValueError, match="not finite"):
            call(method, fun, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True)

    def test_exception_from_fun_propagates_unchanged(self, method):
        class ModelFailed(RuntimeError):
            pass

        error = ModelFailed("run 5 failed")
        calls = []

        def fun(x):
            calls.append(1)
            if len(calls) == 5:
                raise error
            return rosenbrock(x)

        with pytest.raises(ModelFailed) as info:
            call(method, fun, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True)
        assert info.value is error

    def test_deterministic(self, method):
        first = call(method, rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True, max_nfev=300)
        second = call(method, rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True, max_nfev=300)
        assert len(first.evaluations) == len(second.evaluations)
        for (x1, c1), (x2, c2) in zip(first.evaluations, second.evaluations, strict=True):
            np.testing.assert_array_equal(x1, x2)
            assert c1 == c2

    def test_result_contract(self, method):
        calls = []

        def fun(x):
            calls.append(x.copy())
            return rosenbrock(x)

        res = call(method, fun, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True, max_nfev=200)
        assert isinstance(res, OptimiseResult) and res.method == method
        with pytest.raises(dataclasses.FrozenInstanceError):
            res.cost = 0.0  # type: ignore[misc]
        assert res.success == (res.status > 0)
        assert res.message == get_module(method).TERMINATION_MESSAGES[res.status]
        assert res.nfev == len(calls) == len(res.evaluations)
        for (x, cost), x_called in zip(res.evaluations, calls, strict=True):
            np.testing.assert_array_equal(x, x_called)
            assert cost == pytest.approx(float(np.sum(rosenbrock(x) ** 2)))
        np.testing.assert_allclose(res.extra["residuals"], rosenbrock(res.x))
        assert res.nit == len(res.history)
        assert all(isinstance(r, IterationRecord) for r in res.history)
        if res.std is not None:
            assert res.std.shape == (2,) and res.correlation.shape == (2, 2) and res.jac.shape == (2, 2)


def get_module(method):
    import importlib

    return importlib.import_module(get_optimiser(method).__module__)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize(("change", "message"), [
    ({"x0": np.zeros((2, 2))}, "x0 must be a 1-D array"),
    ({"lb": np.zeros(3)}, "lb must have length 2"),
    ({"ub": np.array([2.0, -2.0])}, "lb must be strictly less than ub; at index 1"),
    ({"x0": np.array([0.0, 3.0])}, r"x0 is infeasible: x0\[1\]=3.0"),
    ({"lb": np.array([np.nan, -2.0])}, "lb contains NaN"),
    ({"max_nfev": 0}, "max_nfev must be None or a positive integer"),
    ({"deadline": -1.0}, "deadline must be None or a positive number"),
    ({"options": {"no_such_option": 1}}, "unknown option 'no_such_option'"),
])
def test_invalid_input_names_the_argument(method, change, message):
    args = {"x0": ROSEN_START, "lb": ROSEN_LB, "ub": ROSEN_UB, "options": options(method, rosen=True)}
    args.update(change)
    fun = get_optimiser(method)
    with pytest.raises(ValueError, match=message):
        fun(rosenbrock, args.pop("x0"), args.pop("lb"), args.pop("ub"), **args)


@pytest.mark.parametrize("method", METHODS)
def test_options_of_the_wrong_type(method):
    with pytest.raises(TypeError, match="options must be None"):
        get_optimiser(method)(rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, options=[1, 2])


@pytest.mark.parametrize("method", ["sce_ua", "dds", "glue", "grid"])
def test_sampling_methods_need_finite_bounds(method):
    opts = {} if method == "grid" else options(method)
    with pytest.raises(ValueError, match="finite bounds"):
        get_optimiser(method)(rosenbrock, ROSEN_START, [-np.inf, -2.0], ROSEN_UB, options=opts)


@pytest.mark.parametrize("method", METHODS)
def test_batch_sees_every_evaluation(method):
    sizes = []

    def batch(points):
        sizes.append(len(points))
        return [rosenbrock(p) for p in points]

    res = call(method, rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True, batch=batch, max_nfev=150)
    assert sum(sizes) == res.nfev
    if method in ("dud", "sparse_dud", "trf", "bfgs", "cg", "sce_ua", "grid", "glue", "nelder_mead"):
        assert max(sizes) > 1   # independent points went out together


@pytest.mark.parametrize("method", METHODS)
def test_tiny_deadline_runs_x0_alone(method):
    res = call(method, rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True, deadline=1e-9)
    assert res.status == -2 and res.aborted and res.nfev == 1
    assert [x.tolist() for x, _ in res.evaluations] == [ROSEN_START.tolist()]
    assert res.cost == pytest.approx(float(rosenbrock(ROSEN_START) @ rosenbrock(ROSEN_START)))


def test_no_run_of_a_batch_starts_after_the_deadline():
    """The grid's first batch is x0 and all 289 grid points; at 10 ms a run, a 0.1 s deadline cuts it early."""
    def slow(x):
        time.sleep(0.01)
        return rosenbrock(x)

    res = call("grid", slow, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True, deadline=0.1)
    assert res.status == -2 and 1 <= res.nfev < 100
    assert res.cost == min(c for _, c in res.evaluations)


def test_a_batch_without_within_runs_whole():
    """A caller's batch that cannot stop at a deadline runs its first batch whole; later ones are not started."""
    sizes = []

    def batch(points):
        sizes.append(len(points))
        return [rosenbrock(p) for p in points]

    res = call("grid", rosenbrock, ROSEN_START, ROSEN_LB, ROSEN_UB, rosen=True, batch=batch, deadline=1e-9)
    assert res.nfev == sizes[0] == 1 + 289 and len(sizes) == 1   # x0 and the grid
