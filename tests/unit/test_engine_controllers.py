"""Controllers are part of the engine state: a week in seven daily hot-started runs equals the week in one run,
and a state stored as bytes continues the controllers exactly."""

from __future__ import annotations

import tomllib

import numpy as np
import pandas as pd
import pytest

from rivercal.case import case_from_dict
from rivercal.case.load import resolve_case_path
from rivercal.engine import Simulator
from rivercal.engine.kernels.control import N_STATE, S_INTEGRAL, S_STARTED, S_TIMER
from rivercal.engine.state import EngineState
from rivercal.models import build_model
from rivercal.models.contract import check_parameters
from rivercal.parameters import ClusterTarget, Parameter, ParameterSet


def controlled_synthetic() -> Simulator:
    """The synthetic case with one controller of each kind (PID, interval, time table, relation)."""
    root = resolve_case_path("synthetic")
    data = tomllib.loads((root / "case.toml").read_text(encoding="utf-8"))
    data["controllers"] = [
        {"id": "P2", "type": "pid", "weir": "W2", "measure": "S1.h_up", "setpoint": 13.15, "kp": 0.5, "ki": 2e-4,
         "kd": 60.0, "min": 12.5, "max": 13.1, "max_speed": 0.02},
        {"id": "I5", "type": "interval", "weir": "W5", "measure": "S2.h_up", "setpoint": 8.65, "dead_band": 0.04,
         "step": 0.02, "interval": 900.0, "min": 8.0, "max": 8.6, "max_speed": 0.005},
        {"id": "T7", "type": "time", "weir": "W7", "min": 7.9, "max": 8.4,
         "table": {"times": ["2020-01-01T00:00:00Z", "2020-01-04T12:00:00Z"], "values": [8.257, 8.05],
                   "interpolation": "block"}},
        {"id": "R10", "type": "relation", "weir": "W10", "measure": "S4.Q", "min": 4.3, "max": 4.9,
         "table": {"x": [1.5, 5.0, 10.0], "crest": [4.8, 4.6, 4.4]}},
    ]
    return Simulator(case_from_dict(data, root))


@pytest.fixture(scope="module")
def sim() -> Simulator:
    return controlled_synthetic()


def test_a_week_in_seven_daily_hot_started_runs_equals_the_week(sim: Simulator) -> None:
    start = sim.start
    end = start + pd.Timedelta(days=7)
    params = {"control:P2.setpoint": 13.16, "control:I5.setpoint": 8.64}
    whole, final = sim.simulate(params, start=start, end=end)
    crests = whole.series[["W2.crest", "W5.crest", "W7.crest", "W10.crest"]]
    for name in crests:  # every controller acted within the week
        assert np.ptp(crests[name].to_numpy()) > 0.01, name
    _, state = sim.simulate(params, start=start, end=start)  # the spun-up state at the start
    pieces = []
    for day in range(7):
        a = start + pd.Timedelta(days=day)
        part, state = sim.simulate(params, start=a, end=a + pd.Timedelta(days=1), state=state)
        pieces.append(part.series if day == 0 else part.series.iloc[1:])
    split = pd.concat(pieces)
    assert split.index.equals(whole.series.index)
    assert np.array_equal(split.to_numpy(), whole.series.to_numpy())  # to the last bit
    for name in ("z", "q", "ctl"):
        assert np.array_equal(getattr(state, name), getattr(final, name)), name
    assert np.all(final.ctl[:, S_STARTED] == 1.0) and final.ctl[0, S_INTEGRAL] != 0.0
    assert 0.0 <= final.ctl[1, S_TIMER] < 900.0


def test_controller_state_survives_bytes_and_is_checked(sim: Simulator) -> None:
    start = sim.start + pd.Timedelta(days=1)
    _, state = sim.simulate(None, end=start)
    back = EngineState.from_bytes(state.to_bytes())
    assert back.ctl.shape == (4, N_STATE) and np.array_equal(back.ctl, state.ctl)
    a, _ = sim.simulate(None, start=start, end=start + pd.Timedelta(hours=6), state=state)
    b, _ = sim.simulate(None, start=start, end=start + pd.Timedelta(hours=6), state=back)
    assert np.array_equal(a.series.to_numpy(), b.series.to_numpy())
    stripped = back.copy()
    stripped.ctl = np.zeros((0, N_STATE))
    with pytest.raises(ValueError, match="holds 0 controllers, the case has 4"):
        sim.simulate(None, start=start, end=start + pd.Timedelta(hours=6), state=stripped)


def test_a_calibrated_setpoint_moves_the_controlled_level(sim: Simulator) -> None:
    end = sim.start + pd.Timedelta(days=3)
    base, _ = sim.simulate(None, end=end)
    up, _ = sim.simulate({"control:P2.setpoint": 13.25}, end=end)
    # the PID holds the upstream level at its setpoint while the crest is within its limits: 10 cm higher
    held = (base.series["W2.crest"] > 12.55) & (up.series["W2.crest"] < 13.05)
    late = base.series.index > sim.start + pd.Timedelta(days=1)
    diff = (up.series["S1.h_up"] - base.series["S1.h_up"])[held & late]
    assert diff.size > 10 and np.allclose(diff, 0.10, atol=0.01)


def test_the_embedded_model_declares_controller_quantities_and_simulates_the_crests() -> None:
    model = build_model(controlled_synthetic().case)
    q = model.quantities
    assert q["control:P2.setpoint"].unit == "m AD" and q["control:P2.ki"].unit == "1/s"
    assert q["control:T7.value:2"].unit == "m AD" and q["control:R10.value:3"].unit == "m AD"
    assert "weir:W2.crest_level" not in q and "weir:W3.crest_level" in q  # a controlled crest is no target
    assert {"W2.crest", "W5.crest", "W7.crest", "W10.crest"} <= set(model.observables)
    # a shift cluster moves two setpoints together, as it moves weir crests
    shift = Parameter(name="S", cluster=[
        ClusterTarget(target="control:P2.setpoint", min=12.9, max=13.4, base=13.15),
        ClusterTarget(target="control:I5.setpoint", min=8.4, max=8.9, base=8.65)],
        cluster_mode="shift", min=-0.2, max=0.2, initial=0.0, perturbation=0.05)
    check_parameters(model, ParameterSet([shift]), {})
    assert shift.quantities(0.1) == pytest.approx({"control:P2.setpoint": 13.25, "control:I5.setpoint": 8.75})
    end = model.start + pd.Timedelta(days=2)
    moved, _ = model.simulate(shift.quantities(0.1), end=end)
    same, _ = model.simulate({"control:P2.setpoint": 13.25, "control:I5.setpoint": 8.75}, end=end)
    assert np.array_equal(moved.series.to_numpy(), same.series.to_numpy())
    with pytest.raises(KeyError, match="no controller 'X'"):
        model.simulate({"control:X.setpoint": 1.0}, end=end)


def test_the_crests_reach_the_netcdf_output(sim: Simulator, tmp_path) -> None:
    import xarray as xr

    result, _ = sim.simulate(None, end=sim.start + pd.Timedelta(hours=6))
    result.to_netcdf(tmp_path / "series.nc")
    with xr.open_dataset(tmp_path / "series.nc") as ds:
        assert list(ds["crest_series"].values) == ["W2.crest", "W5.crest", "W7.crest", "W10.crest"]
        assert ds["crest_level"].attrs["units"] == "m"
        assert np.array_equal(ds["crest_level"].values.T, result.series[list(ds["crest_series"].values)].to_numpy())
