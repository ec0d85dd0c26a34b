"""Batches of a calibration on the embedded engine: one batched engine call, the same results and failures."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.errors import EngineDivergedError
from rivercal.evaluate import Evaluator
from rivercal.model import load_model
from rivercal.observations import ObservationSet
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem, calibrate, problem_evaluator


@pytest.fixture(scope="module")
def synthetic():
    """The synthetic case with a lowered divergence velocity: W9's crest 1 m down diverges at once (2.7 m/s)."""
    sim = load_model("synthetic")
    sim.settings = sim.settings.model_copy(update={"max_velocity": 2.5})
    t0 = sim.start + pd.Timedelta("1D")
    _, state = sim.simulate(None, sim.start, t0)
    c0 = sim.default_parameters()["weir:W9.crest_level"]
    params = ParameterSet([
        Parameter(name="W9", targets=["weir:W9.crest_level"], min=c0 - 2.0, max=c0 + 1.0, initial=c0 + 0.2,
                  perturbation=0.05),
        Parameter(name="FA", targets=["friction:global"], min=10.0, max=40.0, initial=22.0, perturbation=1.0),
    ])
    window = (t0 + pd.Timedelta("2h"), t0 + pd.Timedelta("14h"))
    truth, _ = sim.simulate({"weir:W9.crest_level": c0, "friction:global": 25.0}, t0, window[1], state)
    obs = ObservationSet.from_frame(truth.series[["S5.h_up", "S5.h_down", "S6.Q"]])
    return sim, params, obs, window, state, c0


def _problem(synthetic, **kwargs) -> CalibrationProblem:
    sim, params, obs, window, state, _ = synthetic
    return CalibrationProblem(sim, params, obs, window, state=state, warmup="2h", **kwargs)


@pytest.mark.parametrize("threads", [1, 2])
def test_a_batch_equals_its_points_one_by_one(synthetic, threads) -> None:
    problem = _problem(synthetic)
    assert problem.batched
    xs = [problem.parameters.to_x({"W9": synthetic[5] + d, "FA": f}) for d, f in ((0.2, 22.0), (0.0, 25.0),
                                                                                    (-0.4, 31.0))]
    batched = problem.residuals_batch(xs, threads=threads)
    assert problem.n_runs == 3
    for x, r in zip(xs, batched, strict=True):
        assert np.array_equal(r, problem.residuals(x))
    assert np.abs(batched[1]).max() < 1e-12 < np.abs(batched[0]).max()   # the truth's point fits exactly


def test_a_failed_point_follows_the_policy_with_the_single_runs_error(synthetic) -> None:
    problem = _problem(synthetic)
    good, bad = (problem.parameters.to_x({"W9": synthetic[5] + d}) for d in (0.0, -1.0))
    with pytest.raises(EngineDivergedError) as single:
        problem.residuals(bad)
    with pytest.raises(EngineDivergedError) as batched:
        problem.residuals_batch([good, bad, good])
    assert str(batched.value) == str(single.value)   # "at weir:W9: velocity 2.7… m/s exceeds …"
    lenient = _problem(synthetic, on_failure="penalty", penalty=1e6)
    r = lenient.residuals_batch([good, bad, good])
    assert float(r[1] @ r[1]) == pytest.approx(1e6)
    assert np.array_equal(r[0], lenient.residuals(good)) and np.array_equal(r[2], r[0])


def test_a_calibration_with_batches_is_the_serial_calibration(synthetic) -> None:
    """DuD's initial set and Jacobians go through batched calls; every run being identical, so is the result."""
    calls = []

    class Counting(Evaluator):
        def _batched(self, points):
            calls.append(len(points))
            return super()._batched(points)

    serial = calibrate(_problem(synthetic), "dud", workers=1)
    import rivercal.problem.fit as problem_module

    original = problem_module.Evaluator
    problem_module.Evaluator = Counting
    try:
        problem = _problem(synthetic)
        batched = calibrate(problem, "dud", workers=2)
    finally:
        problem_module.Evaluator = original
    assert calls and calls[0] == 3     # p + 1 initial points in one call
    assert batched.estimates == serial.estimates and batched.result.nfev == serial.result.nfev
    assert batched.estimates["FA"] == pytest.approx(25.0, rel=1e-3)


def test_only_the_embedded_engine_gets_batches(synthetic) -> None:
    from tests.unit.test_problem import START, LinearReservoirModel, _obs, _params

    assert problem_evaluator(_problem(synthetic), 2).batch is not None
    stub = LinearReservoirModel()   # a model of the contract that is not the embedded engine
    other = CalibrationProblem(stub, _params(), _obs(stub), (START + pd.Timedelta("2h"), START + pd.Timedelta("24h")),
                               state="s", warmup="2h")
    assert not other.batched and problem_evaluator(other, 2).batch is None
    xs = [other.x0, other.x0 + 0.1]
    assert all(np.array_equal(a, b) for a, b in zip(other.residuals_batch(xs), map(other.residuals, xs), strict=True))
    calls = []
    squares = lambda xs, threads: calls.append(threads) or [x**2 for x in xs]  # noqa: E731
    with Evaluator(np.square, workers=2, batch=squares) as batch:
        assert [float(v[0]) for v in batch([np.array([2.0]), np.array([3.0])])] == [4.0, 9.0]
    assert calls == [2]
    # one worker: point by point (a process a pool forked must not start OpenMP threads its parent used)
    assert Evaluator(np.square, workers=1, batch=lambda xs, threads: []).batch is None
