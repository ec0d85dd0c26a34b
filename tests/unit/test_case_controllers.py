"""``[[controllers]]`` of a case: bad entries fail at load naming the file, field and problem; time tables and
calibration targets of controllers behave as documented."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.case import load_case
from rivercal.case.controllers import TimeTable
from rivercal.engine import Simulator
from rivercal.engine.controllers import table_at
from rivercal.engine.kernels import codes, control
from tests.unit.test_case_validation import expect, load_error, mini_case, write_case


def _pid(**extra) -> dict:
    """A PID controller entry; a keyword set to None leaves that field out."""
    pid = {"id": "C1", "type": "pid", "weir": "W1", "measure": "SW1.h_up", "setpoint": 4.6, "kp": 1.0,
           "ki": 1e-4, "min": 4.0, "max": 4.8, **extra}
    return {k: v for k, v in pid.items() if v is not None}


def _with(*controllers: dict, parameters: list | None = None) -> dict:
    data = mini_case()
    data["controllers"] = list(controllers)
    if parameters:
        data["parameters"] = parameters
    return data


def test_kernel_codes_agree() -> None:
    assert control.OBS_LEVEL == codes.OBS_LEVEL


def test_a_controlled_case_loads_runs_and_simulates_the_crest(tmp_path: Path) -> None:
    data = _with(_pid(max_speed=0.01),
                 {"id": "C2", "type": "time", "weir": "W2", "min": 3.0, "max": 3.6,
                  "table": {"times": ["2020-01-01T00:00:00Z", "2020-01-01T12:00:00Z"], "values": [3.3, 3.5]}})
    sim = Simulator(load_case(write_case(tmp_path, data)))
    result, state = sim.simulate()
    assert "W1.crest" in result.series and "W2.crest" in result.series
    assert state.ctl.shape == (2, control.N_STATE)
    # the time table, linear, reached at the end of each step: the value at each output time
    expected = np.interp((result.series.index - sim.start).total_seconds(), [0, 43200], [3.3, 3.5])
    assert np.allclose(result.series["W2.crest"].to_numpy()[1:], expected[1:], atol=1e-12)
    assert sim.default_parameters()["control:C1.setpoint"] == 4.6


@pytest.mark.parametrize(("change", "field", "phrases"), [
    ({"weir": "W9"}, "controllers[0].weir", ("unknown weir 'W9'",)),
    ({"measure": "SW1.h"}, "controllers[0].measure", ("station 'SW1' has no series 'SW1.h'",)),
    ({"measure": "X9.h_up"}, "controllers[0].measure", ("neither a station nor a structure",)),
    ({"min": 5.0}, "controllers[0].max", ("must be above min",)),
    ({"setpoint": None}, "controllers[0].setpoint", ("needs a setpoint or a setpoint_table",)),
    ({"max_speed": -1.0}, "controllers[0].max_speed", ("greater than 0",)),
])
def test_bad_controller_names_the_field(tmp_path: Path, change: dict, field: str, phrases: tuple) -> None:
    pid = {k: v for k, v in {**_pid(), **change}.items() if v is not None}
    expect(load_error(tmp_path, _with(pid)), "case.toml", field, *phrases)


def test_misspelt_controller_field_gets_a_suggestion(tmp_path: Path) -> None:
    pid = _pid(setpoint=None)
    pid["setpont"] = 4.6
    expect(load_error(tmp_path, _with(pid)), "case.toml", "controllers[0].setpont", "did you mean 'setpoint'?")


def test_unknown_controller_type(tmp_path: Path) -> None:
    expect(load_error(tmp_path, _with(_pid(type="fuzzy"))), "case.toml", "controllers[0].type",
           "unknown controller type 'fuzzy'", "'pid', 'interval', 'time' or 'relation'")


def test_two_controllers_on_one_weir_and_bad_tables(tmp_path: Path) -> None:
    expect(load_error(tmp_path, _with(_pid(), _pid(id="C2"))), "case.toml", "controllers[1].weir",
           "already driven by controller 'C1'")
    table = {"times": ["2020-01-01T06:00:00Z", "2020-01-01T00:00:00Z"], "values": [4.5, 4.6]}
    expect(load_error(tmp_path, _with(_pid(setpoint=None, setpoint_table=table))), "case.toml",
           "controllers[0].setpoint_table.times[1]", "must increase strictly")
    table = {"times": ["2020-01-01T00:00:00Z"], "values": [4.5, 4.6]}
    expect(load_error(tmp_path, _with(_pid(setpoint=None, setpoint_table=table))), "case.toml",
           "controllers[0].setpoint_table.values", "2 values for 1 times")
    bad = {"id": "R", "type": "relation", "weir": "W1", "measure": "SC1.Q", "min": 4.0, "max": 4.8,
           "table": {"x": [1.0, 0.5], "crest": [4.6, 4.2]}}
    expect(load_error(tmp_path, _with(bad)), "case.toml", "controllers[0].table.x[1]", "must increase strictly")


def test_controller_targets_of_parameters_are_checked(tmp_path: Path) -> None:
    def param(target: str) -> list:
        return [{"name": "P", "targets": [target], "min": 0.0, "max": 10.0, "initial": 4.6, "perturbation": 0.1}]

    expect(load_error(tmp_path, _with(_pid(), parameters=param("control:C9.setpoint"))), "case.toml",
           "parameters[0].targets[0]", "unknown controller 'C9'")
    expect(load_error(tmp_path, _with(_pid(), parameters=param("control:C1.value:1"))), "case.toml",
           "parameters[0].targets[0]", "has no table")
    expect(load_error(tmp_path, _with(_pid(), parameters=param("weir:W1.crest_level"))), "case.toml",
           "parameters[0].targets[0]", "driven by controller 'C1'")
    case = load_case(write_case(tmp_path, _with(_pid(), parameters=param("control:C1.setpoint"))))
    sim = Simulator(case)
    with pytest.raises(KeyError, match="a pid controller's quantities are"):
        sim.simulate({"control:C1.dead_band": 1.0})


def test_time_table_interpolation_and_yearly_repeat() -> None:
    table = TimeTable(times=["2019-04-15T00:00:00Z", "2019-10-15T00:00:00Z"], values=[2.0, 1.6],
                      interpolation="block", repeat="yearly")
    at = pd.DatetimeIndex(["2020-01-10", "2020-04-14T23:00", "2020-04-15", "2021-07-01", "2021-10-16"], tz="UTC")
    seconds = at.as_unit("ns").asi8 / 1e9
    assert table_at(table, np.array([2.0, 1.6]), seconds).tolist() == [1.6, 1.6, 2.0, 2.0, 1.6]
    linear = table.model_copy(update={"interpolation": "linear"})
    mid = pd.Timestamp("2019-07-15T00:00:00Z")
    frac = (mid - pd.Timestamp("2019-04-15T00:00:00Z")) / (pd.Timestamp("2019-10-15T00:00:00Z")
                                                            - pd.Timestamp("2019-04-15T00:00:00Z"))
    got = table_at(linear, np.array([2.0, 1.6]), np.array([mid.value / 1e9]))
    assert got[0] == pytest.approx(2.0 - 0.4 * frac, abs=1e-12)
