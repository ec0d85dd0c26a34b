"""The model contract: declared quantities, calibration setup, states as bytes — and who relies on them."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rivercal.models import EmbeddedModel, FileState, Model, Quantity, build_model, load_model
from rivercal.models.contract import check_parameters
from rivercal.observations import ObservationSet
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem


@pytest.fixture(scope="module")
def synthetic() -> EmbeddedModel:
    return load_model("synthetic")


def test_the_embedded_model_declares_its_quantities_with_units_and_bounds(synthetic) -> None:
    assert isinstance(synthetic, Model)
    q = synthetic.quantities
    weirs = [k for k in q if k.startswith("weir:")]
    assert len(weirs) == 11 and q["weir:W1.crest_level"].unit == "m AD"
    assert (q["friction:global"].unit, q["friction:global"].min, q["friction:global"].max) == ("m^(1/3)/s", 1.0, 200.0)
    # branch B has its own Manning friction: its quantity carries Manning's unit and range
    assert (q["friction:branch:B"].unit, q["friction:branch:B"].min) == ("s/m^(1/3)", 0.005)
    assert set(synthetic.default_parameters()) <= set(q)
    assert synthetic.dt == 60.0 and synthetic.output_interval == 3600.0 and synthetic.name == "synthetic"


def test_the_embedded_state_round_trips_and_refuses_another_grid(synthetic, tmp_path) -> None:
    _, state = synthetic.simulate({}, end=synthetic.start + pd.Timedelta("2h"))
    data = synthetic.save_state(state)
    again = synthetic.load_state(data, synthetic.state_format)
    np.testing.assert_array_equal(again.z, state.z)
    assert again.time == state.time
    dommel = load_model("dommel")
    with pytest.raises(ValueError, match="another grid"):
        dommel.load_state(data, synthetic.state_format)
    with pytest.raises(ValueError, match="format"):
        synthetic.load_state(data, "swmm-hotstart")


def test_the_calibration_setup_comes_from_case_toml() -> None:
    dommel = load_model("dommel")
    setup = dommel.calibration
    assert "FA" in setup.names and setup.parameter("Wd").cluster_mode == "shift"
    assert setup.windows["moderate"] == (pd.Timestamp("2010-09-27", tz="UTC"), pd.Timestamp("2010-10-04", tz="UTC"))
    assert setup.algorithm == "dud" and setup.options["max_outer"] == 20
    with pytest.raises(KeyError, match="unknown parameter 'XX'"):
        setup.parameter("XX")


def test_parameters_may_target_only_declared_quantities_within_their_bounds(synthetic) -> None:
    ok = Parameter(name="FA", targets=["friction:global"], min=10, max=40, initial=25, perturbation=1)
    check_parameters(synthetic, [ok])
    typo = Parameter(name="FA", targets=["friction:globl"], min=10, max=40, initial=25, perturbation=1)
    with pytest.raises(ValueError, match="parameter FA: model 'synthetic' has no settable quantity 'friction:globl'"):
        check_parameters(synthetic, [typo])
    wide = Parameter(name="FA", targets=["friction:global"], min=0.5, max=40, initial=25, perturbation=1)
    with pytest.raises(ValueError, match=r"parameter FA: its range \[0.5, 40\].*friction:global: value 0.5"):
        check_parameters(synthetic, [wide])
    with pytest.raises(ValueError, match=r"fixed quantity: .* 'weir:W99\.crest_level'"):
        check_parameters(synthetic, [ok], fixed=["weir:W99.crest_level"])
    # the calibration problem checks before any run
    obs = ObservationSet.from_frame(pd.DataFrame({"S1.h_up": [10.0, 10.1]}, index=pd.date_range(
        synthetic.start + pd.Timedelta("1D"), periods=2, freq="h")))
    window = (synthetic.start + pd.Timedelta("1D"), synthetic.start + pd.Timedelta("2D"))
    with pytest.raises(ValueError, match="no settable quantity 'friction:globl'"):
        CalibrationProblem(synthetic, ParameterSet([typo]), obs, window)


def test_a_parameter_target_is_any_quantity_name_but_no_free_text() -> None:
    for name in ("roughness:factor", "conduit:C1.roughness", "FA", "weir:W-3.crest_level", "a/b"):
        Parameter(name="P", targets=[name], min=0, max=1, initial=0.5, perturbation=0.1)
    for bad in ("1abc", "friction global", "x;y", "{{FA}}", "", "a'b"):
        with pytest.raises(ValueError):
            Parameter(name="P", targets=[bad], min=0, max=1, initial=0.5, perturbation=0.1)


def test_a_case_parameter_must_target_the_embedded_engine(tmp_path) -> None:
    from rivercal.case import case_from_dict
    from rivercal.errors import CaseError
    from tests.conftest import channel_case

    spec = channel_case(days=1.0)
    spec["parameters"] = [{"name": "R", "targets": ["roughness:factor"], "min": 0.5, "max": 2, "initial": 1,
                           "perturbation": 0.1}]
    with pytest.raises(CaseError, match=r"parameters\[0\].targets\[0\].*'roughness:factor' is not a quantity of the "
                                        "embedded engine"):
        case_from_dict(spec, tmp_path)


def test_a_file_state_keeps_its_files_time_and_origin() -> None:
    t = pd.Timestamp("2020-01-02T03:00", tz="UTC")
    s = FileState(time=t, files={"model.hsf": b"\x00\x01binary", "b.txt": b"text"}, origin="swmm:demo")
    back = FileState.from_bytes(s.to_bytes(), origin="swmm:demo")
    assert back == s
    with pytest.raises(ValueError, match="written by 'swmm:demo', not by 'swmm:other'"):
        FileState.from_bytes(s.to_bytes(), origin="swmm:other")
    with pytest.raises(ValueError, match="not a rivercal file-state archive"):
        FileState.from_bytes(b"garbage")


def test_quantity_check_names_the_quantity() -> None:
    q = Quantity("roughness:factor", "-", 0.1, 10.0)
    assert q.check(2) == 2.0
    with pytest.raises(ValueError, match=r"roughness:factor: value 20 - is outside its range \[0.1, 10\]"):
        q.check(20)
    with pytest.raises(ValueError, match="not finite"):
        q.check(float("nan"))
    assert Quantity("x").check(-1e9) == -1e9


def test_build_model_is_the_embedded_model_with_runoff(tmp_path) -> None:
    from rivercal.case import load_case

    model = build_model(load_case("dommel"))
    assert isinstance(model, EmbeddedModel)
    lateral = model.forcing["lateral:L_C10"]
    assert lateral.max() > 0  # the rainfall-runoff inflow replaced the case's series
