"""Twin check on the default case: FA and Wc found back from the FaWc start points (thesis §4-4).

Truth k_s = 20 m^(1/3)/s and Wc = 0.8 over the moderate window (the week ending 4 October 2010), all
stations, noise-free observations; DuD with the case's stopping criteria (thesis Table 4-3) must end
within |Δk_s| ≤ 0.05 and |ΔWc| ≤ 0.002 of the truth from each of the four FaWc start points.
"""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.model import load_model
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from rivercal.twin import twin_truth

TRUTH = {"FA": 20.0, "Wc": 0.8}


@pytest.fixture(scope="module")
def setup():
    sim = load_model("dommel")
    params = ParameterSet(p for p in sim.case.spec.parameters if p.name in ("FA", "Wc"))
    window = next((w.start, w.end) for w in sim.case.spec.windows if w.name == "moderate")
    truth = twin_truth(sim, params.quantities(TRUTH), window)
    return sim, params, window, truth


@pytest.fixture(scope="module")
def serial() -> dict:
    """The serial calibrations made so far, by start point: :func:`test_parallel_batches_give_the_serial_result`
    compares its parallel run with the one the start point's own test made (the same problem, the same options)."""
    return {}


def _problem(setup, start):
    sim, params, window, truth = setup
    return CalibrationProblem(sim, params.with_initial(start), truth.observations, window, state=truth.state), sim


@pytest.mark.slow
@pytest.mark.parametrize("start", [{"FA": 14.0, "Wc": 0.1}, {"FA": 14.0, "Wc": 0.9},
                                   {"FA": 18.0, "Wc": 0.1}, {"FA": 18.0, "Wc": 0.9}])
def test_fawc_start_points_find_the_truth(setup, serial, start) -> None:
    problem, sim = _problem(setup, start)
    result = calibrate(problem, "dud", sim.case.spec.calibration.options, workers=1)
    serial[tuple(start.items())] = result
    assert abs(result.estimates["FA"] - TRUTH["FA"]) <= 0.05
    assert abs(result.estimates["Wc"] - TRUTH["Wc"]) <= 0.002
    assert result.result.success


@pytest.mark.slow
def test_parallel_batches_give_the_serial_result(setup, serial) -> None:
    start = {"FA": 14.0, "Wc": 0.1}
    problem, sim = _problem(setup, start)
    if tuple(start.items()) not in serial:  # run alone: no start point's test made it
        serial[tuple(start.items())] = calibrate(problem, "dud", sim.case.spec.calibration.options, workers=1)
    alone = serial[tuple(start.items())]
    parallel = calibrate(problem, "dud", sim.case.spec.calibration.options, workers=2)
    np.testing.assert_array_equal(alone.result.x, parallel.result.x)
    assert alone.result.nfev == parallel.result.nfev
