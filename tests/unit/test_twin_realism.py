"""The error models of the realism levels against their definitions (docs/realism.md).

Each error of :class:`~rivercal.twin.realism.SensorErrors` is drawn alone on a long series and its
statistics are compared with the model's own: the standard deviation and the lag-1 correlation of white
plus AR(1) noise, the share of spikes and of outage hours, the slope of the drift. The same seed gives
the same errors, also on a part of the period (the grid is anchored at the model's start).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from rivercal.errors import CaseError
from rivercal.twin.realism import (
    REALISM_LEVELS,
    RainErrors,
    SensorErrors,
    apply_sensor_errors,
    event_factors,
    get_realism,
    load_realism,
)

ORIGIN = pd.Timestamp("2010-01-01", tz="UTC")
N = 40_000  # hours (4.6 years)
QUIET = {"gap_fraction": 0.0, "outlier_rate": 0.0, "drift_series": 0}


def _truth(n: int = N) -> pd.DataFrame:
    times = pd.date_range(ORIGIN, periods=n, freq="h")
    return pd.DataFrame({"A.h": np.full(n, 10.0), "A.Q": np.full(n, 4.0)}, index=times)


def test_white_plus_ar1_noise_has_the_stated_sigma_and_lag1_correlation() -> None:
    e = SensorErrors(**QUIET)
    obs, kinds = apply_sensor_errors(_truth(), e, seed=3, origin=ORIGIN)
    assert (kinds == "ok").all().all()
    for col, white, ar1, scale in (("A.h", e.level_white_m, e.level_ar1_m, 1.0),
                                   ("A.Q", e.discharge_white_rel, e.discharge_ar1_rel, 4.0)):
        err = (obs[col] - _truth()[col]).to_numpy() / scale
        var = white**2 + ar1**2
        assert err.std() == pytest.approx(math.sqrt(var), rel=0.08)
        # cov(e_k, e_k+1) = φ σ_ar1² (the white part is independent): ρ₁ = φ σ_ar1² / (σ_w² + σ_ar1²)
        rho = np.corrcoef(err[:-1], err[1:])[0, 1]
        assert rho == pytest.approx(e.ar1_phi * ar1**2 / var, abs=0.04)
        assert abs(err.mean()) < 4 * math.sqrt(var) * math.sqrt((1 + e.ar1_phi) / (1 - e.ar1_phi) / N)


def test_spikes_outages_and_drift_come_at_their_rates() -> None:
    e = SensorErrors(level_white_m=0.0, level_ar1_m=0.0, discharge_white_rel=0.0, discharge_ar1_rel=0.0,
                     outlier_rate=0.01, gap_fraction=0.05, gap_hours=6.0, drift_series=1, drift_m_per_day=0.001)
    truth = _truth()
    obs, kinds = apply_sensor_errors(truth, e, seed=11, origin=ORIGIN)
    gaps = kinds["A.h"] == "gap"
    # one station: its level and discharge go missing together, as NaN
    assert (gaps == (kinds["A.Q"] == "gap")).all() and obs.loc[gaps].isna().all().all()
    assert gaps.mean() == pytest.approx(0.05, abs=0.015)
    spikes = kinds["A.h"] == "outlier"
    assert spikes.mean() == pytest.approx(0.01, abs=4 * math.sqrt(0.01 * 0.99 / N))
    drift = (truth.index - ORIGIN).total_seconds().to_numpy() / 86400.0 * 0.001
    size = (obs["A.h"] - truth["A.h"] - drift)[spikes].abs()
    assert size.between(0.10, 0.50).all()  # the level spikes' range, m
    ok = kinds["A.h"] == "drift"  # the only level series drifts: every value that is no spike or gap
    assert ok.sum() + spikes.sum() + gaps.sum() == N
    np.testing.assert_allclose((obs["A.h"] - truth["A.h"])[ok], drift[ok.to_numpy()], atol=1e-12)
    q_spikes = kinds["A.Q"] == "outlier"
    rel = ((obs["A.Q"] - truth["A.Q"]) / truth["A.Q"])[q_spikes].abs()
    assert rel.between(0.5, 1.0).all()


def test_the_same_seed_gives_the_same_errors_also_on_part_of_the_period() -> None:
    e = SensorErrors()
    full, kinds = apply_sensor_errors(_truth(2000), e, seed=5, origin=ORIGIN)
    part, part_kinds = apply_sensor_errors(_truth(2000).iloc[700:900], e, seed=5, origin=ORIGIN)
    pd.testing.assert_frame_equal(part, full.iloc[700:900])
    pd.testing.assert_frame_equal(part_kinds, kinds.iloc[700:900])
    other, _ = apply_sensor_errors(_truth(2000), e, seed=6, origin=ORIGIN)
    assert not np.allclose(other["A.h"].fillna(0), full["A.h"].fillna(0))
    with pytest.raises(ValueError, match="grid"):
        apply_sensor_errors(_truth(10).shift(freq="30min"), e, seed=5, origin=ORIGIN)


def test_rain_factors_are_one_per_event_and_one_when_dry() -> None:
    wet = [0, 1, 1, 0, 1, 0, 0, 0, 0, 0, 0, 0, 2, 2, 0]  # events: hours 1-4 (2 dry h inside), 12-13
    rain = pd.Series(np.array(wet, float), index=pd.date_range(ORIGIN, periods=len(wet), freq="h"))
    f = event_factors(rain, RainErrors(sigma_ln=0.3, dry_hours=6), seed=2).to_numpy()
    assert f[0] == 1.0 and (f[5:12] == 1.0).all() and f[14] == 1.0
    assert f[1] == f[2] == f[4] and f[12] == f[13] and f[1] != f[12]
    eps = np.random.default_rng([2, *[__import__("zlib").crc32(b"rain")]]).standard_normal(2)
    np.testing.assert_allclose([f[1], f[12]], np.exp(0.3 * eps))


def test_levels_and_toml_files(tmp_path) -> None:
    assert REALISM_LEVELS["ideal"].ideal and not REALISM_LEVELS["noisy"].changes_truth
    assert REALISM_LEVELS["realistic"].changes_truth
    path = tmp_path / "wet.toml"
    path.write_text('description = "wetter"\n[rain]\nsigma_ln = 0.3\n[sensor]\noutlier_rate = 0.0\n')
    level = get_realism(path)
    assert level.name == "wet" and level.rain.sigma_ln == 0.3 and level.rain.dry_hours == 6
    assert level.sensor.outlier_rate == 0.0 and level.sensor.level_ar1_m == 0.010
    assert level.runoff is None and level.structure is None
    path.write_text("[sensor]\nar1_phi = 1.5\n")
    with pytest.raises(CaseError, match=r"sensor\.ar1_phi"):
        load_realism(path)
    path.write_text("[rainfall]\nsigma_ln = 0.3\n")
    with pytest.raises(CaseError, match="rainfall"):
        load_realism(path)
    with pytest.raises(CaseError, match="unknown realism 'foggy'"):
        get_realism("foggy")


# -- the truth under rainfall, runoff and structural errors (dommel case) -------------------------------------


@pytest.fixture(scope="module")
def dommel():
    from rivercal.model import load_model

    return load_model("dommel")


def test_a_truth_with_errors_of_size_zero_is_the_model(dommel) -> None:
    from rivercal.twin.realism import Realism, RunoffErrors, StructureErrors
    from rivercal.twin.truth_model import PerturbedTruth

    zero = Realism(name="zero", rain=RainErrors(sigma_ln=0.0), runoff=RunoffErrors(sigma_ln=0.0),
                   structure=StructureErrors(grid_factor=1.0, friction_sigma_ln=0.0))
    truth = PerturbedTruth(dommel, zero, seed=4)
    end = dommel.start + pd.Timedelta("3D")
    q = {"friction:global": 25.0}
    a, _ = dommel.simulate(q, end=end)
    b, _ = truth.simulate(q, end=end)
    pd.testing.assert_frame_equal(a.series, b.series, rtol=1e-9, atol=1e-9)


def test_the_realistic_truth_runs_finer_with_friction_per_branch_around_the_global_value(dommel) -> None:
    from rivercal.twin.truth_model import truth_model

    truth = truth_model(dommel, "realistic", seed=4)
    assert truth_model(dommel, "noisy") is dommel  # sensor errors leave the truth alone
    lengths = {b.id: b.length for b in dommel.case.spec.branches}
    f = truth.branch_factors
    mean = sum(f[b] * lengths[b] for b in f) / sum(lengths.values())
    assert mean == pytest.approx(1.0, rel=1e-12) and np.std(list(f.values())) > 0.03
    assert truth.truth.compiled.n_hpoints > 1.5 * dommel.compiled.n_hpoints  # dx halved
    q = truth.quantities_of({"friction:global": 25.0, "weir:ZL1-5.crest_level": 7.0})
    inherit = dommel.compiled.branch_inherits
    assert q["weir:ZL1-5.crest_level"] == 7.0
    assert all(q[f"friction:branch:{b}"] == pytest.approx(25.0 * f[b]) for b in inherit)
    # event-wise rain factors with median 1 and the runoff factors of every catchment
    assert truth.rain_factor is not None and set(truth.runoff_factors) == {c.id for c in dommel.case.spec.catchments}
    wet = truth.rain_factor[truth.rain_factor != 1.0]
    assert len(wet) > 0 and 0.5 < float(np.median(wet.unique())) < 2.0
