"""The twin-experiment suites of the reference study (thesis §4-4) and the runner that executes them.

Scenario ids follow the thesis: a letter for the true value (H high, M medium, L low) and a digit for
the start point (1 low, 2 high) per parameter, e.g. ``H1M2``: friction truth high with the low start,
cluster truth medium with the high start.

=========  ==============================  =======================  ==================  ==========
suite      parameters (truth / start)      observed series          window              noise
=========  ==============================  =======================  ==================  ==========
F1W0       F1: 20/16/12 from 14/18          0028.h_down              moderate            none
F0W1       W2: 10.75/10.45/10.15 from       0028.h_up                moderate            none
           10.00/10.90 m AD
FaWc       FA: 20/16/12 from 14/18,         all stations             moderate            none
           Wc: 0.8/0.6/0.4 from 0.1/0.9
FaWcP      FA: 20/12, Wc: 0.8/0.4           all stations             extreme             none
FaWcN      FA: 20/12, Wc: 0.8/0.4           all stations             moderate            white
=========  ==============================  =======================  ==================  ==========

(Thesis Tables 4-5, 4-7, 4-9, 4-11.) A scenario succeeds (robustness, thesis §2-3-3) when every
parameter ends within the suite's tolerance of its truth.
"""

from __future__ import annotations

import itertools
import logging
import multiprocessing
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from rivercal.evaluate import default_workers
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from rivercal.twin.truth import TwinTruth, twin_truth

