"""Real data: the rainfall-runoff model calibrated on one Hupsel Brook year and validated on the next.

The data are GPL-3 and never copied into the repository; without them the test is skipped with the
reason, except in CI, where ``.ci/run`` sets ``RIVERCAL_REQUIRE_HUPSEL`` and the suite stops at once
without them (``tests/conftest.py`` finds them beside the repository, in ``../shared``).

Each method's calibration runs once per test process (the tests of a file share a worker): the test that
compares DuD and TRF reads the same results as the tests of each method.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path
from unittest.mock import patch

import pytest

from rivercal.bench.hupsel import HUPSEL_METHODS, HupselCalibration, calibrate_hupsel

#: Model runs after which the derivative-free methods stop here. By then they are at the optimum: Nelder-Mead has
#: DuD's NSE to 0.0001 in both years, SCE-UA within 0.0003 and 0.0025. Their own stopping rules, which end them
#: after 581 and 1065 runs on these data (``rivercal bench hupsel``), are the business of their tests in
#: tests/optimise (test_behaviour.py, test_sce_ua.py).
BUDGETS = {"nelder_mead": 250, "sce_ua": 500}


@cache
def _calibrated(method: str, path: Path) -> HupselCalibration:
    if method not in BUDGETS:
        return calibrate_hupsel(method, str(path))
    with patch.dict(HUPSEL_METHODS, {method: {**HUPSEL_METHODS[method], "max_nfev": BUDGETS[method]}}):
        return calibrate_hupsel(method, str(path))


@pytest.mark.slow
@pytest.mark.parametrize("method", list(HUPSEL_METHODS))
def test_calibration_improves_the_validation_year(method: str, hupsel_file: Path) -> None:
    result = _calibrated(method, hupsel_file)
    # the fit improves on the a-priori parameters in the calibration year ...
    assert result.nse_calibration > result.nse_calibration_default + 0.1
    assert result.nse_calibration > 0.85 and result.kge_calibration > 0.8
    # ... and carries over to the year it never saw
    assert result.nse_validation > result.nse_validation_default + 0.05
    assert result.nse_validation > 0.8 and result.kge_validation > 0.75
    # every method, within its budget, reaches DuD's optimum
    dud = _calibrated("dud", hupsel_file)
    assert result.nse_calibration == pytest.approx(dud.nse_calibration, abs=0.001)
    assert result.nse_validation == pytest.approx(dud.nse_validation, abs=0.005)


def test_methods_agree_on_the_optimum(hupsel_file: Path) -> None:
    """DuD and TRF (the two fast methods) reach the same validation score."""
    dud, trf = _calibrated("dud", hupsel_file), _calibrated("trf", hupsel_file)
    assert dud.nse_validation == pytest.approx(trf.nse_validation, abs=0.005)
    assert dud.model_runs < 100
