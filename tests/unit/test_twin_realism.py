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


# -- rain and runoff errors on given inflow series (a model without catchments) -------------------------------


def test_each_event_scales_the_flow_above_its_start_flow() -> None:
    from rivercal.twin.realism import layered_event_factors

    # base 1; event A at step 2 rises to 3 and recedes; event B starts at step 8 in A's recession (flow 2), rises
    # to 4; the flow falls below both starts and event C starts at step 16 (flow 0.9) below them
    q = np.array([1, 1, 1, 2, 3, 2.8, 2.5, 2.2, 2, 3, 4, 3, 2.4, 1.5, 1.0, 0.95, 0.9, 1.4, 0.9, 0.0])
    fa, fb, fc = 1.5, 0.6, 2.0
    got = layered_event_factors(q, np.array([2, 8, 16]), np.array([fa, fb, fc]))
    want = q.copy()
    want[2:8] = 1 + fa * (q[2:8] - 1)
    want[8:16] = np.where(q[8:16] > 2, 1 + fa * 1 + fb * (q[8:16] - 2), 1 + fa * np.maximum(q[8:16] - 1, 0))
    want[8:16] = np.where(q[8:16] < 1, q[8:16], want[8:16])
    want[16:] = 0.9 + fc * (q[16:] - 0.9).clip(0)
    np.testing.assert_allclose(got[:-1] * q[:-1], want[:-1], rtol=1e-12)
    assert got[-1] == 1.0  # no flow: nothing to scale
    # continuous: no step in the truth's flow where an event starts
    assert np.abs(np.diff(got[:-1] * q[:-1])).max() <= max(fa, fb, fc) * np.abs(np.diff(q[:-1])).max() + 1e-12


def _hydrographs(n_events: int = 400, every: int = 48) -> dict[str, pd.Series]:
    """Two inflows with isolated events: a 4 h rise each ``every`` hours, an exponential recession to the base."""
    hours = pd.date_range(ORIGIN, periods=n_events * every + 24, freq="h")
    quick = np.zeros(hours.size)
    for j in range(n_events):
        k = 10 + j * every
        quick[k:k + 4] = np.arange(1, 5) * (1.0 + 0.5 * (j % 3))
        quick[k + 4:k + every - 8] = quick[k + 3] * np.exp(-np.arange(1, every - 11) / 6.0)
    return {"inflow:a": pd.Series(2.0 + quick, index=hours), "inflow:b": pd.Series(0.5 + 0.3 * quick, index=hours)}


def test_inflow_rises_give_the_events_and_one_lognormal_factor_each() -> None:
    from rivercal.twin.realism import generator, inflow_event_starts, inflow_factors

    forcing, errors = _hydrographs(), RainErrors(sigma_ln=0.3)
    starts = inflow_event_starts(forcing, errors)
    assert len(starts) == 400 and (starts == ORIGIN + pd.to_timedelta(9 + 48 * np.arange(400), "h")).all()
    f = inflow_factors(forcing, seed=7, rain=errors)
    eps = generator(7, "rain").standard_normal(400)
    for key, q in forcing.items():
        base = q.iloc[9]
        peaks = 13 + 48 * np.arange(400)
        flow = q.to_numpy()[peaks]
        recovered = 1 + (f[key].to_numpy()[peaks] - 1) * flow / (flow - base)  # F_j from Q*/Q at each peak
        np.testing.assert_allclose(recovered, np.exp(0.3 * eps), rtol=1e-9)
        assert (f[key].to_numpy()[48 * np.arange(400) + 9] == 1.0).all()  # at an event's start flow: nothing added
    ln = np.log(recovered)  # the event factors' own statistics: median 1, σ of ln as set
    assert abs(ln.mean()) < 4 * 0.3 / np.sqrt(400) and ln.std() == pytest.approx(0.3, rel=0.1)
    # the same seed, the same factors; another seed, others
    pd.testing.assert_series_equal(inflow_factors(forcing, seed=7, rain=errors)["inflow:a"], f["inflow:a"])
    assert not np.allclose(inflow_factors(forcing, seed=8, rain=errors)["inflow:a"], f["inflow:a"])


def test_events_come_from_the_measured_rain_where_the_model_has_one() -> None:
    from rivercal.twin.realism import inflow_event_starts

    forcing = _hydrographs(n_events=3)
    rain = pd.Series(0.0, index=forcing["inflow:a"].index)
    rain.iloc[[5, 6, 30, 100]] = 1.0  # events from hours 5, 30 and 100: not where the inflows rise
    assert list(inflow_event_starts(forcing, RainErrors(), rain)) == list(rain.index[[5, 30, 100]])


def test_runoff_error_is_one_constant_factor_per_inflow_seeded_by_its_name() -> None:
    from rivercal.twin.realism import RunoffErrors, inflow_factors

    hours = pd.date_range(ORIGIN, periods=5, freq="h")
    forcing = {f"inflow:n{i}": pd.Series(1.0 + np.arange(5.0), index=hours) for i in range(2000)}
    f = inflow_factors(forcing, seed=3, runoff=RunoffErrors(sigma_ln=0.2))
    ln = np.log([s.iloc[0] for s in f.values()])
    assert all(s.nunique() == 1 for s in f.values())
    assert abs(ln.mean()) < 4 * 0.2 / np.sqrt(2000) and ln.std() == pytest.approx(0.2, rel=0.05)
    alone = inflow_factors({"inflow:n7": forcing["inflow:n7"]}, seed=3, runoff=RunoffErrors(sigma_ln=0.2))
    assert alone["inflow:n7"].iloc[0] == f["inflow:n7"].iloc[0]  # a series' factor does not depend on the others


