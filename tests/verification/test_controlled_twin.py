"""Twin experiments on the controlled default case (``dommel-controlled``): known truth, noise-free observations
of every station series (levels and discharge; the crests are not observed), DuD with the case's stopping rules.

- A water manager raises the setpoint of W2 (ZL1-3014, station 0028) by 10 cm while the friction changes by
  20 %, in the same window: both are found back (setpoint within 1 cm, friction within 2 %).
- The controllers act (crests lowered through the November flood) and the friction has not changed: a
  calibration of the friction alone reports no change (within 2 %), while the same calibration on the
  fixed-crest model reads the controllers' action as a friction change.
- On line (scenario PI-SF): the same two changes at one moment are followed from window to window, the
  controllers' state carried in the hot-started engine state.
"""

from __future__ import annotations

import pandas as pd
import pytest

from rivercal.model import load_model
from rivercal.models.contract import spun_up
from rivercal.online.service import OnlineConfig
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from rivercal.twin import twin_truth
from rivercal.workflows.online import run_online

pytestmark = pytest.mark.slow

FA0, S20 = 16.0, 10.56  # the case's friction (m^(1/3)/s) and W2's setpoint (m AD)


@pytest.fixture(scope="module")
def model():
    return load_model("dommel-controlled")


def _problem(model, names, truth, window, start):
    params = {p.name: p for p in model.calibration.parameters}
    levels = [s for s in model.observables if not s.endswith(".crest")]
    quantities = ParameterSet([params[n] for n in truth]).quantities(truth)
    made = twin_truth(model, quantities, model.calibration.windows[window], series=levels)
    chosen = ParameterSet([params[n] for n in names]).with_initial(start)
    return made, CalibrationProblem(model, chosen, made.observations, model.calibration.windows[window],
                                    state=made.state)


def test_a_setpoint_change_and_a_friction_change_in_one_window_are_both_recovered(model) -> None:
    truth = {"FA": FA0 * 1.2, "S2": S20 + 0.10}
    _, problem = _problem(model, ["FA", "S2"], truth, "moderate", {"FA": FA0, "S2": S20})
    cal = calibrate(problem, "dud", dict(model.calibration.options), workers=1)
    assert abs(cal.estimates["S2"] - truth["S2"]) <= 0.01
    assert abs(cal.estimates["FA"] / truth["FA"] - 1.0) <= 0.02


def test_friction_alone_reports_no_change_while_the_controllers_act(model) -> None:
    made, problem = _problem(model, ["FA"], {"FA": FA0}, "extreme", {"FA": FA0})
    window = model.calibration.windows["extreme"]
    crest = made.series.loc[window[0]:window[1], "ZL1-3014.crest"]
    assert crest.max() - crest.min() > 0.2  # W2 moved its crest by more than 20 cm in the window
    cal = calibrate(problem, "dud", dict(model.calibration.options), workers=1)
    assert abs(cal.estimates["FA"] / FA0 - 1.0) <= 0.02

    # the fixed-crest default case, calibrated on the same observations, mistakes the control for friction
    fixed = load_model("dommel")
    params = {p.name: p for p in fixed.calibration.parameters}
    state = spun_up(fixed, None, made.run_start)  # its cold start run to the window's runs (kept by this machine)
    wrong = CalibrationProblem(fixed, ParameterSet([params["FA"]]).with_initial({"FA": FA0}), made.observations,
                               window, state=state)
    misread = calibrate(wrong, "dud", dict(fixed.calibration.options), workers=1)
    assert abs(misread.estimates["FA"] / FA0 - 1.0) > 0.05


def test_the_controlled_case_holds_its_targets_and_its_water(model) -> None:
    result, _ = model.simulate(None)
    series = result.series
    assert abs(result.balance.residual) <= 1e-6 * result.balance.throughput
    # W2's PID holds station 0028 at its setpoint on most days (the crest reaches its lower limit in floods)
    level = series["0028.h_up"]
    assert abs(level.median() - S20) <= 0.01 and (abs(level - S20) <= 0.03).mean() >= 0.9
    # W9 follows its summer/winter table: 4.60 m AD until 15 October, 4.45 m AD after
    crest = series["ZL25-8463.crest"]
    assert (crest[:"2010-10-14T23:00Z"] == 4.6).all() and (crest["2010-10-15T01:00Z":] == 4.45).all()
    for spec in model.controls.specs:  # every crest within its Table 4-2 range
        values = series[f"{spec.weir}.crest"]
        assert spec.min <= values.min() and values.max() <= spec.max, spec.id


def test_the_online_service_follows_a_setpoint_change_during_a_friction_change(model, tmp_path) -> None:
    # PI-SF: on 1 November the water manager raises W2's target level by 0.10 m and the friction rises by 20 %;
    # the service (2-day windows, a cycle every 2 days) estimates FA and S2 and carries the controllers from one
    # window to the next in its hot-started engine state
    config = OnlineConfig(parameters=("FA", "S2"), window="2D", period="2D", horizon="12h", warmup="12h",
                          workers=1, deadline_s=None)
    summary = run_online(model, tmp_path / "store.db", "pi-sf", config, pd.Timestamp("2010-11-01T00:00Z"),
                         pd.Timestamp("2010-11-03T00:00Z"), scenario="PI-SF")
    assert len(summary["estimates"]) == 2
    last = summary["estimates"][-1]
    assert abs(last["S2"] - (S20 + 0.10)) <= 0.01
    assert abs(last["FA"] / (FA0 * 1.2) - 1.0) <= 0.02
    first = summary["estimates"][0]  # the window before the change: nothing to estimate yet
    assert abs(first["S2"] - S20) <= 0.01 and abs(first["FA"] / FA0 - 1.0) <= 0.02
