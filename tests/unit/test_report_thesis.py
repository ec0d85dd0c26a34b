"""The thesis report's pieces: thesis summaries of partial runs, targets, the Eq. 2-14 bias per scenario."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.report.thesis import suite_indicators, targets
from rivercal.report.twin import bias_table
from rivercal.twin.reference import thesis_summary
from rivercal.twin.suites import SUITES, ScenarioResult, suite_scenarios

TIMES = pd.date_range("2010-09-27", periods=49, freq="h", tz="UTC")


def _result(suite: str, sid: str, *, error: float = 0.0, iterations: int = 4, offset: np.ndarray | None = None
            ) -> ScenarioResult:
    """A scenario result with ``error`` added to every estimate and ``offset`` (m) to the calibrated series."""
    s = suite_scenarios(suite, ids=[sid])[0]
    series = SUITES[suite].bias_series
    observed = pd.DataFrame({series: 9.5 + 0.1 * np.sin(np.arange(TIMES.size) / 5.0)}, index=TIMES)
    calibrated = observed + (offset[:, None] if offset is not None else 0.0)
    estimates = {n: v + error for n, v in s.truth.items()}
    return ScenarioResult(
        suite=suite, id=sid, truth=s.truth, start=s.start, estimates=estimates,
        errors={n: error for n in s.truth}, std={n: 0.0 for n in s.truth}, iterations=iterations, model_runs=9,
        wall_s=1.0, cost=1e-12, rmse=1e-6, bias=0.0, std_error=1e-6, state_rmse=0.0, success=True,
        within_tolerance=all(abs(error) <= s.tolerance[n] for n in s.truth), message="T1",
        series={"observed": observed, "initial": observed, "calibrated": calibrated, "truth": observed},
        sigma={series: 0.025})


def test_thesis_summary_of_the_scenarios_that_ran() -> None:
    full = thesis_summary("F1W0", SUITES["F1W0"].tolerance)
    part = thesis_summary("F1W0", SUITES["F1W0"].tolerance, ids=["H1", "L2"])
    assert full["scenarios"] == 6 and full["iterations_max"] == 5 and full["robustness"] == 1.0
    # Table 4-5/4-6: H1 19.9997 in 4 iterations, L2 12.0002 in 5
    assert part["scenarios"] == 2 and part["iterations_max"] == 5 and part["iterations_median"] == 4.5
    assert part["max_abs_error"]["F1"] == pytest.approx(3e-4)
    assert thesis_summary("F1W0", ids=["X1"]) is None and thesis_summary("nope") is None


def test_targets_judge_what_ran_and_only_that() -> None:
    fawc = [_result("FaWc", s.id) for s in suite_scenarios("FaWc")[:4]]
    fawcn = [_result("FaWcN", "H1H1", error=0.5), _result("FaWcN", "L2L2")]
    f1w0 = [_result("F1W0", "H1", iterations=7), _result("F1W0", "L2", iterations=3)]
    t = targets({"FaWc": fawc, "FaWcN": fawcn, "F1W0": f1w0}, wall_s=500.0, complete=True, workers=2)
    met = t["met"].to_dict()
    assert met["FaWc: robustness 100 % (|ΔFA| ≤ 0.05, |ΔWc| ≤ 0.002)"] is True
    assert met["FaWcN: robustness 100 % (|ΔFA| ≤ 0.2, |ΔWc| ≤ 0.01)"] is False
    assert t.loc["FaWcN: robustness 100 % (|ΔFA| ≤ 0.2, |ΔWc| ≤ 0.01)", "measured"] == "50% (1/2)"
    assert met["FaWcP: robustness 100 % (|ΔFA| ≤ 0.05, |ΔWc| ≤ 0.002)"] is None  # not run
    assert met["F1W0: at most 6 DuD iterations"] is False
    assert t.loc["F1W0: at most 6 DuD iterations", "measured"] == "max 7 (H1)"
    assert met["whole thesis run ≤ 10 min wall on 2 cores"] is True
    slow = targets({}, wall_s=700.0, complete=True, workers=2)
    assert slow.loc["whole thesis run ≤ 10 min wall on 2 cores", "met"] is False
    partial = targets({}, wall_s=100.0, complete=False, workers=2)
    assert partial.loc["whole thesis run ≤ 10 min wall on 2 cores", "met"] is None


def test_eq_2_14_bias_tells_a_systematic_from_a_random_error() -> None:
    rng = np.random.default_rng(1)
    systematic = _result("FaWc", "H1H1", offset=np.full(TIMES.size, 0.01) + 0.001 * rng.standard_normal(TIMES.size))
    # a scatter whose every full 2-h window (three hourly values) averages to zero
    scatter = _result("FaWc", "H1H2", offset=0.01 * np.resize([1.0, -2.0, 1.0], TIMES.size))
    table, moving = bias_table("FaWc", [systematic, scatter])
    assert list(table.index) == ["H1H1", "H1H2"]
    assert set(table["series"]) == {"0040.h_down"}  # thesis Fig. 4-25
    assert bool(table.loc["H1H1", "significant"]) and not bool(table.loc["H1H2", "significant"])
    # weighted errors (σ = 2.5 cm): a constant 1 cm error gives b = (0.01 / 0.025)² = 0.16
    assert table.loc["H1H1", "bias"] == pytest.approx(0.16, rel=0.05)
    # (only the first, two-value window is biased)
    assert table.loc["H1H2", "bias"] < 0.01 * table.loc["H1H2", "variance"] and table.loc["H1H2", "variance"] > 0.1
    assert set(moving["scenario"]) == {"H1H1", "H1H2"} and {"time", "bias", "variance"} <= set(moving.columns)


def test_indicators_put_the_thesis_beside_ours() -> None:
    results = [_result("F0W1", "H1", iterations=3), _result("F0W1", "M2", iterations=2)]
    frame = suite_indicators("F0W1", results)
    assert frame.loc["scenarios"].tolist() == ["2", "2"]
    assert frame.loc["DuD iterations, max"].tolist() == ["3", "2"]  # thesis Table 4-6: 2 iterations each
    assert frame.loc["model runs, total", "thesis"] == "not reported"
    assert frame.loc["robustness (|ΔW2| ≤ 0.002)"].tolist() == ["100% (2/2)", "100%"]
