"""The measured dependency map of Sparse DuD (rivercal.analysis.dependency).

The arithmetic is checked by hand on small tables; the measured map against the synthetic network's
topology (a station upstream of every confluence sees only its own stream); Sparse DuD with the map
against the known truth of a twin.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.analysis.dependency import DependencyMap, dependency_map, effects_of
from rivercal.analysis.jacobian import Jacobian
from rivercal.model import load_model
from rivercal.observations import ObservationSet
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem, calibrate

BRANCHES = ("M", "A", "T", "C")  # the synthetic case's Strickler branches (B has its own Manning friction)
TRUTH = 32.0  # tributary T's true friction, m^(1/3)/s; every other branch stays at 25


def _parameters() -> ParameterSet:
    return ParameterSet([Parameter(name=f"F{b}", targets=[f"friction:branch:{b}"], min=10.0, max=50.0,
                                   initial=25.0, perturbation=2.0, unit="m^(1/3)/s") for b in BRANCHES])


@pytest.fixture(scope="module")
def twin():
    """The synthetic network, its region frictions and observations of a truth with T at 32 m^(1/3)/s."""
    model = load_model("synthetic")
    end = model.start + pd.Timedelta(days=6)
    truth = {"friction:global": 25.0, **{f"friction:branch:{b}": 25.0 for b in BRANCHES},
             "friction:branch:T": TRUTH}
    result, _ = model.simulate(truth, end=end)
    window = (model.start + pd.Timedelta(days=2), end)
    observations = ObservationSet.from_frame(result.series.loc[window[0]:])
    return model, observations, window


def _problem(twin, observations=None) -> CalibrationProblem:
    model, obs, window = twin
    return CalibrationProblem(model, _parameters(), observations or obs, window, warmup="24h")


def test_effects_are_the_largest_change_of_a_first_step_per_series() -> None:
    jac = Jacobian(matrix=np.array([[1.0, -0.5], [-3.0, 0.0], [0.2, 0.25]]), x=np.zeros(2), steps=np.ones(2),
                   residuals=np.zeros(3), names=("a", "b"), rows=("s.h", "s.h", "t.Q"), scale=np.ones(2),
                   scheme="forward", nfev=3)
    effects = effects_of(jac, np.array([0.1, 2.0]))
    assert list(effects.index) == ["s.h", "t.Q"]
    np.testing.assert_allclose(effects.to_numpy(), [[0.3, 1.0], [0.02, 0.5]])


def test_a_parameter_no_series_sees_keeps_its_strongest_series() -> None:
    effects = pd.DataFrame({"a": [0.5, 0.0], "b": [0.01, 0.03]}, index=["s.h", "t.Q"])
    seen = DependencyMap(effects, threshold=0.1).seen
    assert seen.to_dict() == {"a": {"s.h": True, "t.Q": False}, "b": {"s.h": False, "t.Q": True}}
    assert DependencyMap(effects, threshold=0.0).k == 2


def test_rows_follow_the_observed_series_and_what_the_map_does_not_name_counts_everywhere(twin) -> None:
    problem = _problem(twin)
    ids = problem.observations.ids
    named = [s for s in ids if not s.startswith("S6.")]  # S6 is left out of the map: it sees everything
    effects = pd.DataFrame(0.0, index=named, columns=["FM", "FA", "FT", "Fx"])  # FC is not named, Fx is not estimated
    effects.loc[[s for s in named if s.startswith("S1.")], "FM"] = 1.0
    effects.loc[[s for s in named if not s.startswith("S1.")], "FA"] = 0.5
    effects.loc["S5.Q", "FT"] = 0.2
    matrix = DependencyMap(effects).rows(problem)
    assert matrix.shape == (problem.sqrt_weights.size, 4)
    start = 0
    for s in problem.observations:
        block = matrix[start:start + len(s)]
        start += len(s)
        expected = ([True, True, True, True] if s.id.startswith("S6.")
                    else [s.id.startswith("S1."), not s.id.startswith("S1."), s.id == "S5.Q", True])
        assert (block == expected).all(), s.id


def test_csv_round_trip_and_errors_name_the_file(tmp_path: Path) -> None:
    effects = pd.DataFrame({"FA": [0.25, 1.5], "W2": [0.0, 3.0]}, index=pd.Index(["0028.h_up", "0028.Q"]))
    path = DependencyMap(effects).to_csv(tmp_path / "dependency.csv")
    back = DependencyMap.from_csv(path, threshold=0.3)
    pd.testing.assert_frame_equal(back.effects, effects, check_names=False)
    assert back.threshold == 0.3 and list(back.effects.index) == ["0028.h_up", "0028.Q"]  # leading zeros kept
    cases = {
        "station,FA\ns.h,1\n": "a first column 'series'",
        "series,FA\ns.h,-1\n": "column 'FA' must hold a number >= 0",
        "series,FA\ns.h,much\n": "column 'FA' must hold a number >= 0",
        "series,FA\ns.h,1\ns.h,2\n": "series 's.h' appears twice",
        "": "cannot read the dependency map",
    }
    for text, message in cases.items():
        bad = tmp_path / "bad.csv"
        bad.write_text(text, encoding="utf-8")
        with pytest.raises(ValueError, match=message) as info:
            DependencyMap.from_csv(bad)
        assert str(bad) in str(info.value)
    with pytest.raises(ValueError, match="cannot read"):
        DependencyMap.from_csv(tmp_path / "missing.csv")
    with pytest.raises(ValueError, match="threshold"):
        DependencyMap(effects, threshold=-1.0)


@pytest.mark.slow
def test_measured_map_follows_the_network_and_sparse_dud_finds_the_truth_with_it(twin) -> None:
    measured = dependency_map(_problem(twin), workers=1)
    seen = measured.seen
    # S1 lies on the main stream above every confluence: no tributary's friction reaches it
    s1 = seen.loc[[s for s in seen.index if s.startswith("S1.")]]
    assert s1.columns[s1.any(axis=0)].tolist() == ["FM"]
    cal = calibrate(_problem(twin), "sparse_dud", workers=1, dependency=measured)
    assert cal.result.success, cal.result.message
    assert cal.estimates["FT"] == pytest.approx(TRUTH, abs=0.05)
    for name in ("FM", "FA", "FC"):
        assert cal.estimates[name] == pytest.approx(25.0, abs=0.05), name


def test_a_map_for_another_optimiser_is_refused_before_any_run(twin) -> None:
    problem = _problem(twin)
    effects = pd.DataFrame(1.0, index=problem.observations.ids, columns=problem.parameters.names)
    with pytest.raises(ValueError, match="serves Sparse DuD only, not 'dud'"):
        calibrate(problem, "dud", dependency=DependencyMap(effects))
    assert problem.n_runs == 0
