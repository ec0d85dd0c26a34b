"""One-at-a-time sensitivity: thesis Table 4-4 from the dommel case, and costs against a linear stub model."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.analysis import scenario_table, sensitivity, thesis_scenarios
from rivercal.case import load_case
from rivercal.parameters import ParameterSet
from tests.unit.test_analysis_identifiability import linear_problem, random_a

# thesis Table 4-4, row AVG: W1 … W9 (m AD) and FA (m^(1/3)/s)
AVG = {"W1": 10.82, "W2": 10.45, "W3": 8.4, "W4": 7.145, "W5": 9.15, "W6": 7.2, "W7": 6.75, "W8": 5.78, "W9": 4.6,
       "FA": 16.0}
NAMES = list(AVG)


@pytest.fixture(scope="module")
def dommel_parameters() -> ParameterSet:
    case = load_case("dommel")
    return ParameterSet(p for p in case.spec.parameters if p.name in NAMES).subset(NAMES)


def test_thesis_table_4_4_from_the_dommel_case(dommel_parameters) -> None:
    values = thesis_scenarios(dommel_parameters)
    assert list(values) == NAMES
    for name in NAMES[:-1]:  # W·-1 … W·-5: AVG − 0.30, − 0.15, + 0, + 0.15, + 0.30 m
        np.testing.assert_allclose(values[name], [AVG[name] + d for d in (-0.30, -0.15, 0.0, 0.15, 0.30)],
                                   atol=1e-9)
    assert values["FA"] == [20.0, 18.0, 16.0, 14.0, 12.0]  # FA1 … FA5
    assert values["W4"] == [6.845, 6.995, 7.145, 7.295, 7.445]  # spot checks against the printed table
    assert values["W8"] == [5.48, 5.63, 5.78, 5.93, 6.08]
    table = scenario_table(dommel_parameters, values)
    assert len(table) == 51 and table.index[0] == "AVG" and table.index[1] == "W1-1" and table.index[-1] == "FA-5"
    assert table.loc["AVG", NAMES].to_dict() == AVG
    row = table.loc["W2-1"]  # one parameter changed, the others at AVG
    assert row["parameter"] == "W2" and row["step"] == 1 and row["W2"] == pytest.approx(10.15)
    assert {n: row[n] for n in NAMES if n != "W2"} == {n: v for n, v in AVG.items() if n != "W2"}
    assert table.loc["FA-1", "FA"] == 20.0 and table.loc["FA-5", "FA"] == 12.0


def test_custom_lists_replace_the_thesis_values(dommel_parameters) -> None:
    values = thesis_scenarios(dommel_parameters, ["W2", "FA"], custom={"FA": [10.0, 30.0]})
    assert values["FA"] == [10.0, 30.0] and len(values["W2"]) == 5
    with pytest.raises(ValueError, match="not among the parameters"):
        thesis_scenarios(dommel_parameters, ["W2"], custom={"FA": [10.0]})
    with pytest.raises(KeyError, match="no parameter 'Wx'"):
        scenario_table(dommel_parameters, {"Wx": [1.0]})


def test_costs_of_a_linear_model_per_station_and_in_one_batch() -> None:
    # σ = 1, truth = base: changing θ_j by δ costs δ² ‖A_j‖², split over the stations' rows
    a = random_a(seed=8, m=60, p=3)
    problem = linear_problem(a, n_series=3)
    deltas = [-0.5, 0.0, 0.25]
    values = {f"P{j}": [j + 1.0 + d for d in deltas] for j in range(3)}
    calls = []

    def batch(points):
        calls.append(len(points))
        return [problem.residuals(x) for x in points]

    result = sensitivity(problem, values, batch=batch)
    assert calls == [7] and result.nfev == 7  # ONE batch: 3 × 3 scenarios, the base run once
    costs = result.costs("station")
    assert list(costs.columns) == ["parameter", "value", "total", "S0", "S1", "S2"]
    for j in range(3):
        for i, d in enumerate(deltas, start=1):
            row = costs.loc[f"P{j}-{i}"]
            assert row["parameter"] == f"P{j}" and row["value"] == pytest.approx(j + 1.0 + d)
            assert row["total"] == pytest.approx(d**2 * a[:, j] @ a[:, j], rel=1e-9, abs=1e-12)
            for k in range(3):
                rows = slice(20 * k, 20 * (k + 1))
                assert row[f"S{k}"] == pytest.approx(d**2 * a[rows, j] @ a[rows, j], rel=1e-9, abs=1e-12)
    assert result.base_cost == pytest.approx(0.0, abs=1e-20)
    series = result.costs("series")
    assert list(series.columns[3:]) == ["S0.h", "S1.h", "S2.h"]
    ranking = result.ranking()
    expected = sorted(range(3), key=lambda j: -0.25 * (a[:, j] @ a[:, j]))
    assert list(ranking.index) == [f"P{j}" for j in expected]
    assert set(result.frame.columns) == {"scenario", "parameter", "step", "value", "scope", "name", "cost"}


def test_default_scenarios() -> None:
    """(The same scenarios on two worker processes: tests/integration/test_in_other_processes.py.)"""
    a = random_a(seed=9, m=40, p=2)
    problem = linear_problem(a)
    serial = sensitivity(problem, workers=1)
    assert len(serial.table) == 11 and serial.nfev == 9  # thesis steps ± 0.15 / 0.30 m for the stub's crests
    summary = serial.summary()
    assert summary["model_runs"] == 9 and summary["ranking"][0]["max_cost"] > 0


def test_a_model_with_many_stations_gets_the_panels_of_the_stations_the_scenarios_move_most(tmp_path) -> None:
    # an imported model has a station at every observation point and structure: one panel each made a figure
    # tens of thousands of pixels tall; the figure keeps the stations whose cost the scenarios move most
    from PIL import Image

    from rivercal.analysis.figures import most_moved_stations, plot_sensitivity_stations

    a = random_a(seed=8, m=200, p=2)
    a[40:50] *= 30.0  # station S4's rows: the scenarios move its cost most
    problem = linear_problem(a, n_series=20)
    result = sensitivity(problem, {"P0": [0.5, 1.0, 1.5], "P1": [1.5, 2.0, 2.5]},
                         batch=lambda points: [problem.residuals(x) for x in points])
    costs = result.costs("station")
    stations = [f"S{k}" for k in range(20)]
    spread = costs[stations].max() - costs[stations].min()
    chosen = most_moved_stations(costs, stations, 4)
    assert "S4" in chosen and len(chosen) == 4 and chosen == sorted(chosen, key=stations.index)
    assert spread[chosen].min() >= spread.drop(chosen).max()
    few = plot_sensitivity_stations(result, tmp_path / "few.png", max_panels=4)
    every = plot_sensitivity_stations(result, tmp_path / "every.png", max_panels=20)
    assert Image.open(few).height < Image.open(every).height / 3
