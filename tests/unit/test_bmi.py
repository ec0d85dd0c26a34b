"""BMI both ways: the embedded engine as a bmipy component (checked against the engine's own runs; CSDMS's
bmi-tester, a command, checks it in tests/integration/test_in_other_processes.py), and any BMI component behind
the model contract (calibrated in a twin with known truth).
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from bmipy import Bmi

from rivercal.models import load_model
from rivercal.models.bmi import BmiModel, RivercalBmi
from rivercal.models.bmi.engine import (
    BED,
    CREST,
    DISCHARGE,
    FRICTION,
    INFLOW_FACTOR,
    LEVEL,
    LEVEL_CHANGE,
    VELOCITY,
    VOLUME,
)
from rivercal.observations import ObservationSet
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem, calibrate

START = pd.Timestamp("2020-01-02", tz="UTC")
END = pd.Timestamp("2020-01-04", tz="UTC")
HOUR = 3600.0


@pytest.fixture
def config(tmp_path) -> Path:
    path = tmp_path / "engine.toml"
    path.write_text(f'case = "synthetic"\nstart = "{START.isoformat()}"\nend = "{END.isoformat()}"\n')
    return path


@pytest.fixture(scope="module")
def synthetic():
    return load_model("synthetic")


def test_update_until_reproduces_the_engine_and_set_value_changes_it(config, synthetic) -> None:
    bmi = RivercalBmi()
    assert isinstance(bmi, Bmi)
    bmi.initialize(str(config))
    assert (bmi.get_start_time(), bmi.get_current_time(), bmi.get_time_units()) == (0.0, 0.0, "s")
    assert bmi.get_time_step() == 60.0 and bmi.get_end_time() == 2 * 86400.0
    c = synthetic.compiled
    level = bmi.get_value_ptr(LEVEL)
    reference, _ = synthetic.simulate({}, start=START, end=START + pd.Timedelta("6h"),
                                      state=synthetic.start_state(START))
    k1 = c.arrays.lk_k1[c.structure_link["W2"]]
    bmi.update()
    assert bmi.get_current_time() == 60.0
    bmi.update_until(6 * HOUR + 30.0)  # whole steps only: stops at 6 h
    assert bmi.get_current_time() == 6 * HOUR
    assert level is bmi.get_value_ptr(LEVEL)  # the pointer stays valid and holds the new levels
    assert level[k1] == pytest.approx(reference.series["S1.h_up"].iloc[-1], abs=1e-12)
    out = np.empty(1)
    bmi.get_value_at_indices(LEVEL, out, np.array([k1]))
    assert out[0] == level[k1]
    q = np.empty(bmi.get_var_nbytes(DISCHARGE) // bmi.get_var_itemsize(DISCHARGE))
    bmi.get_value(DISCHARGE, q)
    assert q[c.structure_link["W2"]] == pytest.approx(reference.series["S1.Q"].iloc[-1], abs=1e-12)
    # crest and friction: set through BMI, they move the engine as the same quantities do
    w2 = list(c.weir_ids).index("W2")
    bmi.set_value_at_indices(CREST, np.array([w2]), np.array([13.0]))
    friction = np.empty(len(c.branch_ids))
    bmi.get_value(FRICTION, friction)
    assert friction[list(c.branch_ids).index("B")] == 0.04  # branch B keeps its Manning value
    bmi.set_value(FRICTION, np.where(np.arange(friction.size) == list(c.branch_ids).index("M"), 20.0, friction))
    _, state6 = synthetic.simulate({}, start=START, end=START + pd.Timedelta("6h"), state=synthetic.start_state(START))
    changed, _ = synthetic.simulate({"weir:W2.crest_level": 13.0, "friction:branch:M": 20.0},
                                    start=START + pd.Timedelta("6h"), end=START + pd.Timedelta("12h"), state=state6)
    bmi.update_until(12 * HOUR)
    assert level[k1] == pytest.approx(changed.series["S1.h_up"].iloc[-1], abs=1e-12)
    assert bmi.get_var_units(FRICTION) == "m1/3 s-1" and bmi.get_var_units(DISCHARGE) == "m3 s-1"
    assert [bmi.get_var_location(v) for v in (LEVEL, VOLUME, LEVEL_CHANGE, DISCHARGE, VELOCITY)] == [
        "node", "node", "node", "edge", "edge"]
    assert bmi.get_var_type(LEVEL) == "float64" and bmi.get_input_item_count() + 1 == bmi.get_output_item_count() == 9
    with pytest.raises(ValueError, match="past the end"):
        bmi.update_until(3 * 86400.0)
    bmi.finalize()


def test_the_grid_is_the_network(config, synthetic) -> None:
    bmi = RivercalBmi()
    bmi.initialize(str(config))
    c = synthetic.compiled
    n, m = c.n_hpoints, c.n_links
    assert (bmi.get_grid_type(0), bmi.get_grid_rank(0), bmi.get_grid_node_count(0), bmi.get_grid_edge_count(0),
            bmi.get_grid_face_count(0)) == ("unstructured", 2, n, m, 0)
    assert bmi.get_var_grid(LEVEL) == bmi.get_var_grid(DISCHARGE) == 0
    edges = np.empty(2 * m, dtype=np.int32)
    bmi.get_grid_edge_nodes(0, edges)
    np.testing.assert_array_equal(edges.reshape(-1, 2), np.column_stack([c.arrays.lk_k1, c.arrays.lk_k2]))
    x, y, z = np.empty(n), np.empty(n), np.empty(n)
    np.testing.assert_array_equal(bmi.get_grid_x(0, x), c.hp_xy[:, 0])
    np.testing.assert_array_equal(bmi.get_grid_y(0, y), c.hp_xy[:, 1])
    np.testing.assert_array_equal(bmi.get_grid_z(0, z), c.arrays.hp_bed)
    assert bmi.get_grid_size(1) == len(c.weir_ids) and bmi.get_grid_size(2) == len(c.branch_ids)
    for fill in (bmi.get_grid_face_edges, bmi.get_grid_face_nodes, bmi.get_grid_nodes_per_face):
        assert fill(0, np.empty(0, dtype=np.int32)).size == 0
    for method in (bmi.get_grid_shape, bmi.get_grid_spacing, bmi.get_grid_origin):
        with pytest.raises(NotImplementedError):
            method(0, np.empty(2))
    with pytest.raises(KeyError, match="unknown BMI variable"):
        bmi.get_var_grid("water")


def _bmi_model(tmp_path: Path, synthetic, *, assimilate: bool = False) -> BmiModel:
    c = synthetic.compiled
    link = c.structure_link["W2"]
    (tmp_path / "engine.toml.tmpl").write_text('case = "synthetic"\nstart = "{{run_start}}"\nend = "{{end}}"\n')
    state = [LEVEL, VOLUME, LEVEL_CHANGE, DISCHARGE, VELOCITY]
    (tmp_path / "model.toml").write_text(textwrap.dedent(f'''\
        [model]
        name = "synthetic-bmi"
        kind = "bmi"
        start = "2020-01-01T00:00:00Z"
        end = "2020-01-15T00:00:00Z"
        output_interval = 3600

        [bmi]
        component = "rivercal.models.bmi.engine:RivercalBmi"
        config = "engine.toml.tmpl"
        state = {state!r}

        [bmi.quantities.crest_W2]
        var = "{CREST}"
        index = {list(c.weir_ids).index("W2")}
        unit = "m"

        [bmi.quantities.ks_M]
        var = "{FRICTION}"
        index = {list(c.branch_ids).index("M")}
        unit = "m^(1/3)/s"
        min = 5
        max = 60

        [bmi.stations]
        "S1.h_up" = {{ var = "{LEVEL}", index = {c.arrays.lk_k1[link]} }}
        "S1.h_down" = {{ var = "{LEVEL}", index = {c.arrays.lk_k2[link]} }}
        "S1.Q" = {{ var = "{DISCHARGE}", index = {link} }}
        ''').replace("'", '"') + _PARAMETERS + (_ASSIMILATE if assimilate else ""))
    return load_model(tmp_path / "model.toml")


#: The variables of state updating, and the scale factor of every inflow and lateral of the synthetic case.
_ASSIMILATE = textwrap.dedent(f'''\
    [bmi.assimilate]
    levels = "{LEVEL}"
    discharges = "{DISCHARGE}"
    floor = "{BED}"
    derived = ["{VOLUME}", "{VELOCITY}"]
    ''') + "".join(f'[bmi.assimilate.forcing."{key}"]\nvar = "{INFLOW_FACTOR}"\nindex = {k}\n'
                     for k, key in enumerate(("boundary:Qup", "boundary:Qtrib",
                                              *(f"lateral:L{i}" for i in range(1, 11)))))
#: A calibration parameter of the model (the on-line service estimates the model's own parameters).
_PARAMETERS = textwrap.dedent('''\
    [[parameters]]
    name = "W2"
    targets = ["crest_W2"]
    min = 12.5
    max = 13.5
    initial = 12.85
    perturbation = 0.05
    unit = "m"
    ''')


def test_any_bmi_component_is_calibrated_through_the_adapter(tmp_path, synthetic) -> None:
    model = _bmi_model(tmp_path, synthetic)
    assert isinstance(model, BmiModel) and model.dt == 60.0
    assert model.default_parameters()["crest_W2"] == pytest.approx(12.85)
    # the adapter's runs are the engine's: a hot-started day equals the embedded model's
    _, state = synthetic.simulate({}, end=START)
    bmi_state = model.load_state(model.save_state(model_state(model, synthetic, state)), model.state_format)
    truth_q = {"crest_W2": 12.95, "ks_M": 28.0}
    engine_q = {"weir:W2.crest_level": 12.95, "friction:branch:M": 28.0}
    got, end_state = model.simulate(truth_q, start=START, end=START + pd.Timedelta("1D"), state=bmi_state)
    want, _ = synthetic.simulate(engine_q, start=START, end=START + pd.Timedelta("1D"), state=state)
    np.testing.assert_allclose(got.series.to_numpy(), want.series[model.observables].to_numpy(), atol=1e-10)
    assert end_state.time == START + pd.Timedelta("1D")
    # a twin through BMI: DuD finds crest and friction back
    obs = ObservationSet.from_frame(got.series.iloc[6:], sigma={"h_up": 0.01, "h_down": 0.01, "Q": 0.01})
    params = ParameterSet([Parameter(name="W2", targets=["crest_W2"], min=12.5, max=13.5, initial=12.85,
                                     perturbation=0.05),
                           Parameter(name="KM", targets=["ks_M"], min=10, max=50, initial=22, perturbation=2)])
    problem = CalibrationProblem(model, params, obs, (START + pd.Timedelta("6h"), START + pd.Timedelta("1D")),
                                 state=bmi_state, warmup="6h")
    cal = calibrate(problem, "dud", workers=1)
    assert cal.estimates["W2"] == pytest.approx(12.95, abs=1e-4)
    assert cal.estimates["KM"] == pytest.approx(28.0, rel=1e-3)


def model_state(model: BmiModel, synthetic, state):
    """The engine state as the adapter's BMI state (its five state variables)."""
    from rivercal.models.bmi import BmiState

    return BmiState(state.time, {LEVEL: state.z, VOLUME: state.vol, LEVEL_CHANGE: state.dz, DISCHARGE: state.q,
                                 VELOCITY: state.u})


