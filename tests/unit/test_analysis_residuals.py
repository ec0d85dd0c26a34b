"""Residual statistics against numpy and the moving-window bias of thesis Eq. 2-14 on synthetic errors."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.analysis import bias_significance, error_statistics, errors, moving_bias, residual_statistics
from rivercal.observations import ObservationSet

T0 = pd.Timestamp("2010-09-27", tz="UTC")


def hourly(n: int, start=T0) -> pd.DatetimeIndex:
    return pd.date_range(start, periods=n, freq="h")


def test_errors_interpolate_the_simulation_to_the_observation_times() -> None:
    sim = pd.DataFrame({"A.h": np.arange(5.0), "A.Q": 10 * np.arange(5.0)}, index=hourly(5))
    times = T0 + pd.to_timedelta([0.5, 1.0, 2.25, 6.0], unit="h")  # the last lies after the simulation
    obs = pd.DataFrame({"A.h": [1.0, np.nan, 2.0, 3.0], "A.Q": [5.0, 10.0, 20.0, 0.0]}, index=times)
    e = errors(obs, sim)
    np.testing.assert_allclose(e["A.h"].to_numpy(), [0.5, np.nan, -0.25, np.nan])  # y − ŷ
    np.testing.assert_allclose(e["A.Q"].to_numpy(), [0.0, 0.0, -2.5, np.nan])
    weighted = errors(obs, sim, sigma={"h": 0.5, "A.Q": 2.0})
    np.testing.assert_allclose(weighted["A.h"].to_numpy(), [1.0, np.nan, -0.5, np.nan])
    np.testing.assert_allclose(weighted["A.Q"].to_numpy(), [0.0, 0.0, -1.25, np.nan])
    with pytest.raises(ValueError, match=r"'B\.h' is not in the simulated series"):
        errors(obs.rename(columns={"A.h": "B.h"}), sim)


def test_observation_sets_bring_their_own_sigma() -> None:
    sim = pd.DataFrame({"A.h": np.zeros(4), "A.Q": np.zeros(4)}, index=hourly(4))
    obs = ObservationSet.from_frame(pd.DataFrame({"A.h": [0.05, 0.1, 0.0, 0.0], "A.Q": [1.0, 0.0, 0.0, 0.0]},
                                                 index=hourly(4)))  # default σ: 0.025 m and 0.1 m³/s
    e = errors(obs, sim)
    np.testing.assert_allclose(e["A.h"], [2.0, 4.0, 0.0, 0.0])
    np.testing.assert_allclose(e["A.Q"], [10.0, 0.0, 0.0, 0.0])


def test_statistics_against_numpy() -> None:
    rng = np.random.default_rng(3)
    a, b = rng.normal(0.2, 1.0, 50), rng.normal(-0.1, 0.5, 30)
    frame = pd.DataFrame({"S.h_up": np.r_[a, [np.nan] * 20], "S.Q": np.r_[b, [np.nan] * 40]}, index=hourly(70))
    stats = error_statistics(frame)
    assert list(stats.index) == ["S.h_up", "S.Q", "total"]
    assert list(stats.columns) == ["n", "cost", "rmse", "bias", "std"]
    for name, e in (("S.h_up", a), ("S.Q", b), ("total", np.r_[a, b])):
        row = stats.loc[name]
        assert row["n"] == e.size
        assert row["cost"] == pytest.approx(np.sum(e**2))
        assert row["rmse"] == pytest.approx(np.sqrt(np.mean(e**2)))
        assert row["bias"] == pytest.approx(np.mean(e))
        assert row["std"] == pytest.approx(np.std(e))
        assert row["rmse"] ** 2 == pytest.approx(row["bias"] ** 2 + row["std"] ** 2)  # as in thesis Table 4-6


def test_residual_statistics_of_a_constant_offset() -> None:
    sim = pd.DataFrame({"A.h": np.linspace(1, 2, 24)}, index=hourly(24))
    obs = sim + 0.05
    stats = residual_statistics(obs, sim, sigma={"h": 0.025})
    assert stats.loc["A.h", "bias"] == pytest.approx(2.0)
    assert stats.loc["A.h", "std"] == pytest.approx(0.0, abs=1e-9)
    assert stats.loc["A.h", "cost"] == pytest.approx(24 * 4.0)


def test_moving_bias_is_the_squared_window_mean_of_alternating_errors() -> None:
    # e = μ ± a alternately; a 1 h window [t − 1 h, t] holds two hourly values: mean μ, variance a²
    mu, amp = 0.3, 1.0
    e = pd.Series(mu + amp * (-1.0) ** np.arange(48), index=hourly(48))
    m = moving_bias(e, "1h")
    assert np.isnan(m["bias"].iloc[0]) and m["n"].iloc[0] == 1  # one value: no variance yet
    full = m.iloc[1:]
    assert (full["n"] == 2).all()
    np.testing.assert_allclose(full["mse"], mu**2 + amp**2)
    np.testing.assert_allclose(full["variance"], amp**2)
    np.testing.assert_allclose(full["bias"], mu**2, atol=1e-12)  # mse − σ²_w = ē²
    np.testing.assert_allclose(full["mean_error"], mu)
    assert not full["significant"].any()  # 0.09 < 0.1 · 1
    overall = bias_significance(m)
    assert overall.loc["series", "bias"] == pytest.approx(mu**2)
    assert overall.loc["series", "variance"] == pytest.approx(amp**2)
    assert not overall.loc["series", "significant"]
    biased = bias_significance(moving_bias(e + 0.1, "1h"))  # ē = 0.4: 0.16 > 0.1
    assert biased.loc["series", "significant"] and biased.loc["series", "fraction_significant"] == 1.0


def test_the_default_window_of_two_hours_holds_three_hourly_values() -> None:
    e = pd.Series([1.0, 2.0, 3.0, 4.0, 5.0], index=hourly(5))
    m = moving_bias(e)
    assert list(m["n"]) == [1, 2, 3, 3, 3]
    np.testing.assert_allclose(m["mse"].iloc[2:], [14 / 3, 29 / 3, 50 / 3])
    np.testing.assert_allclose(m["variance"].iloc[2:], 2 / 3)
    np.testing.assert_allclose(m["bias"].iloc[2:], [4.0, 9.0, 16.0])


def test_moving_bias_of_random_errors_with_known_mean_and_variance() -> None:
    # minute values, T = 2 h (n_w = 121): E[b] = μ² + σ²/n_w, E[σ²_w] = σ² (n_w − 1)/n_w
    rng = np.random.default_rng(12)
    idx = pd.date_range(T0, periods=20_000, freq="min")
    sigma, n_w = 0.5, 121
    for mu, significant in ((0.0, False), (0.5, True)):
        e = pd.Series(rng.normal(mu, sigma, idx.size), index=idx)
        m = moving_bias(e, "2h", min_periods=n_w)
        overall = bias_significance(m)
        assert overall.loc["series", "bias"] == pytest.approx(mu**2 + sigma**2 / n_w, rel=0.1)
        assert overall.loc["series", "variance"] == pytest.approx(sigma**2 * (n_w - 1) / n_w, rel=0.02)
        assert overall.loc["series", "significant"] == significant


def test_perfect_fits_and_pure_offsets() -> None:
    zero = bias_significance(moving_bias(pd.Series(np.zeros(10), index=hourly(10))))
    assert zero.loc["series", "bias"] == 0.0 and not zero.loc["series", "significant"]
    offset = moving_bias(pd.Series(np.full(10, 0.02), index=hourly(10)))
    assert offset["significant"].iloc[1:].all()  # systematic error without scatter
    assert bias_significance(offset).loc["series", "significant"]


def test_frames_stack_per_series() -> None:
    frame = pd.DataFrame({"A.h": np.arange(6.0), "B.h": np.r_[np.ones(3), [np.nan] * 3]}, index=hourly(6))
    m = moving_bias(frame)
    assert set(m["series"]) == {"A.h", "B.h"} and len(m) == 6 + 3
    assert list(m.columns[:2]) == ["time", "series"]
    overall = bias_significance(m)
    assert list(overall.index) == ["A.h", "B.h"]
    assert overall.loc["B.h", "bias"] == pytest.approx(1.0)


def test_bad_input_is_refused() -> None:
    e = pd.Series(np.ones(5), index=hourly(5))
    with pytest.raises(ValueError, match="min_periods"):
        moving_bias(e, min_periods=1)
    with pytest.raises(ValueError, match="window"):
        moving_bias(e, "0h")
    with pytest.raises(ValueError, match="indexed by time"):
        moving_bias(pd.Series(np.ones(5)))
