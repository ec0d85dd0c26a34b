"""The Python API as users meet it: lazy top-level names, short reprs, DataFrame views and the fit report.

The fit report is checked against an independent reference: scipy's ``curve_fit`` on the same weighted
least-squares problem (estimates, standard deviations with ``absolute_sigma=True``, correlation).
"""

from __future__ import annotations

import importlib
import re
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import curve_fit

import rivercal
from rivercal.models import Quantity

START = pd.Timestamp("2020-01-01", tz="UTC")
SIGMA = 0.05  # m


def test_every_main_name_resolves_lazily() -> None:
    """(That ``import rivercal`` itself loads no engine is checked in a fresh interpreter: tests/integration.)"""
    for name in rivercal.__all__:
        if name == "__version__":
            continue
        module = importlib.import_module(rivercal._LAZY[name])
        assert getattr(rivercal, name) is getattr(module, name), name
    assert set(rivercal.__all__) <= set(dir(rivercal))
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        rivercal.nonsense  # noqa: B018


@dataclass
class _Result:
    series: pd.DataFrame


class ExponentialModel:
    """h(t) = a·exp(−k t) + 10 m AD at one station, hourly, t in h (a model of the model contract)."""

    name = "exponential"
    observables: ClassVar[list[str]] = ["S.h"]
    quantities: ClassVar[dict[str, Quantity]] = {"a": Quantity("a", "m", 0.0, 10.0),
                                                  "k": Quantity("k", "1/h", 0.0, 1.0)}

    def simulate(self, parameters, start=None, end=None, state=None):
        times = pd.date_range(START if start is None else start, end, freq="h")
        t = (times - START).total_seconds().to_numpy() / 3600.0
        return _Result(pd.DataFrame({"S.h": 10.0 + curve(t, parameters["a"], parameters["k"])}, index=times)), None


def curve(t: np.ndarray, a: float, k: float) -> np.ndarray:
    return a * np.exp(-k * t)


def _calibration():
    model = ExponentialModel()
    t = np.arange(0.0, 49.0)
    rng = np.random.default_rng(7)
    y = curve(t, 2.0, 0.1) + rng.normal(0.0, SIGMA, t.size)
    frame = pd.DataFrame({"S.h": 10.0 + y}, index=START + pd.to_timedelta(t, unit="h"))
    observations = rivercal.ObservationSet.from_frame(frame, sigma={"h": SIGMA}, source="synthetic")
    params = rivercal.ParameterSet([
        rivercal.Parameter(name="a", targets=["a"], min=0.1, max=10.0, initial=1.0, perturbation=0.2, unit="m"),
        rivercal.Parameter(name="k", targets=["k"], min=0.01, max=1.0, initial=0.2, perturbation=0.02, unit="1/h"),
    ])
    problem = rivercal.CalibrationProblem(model, params, observations, (START, START + pd.Timedelta("48h")),
                                          state="cold", warmup="0h")
    options = {"abs_tol": 0.0, "rel_tol": 1e-10, "rel_tol_linear": 1e-10}
    return problem, rivercal.calibrate(problem, "dud", options, workers=1), (t, y)


def test_fit_report_matches_scipy_curve_fit() -> None:
    _, cal, (t, y) = _calibration()
    popt, pcov = curve_fit(curve, t, y, p0=[1.0, 0.2], sigma=np.full(t.size, SIGMA), absolute_sigma=True)
    std = np.sqrt(np.diag(pcov))
    correlation = pcov[0, 1] / (std[0] * std[1])
    np.testing.assert_allclose([cal.estimates["a"], cal.estimates["k"]], popt, rtol=1e-4)
    np.testing.assert_allclose([cal.std["a"], cal.std["k"]], std, rtol=0.02)

    report = cal.fit_report()
    assert "method       = dud" in report and f"model runs   = {cal.result.nfev}" in report
    assert f"residuals    = {t.size}" in report
    lines = dict(re.findall(r"^    (\w+): (.*)$", report, flags=re.M))
    for i, name in enumerate(("a", "k")):
        value, sigma = re.match(r"(\S+) \+/- (\S+)", lines[name]).groups()
        assert float(value) == pytest.approx(popt[i], rel=1e-4)
        assert float(sigma) == pytest.approx(std[i], rel=0.02)
    c = float(re.search(r"C\(a, k\) = (\S+)", report).group(1))
    assert c == pytest.approx(correlation, abs=0.01)
    assert re.search(rf"cost S       = {cal.result.cost:.6g} \(start: ", report)


def test_views_and_reprs_say_what_the_objects_hold() -> None:
    problem, cal, _ = _calibration()
    table = cal.to_frame()
    assert list(table.index) == ["a", "k"] and table.loc["k", "unit"] == "1/h"
    assert table.loc["a", "estimate"] == cal.estimates["a"] and table.loc["a", "std"] == cal.std["a"]
    cor = cal.correlation_frame()
    assert cor.loc["a", "k"] == cor.loc["k", "a"] and cor.loc["a", "a"] == pytest.approx(1.0)
    history = cal.history_frame()
    assert history.index[0] == 0 and history["cost"].iloc[-1] == pytest.approx(cal.result.cost)
    assert repr(cal).startswith("Calibration(dud, converged, cost ")

    params = problem.parameters.to_frame()
    assert params.loc["a", ["min", "max", "initial", "unit"]].tolist() == [0.1, 10.0, 1.0, "m"]
    assert repr(problem.parameters) == "ParameterSet(a=1 in [0.1, 10] m, k=0.2 in [0.01, 1] 1/h)"
    assert repr(problem.observations) == ("ObservationSet(1 series, 49 values 2020-01-01 00:00 … 2020-01-03 00:00 UTC, "
                                          "0 missing)")
    summary = problem.observations.summary()
    assert summary.loc["S.h", ["values", "missing", "sigma"]].tolist() == [49, 0, SIGMA]
    assert repr(problem) == ("CalibrationProblem(model='exponential', parameters=['a', 'k'], 1 series / 49 values, "
                             "window 2020-01-01 00:00 … 2020-01-03 00:00 UTC, warmup 0 h, on_failure='raise')")
    frame = cal.result.to_frame(["a", "k"])
    assert frame["x"].tolist() == list(cal.result.x)


def test_engine_model_repr_and_quantities_frame() -> None:
    model = rivercal.load_model("synthetic")
    text = repr(model)
    assert text.startswith("EmbeddedModel('synthetic', 2020-01-01 00:00 … 2020-01-15 00:00 UTC, Δt 60 s, ")
    assert f"{len(model.observables)} series" in text
    table = model.quantities_frame()
    assert set(table.index) == set(model.quantities)
    for name, value in model.default_parameters().items():
        assert table.loc[name, "value"] == value
    assert table.loc["friction:global", "unit"] == model.quantities["friction:global"].unit