__all__ = ["SUITES", "Scenario", "ScenarioResult", "SuiteDefinition", "run_scenarios", "suite_scenarios"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SuiteDefinition:
    """A suite: per parameter the true values by letter and the start values by digit."""

    name: str
    truths: dict[str, dict[str, float]]
    starts: dict[str, dict[str, float]]
    window: str
    series: tuple[str, ...] | None
    noise: str
    tolerance: dict[str, float]
    description: str


_FA = {"H": 20.0, "M": 16.0, "L": 12.0}
_FA_START = {"1": 14.0, "2": 18.0}
_WC = {"H": 0.8, "M": 0.6, "L": 0.4}
_WC_START = {"1": 0.1, "2": 0.9}

SUITES: dict[str, SuiteDefinition] = {
    "F1W0": SuiteDefinition(
        "F1W0", {"F1": dict(_FA)}, {"F1": dict(_FA_START)}, "moderate", ("0028.h_down",), "none",
        {"F1": 0.05}, "friction of the section just downstream of ZL1-3014 from the downstream level of 0028"),
    "F0W1": SuiteDefinition(
        "F0W1", {"W2": {"H": 10.75, "M": 10.45, "L": 10.15}}, {"W2": {"1": 10.00, "2": 10.90}}, "moderate",
        ("0028.h_up",), "none", {"W2": 0.002}, "crest level of ZL1-3014 from the upstream level of 0028"),
    "FaWc": SuiteDefinition(
        "FaWc", {"FA": dict(_FA), "Wc": dict(_WC)}, {"FA": dict(_FA_START), "Wc": dict(_WC_START)}, "moderate",
        None, "none", {"FA": 0.05, "Wc": 0.002}, "global friction and clustered crest levels, all stations"),
    "FaWcP": SuiteDefinition(
        "FaWcP", {"FA": {"H": 20.0, "L": 12.0}, "Wc": {"H": 0.8, "L": 0.4}},
        {"FA": dict(_FA_START), "Wc": dict(_WC_START)}, "extreme", None, "none", {"FA": 0.05, "Wc": 0.002},
        "as FaWc, high and low values, in the extreme-rain window"),
    "FaWcN": SuiteDefinition(
        "FaWcN", {"FA": {"H": 20.0, "L": 12.0}, "Wc": {"H": 0.8, "L": 0.4}},
        {"FA": dict(_FA_START), "Wc": dict(_WC_START)}, "moderate", None, "white", {"FA": 0.2, "Wc": 0.01},
        "as FaWcP in the moderate window, with white noise (±2.5 cm, ±0.1 m³/s)"),
}


@dataclass(frozen=True)
class Scenario:
    """One twin calibration: truth and start values by parameter name."""

    suite: str
    id: str
    truth: dict[str, float]
    start: dict[str, float]
    window: str
    series: tuple[str, ...] | None
    noise: str
    seed: int
    tolerance: dict[str, float]

    @property
    def truth_key(self) -> tuple:
        """Scenarios with the same key share one truth run."""
        return (tuple(sorted(self.truth.items())), self.window, self.series, self.noise, self.seed)


def suite_scenarios(name: str, *, ids: Sequence[str] | None = None, window: str | None = None) -> list[Scenario]:
    """The scenarios of a suite in the thesis' order (truth letters outer, start digits inner).

    ``ids`` keeps only these scenarios; ``window`` replaces the suite's window (a window name of the
    case, or ``START/END`` in UTC).
    """
    if name not in SUITES:
        raise KeyError(f"unknown suite {name!r}; choose one of {', '.join(SUITES)}")
    d = SUITES[name]
    params = list(d.truths)
    out = []
    for letters in itertools.product(*(d.truths[p] for p in params)):
        for digits in itertools.product(*(d.starts[p] for p in params)):
            sid = "".join(letter + digit for letter, digit in zip(letters, digits, strict=True))
            truth = {p: d.truths[p][letter] for p, letter in zip(params, letters, strict=True)}
            start = {p: d.starts[p][digit] for p, digit in zip(params, digits, strict=True)}
            seed = 1000 + sum(ord(c) for c in "".join(letters))  # one noise realisation per truth
            out.append(Scenario(name, sid, truth, start, window or d.window, d.series, d.noise, seed,
                                dict(d.tolerance)))
    if ids is not None:
        unknown = sorted(set(ids) - {s.id for s in out})
        if unknown:
            raise KeyError(f"suite {name} has no scenario {unknown[0]!r} (it has {', '.join(s.id for s in out)})")
        out = [s for s in out if s.id in set(ids)]
    # thesis order: for FaWc-type suites the friction letter and its start digit lead (H1H1, H1H2, H2H1, ...)
    return sorted(out, key=lambda s: ("HML".index(s.id[0]), "HML".index(s.id[2]) if len(s.id) > 2 else 0,
                                      s.id[1], s.id[3:]))


@dataclass
class ScenarioResult:
    """Outcome of one scenario: effectiveness, efficiency and robustness (thesis §2-3-3).

    Costs and residual statistics are dimensionless (weighted residuals, thesis Tables 4-6…4-12);
    ``state_rmse`` is the RMS difference (m) between the calibrated and the true noise-free levels at
    the observed stations in the window.
    """

    suite: str
    id: str
    truth: dict[str, float]
    start: dict[str, float]
    estimates: dict[str, float]
    errors: dict[str, float]
    std: dict[str, float]
    iterations: int
    model_runs: int
    wall_s: float
    cost: float
    rmse: float
    bias: float
    std_error: float
    state_rmse: float
    success: bool
    within_tolerance: bool
    message: str
    history: list[dict[str, float]] = field(default_factory=list)
    series: dict[str, pd.DataFrame] = field(default_factory=dict, repr=False)

    def row(self) -> dict[str, Any]:
        """A flat row for tables (no history or series)."""
        out = {k: v for k, v in asdict(self).items() if k not in ("history", "series", "truth", "start",
                                                                  "estimates", "errors", "std")}
        for name in self.truth:
            out[f"{name}_true"] = self.truth[name]
            out[f"{name}_start"] = self.start[name]
            out[f"{name}_estimate"] = self.estimates[name]
            out[f"{name}_error"] = self.errors[name]
        return out


# -- running -----------------------------------------------------------------------------------------

_MODEL: Any = None
_PARAMS: dict[str, Any] = {}
_WINDOWS: dict[str, tuple[pd.Timestamp, pd.Timestamp]] = {}
_OPTIONS: dict[str, Any] = {}


def _setup(model: Any) -> None:
    global _MODEL, _PARAMS, _WINDOWS, _OPTIONS
    _MODEL = model
    _PARAMS = {p.name: p for p in model.case.spec.parameters}
    _WINDOWS = {w.name: (pd.Timestamp(w.start), pd.Timestamp(w.end)) for w in model.case.spec.windows}
    _OPTIONS = dict(model.case.spec.calibration.options)


def _window(name: str) -> tuple[pd.Timestamp, pd.Timestamp]:
    if name in _WINDOWS:
        return _WINDOWS[name]
    start, _, end = name.partition("/")
    return pd.Timestamp(start, tz="UTC"), pd.Timestamp(end, tz="UTC")


def _truth(scenario: Scenario) -> TwinTruth:
    params = ParameterSet(_PARAMS[n] for n in scenario.truth)
    return twin_truth(_MODEL, params.quantities(scenario.truth), _window(scenario.window), series=scenario.series,
                      noise=scenario.noise, seed=scenario.seed)


def _calibrate(scenario: Scenario, truth: TwinTruth) -> ScenarioResult:
    params = ParameterSet(_PARAMS[n] for n in scenario.truth).with_initial(scenario.start)
    window = _window(scenario.window)
    problem = CalibrationProblem(_MODEL, params, truth.observations, window, state=truth.state)
    cal = calibrate(problem, "dud", _OPTIONS, workers=1)
    r = cal.result
    residual = r.extra.get("residuals")
    residual = np.asarray(residual if residual is not None else problem.residuals(r.x))[: problem.observations.n_values]
    initial, final = problem.simulate(problem.x0).series, problem.simulate(r.x).series
    ids = problem.observations.ids
    true = truth.series.loc[window[0]:window[1], ids]
    levels = [i for i in ids if not i.endswith(".Q")]
    state_rmse = float(np.sqrt(np.mean((final.loc[window[0]:window[1], levels] - true[levels]).to_numpy() ** 2)))
    errors = {n: cal.estimates[n] - scenario.truth[n] for n in scenario.truth}
    return ScenarioResult(
        suite=scenario.suite, id=scenario.id, truth=scenario.truth, start=scenario.start, estimates=cal.estimates,
        errors=errors, std=cal.std, iterations=r.nit, model_runs=r.nfev, wall_s=cal.wall_time, cost=r.cost,
        rmse=float(np.sqrt(np.mean(residual**2))), bias=float(np.mean(residual)), std_error=float(np.std(residual)),
        state_rmse=state_rmse, success=bool(r.success),
        within_tolerance=all(abs(errors[n]) <= scenario.tolerance[n] for n in errors), message=r.message,
        history=cal.history,
        series={"observed": truth.observations.to_frame(), "initial": initial.loc[window[0]:window[1], ids],
                "calibrated": final.loc[window[0]:window[1], ids], "truth": true},
    )


def _scenario_job(args: tuple[Scenario, TwinTruth]) -> ScenarioResult:
    return _calibrate(*args)


def run_scenarios(model: Any, scenarios: Sequence[Scenario], *, workers: int | None = None,
                  progress: Callable[[ScenarioResult], None] | None = None) -> list[ScenarioResult]:
    """Run scenarios on ``model`` (the packaged ``dommel`` case or one with the same parameters and windows).

    Each distinct truth runs once; the scenarios then run in parallel, one calibration per worker
    process (serial model runs inside each), which keeps every core busy for the whole suite.
    """
    _setup(model)
    workers = default_workers() if workers is None else workers
    keys: dict[tuple, Scenario] = {}
    for s in scenarios:
        keys.setdefault(s.truth_key, s)
    t0 = time.perf_counter()
    results: list[ScenarioResult] = []
    if workers <= 1:
        truths = {k: _truth(s) for k, s in keys.items()}
        log.info("%d truths in %.1f s", len(truths), time.perf_counter() - t0)
        for s in scenarios:
            results.append(_calibrate(s, truths[s.truth_key]))
            if progress:
                progress(results[-1])
        return results
    context = multiprocessing.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    with ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_setup, initargs=(model,)) as pool:
        truths = dict(zip(keys, pool.map(_truth, keys.values()), strict=True))
        log.info("%d truths in %.1f s", len(truths), time.perf_counter() - t0)
        for result in pool.map(_scenario_job, [(s, truths[s.truth_key]) for s in scenarios]):
            results.append(result)
            if progress:
                progress(result)
    return results
