"""Identifiability on problems with known Jacobians: a linear stub model y = A θ (the model protocol).

With σ = 1 the weighted residuals are r = y_obs − A θ, so J = −A exactly: the singular values are those of
A, the covariance is (AᵀA)⁻¹, and the identifiability index follows from A's right singular vectors. The
sentences that explain the verdict come from :mod:`rivercal.report.identifiability` and are checked here too.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from rivercal.analysis import (
    COMBINATION,
    IDENTIFIABLE,
    NOT_IDENTIFIABLE,
    IdentifiabilityOptions,
    analyse_jacobian,
    context_from_problem,
    fd_jacobian,
    identifiability,
    identifiability_index,
)
from rivercal.models import Quantity
from rivercal.observations import ObservationSet
from rivercal.parameters import Parameter, ParameterSet
from rivercal.problem import CalibrationProblem
from rivercal.report.identifiability import explanations, summary, text, verdict_table

START = pd.Timestamp("2020-01-01", tz="UTC")


@dataclass
class Result:
    series: pd.DataFrame


class LinearModel:
    """Series ``S<k>.h``: y_k(t_i) = Σ_j A[k T + i, j] θ_j at hour i (T hours per series), 0 outside."""

    def __init__(self, a: np.ndarray, n_series: int):
        self.a = np.asarray(a, dtype=float)
        self.n_series = n_series
        self.T = self.a.shape[0] // n_series
        self.observables = [f"S{k}.h" for k in range(n_series)]
        self.targets = [f"weir:P{j}.crest_level" for j in range(self.a.shape[1])]
        self.quantities = {t: Quantity(t, "m AD") for t in self.targets}
        self.runs = 0

    def simulate(self, parameters, start=None, end=None, state=None):
        self.runs += 1
        start = START if start is None else start
        times = pd.date_range(start, end, freq="h")
        theta = np.array([parameters[t] for t in self.targets])
        i = ((times - START) / pd.Timedelta("1h")).to_numpy().astype(int)
        y = self.a @ theta
        inside = (i >= 0) & (i < self.T)
        out = {}
        for k in range(self.n_series):
            col = np.zeros(len(times))
            col[inside] = y[k * self.T + i[inside]]
            out[f"S{k}.h"] = col
        return Result(pd.DataFrame(out, index=times)), "state"


def linear_problem(a, n_series=2, truth=None, initial=None, bounds=(-10.0, 10.0)) -> CalibrationProblem:
    model = LinearModel(a, n_series)
    p = model.a.shape[1]
    truth = np.arange(1.0, p + 1) if truth is None else np.asarray(truth, dtype=float)
    initial = truth if initial is None else np.asarray(initial, dtype=float)
    pset = ParameterSet(Parameter(name=f"P{j}", targets=[model.targets[j]], min=bounds[0], max=bounds[1],
                                  initial=float(initial[j]), perturbation=0.1, unit="m AD") for j in range(p))
    end = START + pd.Timedelta(hours=model.T - 1)
    frame = model.simulate(dict(zip(model.targets, truth, strict=True)), START, end)[0].series
    obs = ObservationSet.from_frame(frame, sigma={"h": 1.0})
    return CalibrationProblem(model, pset, obs, (START, end), state="s", warmup="1h")


def random_a(seed=1, m=40, p=4) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(m, p))


# -- the Jacobian -----------------------------------------------------------------------------------


@pytest.mark.parametrize("scheme", ["forward", "central"])
def test_fd_jacobian_of_a_linear_model_is_minus_a(scheme) -> None:
    a = random_a()
    problem = linear_problem(a)
    calls = []

    def batch(points):
        calls.append(len(points))
        return [problem.residuals(x) for x in points]

    jac = fd_jacobian(problem, scheme=scheme, batch=batch)
    np.testing.assert_allclose(jac.matrix, -a, atol=1e-9)
    assert calls == [jac.nfev] and jac.nfev == (5 if scheme == "forward" else 9)  # ONE batch
    assert jac.rows == tuple(["S0.h"] * 20 + ["S1.h"] * 20)
    np.testing.assert_allclose(jac.scale, 20.0)  # default scale: the range ub - lb
    np.testing.assert_allclose(np.abs(jac.steps), 0.2 * (2 if scheme == "central" else 1))


def test_steps_are_relative_to_the_scale_and_point_into_the_bounds() -> None:
    a = random_a(p=2)
    problem = linear_problem(a, truth=[1.0, 2.0], initial=[10.0, 0.0])  # P0 at its upper bound
    jac = fd_jacobian(problem, rel_step=0.05, scale=[2.0, 4.0], batch=lambda xs: [problem.residuals(x) for x in xs])
    np.testing.assert_allclose(jac.steps, [-0.1, 0.2])
    np.testing.assert_allclose(jac.matrix, -a, atol=1e-9)
    with pytest.raises(ValueError, match="rel_step"):
        fd_jacobian(problem, rel_step=0.0, workers=1)
    with pytest.raises(ValueError, match="scale"):
        fd_jacobian(problem, scale=[1.0, -1.0], workers=1)
    with pytest.raises(ValueError, match="scheme"):
        fd_jacobian(problem, scheme="backward", workers=1)


# -- the analysis against numpy ------------------------------------------------------------------------


def test_svd_covariance_correlation_and_index_of_a_known_a() -> None:
    a = random_a(seed=3, m=30, p=3)
    problem = linear_problem(a, n_series=3)
    result = identifiability(problem, scale=np.ones(3), workers=1)
    _, s, vt = np.linalg.svd(a, full_matrices=False)
    np.testing.assert_allclose(result.singular_values, s, rtol=1e-8)
    for j in range(3):  # the same vectors up to sign; our sign: the largest component positive
        v = vt[j] * np.sign(vt[j][np.argmax(np.abs(vt[j]))])
        np.testing.assert_allclose(result.vectors[:, j], v, atol=1e-7)
    cov = np.linalg.inv(a.T @ a)
    np.testing.assert_allclose(result.covariance, cov, rtol=1e-7)
    std = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(result.std, std, rtol=1e-7)
    np.testing.assert_allclose(result.correlation, cov / np.outer(std, std), atol=1e-8)
    assert result.k == 3 and not result.singular
    np.testing.assert_allclose(result.index, 1.0)
    np.testing.assert_allclose(identifiability_index(vt.T, 2), np.sum(vt.T[:, :2] ** 2, axis=1))
    assert result.extra["nfev"] == 4


def test_orthogonal_columns_give_the_index_and_verdict_by_hand() -> None:
    # columns e1·3, e2·2, e3·1e-4 (orthogonal): s = 3, 2, 1e-4; V = I; k = 2 with the 1 % threshold
    a = np.zeros((12, 3))
    a[0, 0], a[1, 1], a[2, 2] = 3.0, 2.0, 1e-4
    result = analyse_jacobian(a, ["A", "B", "C"])
    np.testing.assert_allclose(result.singular_values, [3.0, 2.0, 1e-4])
    np.testing.assert_allclose(np.abs(result.vectors), np.eye(3))
    assert result.k == 2
    np.testing.assert_allclose(result.index, [1.0, 1.0, 0.0])
    assert list(result.verdict["verdict"]) == [IDENTIFIABLE, IDENTIFIABLE, NOT_IDENTIFIABLE]
    np.testing.assert_allclose(result.std, [1 / 3, 1 / 2, 1e4])
    # k given explicitly: the index counts only the strongest vector
    one = analyse_jacobian(a, ["A", "B", "C"], options={"k": 1})
    np.testing.assert_allclose(one.index, [1.0, 0.0, 0.0])
    assert list(one.verdict["verdict"]) == [IDENTIFIABLE, NOT_IDENTIFIABLE, NOT_IDENTIFIABLE]


def test_collinear_parameters_are_identifiable_only_in_combination() -> None:
    a = random_a(seed=5, p=3)
    a[:, 2] = a[:, 1]  # P1 and P2 do exactly the same
    problem = linear_problem(a)
    result = identifiability(problem, scale=np.ones(3), workers=1)
    assert result.singular and result.k == 2
    np.testing.assert_allclose(result.index, [1.0, 0.5, 0.5], atol=1e-9)
    verdict = result.verdict
    assert verdict.loc["P0", "verdict"] == IDENTIFIABLE
    assert verdict.loc["P1", "verdict"] == verdict.loc["P2", "verdict"] == COMBINATION
    assert verdict.loc["P1", "partners"] == "P2" and verdict.loc["P2", "partners"] == "P1"
    # the weak direction: raising one while lowering the other changes nothing
    weak = result.vectors[:, 2]
    np.testing.assert_allclose(np.abs(weak), [0.0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-9)
    words = explanations(result)
    assert "cannot tell them apart" in words["P1"]
    assert "together with lowering" in words["P1"]
    assert np.isinf(result.std[1]) and np.isinf(result.std[2]) and np.isfinite(result.std[0])
    np.testing.assert_allclose(np.abs(result.correlation[1, 2]), 1.0)  # pseudo-inverse (JᵀJ)⁺
    np.testing.assert_allclose(result.covariance, np.linalg.pinv(a.T @ a), atol=1e-10)
    (cluster,) = result.clusters
    assert cluster.members == ("P1", "P2") and cluster.action == "cluster"


def test_strongly_correlated_but_seen_parameters_count_only_in_combination() -> None:
    rng = np.random.default_rng(7)
    base = rng.normal(size=60)
    a = np.column_stack([base, base + 0.2 * rng.normal(size=60), rng.normal(size=60)])
    result = analyse_jacobian(a, ["A", "B", "C"])
    cov = np.linalg.inv(a.T @ a)
    corr_ab = cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1])
    assert corr_ab < -0.9 and result.k == 3  # both directions are seen, but A and B trade off
    assert list(result.verdict["verdict"]) == [COMBINATION, COMBINATION, IDENTIFIABLE]
    assert result.verdict.loc["A", "correlated_with"] == "B"
    assert "correlation -0.9" in explanations(result)["A"]
    lenient = analyse_jacobian(a, ["A", "B", "C"], options=IdentifiabilityOptions(correlation=0.99))
    assert list(lenient.verdict["verdict"]) == [IDENTIFIABLE] * 3


def test_a_parameter_without_effect_is_not_identifiable() -> None:
    a = random_a(seed=2, p=3)
    a[:, 1] = 0.0
    problem = linear_problem(a)
    result = identifiability(problem, workers=1)
    assert result.verdict.loc["P1", "verdict"] == NOT_IDENTIFIABLE
    assert result.index[1] == pytest.approx(0.0, abs=1e-20)
    assert np.isinf(result.std[1])
    assert np.isnan(result.correlation[1, 0]) and np.isnan(result.correlation[1, 1])
    assert "no observation changes at all" in explanations(result)["P1"]
    assert [c.action for c in result.clusters] == ["fix"] and result.clusters[0].members == ("P1",)


def test_a_noise_level_parameter_does_not_spoil_a_well_seen_one() -> None:
    # C is hardly seen and its tiny column looks like A's: the full correlation A-C is strong, but C is
    # not identifiable and would be fixed, so A stays identifiable
    rng = np.random.default_rng(11)
    col = rng.normal(size=50)
    a = np.column_stack([col, rng.normal(size=50), 1e-5 * (col + 0.1 * rng.normal(size=50))])
    result = analyse_jacobian(a, ["A", "B", "C"])
    assert abs(result.correlation[0, 2]) > 0.9
    assert list(result.verdict["verdict"]) == [IDENTIFIABLE, IDENTIFIABLE, NOT_IDENTIFIABLE]


def test_scaling_changes_the_index_not_the_correlation() -> None:
    a = random_a(seed=4, p=3)
    a[:, 2] = 0.01 * a[:, 2] + 0.02 * a[:, 0]
    plain = analyse_jacobian(a, ["A", "B", "C"])
    scaled = analyse_jacobian(a, ["A", "B", "C"], scale=[1.0, 1.0, 100.0])
    assert plain.verdict.loc["C", "verdict"] == NOT_IDENTIFIABLE
    assert scaled.verdict.loc["C", "verdict"] != NOT_IDENTIFIABLE
    np.testing.assert_allclose(plain.correlation, scaled.correlation, atol=1e-8)
    np.testing.assert_allclose(plain.covariance, scaled.covariance, rtol=1e-8)


def test_the_verdict_is_deterministic() -> None:
    a = random_a(seed=9, p=4)
    a[:, 3] = a[:, 2]
    first = analyse_jacobian(a, ["A", "B", "C", "D"])
    second = analyse_jacobian(a.copy(), ["A", "B", "C", "D"])
    pd.testing.assert_frame_equal(first.verdict, second.verdict)
    assert text(first) == text(second)
    assert first.summary() == second.summary() and summary(first) == summary(second)
    flipped = analyse_jacobian(-a, ["A", "B", "C", "D"])  # the sign of J does not matter
    np.testing.assert_allclose(flipped.vectors, first.vectors, atol=1e-12)
    assert list(flipped.verdict["verdict"]) == list(first.verdict["verdict"])


def test_plain_language_names_the_station_at_the_weir() -> None:
    # P0 acts on S0 only, P1 on S1 only; the fake network puts station S0 at weir P0
    a = np.zeros((40, 2))
    a[:20, 0] = np.linspace(1, 2, 20)
    a[20:, 1] = np.linspace(0.5, 1, 20)
    problem = linear_problem(a)
    stations = [SimpleNamespace(id="S0", structure="P0", branch=None, chainage=None, quantities=["h_up"]),
                SimpleNamespace(id="S1", structure=None, branch="B", chainage=100.0, quantities=["h"])]
    problem.model.case = SimpleNamespace(network=SimpleNamespace(stations=stations))
    context = context_from_problem(problem)
    assert context.at == {"P0": ("S0",)}
    assert context.descriptions["P0"] == "crest level of weir P0"
    result = identifiability(problem, workers=1)
    words = verdict_table(result)["explanation"]
    assert words["P0"].startswith("P0 (crest level of weir P0) is identifiable")
    assert "station S0 measures right at this weir (100% of its signal, S0.h)" in words["P0"]
    assert "at station S1, which measures the level on branch B at 100 m" in words["P1"]
    assert "cm" in words["P0"]  # the uncertainty of a crest in cm


def test_the_uncertainty_of_a_dimensionless_parameter_carries_no_unit() -> None:
    # an imported SOBEK 3 model's friction factor (unit "-"): "determined to ±0.5.", not "±0.5 -."; k_s keeps its unit
    from rivercal.analysis import Context

    a = np.zeros((12, 2))
    a[0, 0], a[1, 1] = 2.0, 4.0   # σ = 1/2 and 1/4
    context = Context(units={"F_scale": "-", "FA": "m^(1/3)/s"})
    words = explanations(analyse_jacobian(a, ["F_scale", "FA"], context=context))
    assert words["F_scale"].endswith("determined to ±0.5.")
    assert words["FA"].endswith("determined to ±0.25 m^(1/3)/s.")


def test_a_station_at_a_culvert_is_said_to_be_at_a_culvert_not_a_weir() -> None:
    # the imported Korte Woerden model: 'station PMP2, which measures the levels up- and downstream of weir PMP2'
    # (a pump); the synthetic case has a culvert K1 beside its weirs
    from rivercal.case import load_case

    network = load_case("synthetic").network
    stations = [SimpleNamespace(id="SK", structure="K1", branch=None, chainage=None,
                                quantities=["h_up", "h_down", "Q"]),
                SimpleNamespace(id="SW", structure="W1", branch=None, chainage=None, quantities=["h_up", "Q"])]
    model = SimpleNamespace(case=SimpleNamespace(network=SimpleNamespace(stations=stations,
                                                                         structure=network.structure)))
    context = context_from_problem(SimpleNamespace(parameters=[], model=model))
    assert context.stations["SK"] == "the levels up- and downstream of culvert K1 and the discharge through it"
    assert context.stations["SW"] == "the level upstream of weir W1 and the discharge over it"


def test_a_parameter_the_window_hardly_sees_is_not_identifiable_even_alone() -> None:
    # the D-HYDRO model c01 observes only discharges that its boundaries set: 'rivercal analyse --params F_T1' said
    # 'identifiable (identifiability index 1.00) ... determined to ±1.79e+10', because the significance of a
    # singular value is relative to the largest, which was F_T1's own. Over its whole range (20 here) it now has to
    # move the weighted misfit by one σ (σ = 1 m): an effect of 1e-4 m per unit does not
    a = np.zeros((40, 1))
    a[:20, 0] = 1e-4
    result = identifiability(linear_problem(a), workers=1)
    assert result.extra["unseen"] and result.singular_values[0] < 1.0
    assert list(result.verdict["verdict"]) == [NOT_IDENTIFIABLE]
    words = explanations(result)["P0"]
    assert words.startswith("P0 (crest level of weir P0) is not identifiable (identifiability index 0.00): moving "
                            "it over its whole range (20 m) changes the misfit by less than one observation error")
    from rivercal.report.identifiability import suggestions

    assert suggestions(result) == ["fix P0 at its current value: moved over its whole range it changes the misfit "
                                   "by less than one observation error."]
    a[:20, 0] = 0.1   # moved over its range of 20: 2 m at 20 hours, well seen
    seen = identifiability(linear_problem(a), workers=1)
    assert not seen.extra["unseen"] and list(seen.verdict["verdict"]) == [IDENTIFIABLE]


def test_options_are_checked() -> None:
    with pytest.raises(ValueError, match="sv_threshold"):
        IdentifiabilityOptions(sv_threshold=0.0)
    with pytest.raises(ValueError, match="below identifiable"):
        IdentifiabilityOptions(identifiable=0.3, unidentifiable=0.5)
    with pytest.raises(ValueError, match="k must be"):
        IdentifiabilityOptions(k=-1)
    with pytest.raises(ValueError, match="shape"):
        analyse_jacobian(np.ones((3, 2)), ["A"])
    with pytest.raises(ValueError, match="non-finite"):
        analyse_jacobian(np.array([[1.0, np.nan]]), ["A", "B"])


def test_summary_is_json_friendly() -> None:
    import json

    a = random_a(seed=6, p=3)
    a[:, 1] = 0.0
    result = analyse_jacobian(a, ["A", "B", "C"])
    numbers = result.summary()
    dumped = json.dumps(numbers, allow_nan=False)
    assert "Doherty" in dumped and numbers["verdict"]["B"] == NOT_IDENTIFIABLE and numbers["std"]["B"] is None
    assert "explanations" not in numbers   # the numbers carry no sentences
    worded = summary(result)
    json.dumps(worded, allow_nan=False)
    assert worded["explanations"]["B"].startswith("B is not identifiable")
    assert worded["clusters"][0]["explanation"].startswith("fix B at its current value")
