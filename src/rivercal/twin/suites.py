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
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from rivercal.analysis import (
    Identifiability,
    IdentifiabilityOptions,
    SensitivityResult,
    identifiability,
    sensitivity,
    summary_statistics,
    thesis_scenarios,
)
from rivercal.evaluate import Tasks, Workers, as_completed
from rivercal.models.contract import Model
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem, calibrate, problem_evaluator
from rivercal.twin.truth import TwinTruth, twin_truth

__all__ = ["SENSITIVITY_PARAMETERS", "SUITES", "InitialAnalysis", "Scenario", "ScenarioResult", "SuiteDefinition",
           "initial_analysis", "run_scenarios", "suite_scenarios"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SuiteDefinition:
    """A suite: per parameter the true values by letter and the start values by digit.

    ``bias_series`` is the observed series whose moving-window bias the report plots (thesis Figs. 4-11,
    4-15, 4-25, 4-29, 4-33: 0028 for the one-parameter suites, the downstream level of 0040 for the others;
    F0W1 observes only the upstream level of 0028, so its bias is that of ``0028.h_up``). Tolerances are in
    the parameters' units (k_s in m^(1/3)/s, crest in m, Wc dimensionless).
    """

    name: str
    truths: dict[str, dict[str, float]]
    starts: dict[str, dict[str, float]]
    window: str
    series: tuple[str, ...] | None
    noise: str
    tolerance: dict[str, float]
    description: str
    bias_series: str = "0040.h_down"


_FA = {"H": 20.0, "M": 16.0, "L": 12.0}
_FA_START = {"1": 14.0, "2": 18.0}
_WC = {"H": 0.8, "M": 0.6, "L": 0.4}
_WC_START = {"1": 0.1, "2": 0.9}

SUITES: dict[str, SuiteDefinition] = {
    "F1W0": SuiteDefinition(
        "F1W0", {"F1": dict(_FA)}, {"F1": dict(_FA_START)}, "moderate", ("0028.h_down",), "none",
        {"F1": 0.05}, "friction of the section just downstream of ZL1-3014 from the downstream level of 0028",
        "0028.h_down"),
    "F0W1": SuiteDefinition(
        "F0W1", {"W2": {"H": 10.75, "M": 10.45, "L": 10.15}}, {"W2": {"1": 10.00, "2": 10.90}}, "moderate",
        ("0028.h_up",), "none", {"W2": 0.002}, "crest level of ZL1-3014 from the upstream level of 0028",
        "0028.h_up"),
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
    the observed stations in the window. ``series`` holds the ``observed``, ``initial``, ``calibrated``
    and ``truth`` frames of the observed series in the window (m, m³/s) and ``sigma`` the σ of each
    observed series (same units) that weighs its residuals.
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
    sigma: dict[str, float] = field(default_factory=dict)

    def row(self) -> dict[str, Any]:
        """A flat row for tables (no history or series)."""
        out = {k: v for k, v in asdict(self).items() if k not in ("history", "series", "truth", "start",
                                                                  "estimates", "errors", "std", "sigma")}
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


def _setup(model: Model) -> None:
    global _MODEL, _PARAMS, _WINDOWS, _OPTIONS
    _MODEL = model
    _PARAMS = {p.name: p for p in model.calibration.parameters}
    _WINDOWS = dict(model.calibration.windows)
    _OPTIONS = dict(model.calibration.options)


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
    stats = summary_statistics(residual)
    return ScenarioResult(
        suite=scenario.suite, id=scenario.id, truth=scenario.truth, start=scenario.start, estimates=cal.estimates,
        errors=errors, std=cal.std, iterations=r.nit, model_runs=r.nfev, wall_s=cal.wall_time, cost=r.cost,
        rmse=stats["rmse"], bias=stats["bias"], std_error=stats["std"],
        state_rmse=state_rmse, success=bool(r.success),
        within_tolerance=all(abs(errors[n]) <= scenario.tolerance[n] for n in errors), message=r.message,
        history=cal.history,
        series={"observed": truth.observations.to_frame(), "initial": initial.loc[window[0]:window[1], ids],
                "calibrated": final.loc[window[0]:window[1], ids], "truth": true},
        sigma={o.id: float(o.sigma) for o in problem.observations if o.sigma is not None},
    )


def _expected_work(scenario: Scenario) -> int:
    """A rough rank of a scenario's cost: more parameters and noise take more iterations."""
    return len(scenario.truth) + (1 if scenario.noise != "none" else 0)


def _truth_on(model: Model, scenario: Scenario) -> TwinTruth:
    _setup(model)
    return _truth(scenario)


def _calibrate_on(model: Model, scenario: Scenario, truth: TwinTruth) -> ScenarioResult:
    _setup(model)
    return _calibrate(scenario, truth)


def run_scenarios(model: Model, scenarios: Sequence[Scenario], *, workers: Workers = None,
                  progress: Callable[[ScenarioResult], None] | None = None) -> list[ScenarioResult]:
    """Run scenarios on ``model`` (the packaged ``dommel`` case or one with the same parameters and windows).

    Each distinct truth runs once; the scenarios then run in parallel, one calibration per worker
    process (serial model runs inside each), which keeps every core busy for the whole suite. Scenarios
    of several suites can go in one call (one pool for all); all are submitted at once, the likely longest
    first, so that no worker idles at the end. ``workers`` may be a Dask cluster (the model goes to each of
    its workers once). Results come back in the order of ``scenarios``; ``progress`` is called as each one
    finishes.
    """
    _setup(model)
    keys: dict[tuple, Scenario] = {}
    for s in scenarios:
        keys.setdefault(s.truth_key, s)
    t0 = time.perf_counter()
    tasks = Tasks(model, workers)
    if not tasks.parallel or len(scenarios) <= 1:
        truths = {k: _truth(s) for k, s in keys.items()}
        log.info("%d truths in %.1f s", len(truths), time.perf_counter() - t0)
        results = []
        for s in scenarios:
            results.append(_calibrate(s, truths[s.truth_key]))
            if progress:
                progress(results[-1])
        return results
    out: list[ScenarioResult | None] = [None] * len(scenarios)
    with tasks:
        order = sorted(keys, key=lambda k: -_expected_work(keys[k]))
        truths = dict(zip(order, tasks.map(_truth_on, [keys[k] for k in order]), strict=True))
        log.info("%d truths in %.1f s", len(truths), time.perf_counter() - t0)
        jobs = sorted(range(len(scenarios)), key=lambda i: -_expected_work(scenarios[i]))
        submitted = tasks.submit_all(_calibrate_on, [(scenarios[i], truths[scenarios[i].truth_key]) for i in jobs])
        futures = dict(zip(submitted, jobs, strict=True))
        for future in as_completed(futures):
            result = future.result()
            out[futures[future]] = result
            if progress:
                progress(result)
    return [r for r in out if r is not None]


# -- the initial model analysis (thesis §4-5-1) ------------------------------------------------------

#: The parameters of thesis Table 4-4, in its order: the nine crests and the global friction.
SENSITIVITY_PARAMETERS = ("W1", "W2", "W3", "W4", "W5", "W6", "W7", "W8", "W9", "FA")


@dataclass(frozen=True)
class InitialAnalysis:
    """The initial model analysis of thesis §4-5-1 at the base point (the case's initial values).

    The observations are a noise-free twin truth at the base point, so the base cost is zero and every
    scenario's cost (thesis Eq. 2-3, dimensionless) measures how far its change moves the stations.

    Attributes
    ----------
    parameters
        The parameters analysed, in order.
    kinds
        Per parameter ``crest`` (it sets weir crest levels, also as a cluster), ``friction`` or ``other``.
    window
        (start, end) of the window, UTC.
    sensitivity
        One-at-a-time scenarios of thesis Table 4-4 (Fig. 4-5, C-1 … C-5).
    identifiability
        Jacobian SVD, correlation and verdict (Figs. 4-6, 4-7); None when not asked for.
    model_runs
        Model runs of both analyses (not the truth and its spin-up).
    wall_s
        Wall time in s, truth included.
    """

    parameters: tuple[str, ...]
    kinds: dict[str, str]
    window: tuple[pd.Timestamp, pd.Timestamp]
    sensitivity: SensitivityResult
    identifiability: Identifiability | None
    model_runs: int
    wall_s: float


def _kind(p: Any) -> str:
    targets = [c.target for c in p.cluster] if p.cluster else list(p.targets)
    if targets and all(t.startswith("weir:") and t.endswith(".crest_level") for t in targets):
        return "crest"
    if targets and all(t.startswith("friction:") for t in targets):
        return "friction"
    return "other"


def initial_analysis(model: Model, names: Sequence[str] = SENSITIVITY_PARAMETERS, window: str = "moderate", *,
                     workers: Workers = None, identifiability_too: bool = True,
                     options: IdentifiabilityOptions | None = None) -> InitialAnalysis:
    """Sensitivity (thesis Table 4-4) and identifiability of ``names`` at the base point, one worker pool.

    Parameters
    ----------
    model
        The model (the ``dommel`` case or one with the same parameter names and windows).
    names
        Parameters of the case to analyse (default: W1 … W9 and FA, as thesis Table 4-4).
    window
        A window of the case or ``START/END`` (UTC).
    workers
        Worker processes for the runs (None: all cores), or a Dask cluster.
    identifiability_too
        Also compute the Jacobian (p + 1 runs) and the identifiability verdict.
    options
        Thresholds of the verdict.

    Raises
    ------
    KeyError
        For a parameter the case does not define.
    """
    t0 = time.perf_counter()
    _setup(model)
    unknown = [n for n in names if n not in _PARAMS]
    if unknown:
        raise KeyError(f"parameter {unknown[0]!r} is not defined by the case (it has {', '.join(_PARAMS)})")
    params = ParameterSet(_PARAMS[n] for n in names)
    win = _window(window)
    truth = twin_truth(model, params.quantities({n: _PARAMS[n].initial for n in names}), win)
    problem = CalibrationProblem(model, params, truth.observations, win, state=truth.state)
    problem.sqrt_weights  # noqa: B018 - computed before the workers fork
    with problem_evaluator(problem, workers) as batch, ThreadPoolExecutor(1) as side:
        # On a cluster the Jacobian's runs go out beside the sensitivity scenarios' (one batch each).
        ident_job = side.submit(identifiability, problem, batch=batch, options=options) \
            if identifiability_too and batch.cluster is not None else None
        sens = sensitivity(problem, thesis_scenarios(params), batch=batch)
        if ident_job is not None:
            ident = ident_job.result()
        else:
            ident = identifiability(problem, batch=batch, options=options) if identifiability_too else None
    runs = sens.nfev + (int(ident.extra["nfev"]) if ident is not None else 0)
    log.info("initial analysis of %d parameters: %d runs in %.1f s", len(params), runs, time.perf_counter() - t0)
    return InitialAnalysis(parameters=tuple(names), kinds={p.name: _kind(p) for p in params}, window=win,
                           sensitivity=sens, identifiability=ident,
                           model_runs=runs, wall_s=time.perf_counter() - t0)
