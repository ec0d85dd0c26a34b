"""The calibration problem with a stub model: any model that follows the protocol can be calibrated."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest

from rivercal.errors import EngineDivergedError
from rivercal.models import Quantity
from rivercal.observations import ObservationSeries, ObservationSet
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem, calibrate

START = pd.Timestamp("2020-01-01", tz="UTC")


@dataclass
class Result:
    series: pd.DataFrame


class LinearReservoirModel:
    """h(t) = crest + a (1 - exp(-t/τ)), Q = k (h - crest): hourly output; fails when k > 5."""

    observables: ClassVar[list[str]] = ["S.h", "S.Q"]
    quantities: ClassVar[dict[str, Quantity]] = {"friction:global": Quantity("friction:global", "-", 0.0, 20.0),
                                                  "weir:W.crest_level": Quantity("weir:W.crest_level", "m AD")}

    def __init__(self):
        self.runs = 0

    def simulate(self, parameters, start=None, end=None, state=None):
        self.runs += 1
        start = START if start is None else start
        times = pd.date_range(start, end, freq="h")
        k = parameters.get("friction:global", 1.0)
        crest = parameters.get("weir:W.crest_level", 10.0)
        if k > 5.0:
            raise EngineDivergedError(str(end), "S", "stub failure")
        t = (times - START).total_seconds().to_numpy() / 3600.0
        h = crest + 2.0 * (1 - np.exp(-t / 10.0))
        return Result(pd.DataFrame({"S.h": h, "S.Q": k * (h - crest)}, index=times)), "state"


def _params(k0=2.0, crest0=10.2) -> ParameterSet:
    return ParameterSet([
        Parameter(name="k", targets=["friction:global"], min=0.5, max=10.0, initial=k0, perturbation=0.5),
        Parameter(name="crest", targets=["weir:W.crest_level"], min=9.0, max=11.0, initial=crest0, perturbation=0.1),
    ])


def _obs(model, k=3.0, crest=10.0, half_hours=False) -> ObservationSet:
    truth = {"friction:global": k, "weir:W.crest_level": crest}
    series = model.simulate(truth, START, START + pd.Timedelta("48h"))[0].series
    if half_hours:  # observations between the model's output times
        series = series.resample("30min").interpolate()
    return ObservationSet.from_frame(series)


def test_twin_recovers_the_truth_and_counts_runs() -> None:
    model = LinearReservoirModel()
    window = (START + pd.Timedelta("6h"), START + pd.Timedelta("48h"))
    problem = CalibrationProblem(model, _params(), _obs(model), window, state="s", warmup="6h")
    assert problem.cost(problem.parameters.to_x({"k": 3.0, "crest": 10.0})) == pytest.approx(0.0, abs=1e-20)
    result = calibrate(problem, "dud", workers=1)
    assert result.estimates["k"] == pytest.approx(3.0, abs=1e-6)
    assert result.estimates["crest"] == pytest.approx(10.0, abs=1e-6)
    assert result.result.nfev <= 20


def test_the_numerical_noise_is_what_the_model_declares_also_through_the_transition_wrapper() -> None:
    from rivercal.case import load_case
    from rivercal.models import build_model
    from rivercal.models.transition import TransitionModel

    window = (START + pd.Timedelta("6h"), START + pd.Timedelta("48h"))
    model = LinearReservoirModel()
    assert CalibrationProblem(model, _params(), _obs(model), window).noise is None  # declares none
    model.numerical_noise = 0.002
    assert CalibrationProblem(model, _params(), _obs(model), window).noise == 0.002
    assert CalibrationProblem(model, _params(), _obs(model), window, noise=0.01).noise == 0.01
    embedded = build_model(load_case("synthetic"))
    assert embedded.numerical_noise == embedded.settings.tolerance == 1e-4  # the Picard level tolerance, m
    assert TransitionModel(embedded, "friction:global", reference=embedded.start).numerical_noise == 1e-4


def test_observations_between_output_times_are_interpolated() -> None:
    model = LinearReservoirModel()
    obs = _obs(model, half_hours=True)
    problem = CalibrationProblem(model, _params(), obs, (START + pd.Timedelta("1h"), START + pd.Timedelta("40h")),
                                 state="s", warmup="1h")
    x_true = problem.parameters.to_x({"k": 3.0, "crest": 10.0})
    r = problem.residuals(x_true)
    assert r.size == problem.observations.n_values == 2 * (2 * 39 + 1)
    # the model output is hourly; the half-hour observations are linear interpolations of the same curve
    assert np.abs(r).max() < 1e-12


def test_weights_are_one_over_sigma_or_thesis_eq_2_6() -> None:
    model = LinearReservoirModel()
    obs = _obs(model)
    obs = ObservationSet((obs["S.h"], ObservationSeries(id="S.Q", times=obs["S.Q"].times, values=obs["S.Q"].values,
                                                       sigma=None)))
    problem = CalibrationProblem(model, _params(k0=2.0), obs, (START + pd.Timedelta("2h"), START + pd.Timedelta("24h")),
                                 state="s", warmup="2h")
    w = problem.sqrt_weights
    n_h = len(problem.observations["S.h"])
    np.testing.assert_allclose(w[:n_h], 1 / 0.025)
    prior = problem.predictions(problem.simulate(problem.x0))["S.Q"]
    dmax = np.abs(problem.observations["S.Q"].values - prior).max()
    np.testing.assert_allclose(w[n_h:], 1 / dmax)  # W = 1 / Δŷ²_max


def test_cost_breakdown_adds_up() -> None:
    model = LinearReservoirModel()
    problem = CalibrationProblem(model, _params(), _obs(model), (START, START + pd.Timedelta("24h")), state="s",
                                 warmup="0h")
    b = problem.cost_breakdown(problem.x0)
    assert b.total == pytest.approx(sum(b.by_series.values()))
    assert b.by_station == {"S": pytest.approx(b.total)}


def test_failure_policy_raise_and_penalty() -> None:
    model = LinearReservoirModel()
    obs = _obs(model)
    window = (START + pd.Timedelta("2h"), START + pd.Timedelta("24h"))
    x_bad = _params().to_x({"k": 8.0})
    with pytest.raises(EngineDivergedError):
        CalibrationProblem(model, _params(), obs, window, state="s", warmup="2h").residuals(x_bad)
    problem = CalibrationProblem(model, _params(), obs, window, state="s", warmup="2h", on_failure="penalty",
                                 penalty=1e6)
    assert problem.cost(x_bad) == pytest.approx(1e6)


def test_bad_setups_fail_before_any_model_run() -> None:
    model = LinearReservoirModel()
    obs = _obs(model)
    with pytest.raises(ValueError, match="holds no observations"):
        CalibrationProblem(model, _params(), obs, (START + pd.Timedelta("100h"), START + pd.Timedelta("120h")))
    with pytest.raises(ValueError, match="not simulated by the model"):
        CalibrationProblem(model, _params(), ObservationSet((ObservationSeries.from_series(
            pd.Series([1.0], index=[START]), id="X.h"),)), (START, START + pd.Timedelta("2h")))
    with pytest.raises(ValueError, match="on_failure"):
        CalibrationProblem(model, _params(), obs, (START, START + pd.Timedelta("2h")), on_failure="ignore")
    assert model.runs == 1  # only the run that made the observations


def test_ln_transform_reports_std_in_physical_units() -> None:
    model = LinearReservoirModel()
    ps = ParameterSet([Parameter(name="k", targets=["friction:global"], min=0.5, max=10.0, initial=2.0,
                                 transform="ln", perturbation=0.2)])
    obs = _obs(model)
    obs = ObservationSet((obs["S.Q"],))
    problem = CalibrationProblem(model, ps, obs, (START + pd.Timedelta("2h"), START + pd.Timedelta("48h")),
                                 state="s", warmup="2h")
    result = calibrate(problem, "dud", workers=1)
    # noise-free: DuD stops once the cost is negligible, within about 10⁻³ of the perturbation 0.2 (in ln k)
    assert result.estimates["k"] == pytest.approx(3.0, rel=1e-3)
    assert problem.x0[0] == pytest.approx(math.log(2.0))
    # d k = k d(ln k): the reported std is the physical one
    k = math.exp(result.result.x[0])
    assert result.std["k"] == pytest.approx(k * result.result.std[0], rel=1e-12)
    assert result.std_scaled["k"] == pytest.approx(k * result.result.extra["std_scaled"][0], rel=1e-12)


@pytest.mark.parametrize("loss", ["huber", "student-t"])
def test_robust_cost_gives_the_m_estimate_and_resists_spikes(loss) -> None:
    # a level offset (the crest) seen through noisy observations with a few 0.5 m spikes: its estimate is an
    # M-estimate of location, whose reference is scipy's robust least squares (Huber) or the estimating
    # equation Σ w(r) r = 0 with the Student-t weights w = (1 + r²/(ν c²))⁻¹, solved by brentq
    from scipy.optimize import brentq, least_squares

    from rivercal.problem import LOSSES, STUDENT_T_DOF

    model = LinearReservoirModel()
    clean = _obs(model)["S.h"]
    rng = np.random.default_rng(7)
    values = clean.values + rng.normal(0.0, 0.025, clean.values.size)
    values[[5, 17, 30]] += 0.5
    obs = ObservationSet((ObservationSeries(id="S.h", times=clean.times, values=values, sigma=0.025),))
    params = ParameterSet([_params()["crest"]])
    window = (START, START + pd.Timedelta("48h"))
    robust = calibrate(CalibrationProblem(model, params, obs, window, state="s", warmup="0h", loss=loss), "dud",
                       workers=1).estimates["crest"]
    plain = calibrate(CalibrationProblem(model, params, obs, window, state="s", warmup="0h"), "dud",
                      workers=1).estimates["crest"]
    d = (values - (clean.values - 10.0)) / 0.025  # crest + noise, in σ
    c = LOSSES[loss]
    if loss == "huber":  # scipy's Huber: ρ(z) = z for z ≤ 1, 2√z − 1 beyond, z = (r/c)², times c²/2
        ref = least_squares(lambda m: d - m, x0=[np.median(d)], loss="huber", f_scale=c, xtol=1e-15,
                            ftol=1e-15, gtol=1e-15).x[0] * 0.025
    else:
        def score(m: float) -> float:
            r = d - m
            return float(np.sum(r / (1.0 + r * r / (STUDENT_T_DOF * c * c))))

        ref = brentq(score, d.min(), d.max(), xtol=1e-14) * 0.025
    assert robust == pytest.approx(ref, abs=3e-5)  # DuD's stopping rules: 0.001 σ
    assert plain == pytest.approx(float(np.mean(d)) * 0.025, abs=2e-5)  # l2: the mean, pulled up by the spikes
    assert abs(robust - 10.0) < 0.5 * abs(plain - 10.0)


def test_robust_residuals_square_to_twice_rho() -> None:
    from rivercal.problem import robust_residuals

    r = np.array([-5.0, -1.0, 0.0, 0.3, 2.0, 40.0])
    huber = robust_residuals(r, "huber", 1.0)
    rho = np.where(np.abs(r) <= 1.0, 0.5 * r * r, np.abs(r) - 0.5)
    np.testing.assert_allclose(huber**2, 2 * rho)
    np.testing.assert_allclose(np.sign(huber), np.sign(r))
    t = robust_residuals(r, "student-t", 2.0)
    np.testing.assert_allclose(t**2, 4.0 * 4.0 * np.log1p(r * r / 16.0))
    assert robust_residuals(r, "l2") is r
    with pytest.raises(ValueError, match="unknown loss 'cauchy'"):
        robust_residuals(r, "cauchy")
    with pytest.raises(ValueError, match="loss_scale"):
        CalibrationProblem(LinearReservoirModel(), _params(), _obs(LinearReservoirModel()),
                           (START, START + pd.Timedelta("2h")), loss="huber", loss_scale=0.0)
