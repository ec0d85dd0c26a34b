"""The WALRUS-type rainfall-runoff model: water balance, pulse response, parameters, units."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import rivercal.cases
from rivercal.hydrology import _kernels
from rivercal.hydrology.disaggregate import hourly_forcing
from rivercal.hydrology.knmi import read_knmi_daily
from rivercal.hydrology.runoff import (
    CALIBRATION_PARAMETERS,
    PARAMETERS,
    SOIL_TYPES,
    WalrusParameters,
    WalrusState,
    lateral_inflow,
    simulate,
    steady_state,
)

EINDHOVEN = Path(rivercal.cases.__file__).parent / "dommel" / "meteo" / "etmgeg_370_20100901-20101201.txt"


@pytest.fixture(scope="module")
def forcing_2010() -> pd.DataFrame:
    return hourly_forcing(read_knmi_daily(EINDHOVEN))


def _synthetic_year(seed: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """One year of hourly forcing: intermittent showers (some extreme) and a daily/seasonal ET cycle."""
    rng = np.random.default_rng(seed)
    n = 8760
    t = np.arange(n)
    wet = rng.random(n) < 0.08
    p = np.where(wet, rng.gamma(0.6, 2.0, n), 0.0)
    p[4000:4006] = 40.0  # a cloudburst: 240 mm in 6 h
    season = 0.5 - 0.5 * np.cos(2 * np.pi * (t / n - 0.05))
    daylight = np.maximum(np.sin(2 * np.pi * (t % 24 - 6) / 24), 0.0)
    e = 0.45 * season * daylight
    return p, e


def test_water_balance_closes_to_round_off() -> None:
    p, e = _synthetic_year()
    for params in (WalrusParameters(), WalrusParameters(c_w=50.0, c_q=1.0, a_s=0.002, c_s=30.0, c_v=0.5)):
        result = simulate(params, p, e)
        wb = result.water_balance()
        assert abs(wb["residual"]) < 1e-9 * max(1.0, wb["P"])
        s = result.series
        assert (s["h_q"] >= 0.0).all() and (s["h_s"] >= 0.0).all() and (s["q"] >= 0.0).all()
        assert (s["ETact"] >= 0.0).all() and (s["ETact"] <= s["ETpot"] + 1e-12).all()
        # step by step: the storage column follows P - ETact - q
        storage = np.concatenate([[result.initial.storage(params)], s["storage"].to_numpy()])
        step = s["P"] - s["ETact"] - s["q"] - np.diff(storage)
        assert np.abs(step).max() < 1e-9


def test_water_balance_with_2010_forcing(forcing_2010: pd.DataFrame) -> None:
    result = simulate(WalrusParameters(), forcing_2010["P"], forcing_2010["ETpot"])
    wb = result.water_balance()
    assert abs(wb["residual"]) < 1e-9
    assert wb["P"] == pytest.approx(forcing_2010["P"].sum())
    assert result.series.index.equals(forcing_2010.index)


def test_november_2010_raises_discharge_several_fold(forcing_2010: pd.DataFrame) -> None:
    q = simulate(WalrusParameters(), forcing_2010["P"], forcing_2010["ETpot"]).q
    dry = q.loc["2010-09-01":"2010-09-06"].mean()
    assert 0.0 < dry < 0.05  # dry-weather flow: small but not zero (mm/h)
    assert q.min() > 0.0
    assert q.loc["2010-11-08":"2010-11-20"].max() > 5.0 * dry


def _pulse_response(params: WalrusParameters, depth_mm: float = 10.0, hours: int = 24 * 30) -> np.ndarray:
    """Discharge above the no-rain run after a one-hour pulse at step 24 (no evaporation)."""
    p = np.zeros(hours)
    e = np.zeros(hours)
    start = steady_state(params, 0.02)
    base = simulate(params, p, e, initial=start).q.to_numpy()
    p[24] = depth_mm
    wet = simulate(params, p, e, initial=start).q.to_numpy()
    return wet - base


def test_pulse_response_has_delay_and_recession() -> None:
    r = _pulse_response(WalrusParameters())
    assert np.abs(r[:24]).max() == 0.0  # nothing before the rain
    peak = int(np.argmax(r))
    assert 25 <= peak <= 24 + 48  # the peak comes hours after the pulse, within two days
    tail = r[peak:]
    assert (np.diff(tail) <= 1e-12).all()  # recession: no second peak
    assert tail[-1] < 0.1 * r[peak]
    assert 0.0 < r.sum() < 10.0  # part of the pulse leaves as discharge within a month


def test_pulse_response_monotone_in_quickflow_constant() -> None:
    peaks, times = [], []
    for c_q in (2.0, 5.0, 10.0, 20.0, 50.0):
        r = _pulse_response(WalrusParameters(c_q=c_q))
        peaks.append(r.max())
        times.append(int(np.argmax(r)))
    assert all(a > b for a, b in itertools.pairwise(peaks))  # slower reservoir: lower peak
    assert all(a <= b for a, b in itertools.pairwise(times))  # ... and later
    assert times[-1] > times[0]


def test_pulse_response_monotone_in_wetness_parameter() -> None:
    # a larger c_w sends a larger share of the rain to the quickflow route at the same deficit
    peaks = [_pulse_response(WalrusParameters(c_w=c_w)).max() for c_w in (160.0, 200.0, 300.0, 500.0)]
    assert all(a < b for a, b in itertools.pairwise(peaks))


def test_steady_state_discharges_its_dry_weather_flow() -> None:
    params = WalrusParameters()
    for q0 in (0.005, 0.02, 0.1):
        s = steady_state(params, q0)
        assert s.h_q == 0.0
        result = simulate(params, np.zeros(3), np.zeros(3), initial=s)
        assert result.q.iloc[0] == pytest.approx(q0, rel=0.01)
    with pytest.raises(ValueError, match="positive"):
        steady_state(params, 0.0)


def test_compiled_kernel_matches_python() -> None:
    p, e = _synthetic_year()
    p, e = p[3900:4300].copy(), e[3900:4300].copy()
    params = WalrusParameters()
    par = params._vector(10.0, 1e-3)
    outs = []
    for fn in (_kernels.run_walrus, _kernels.run_walrus.py_func):
        state = steady_state(params, 0.02)._array()
        n = p.size
        arrays = [np.empty(n) for _ in range(4)] + [np.empty((n, 4)), np.empty(n), np.empty(n, dtype=np.int64)]
        fn(p, e, 1.0, par, state, *arrays)
        outs.append((state, arrays))
    (s1, a1), (s2, a2) = outs
    np.testing.assert_allclose(s1, s2, rtol=1e-12, atol=1e-12)
    for x, y in zip(a1, a2, strict=True):
        np.testing.assert_allclose(x, y, rtol=1e-10, atol=1e-12)


def test_hot_start_equals_one_run() -> None:
    p, e = _synthetic_year()
    params = WalrusParameters()
    whole = simulate(params, p[:2000], e[:2000])
    first = simulate(params, p[:1000], e[:1000])
    second = simulate(params, p[1000:2000], e[1000:2000], initial=first.final)
    np.testing.assert_allclose(second.q.to_numpy(), whole.q.to_numpy()[1000:], rtol=1e-12, atol=1e-15)


def test_forcing_validation() -> None:
    params = WalrusParameters()
    with pytest.raises(ValueError, match=r"precip_mm_h: 1 missing.*at 2"):
        simulate(params, [0.0, 1.0, np.nan], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="negative"):
        simulate(params, [0.0, 1.0], [0.0, -0.1])
    with pytest.raises(ValueError, match="2 values"):
        simulate(params, [0.0, 1.0, 2.0], [0.0, 0.0])
    a = pd.Series([0.0, 1.0], index=pd.date_range("2010-01-01", periods=2, freq="h"))
    b = pd.Series([0.0, 1.0], index=pd.date_range("2011-01-01", periods=2, freq="h"))
    with pytest.raises(ValueError, match="different indexes"):
        simulate(params, a, b)


def test_parameter_vector_round_trip_and_validation() -> None:
    params = WalrusParameters()
    names = WalrusParameters.names()
    assert names == tuple(s.name for s in PARAMETERS)
    assert set(CALIBRATION_PARAMETERS) <= set(names)
    for spec in PARAMETERS:
        assert spec.lower <= getattr(params, spec.name) <= spec.upper, spec.name
        assert spec.unit
    x = params.to_vector()
    assert np.array_equal(WalrusParameters.from_vector(x).to_vector(), x)
    lb, ub = WalrusParameters.bounds()
    assert (lb < x).all() and (x < ub).all()
    changed = params.replace(c_w=150.0)
    assert changed.c_w == 150.0 and params.c_w == 200.0
    assert WalrusParameters.from_vector([1.0, 2.0], ("c_q", "c_v"), base=changed).as_dict()["c_w"] == 150.0
    with pytest.raises(TypeError, match="unknown parameter"):
        params.replace(cw=1.0)
    with pytest.raises(ValueError, match="c_q"):
        params.replace(c_q=-1.0)
    with pytest.raises(ValueError, match="a_s"):
        params.replace(a_s=1.0)
    sand = WalrusParameters.for_soil("sand", c_w=120.0)
    assert (sand.b, sand.psi_ae, sand.theta_s) == SOIL_TYPES["sand"] and sand.c_w == 120.0
    with pytest.raises(ValueError, match="h_s"):
        WalrusState(d_v=0.0, d_g=100.0, h_q=0.0, h_s=-1.0)


def test_lateral_inflow_unit_conversion() -> None:
    assert lateral_inflow(360.0, 1.0) == pytest.approx(1.0)  # 1 mm/h over 360 ha = 1 m3/s
    assert lateral_inflow(1000.0, 0.036) == pytest.approx(0.1)
    q = pd.Series([0.0, 0.36], index=pd.date_range("2010-11-13", periods=2, freq="h", tz="UTC"))
    out = lateral_inflow(100.0, q)
    assert out.name == "Q" and out.index.equals(q.index)
    np.testing.assert_allclose(out.to_numpy(), [0.0, 0.1])
    np.testing.assert_allclose(lateral_inflow(3600.0, np.array([1.0, 2.0])), [10.0, 20.0])
    with pytest.raises(ValueError, match="area_ha"):
        lateral_inflow(-1.0, 1.0)


def test_equilibrium_deficit_is_the_profile_integral() -> None:
    b, psi_ae, theta_s, d_g = 4.38, 90.0, 0.41, 1250.0
    z = np.linspace(0.0, d_g - psi_ae, 200001)  # height above the water table's air-entry fringe
    psi = d_g - z
    theta = theta_s * (psi / psi_ae) ** (-1.0 / b)
    integrand = theta_s - theta
    numeric = float(np.sum((integrand[1:] + integrand[:-1]) * np.diff(z)) / 2.0)
    assert _kernels.equilibrium_deficit(d_g, b, psi_ae, theta_s) == pytest.approx(numeric, rel=1e-6)
    assert _kernels.equilibrium_deficit(50.0, b, psi_ae, theta_s) == 0.0
    assert _kernels.equilibrium_deficit(-20.0, b, psi_ae, theta_s) == -20.0
