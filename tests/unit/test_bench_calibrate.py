"""The calibration benchmark's settings are valid for every algorithm it runs.

``rivercal bench calibrate`` runs the FaWc twin with each algorithm on the dommel case (minutes). Here each
algorithm gets exactly the options and keyword arguments the benchmark gives it, on a linear least-squares
problem with the same bounds (FA in [8, 40] m^(1/3)/s, Wc in [0, 1]) and the known answer (20, 0.8), so
a setting an optimiser refuses fails in seconds instead of after the slow ones have run.
"""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.bench.calibrate import ALGORITHMS, START, TRUTH, algorithm_arguments
from rivercal.optimise import get_optimiser

CASE_OPTIONS = {"max_outer": 20, "max_inner": 5, "abs_tol": 1e-3, "rel_tol": 1e-4, "rel_tol_linear": 1e-4}
A = np.array([[1.0, 0.0], [0.5, 20.0], [0.2, -10.0], [1.0, 5.0]])
TRUE = np.array([TRUTH["FA"], TRUTH["Wc"]])


def residuals(x: np.ndarray) -> np.ndarray:
    return A @ (np.asarray(x) - TRUE)


@pytest.mark.parametrize("name", list(ALGORITHMS))
def test_every_benchmark_setting_is_accepted_and_moves_towards_the_truth(name: str) -> None:
    options, kwargs = algorithm_arguments(name, CASE_OPTIONS)
    kwargs.setdefault("max_nfev", 200)
    x0 = np.array([START["FA"], START["Wc"]])
    result = get_optimiser(name)(residuals, x0, np.array([8.0, 0.0]), np.array([40.0, 1.0]), options=options,
                                 **kwargs)
    assert result.cost < 0.5 * float(residuals(x0) @ residuals(x0))
