"""The bound of :mod:`rivercal.bench.realism_bound` on the identical twin, where its answer is known."""

from __future__ import annotations

import pytest

from rivercal.bench.realism_bound import realism_bound


@pytest.mark.slow
def test_the_truths_own_parameters_forecast_an_identical_twin_exactly() -> None:
    # PI-Fg under ideal: the model with the truth's parameters is the truth (errors at round-off); the DSS
    # keeps FA = 16 after the mowing to 25 and misses by centimetres (6.10 cm in the realism table)
    out = realism_bound("PI-Fg", "ideal", values=[16.0, 25.0], last="2010-11-05")
    assert out["mae_m"]["true"] < 1e-6
    assert out["mae_m"]["FA=25"] == pytest.approx(out["mae_m"]["true"], abs=1e-9)  # the same runs
    assert out["mae_m"]["FA=16"] == pytest.approx(out["mae_m"]["dss"], abs=1e-9)  # FA = 16 is the DSS
    assert 0.01 < out["mae_m"]["dss"] < 0.2
    assert out["scored_from"] == "2010-11-02T01:00:00+00:00" and out["scored_to"] == "2010-11-06T00:00:00+00:00"
    with pytest.raises(ValueError, match="PI-0 changes 0 parameters"):
        realism_bound("PI-0", "ideal", values=[16.0], last="2010-11-03")