def test_a_bmi_model_updates_its_state_as_the_engine_does(tmp_path, synthetic) -> None:
    """[bmi.assimilate]: the levels and discharges through get_value/set_value are the engine's own arrays."""
    from rivercal.models.capabilities import CAPABILITIES, has_capability

    plain = _bmi_model(tmp_path, synthetic)
    assert not has_capability(plain, "state arrays") and not has_capability(plain, "perturbable forcing")
    model = _bmi_model(tmp_path, synthetic, assimilate=True)
    assert {n for n in CAPABILITIES if has_capability(model, n)} == {"state arrays", "perturbable forcing"}
    assert model.perturbable_forcing() == synthetic.perturbable_forcing()
    layout, engine = model.state_layout(), synthetic.state_layout()
    assert np.array_equal(layout.link_ends, engine.link_ends) and np.array_equal(layout.floor, engine.floor)
    assert layout.places == {k: engine.places[k] for k in model.observables}
    assert layout.forcing_places == engine.forcing_places
    _, state = synthetic.simulate({}, end=START)
    bmi_state = model_state(model, synthetic, state)
    z, q = model.state_arrays(bmi_state)
    assert np.array_equal(z, state.z) and np.array_equal(q, state.q)
    # written back: levels 5 cm up, discharges 10 % up; through BMI and in the engine, the runs agree
    written = model.with_state_arrays(bmi_state, z + 0.05, 1.1 * q)
    assert VOLUME not in written.values and VELOCITY not in written.values   # the component derives them
    engine_written = synthetic.with_state_arrays(state, state.z + 0.05, 1.1 * state.q)
    factors = np.full((6, len(synthetic.perturbable_forcing())), 1.3)
    end = START + pd.Timedelta("6h")
    got, _ = model.simulate_perturbed({}, START, end, written, factors, 3600.0)
    want, _ = synthetic.simulate_perturbed({}, START, end, engine_written, factors, 3600.0)
    np.testing.assert_allclose(got.series.to_numpy(), want.series[model.observables].to_numpy(), atol=1e-6)
    base, _ = synthetic.simulate({}, start=START, end=end, state=engine_written)
    assert (want.series["S1.Q"].iloc[1:] > base.series["S1.Q"].iloc[1:]).all()   # 30 % more inflow arrives
