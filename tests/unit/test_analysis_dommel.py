"""Identifiability on the default case: W2 and FA are seen, W8 is not (thesis §4-5-1).

Station 0028 sits at W2's weir (ZL1-3014) and global friction FA changes every level; W8 (ZL25-6292) lies
on ZL25 far upstream of the confluence and no station is near it. Twin observations at the case's initial
values over the moderate window.
"""

from __future__ import annotations

import pytest

from rivercal.analysis import IDENTIFIABLE, NOT_IDENTIFIABLE, identifiability
from rivercal.model import load_model
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem
from rivercal.report.identifiability import explanations
from rivercal.twin import twin_truth


@pytest.mark.slow
def test_w2_and_fa_are_identifiable_and_w8_is_not() -> None:
    sim = load_model("dommel")
    params = ParameterSet(p for p in sim.case.spec.parameters if p.name in ("W2", "FA", "W8")).subset(
        ["W2", "FA", "W8"])
    window = next((w.start, w.end) for w in sim.case.spec.windows if w.name == "moderate")
    truth = twin_truth(sim, params.quantities({}), window)
    problem = CalibrationProblem(sim, params, truth.observations, window, state=truth.state)
    result = identifiability(problem, workers=2)
    verdict = result.verdict
    assert verdict.loc["W2", "verdict"] == IDENTIFIABLE and verdict.loc["FA", "verdict"] == IDENTIFIABLE
    assert verdict.loc["W8", "verdict"] == NOT_IDENTIFIABLE
    assert result.index[2] < 0.1 < 0.9 < min(result.index[0], result.index[1])
    assert verdict.loc["W2", "top_station"] == "0028" and verdict.loc["W2", "top_station_share"] > 0.9
    assert "station 0028 measures right at this weir" in explanations(result)["W2"]
    assert verdict.loc["W8", "top_station"] == "0031"  # what little W8 does reaches 0031 after the confluence
    assert result.std[0] < 0.01  # W2 to better than a centimetre with σ = 2.5 cm
    assert result.extra["nfev"] == 4
