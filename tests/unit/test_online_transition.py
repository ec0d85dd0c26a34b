"""Transition discretisation (thesis §6-3): the wrapper, its smoothness in τ, the test rule, and dating a jump.

The wrapper's mechanics run on a 5 km channel (conftest ``channel_case``, a day at Δt = 60 s, hourly output).
The demonstration runs on the default case: global friction k_s jumps 16 → 25 m^(1/3)/s at 2010-11-01 00:00
UTC; the truth is simulated with 16 up to the change and with 25 from that state; hourly observations at all
stations. The fast test uses a two-day window, noise-free; four days 2010-10-30 … 11-03 with the white noise of
rivercal.twin.noise (and four days without a change) are marked slow. The on-line service's default window, a
week, dates a change under realistic errors in tests/e2e/test_online_cli.py.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from rivercal.case import case_from_dict
from rivercal.model import load_model
from rivercal.models import EmbeddedModel, Quantity
from rivercal.observations import ObservationSet
from rivercal.online import (
    AFTER,
    BEFORE,
    TIME,
    TransitionModel,
    estimate_transition,
    transition_start,
    transition_test,
)
from rivercal.online.transition_search import effective_size
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from rivercal.twin.noise import add_noise
from tests.conftest import channel_case

FG = "friction:global"
HOUR = pd.Timedelta("1h")


def _observations(series: pd.DataFrame, start, end, noise: str = "none", seed: int = 0) -> ObservationSet:
    frame = series.loc[start:end].copy()
    rng = np.random.default_rng(seed)
    for col in frame.columns:
        frame[col] = add_noise(frame[col].to_numpy(), col.rpartition(".")[2], noise, rng)
    return ObservationSet.from_frame(frame, source=f"twin truth, {noise} noise")


# -- the wrapper on a channel ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def channel(tmp_path_factory) -> EmbeddedModel:
    case = case_from_dict(channel_case(days=1.0), tmp_path_factory.mktemp("channel"))
    return EmbeddedModel(case)


def _plain(sim, pieces, output_interval=None):
    """Consecutive plain runs [(value, start, end)] from a cold start; the joined series and final state."""
    frames, state = [], None
    for value, a, b in pieces:
        result, state = sim.simulate({FG: value}, a, b, state, output_interval=output_interval)
        frames.append(result.series if not frames else result.series.iloc[1:])
    return pd.concat(frames), state


def test_switch_on_the_output_grid_is_two_plain_runs(channel) -> None:
    t6 = channel.start + 6 * HOUR
    expected, state = _plain(channel, [(30.0, channel.start, t6), (45.0, t6, channel.end)])
    tm = TransitionModel(channel, FG, reference=channel.start)
    result, tm_state = tm.simulate({BEFORE: 30.0, AFTER: 45.0, TIME: 6.0})
    pd.testing.assert_frame_equal(result.series, expected)
    np.testing.assert_array_equal(tm_state.z, state.z)
    assert tm_state.time == channel.end
    assert result.balance.relative_error < 1e-12  # the joined balance closes
    assert result.series.loc[t6 + HOUR, "mid.h"] < result.series.loc[t6, "mid.h"] - 0.1  # smoother bed: lower


def test_switch_outside_the_period_is_one_plain_run(channel) -> None:
    tm = TransitionModel(channel, FG, reference=channel.start + 2 * HOUR)
    before_only, _ = channel.simulate({FG: 30.0})
    after_only, _ = channel.simulate({FG: 45.0})
    for tau, plain in ((-2.0, after_only), (-5.0, after_only), (22.0, before_only), (40.0, before_only)):
        result, _ = tm.simulate({BEFORE: 30.0, AFTER: 45.0, TIME: tau})
        pd.testing.assert_frame_equal(result.series, plain.series)


def test_switch_between_steps_runs_the_step_with_the_time_weighted_value(channel) -> None:
    t = channel.start + 6 * HOUR + pd.Timedelta("10min")
    tm = TransitionModel(channel, FG, reference=channel.start)
    result, state = tm.simulate({BEFORE: 30.0, AFTER: 45.0, TIME: 6.0 + 10.5 / 60.0})  # 06:10:30
    assert tm.segments(30.0, 45.0, 6.0 + 10.5 / 60.0, channel.start, channel.end) == [
        (channel.start, t, 30.0), (t, t + pd.Timedelta("1min"), 37.5), (t + pd.Timedelta("1min"), channel.end, 45.0)]
    fine, fine_state = _plain(channel, [(30.0, channel.start, t), (37.5, t, t + pd.Timedelta("1min")),
                                        (45.0, t + pd.Timedelta("1min"), channel.end)], output_interval=60.0)
    plain_index = channel.simulate({FG: 30.0})[0].series.index
    assert result.series.index.equals(plain_index)  # the output times of a plain run
    pd.testing.assert_frame_equal(result.series, fine.loc[plain_index], check_freq=False)
    np.testing.assert_array_equal(state.q, fine_state.q)


def test_substep_smoothing_is_continuous_in_tau_and_none_is_a_staircase(channel) -> None:
    """Q at 07:00 against τ across the step 06:10 .. 06:11 (seconds after 06:10)."""

    def q7(smoothing, seconds):
        tm = TransitionModel(channel, FG, reference=channel.start, smoothing=smoothing)
        result, _ = tm.simulate({BEFORE: 30.0, AFTER: 45.0, TIME: 6.0 + (600.0 + seconds) / 3600.0})
        return result.series["mid.Q"].iloc[7]

    seconds = [0.0, 1e-3, 15.0, 30.0, 45.0, 60.0 - 1e-3, 60.0]
    smooth = np.array([q7("substep", s) for s in seconds])
    assert abs(smooth[1] - smooth[0]) < 1e-4 * abs(smooth[-1] - smooth[0])  # continuous at both step edges
    assert abs(smooth[-2] - smooth[-1]) < 1e-4 * abs(smooth[-1] - smooth[0])
    assert np.all(np.diff(smooth) != 0) and len(set(np.sign(np.diff(smooth)))) == 1  # strictly monotone
    stairs = np.array([q7("none", s) for s in seconds])  # switch at τ rounded to the nearest step
    assert stairs[0] == stairs[1] == stairs[2] and stairs[3] == stairs[4] == stairs[5] == stairs[6]
    assert stairs[2] != stairs[3]  # a jump at the half step
    assert stairs[0] == smooth[0] and stairs[-1] == smooth[-1]  # both agree on the step grid


def test_quantities_pass_through_and_the_adapter_declares_its_own(channel) -> None:
    tm = TransitionModel(channel, FG, reference=channel.start)
    plain, _ = channel.simulate({FG: 35.0})
    pd.testing.assert_frame_equal(tm.simulate({FG: 35.0})[0].series, plain.series)  # no transition quantity
    assert tm.observables == channel.observables and tm.dt == 60.0 and tm.name == channel.name
    assert tm.output_interval == channel.output_interval and tm.state_format == channel.state_format
    q = tm.quantities
    assert set(q) == set(channel.quantities) | {BEFORE, AFTER, TIME}
    assert (q[BEFORE].unit, q[BEFORE].min, q[BEFORE].max) == (q[FG].unit, q[FG].min, q[FG].max)
    assert q[TIME].unit == "h"
    _, state = tm.simulate({BEFORE: 30.0, AFTER: 45.0, TIME: 3.25})
    again = tm.load_state(tm.save_state(state), tm.state_format)
    np.testing.assert_array_equal(again.z, state.z)


def test_wrapper_errors_name_the_problem(channel) -> None:
    tm = TransitionModel(channel, FG, reference=channel.start)
    with pytest.raises(ValueError, match="missing transition:time"):
        tm.simulate({BEFORE: 30.0, AFTER: 45.0})
    with pytest.raises(ValueError, match="friction:global is set both directly and by the transition"):
        tm.simulate({BEFORE: 30.0, AFTER: 45.0, TIME: 3.0, FG: 20.0})
    with pytest.raises(ValueError, match=r"transition:time: value nan is not finite"):
        tm.simulate({BEFORE: 30.0, AFTER: 45.0, TIME: math.nan})
    with pytest.raises(ValueError, match="multiple of the output interval"):
        tm.simulate({BEFORE: 30.0, AFTER: 45.0, TIME: 3.0}, end=channel.start + pd.Timedelta("90min"))
    with pytest.raises(ValueError, match="'friction:branch:nowhere' is not a settable quantity of model"):
        TransitionModel(channel, "friction:branch:nowhere", reference=channel.start)
    with pytest.raises(ValueError, match="is itself a quantity of the transition"):
        TransitionModel(channel, TIME, reference=channel.start)
    with pytest.raises(ValueError, match="smoothing must be 'substep' or 'none', got 'ramp'"):
        TransitionModel(channel, FG, reference=channel.start, smoothing="ramp")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="bounds are needed for the plain model quantity 'friction:global'"):
        tm.parameter_set((channel.start, channel.end), before=30.0, after=30.0)


def test_parameter_set_bounds_before_after_and_the_window() -> None:
    fa = Parameter(name="FA", targets=[FG], min=8.0, max=40.0, initial=16.0, perturbation=1.5, unit="m^(1/3)/s")

    class Stub:
        dt = 60.0
        quantities: ClassVar[dict] = {FG: Quantity(FG, "m^(1/3)/s", 1.0, 200.0)}

    tm = TransitionModel(Stub(), fa, reference="2010-10-28")
    params = tm.parameter_set(("2010-10-28", "2010-11-04"), after=20.0)
    assert params.names == ["FA_before", "FA_after", "FA_time"]
    lb, ub = params.bounds()
    np.testing.assert_array_equal(lb, [8.0, 8.0, 0.0])
    np.testing.assert_array_equal(ub, [40.0, 40.0, 168.0])
    np.testing.assert_array_equal(params.to_x(), [16.0, 20.0, 84.0])
    assert params.quantities(params.values(params.to_x())) == {BEFORE: 16.0, AFTER: 20.0, TIME: 84.0}
    assert params["FA_time"].unit == "h" and params["FA_after"].unit == "m^(1/3)/s"
    assert tm.time_of(96.0) == pd.Timestamp("2010-11-01", tz="UTC")


# -- the decision rule -----------------------------------------------------------------------------------


def test_transition_test_is_an_f_test_with_a_relevance_floor() -> None:
    verdict = transition_test(200.0, 150.0, 503)
    assert verdict.f_statistic == pytest.approx((50.0 / 2) / (150.0 / 500))
    assert verdict.p_value == pytest.approx(stats.f.sf(verdict.f_statistic, 2, 500))
    assert verdict.reduction == pytest.approx(0.25) and verdict.transition
    assert not transition_test(200.0, 190.0, 503).transition  # significant (p ~ 1e-5) but only 5 %: not worth it
    assert "only 5.0%" in transition_test(200.0, 190.0, 503).reason
    assert not transition_test(10.0, 7.0, 20).transition  # 30 % but not significant with 20 residuals
    assert not transition_test(1e-9, 1e-12, 500).transition  # round-off of two perfect fits
    assert not transition_test(5.0, 6.0, 500).transition  # the 3-value fit did worse: no evidence
    with pytest.raises(ValueError, match="n_residuals must exceed the 3 parameters"):
        transition_test(1.0, 0.5, 3)
    with pytest.raises(ValueError, match="cost_transition must be a finite cost >= 0, got nan"):
        transition_test(1.0, math.nan, 30)


def test_correlated_residuals_count_as_fewer_in_the_f_test() -> None:
    # the same costs, worth 40 independent residuals instead of 503: F scaled by 40/503, 37 degrees of freedom
    verdict = transition_test(200.0, 150.0, 503, n_effective=40.0)
    assert verdict.f_statistic == pytest.approx((50.0 / 2) / (150.0 / 500) * 40.0 / 503)
    assert verdict.p_value == pytest.approx(stats.f.sf(verdict.f_statistic, 2, 37))
    assert transition_test(200.0, 150.0, 503).transition and not verdict.transition
    assert "40 independent of 503 residuals" in verdict.reason
    with pytest.raises(ValueError, match="n_effective must lie in"):
        transition_test(200.0, 150.0, 503, n_effective=600.0)


@pytest.mark.parametrize("phi", [0.0, 0.5, 0.9])
def test_effective_size_gives_the_variance_of_the_mean_of_an_ar1_sequence(phi) -> None:
    """Monte Carlo reference: Var(mean of n AR(1) values) = Var(x)/n_eff, to the sampling error."""
    rng = np.random.default_rng(7)
    n, runs = 400, 3000
    e = rng.standard_normal((runs, n + 200))
    x = np.zeros_like(e)
    for t in range(1, e.shape[1]):
        x[:, t] = phi * x[:, t - 1] + e[:, t]
    x = x[:, 200:]  # stationary
    measured = x.var() / x.mean(axis=1).var()
    # pooled over two series of the 400 values: the pairs across the seam are not counted
    sizes = [effective_size(np.concatenate([x[i, :150], x[i, 150:]]), [150, 250]) for i in range(200)]
    assert np.median(sizes) == pytest.approx(measured, rel=0.15), (np.median(sizes), measured)
    with pytest.raises(ValueError, match="do not add up"):
        effective_size(x[0], [100, 100])


def test_cusum_of_the_one_value_residuals_starts_the_fit_near_the_jump(channel) -> None:
    fric = Parameter(name="ks", targets=[FG], min=15.0, max=60.0, initial=30.0, perturbation=3.0)
    t_change = channel.start + pd.Timedelta("12h")
    truth, _ = _plain(channel, [(30.0, channel.start, t_change), (45.0, t_change, channel.end)])
    _, state6 = channel.simulate({FG: 30.0}, end=channel.start + pd.Timedelta("6h"))
    window = (channel.start + pd.Timedelta("7h"), channel.end)
    problem = CalibrationProblem(channel, ParameterSet([fric]), _observations(truth, *window), window, state=state6,
                                 warmup="1h")
    single = calibrate(problem, "dud", workers=1)
    assert 33.0 < single.estimates["ks"] < 42.0  # the average of 30 (5 h) and 45 (12 h)
    runs = problem.n_runs
    start = transition_start(problem, single)
    assert problem.n_runs == runs + 1  # one run for the sensitivity
    assert start["time"] == pytest.approx(5.5)  # between the last sample before (12:00) and the first after
    assert abs(start["before"] - 30.0) < 0.3 * abs(single.estimates["ks"] - 30.0)  # most of the way back
    assert abs(start["after"] - 45.0) < 0.3 * abs(single.estimates["ks"] - 45.0)


def test_channel_jump_is_dated_and_a_steady_window_is_not_a_transition(channel) -> None:
    fric = Parameter(name="ks", targets=[FG], min=15.0, max=60.0, initial=30.0, perturbation=3.0, unit="m^(1/3)/s")
    t_change = channel.start + pd.Timedelta("12h")
    truth, _ = _plain(channel, [(30.0, channel.start, t_change), (45.0, t_change, channel.end)])
    _, state6 = channel.simulate({FG: 30.0}, end=channel.start + pd.Timedelta("6h"))
    window = (channel.start + pd.Timedelta("7h"), channel.end)
    jump = estimate_transition(channel, fric, _observations(truth, *window, "white"), window, state=state6,
                               warmup="1h")
    assert jump.test.transition, jump.test.reason
    assert abs((jump.time - t_change) / HOUR) < 0.5
    assert jump.before == pytest.approx(30.0, rel=0.02) and jump.after == pytest.approx(45.0, rel=0.02)
    unweighted = ObservationSet.from_frame(truth.loc[window[0]:window[1]], sigma={})  # thesis Eq. 2-6 weights
    eq26 = estimate_transition(channel, fric, unweighted, window, state=state6, warmup="1h")
    assert eq26.test.transition and abs((eq26.time - t_change) / HOUR) < 0.5
    assert eq26.model_runs == eq26.single.result.nfev + 1 + eq26.transition.result.nfev + 1  # S₁ re-weighted
    steady, _ = channel.simulate({FG: 30.0}, channel.start + pd.Timedelta("6h"), channel.end, state6)
    calm = estimate_transition(channel, fric, _observations(steady.series, *window, "white"), window, state=state6,
                               warmup="1h")
    assert not calm.test.transition, calm.test.reason


# -- the default case: k_s 16 → 25 at 2010-11-01 00:00 -----------------------------------------------------

CHANGE = pd.Timestamp("2010-11-01", tz="UTC")


@pytest.fixture(scope="module")
def dommel():
    sim = load_model("dommel")
    return sim, sim.calibration.parameter("FA")


def _truth(sim, run_start, end, cold_from=None):
    """The truth: 16 up to the change, then 25 from that state; state at run_start and series from there."""
    _, state = sim.simulate({FG: 16.0}, start=cold_from, end=run_start)
    r1, s1 = sim.simulate({FG: 16.0}, run_start, CHANGE, state)
    r2, _ = sim.simulate({FG: 25.0}, CHANGE, end, s1)
    return state, pd.concat([r1.series, r2.series.iloc[1:]])


def test_dud_dates_the_friction_jump_on_the_default_case(dommel) -> None:
    """Two-day window 2010-10-31 06:00 .. 11-02 06:00 (τ = 18 h), 6 h warm-up, noise-free."""
    sim, fa = dommel
    window = (pd.Timestamp("2010-10-31 06:00", tz="UTC"), pd.Timestamp("2010-11-02 06:00", tz="UTC"))
    cold = pd.Timestamp("2010-10-27", tz="UTC")  # cold start and the case's 96 h spin-up: a realistic state
    state, series = _truth(sim, window[0] - pd.Timedelta("6h"), window[1], cold_from=cold)
    est = estimate_transition(sim, fa, _observations(series, *window), window, state=state, warmup="6h",
                              options=sim.calibration.options)
    assert abs(est.time - CHANGE) < pd.Timedelta("1h"), est.summary()  # measured: 9 s late
    assert est.before == pytest.approx(16.0, rel=0.02) and est.after == pytest.approx(25.0, rel=0.02)
    assert 16.0 * 1.05 < est.single.estimates["FA"] < 25.0 * 0.95  # the one-value "average" (19.6)
    assert est.test.transition and est.transition.result.success, est.test.reason
    assert est.model_runs <= 30  # measured: 15 (6 one-value, 1 for the start, 8 three-value)


@pytest.mark.slow
def test_noisy_window_with_the_jump_dud_dates_it_and_one_value_averages_it(dommel) -> None:
    """4-day window 2010-10-30 .. 11-03 (τ = 48 h: the jump in the middle), 24 h warm-up, truth cold-started four
    days before it (as the two-day test: the case's 96 h spin-up, then four days of the real forcing), with the
    reference study's sensor noise (noise-free observations are dated by the two-day test above)."""
    sim, fa = dommel
    window = (pd.Timestamp("2010-10-30", tz="UTC"), pd.Timestamp("2010-11-03", tz="UTC"))
    cold = pd.Timestamp("2010-10-25", tz="UTC")
    state, series = _truth(sim, window[0] - pd.Timedelta("24h"), window[1], cold_from=cold)
    est = estimate_transition(sim, fa, _observations(series, *window, "white"), window, state=state,
                              options=sim.calibration.options)
    assert est.test.transition, est.test.reason
    assert abs(est.time - CHANGE) < pd.Timedelta("2h"), est.summary()
    assert est.before == pytest.approx(16.0, rel=0.02) and est.after == pytest.approx(25.0, rel=0.02)
    single = est.single.estimates["FA"]
    assert 16.0 * 1.05 < single < 25.0 * 0.95  # the "average value" of thesis §6-3: neither before nor after (19.1)


@pytest.mark.slow
def test_noisy_window_without_a_change_is_not_a_transition(dommel) -> None:
    """4-day window 2010-10-24 .. 10-28 with sensor noise, the truth k_s = 16 throughout (cold-started four days
    before the warm-up, as above)."""
    sim, fa = dommel
    window = (pd.Timestamp("2010-10-24", tz="UTC"), pd.Timestamp("2010-10-28", tz="UTC"))
    cold = pd.Timestamp("2010-10-19", tz="UTC")
    _, state = sim.simulate({FG: 16.0}, start=cold, end=window[0] - pd.Timedelta("24h"))
    result, _ = sim.simulate({FG: 16.0}, window[0] - pd.Timedelta("24h"), window[1], state)
    est = estimate_transition(sim, fa, _observations(result.series, *window, "white"), window, state=state,
                              options=sim.calibration.options, max_nfev=40)
    assert not est.test.transition, est.test.reason
    assert est.single.estimates["FA"] == pytest.approx(16.0, rel=0.02)

