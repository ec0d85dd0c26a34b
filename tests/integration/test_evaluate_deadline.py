"""A deadline inside a batch: no model run but the kept start point starts after it, wherever the batch runs
(this process, local worker processes, a batched engine call on threads). The Dask cluster's case is in
``test_evaluate_dask``.

The reference is the same evaluation without a deadline: the runs that were done by the deadline return
exactly what they return without one. Each run logs when it started (``time.monotonic``, one clock for
every process of the machine), so that a run started too late shows even when its result is dropped.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.evaluate import Evaluator
from rivercal.optimise.result import STATUS_DEADLINE
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem, calibrate, problem_evaluator
from tests.dask_helpers import Logged


@pytest.mark.parametrize("workers", [1, 2])
def test_no_run_starts_after_the_deadline(workers: int, tmp_path: Path) -> None:
    """Ten runs of 0.3 s take 3 s in this process (1.5 s on two processes); a 0.5 s deadline cuts both."""
    xs = [np.array([float(i)]) for i in range(10)]
    fun = Logged(tmp_path / "starts.txt", 0.3)
    with Evaluator(fun, workers=workers) as batch:
        batch(xs[:2])  # the worker processes are up before the clock starts
        before = len(fun.starts())
        deadline = time.monotonic() + 0.5
        out = batch.within(xs, deadline, keep=4)
    done = [i for i, r in enumerate(out) if r is not None]
    assert 4 in done and 1 < len(done) < 10
    for i in done:
        np.testing.assert_array_equal(out[i], xs[i] ** 2)
    started = fun.starts()[before:]
    assert all(t < deadline + 0.2 for t in started), [t - deadline for t in started]
    in_flight = workers if workers > 1 else 0   # runs going at the deadline on worker processes are not waited for
    assert len(started) <= len(done) + in_flight


@pytest.mark.parametrize("workers", [1, 2])
def test_a_deadline_already_passed_runs_the_kept_point_alone(workers: int, tmp_path: Path) -> None:
    xs = [np.array([float(i)]) for i in range(4)]
    fun = Logged(tmp_path / "starts.txt", 0.1)
    with Evaluator(fun, workers=workers) as batch:
        out = batch.within(xs, time.monotonic() - 1.0, keep=2)
    assert [r is not None for r in out] == [False, False, True, False]
    assert len(fun.starts()) == 1


@pytest.fixture(scope="module")
def problem() -> CalibrationProblem:
    """FA and Wc of the default case over two days, twin observations of FA=20, Wc=0.6."""
    from rivercal.model import load_model
    from rivercal.twin.truth import twin_truth

    model = load_model("dommel")
    known = {p.name: p for p in model.case.spec.parameters}
    params = ParameterSet([known["FA"], known["Wc"]])
    window = (pd.Timestamp("2010-09-27", tz="UTC"), pd.Timestamp("2010-09-29", tz="UTC"))
    truth = twin_truth(model, params.quantities({"FA": 20.0, "Wc": 0.6}), window)
    return CalibrationProblem(model, params, truth.observations, window, state=truth.state)


def test_a_batched_engine_call_goes_in_groups_of_one_run_per_worker(problem) -> None:
    """On the embedded engine two workers run a batch as batched calls on two threads, one group at a time."""
    xs = [problem.x0 + np.array([0.3 * i, 0.02 * i]) for i in range(5)]
    reference = [problem.residuals(x) for x in xs]
    with problem_evaluator(problem, workers=2) as batch:
        assert batch.batch is not None
        whole = batch.within(xs, time.monotonic() + 600.0)
        cut = batch.within(xs, time.monotonic() - 1.0, keep=3)
    for a, b in zip(whole, reference, strict=True):
        np.testing.assert_array_equal(a, b)
    assert [i for i, r in enumerate(cut) if r is not None] == [3]   # past the deadline: the kept point alone
    np.testing.assert_array_equal(cut[3], reference[3])


@pytest.mark.parametrize("workers", [1, 2])
def test_a_calibration_past_its_deadline_runs_the_start_point_alone(problem, workers: int) -> None:
    """DuD's first batch is x0 and one step per parameter; past the deadline only x0 runs."""
    cal = calibrate(problem, "dud", workers=workers, deadline=1e-6)
    assert cal.result.status == STATUS_DEADLINE and cal.result.aborted and cal.result.nfev == 1
    (x, cost), = cal.result.evaluations
    r0 = problem.residuals(problem.x0)
    np.testing.assert_array_equal(x, problem.x0)
    assert cost == pytest.approx(float(r0 @ r0), rel=1e-12) and cal.result.cost == cost
