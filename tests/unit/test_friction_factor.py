"""A friction factor (``[[friction_factors]]``, target ``friction:factor:<id>``) against hand-scaled cases.

- a run with a factor f equals, bit for bit, the run of the case whose listed coefficients were scaled by hand in
  ``case.toml`` (a Strickler k_s and a group's Strickler value times f, a Manning n divided by f), including a
  branch whose links take a friction group's value that another branch shares (it gets a slot of its own) and the
  branch-specific value given in the same call (applied first, then the factor);
- a factor on a group scales the group's own value and its values on particular branches together;
- a twin calibration of one factor recovers the truth from the levels of its own run;
- the case refuses, naming the file and the field: an unknown branch or group, a branch or group in two factors
  (or twice in one), a White-Colebrook group, a group whose profile names another group not in the factor, a
  target naming an undeclared factor; the model refuses a branch factor that overlaps a group factor through
  the branch's links and a factor on links with White-Colebrook friction; a factor outside 0.2-5.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.case import case_from_dict
from rivercal.engine import Simulator
from rivercal.engine.quantities import FACTOR_RANGE
from rivercal.errors import CaseError
from rivercal.models import build_model
from rivercal.observations import ObservationSet
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem, calibrate

START = "2020-01-01T00:00:00Z"
K_A, N_B, MAIN, MAIN_D = 28.0, 0.035, 30.0, 35.0  # k_s of A (m^(1/3)/s), n of B (s/m^(1/3)), group main's k_s


def _case(factors=None, parameters=None, *, wc: bool = False) -> dict:
    """Four branches in a row, u → n1 → n2 → n3 → d: A (own Strickler), B (own Manning), C and D (group main).

    Group main is Strickler 30 with 35 on D, so that C conveys with the group's own value (a slot that any other
    branch on it would share) and D with a value of its own. A discharge wave enters at u, the level is held at d.
    """
    trap = {"id": "trap", "type": "trapezoidal", "bottom_width": 4.0, "side_slope": 1.5, "height": 3.0}
    grouped = {"id": "grouped", "type": "zw", "heights": [0.0, 3.0], "flow_widths": [4.0, 13.0],
               "friction": ["main"]}

    def branch(bid, a, b, bed0, bed1, profile, friction=None):
        out = {"id": bid, "from_node": a, "to_node": b, "length": 2000.0, "dx": 250.0,
               "cross_sections": [{"chainage": 0.0, "profile": profile, "bed_level": bed0},
                                  {"chainage": 2000.0, "profile": profile, "bed_level": bed1}]}
        if friction is not None:
            out["friction"] = friction
        return out

    return {
        "case": {"name": "factors", "start": START, "end": "2020-01-01T12:00:00Z"},
        "engine": {"dt": 60.0, "output_interval": 1800.0},
        "initial": {"depth": 1.0, "spinup": 6.0},
        "friction": {"type": "strickler", "value": 25.0},
        "profiles": [trap, grouped],
        "nodes": [{"id": n} for n in ("u", "n1", "n2", "n3", "d")],
        "branches": [branch("A", "u", "n1", 4.0, 3.4, "trap", {"type": "strickler", "value": K_A}),
                     branch("B", "n1", "n2", 3.4, 2.8, "trap", {"type": "manning", "value": N_B}),
                     branch("C", "n2", "n3", 2.8, 2.2, "grouped"),
                     branch("D", "n3", "d", 2.2, 1.6, "grouped")],
        "friction_groups": [{"id": "main", "type": "white-colebrook" if wc else "strickler",
                             "value": 0.05 if wc else MAIN,
                             "branches": [{"branch": "D", "value": 0.08 if wc else MAIN_D}]}],
        "boundaries": [{"id": "q", "node": "u", "type": "discharge", "series": {"file": "q.csv", "column": "q"}},
                       {"id": "h", "node": "d", "type": "level", "value": 3.0}],
        "stations": [{"id": s, "branch": b, "chainage": 1000.0} for s, b in
                     (("SA", "A"), ("SB", "B"), ("SC", "C"), ("SD", "D"))],
        "friction_factors": factors or [],
        "parameters": parameters or [],
    }


#: The inflow wave at u, m³/s, hourly from the start.
WAVE = [2.0, 2.0, 4.0, 8.0, 10.0, 8.0, 6.0, 4.0, 3.0, 2.0, 2.0, 2.0, 2.0]


def _load(data: dict, tmp_path: Path):
    times = pd.date_range(START, periods=len(WAVE), freq="h")
    pd.DataFrame({"time": times.strftime("%Y-%m-%dT%H:%M:%SZ"), "q": WAVE}).to_csv(tmp_path / "q.csv", index=False)
    return case_from_dict(data, tmp_path)


def _sim(data: dict, tmp_path: Path) -> Simulator:
    return Simulator(_load(data, tmp_path))


def _series(sim: Simulator, parameters: dict) -> pd.DataFrame:
    return sim.simulate(parameters)[0].series


def _problem(data: dict, tmp_path: Path, pattern: str) -> CaseError:
    with pytest.raises(CaseError, match=pattern) as info:
        _sim(data, tmp_path)
    return info.value


# -- exactness -----------------------------------------------------------------------------------------------


def test_a_factor_on_branches_equals_the_case_scaled_by_hand_bit_for_bit(tmp_path: Path) -> None:
    f = 1.37
    sim = _sim(_case([{"id": "upper", "branches": ["A", "B", "C"]}]), tmp_path)
    by_factor = _series(sim, {"friction:factor:upper": f})
    hand = _case()
    hand["branches"][0]["friction"]["value"] = K_A * f
    hand["branches"][1]["friction"]["value"] = N_B / f  # Manning: the factor divides n
    hand["friction_groups"][0]["branches"].append({"branch": "C", "value": MAIN * f})  # C alone, not D
    by_hand = _series(_sim(hand, tmp_path), {})
    plain = _series(sim, {})
    assert not np.allclose(by_factor.to_numpy(), plain.to_numpy(), atol=1e-3)  # the factor does something
    pd.testing.assert_frame_equal(by_factor, by_hand, check_exact=True)


def test_a_split_slot_changes_nothing_until_the_factor_moves_it(tmp_path: Path) -> None:
    plain = _series(_sim(_case(), tmp_path), {"friction:group:main": 27.0})
    sim = _sim(_case([{"id": "c", "branches": ["C"]}]), tmp_path)
    assert len(sim.compiled.friction_slots) == len(_sim(_case(), tmp_path).compiled.friction_slots) + 1
    pd.testing.assert_frame_equal(_series(sim, {"friction:group:main": 27.0, "friction:factor:c": 1.0}), plain,
                                  check_exact=True)


def test_a_branch_value_in_the_same_call_is_set_first_then_scaled(tmp_path: Path) -> None:
    sim = _sim(_case([{"id": "upper", "branches": ["A", "B"]}]), tmp_path)
    both = _series(sim, {"friction:factor:upper": 1.25, "friction:branch:A": 32.0})
    hand = _series(sim, {"friction:branch:A": 32.0 * 1.25, "friction:branch:B": N_B / 1.25})
    pd.testing.assert_frame_equal(both, hand, check_exact=True)
    scaled = _series(sim, {"friction:scale": 0.8, "friction:factor:upper": 1.25})  # the scale on top of it
    hand = _case()
    hand["branches"][0]["friction"]["value"] = K_A * 1.25 * 0.8
    hand["branches"][1]["friction"]["value"] = N_B / 1.25 / 0.8
    hand["friction_groups"][0]["value"] = MAIN * 0.8
    hand["friction_groups"][0]["branches"][0]["value"] = MAIN_D * 0.8
    assert np.abs(scaled.to_numpy() - _series(_sim(hand, tmp_path), {}).to_numpy()).max() < 1e-12


def test_a_factor_on_a_group_scales_its_own_value_and_its_values_on_branches(tmp_path: Path) -> None:
    f = 0.7
    sim = _sim(_case([{"id": "g", "groups": ["main"]}]), tmp_path)
    hand = _case()
    hand["friction_groups"][0]["value"] = MAIN * f
    hand["friction_groups"][0]["branches"][0]["value"] = MAIN_D * f
    pd.testing.assert_frame_equal(_series(sim, {"friction:factor:g": f}), _series(_sim(hand, tmp_path), {}),
                                  check_exact=True)


def test_the_factor_is_declared_with_its_unit_bounds_and_listed(tmp_path: Path) -> None:
    model = build_model(_load(_case([{"id": "upper", "branches": ["A", "C"]}]), tmp_path))
    q = model.quantities["friction:factor:upper"]
    assert (q.unit, q.min, q.max) == ("-", *FACTOR_RANGE)
    table = model.quantities_frame()
    assert table.loc["friction:factor:upper", "value"] == 1.0
    assert "branches A, C" in table.loc["friction:factor:upper", "description"]


# -- twin ----------------------------------------------------------------------------------------------------


def test_a_twin_calibration_of_one_factor_recovers_the_truth(tmp_path: Path) -> None:
    truth = 1.6
    model = build_model(_load(_case([{"id": "reach", "branches": ["A", "B", "C"]}]), tmp_path))
    observed = model.simulate({"friction:factor:reach": truth})[0].series[["SA.h", "SB.h", "SC.h"]]
    params = ParameterSet([Parameter(name="reach", targets=["friction:factor:reach"], min=FACTOR_RANGE[0],
                                     max=FACTOR_RANGE[1], initial=1.0, transform="factor", perturbation=0.1)])
    start = pd.Timestamp(START)
    problem = CalibrationProblem(model, params, ObservationSet.from_frame(observed),
                                 (start + pd.Timedelta("1h"), start + pd.Timedelta("12h")), warmup="1h")
    result = calibrate(problem, "dud", workers=1)
    assert result.estimates["reach"] == pytest.approx(truth, rel=1e-4)
    assert result.result.nfev <= 15


# -- refusals ------------------------------------------------------------------------------------------------


def test_an_unknown_branch_or_group_is_named_with_the_file_and_field(tmp_path: Path) -> None:
    err = _problem(_case([{"id": "x", "branches": ["A", "Q"]}]), tmp_path, "unknown branch 'Q'")
    assert err.field == "friction_factors[0].branches[1]" and err.file.endswith("case.toml")
    err = _problem(_case([{"id": "x", "groups": ["flood"]}]), tmp_path, "unknown group 'flood'.*'main'")
    assert err.field == "friction_factors[0].groups[0]"


def test_a_branch_or_group_in_two_factors_is_refused(tmp_path: Path) -> None:
    err = _problem(_case([{"id": "x", "branches": ["A"]}, {"id": "y", "branches": ["B", "A"]}]), tmp_path,
                   r"branch 'A' is scaled also by friction factor 'x' \(friction_factors\[0\].branches\[0\]\)")
    assert err.field == "friction_factors[1].branches[1]"
    _problem(_case([{"id": "x", "branches": ["A", "A"]}]), tmp_path, "branch 'A' is scaled twice")
    _problem(_case([{"id": "x", "branches": ["A"]}, {"id": "x", "branches": ["B"]}]), tmp_path, "used twice")
    _problem(_case([{"id": "x"}]), tmp_path, "lists no branches and no groups")


def test_a_branch_factor_that_overlaps_a_group_factor_through_its_links_is_refused(tmp_path: Path) -> None:
    err = _problem(_case([{"id": "x", "branches": ["D"]}, {"id": "y", "groups": ["main"]}]), tmp_path,
                   "friction factor 'y' scales the friction of friction group 'main' on branch 'D', which friction "
                   "factor 'x' scales too")
    assert err.field == "friction_factors[1]" and err.file.endswith("case.toml")


def test_white_colebrook_friction_cannot_be_scaled(tmp_path: Path) -> None:
    err = _problem(_case([{"id": "x", "groups": ["main"]}], wc=True), tmp_path, "White-Colebrook")
    assert err.field == "friction_factors[0].groups[0]"
    err = _problem(_case([{"id": "x", "branches": ["A", "C"]}], wc=True), tmp_path,
                   "friction factor 'x': friction group 'main' uses White-Colebrook")
    assert err.field == "friction_factors[0]"
    sim = _sim(_case([{"id": "x", "branches": ["A", "B"]}], wc=True), tmp_path)  # A and B are not W-C: fine
    assert "friction:factor:x" in sim.settable and "friction:scale" not in sim.settable


def test_a_group_beside_another_in_one_profile_needs_both_in_the_factor(tmp_path: Path) -> None:
    data = _case([{"id": "x", "groups": ["main"]}])
    data["profiles"].append({"id": "two", "type": "zw", "heights": [0.0, 3.0], "flow_widths": [4.0, 13.0],
                             "section_widths": [4.0, 9.0], "friction": ["main", "flood"]})
    data["friction_groups"].append({"id": "flood", "type": "strickler", "value": 15.0})
    err = _problem(data, tmp_path, "profile 'two' names friction group 'main' beside 'flood'")
    assert err.field == "friction_factors[0].groups[0]"
    ok = copy.deepcopy(data)
    ok["friction_factors"][0]["groups"] = ["main", "flood"]
    assert "friction:factor:x" in _sim(ok, tmp_path).settable


def test_a_target_naming_an_undeclared_factor_and_a_factor_out_of_bounds_are_refused(tmp_path: Path) -> None:
    param = {"name": "f", "targets": ["friction:factor:nope"], "min": 0.5, "max": 2.0, "initial": 1.0,
             "perturbation": 0.1}
    err = _problem(_case([{"id": "x", "branches": ["A"]}], [param]), tmp_path, "friction factor 'nope'")
    assert err.field == "parameters[0].targets[0]"
    sim = _sim(_case([{"id": "x", "branches": ["A"]}]), tmp_path)
    with pytest.raises(ValueError, match=r"friction:factor:x: factor 6 is outside 0\.2-5"):
        sim.simulate({"friction:factor:x": 6.0})
    with pytest.raises(KeyError, match="declares no friction factor 'y'"):
        sim.simulate({"friction:factor:y": 1.0})
