"""A deadline inside a batch: no model run starts after it, wherever the batch runs (this process, local worker
processes, a batched engine call on threads). The Dask cluster's case is in ``test_evaluate_dask``.

The reference is the same evaluation without a deadline: the runs that were done by the deadline return
exactly what they return without one.
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd
import pytest

from rivercal.evaluate import Evaluator
from rivercal.optimise.result import STATUS_DEADLINE
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem, calibrate, problem_evaluator


def _slow(x: np.ndarray) -> np.ndarray:
    time.sleep(0.3)
    return np.asarray(x, dtype=float) ** 2


@pytest.mark.parametrize("workers", [1, 2])
def test_runs_after_the_deadline_do_not_start(workers: int) -> None:
    """Ten runs of 0.3 s take 3 s in this process (1.5 s on two processes); a 0.5 s deadline cuts both."""
    xs = [np.array([float(i)]) for i in range(10)]
    with Evaluator(_slow, workers=workers) as batch:
        batch(xs[:2])  # the worker processes are up before the clock starts
        out = batch.within(xs, time.monotonic() + 0.5, keep=4)
    done = [i for i, r in enumerate(out) if r is not None]
    assert 4 in done and 1 < len(done) < 10
    for i in done:
        np.testing.assert_array_equal(out[i], xs[i] ** 2)


def test_a_deadline_already_passed_runs_the_kept_point_alone() -> None:
    xs = [np.array([float(i)]) for i in range(4)]
    with Evaluator(_slow, workers=1) as batch:
        out = batch.within(xs, time.monotonic() - 1.0, keep=2)
    assert [r is not None for r in out] == [False, False, True, False]


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
    assert [i for i, r in enumerate(cut) if r is not None] == [0, 3]  # the kept point's group: it and the first
    np.testing.assert_array_equal(cut[3], reference[3])


@pytest.mark.parametrize(("workers", "runs"), [(1, 1), (2, 2)])
def test_a_calibration_past_its_deadline_keeps_the_start_point(problem, workers: int, runs: int) -> None:
    """DuD's first batch is x0 and one step per parameter; past the deadline only x0's group runs."""
    cal = calibrate(problem, "dud", workers=workers, deadline=1e-6)
    assert cal.result.status == STATUS_DEADLINE and cal.result.aborted and cal.result.nfev == runs
    start = next(c for x, c in cal.result.evaluations if np.array_equal(x, problem.x0))
    r0 = problem.residuals(problem.x0)
    assert start == pytest.approx(float(r0 @ r0), rel=1e-12)
    assert cal.result.cost == min(c for _, c in cal.result.evaluations)