def test_the_inflow_rises_of_dommel_follow_its_rain_events(dommel) -> None:
    from rivercal.twin.realism import inflow_event_starts

    inputs = dommel.variant_inputs()
    rain = inflow_event_starts(inputs.forcing, RainErrors(), inputs.rain)
    rises = inflow_event_starts(inputs.forcing, RainErrors())
    gap_h = np.array([np.abs((rain - t).total_seconds()).min() / 3600 for t in rises])
    assert len(rises) > 30 and np.mean(gap_h <= 3) > 0.75


class _Inflows:
    """A model with two given inflows and variants that only scale them (what a SWMM model offers)."""

    name = "stub"
    start, end = ORIGIN, ORIGIN + pd.Timedelta("20D")

    def __init__(self, perturbable: bool = True):
        self.forcing = _hydrographs(n_events=10)
        self.made: dict = {}
        if perturbable:
            self.perturbable_forcing = lambda: tuple(self.forcing)
            self.simulate_perturbed = lambda *a, **k: None

    def variant_inputs(self):
        from rivercal.models.capabilities import VariantInputs

        return VariantInputs(branches={}, inherit=(), catchments=(), rain=None, forcing=self.forcing)

    def variant(self, **kwargs):
        self.made = kwargs
        return self


def test_a_model_without_catchments_takes_rain_and_runoff_errors_on_its_inflows() -> None:
    from rivercal.models.capabilities import MissingCapability
    from rivercal.twin.realism import inflow_factors
    from rivercal.twin.truth_model import PerturbedTruth

    model, level = _Inflows(), REALISM_LEVELS["realistic-forcing"]
    truth = PerturbedTruth(model, level, seed=5)
    want = inflow_factors(model.forcing, 5, rain=level.rain, runoff=level.runoff)
    assert set(model.made["forcing_factors"]) == set(model.forcing)
    for key in model.forcing:
        pd.testing.assert_series_equal(model.made["forcing_factors"][key], want[key])
    assert model.made["branch_factors"] is None and model.made["runoff_factors"] is None
    # no structural error: the scenario's quantities pass to the truth unchanged (friction:global too)
    assert truth.quantities_of({"friction:global": 25.0, "weir:W.crest_level": 7.0}) == {
        "friction:global": 25.0, "weir:W.crest_level": 7.0}
    with pytest.raises(MissingCapability, match="realistic-forcing"):
        PerturbedTruth(model, REALISM_LEVELS["realistic"], seed=5)  # refused, not applied in part
    with pytest.raises(MissingCapability, match="perturbable forcing"):
        PerturbedTruth(_Inflows(perturbable=False), level, seed=5)


def test_the_swmm_truth_runs_on_its_inflow_series_times_the_factors() -> None:
    from rivercal.model import load_model
    from rivercal.twin.truth_model import truth_model

    swmm = load_model("dommel-swmm")
    truth = truth_model(swmm, "realistic-forcing", seed=2)
    before, after = swmm.variant_inputs().forcing, truth.truth.variant_inputs().forcing
    assert set(truth.forcing_factors) == set(before) == set(swmm.perturbable_forcing())
    for key, q in before.items():
        f = truth.forcing_factors[key]
        at = (q.index - f.index[0]).total_seconds()
        expected = q.to_numpy() * np.interp(at, (f.index - f.index[0]).total_seconds(), f.to_numpy())
        np.testing.assert_allclose(after[key].to_numpy(), expected, rtol=1e-8)
        assert not np.allclose(after[key].to_numpy(), q.to_numpy(), rtol=1e-3)


def test_two_inflows_that_share_a_series_each_take_their_own_factors() -> None:
    # a SWMM file may give two [INFLOWS] rows one [TIMESERIES] series; each inflow's error is its own
    from rivercal.model import load_model
    from rivercal.models.swmm.inp import InpFile

    swmm = load_model("dommel-swmm")
    rows = swmm._inflow_rows
    first, second = list(rows)[:2]
    inp = InpFile(swmm._inp.text(), source="shared.inp")
    for row in inp.rows("INFLOWS"):
        if row.tokens[0] == second and row.tokens[1].upper() == "FLOW":
            row.tokens[2] = rows[first].tokens[2]  # the second inflow now reads the first one's series
    shared = type(swmm)(InpFile(inp.text(), source="shared.inp"), swmm.stations, name=swmm.name, start=swmm.start,
                        end=swmm.end, output_interval=swmm.output_interval, spinup=swmm.spinup,
                        calibration=swmm.calibration)
    base = shared.variant_inputs().forcing
    hours = pd.date_range(swmm.start - pd.Timedelta("1D"), swmm.end + pd.Timedelta("1D"), freq="1h")
    factors = {f"inflow:{first}": pd.Series(2.0, index=hours), f"inflow:{second}": pd.Series(3.0, index=hours)}
    varied = shared.variant(forcing_factors=factors).variant_inputs().forcing
    for key, factor in ((f"inflow:{first}", 2.0), (f"inflow:{second}", 3.0)):
        np.testing.assert_allclose(varied[key].to_numpy(), factor * base[key].to_numpy(), rtol=1e-9)
    np.testing.assert_array_equal(base[f"inflow:{first}"].to_numpy() / float(rows[first].tokens[4]) /
                                  float(rows[first].tokens[5]),
                                  base[f"inflow:{second}"].to_numpy() / float(rows[second].tokens[4]) /
                                  float(rows[second].tokens[5]))  # one series, read twice
