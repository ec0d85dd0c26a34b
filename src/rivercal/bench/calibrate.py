"""Calibration benchmark: the FaWc twin calibration of the default case with every algorithm.

Truth k_s = 20 m^(1/3)/s and Wc = 0.8; start k_s = 14, Wc = 0.1; the moderate window (the week ending
4 October 2010), all stations, noise-free observations, batches on all cores. The design targets DuD at
≤ 15 model runs and ≤ 5 s wall. The global and sampling methods get a fixed budget of runs, so that the
table compares what each reaches within it.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Any

from rivercal.model import load_model
from rivercal.parameters import ParameterSet
from rivercal.problem import CalibrationProblem, calibrate
from rivercal.twin import twin_truth

__all__ = ["ALGORITHMS", "CalibrationBenchmark", "algorithm_arguments", "bench_calibrate"]

TRUTH = {"FA": 20.0, "Wc": 0.8}
START = {"FA": 14.0, "Wc": 0.1}

#: Algorithm → keyword arguments of :func:`rivercal.problem.calibrate` (budgets for the global methods).
ALGORITHMS: dict[str, dict[str, Any]] = {
    "dud": {},
    "sparse_dud": {},
    "trf": {},
    "nelder_mead": {},
    "powell": {},
    "cg": {},
    "bfgs": {},
    "dds": {"options": {"seed": 1}, "max_nfev": 60},
    "sce_ua": {"options": {"seed": 1}, "max_nfev": 120},
    "grid": {"options": {"points_per_axis": 9}},
    "glue": {"options": {"n_samples": 80, "seed": 1}},
}


@dataclass(frozen=True)
class CalibrationBenchmark:
    """One row of the benchmark (errors in the parameters' units, wall time in s)."""

    algorithm: str
    model_runs: int
    iterations: int
    wall_s: float
    fa: float
    wc: float
    error_fa: float
    error_wc: float
    cost: float
    status: str

    def to_dict(self) -> dict:
        """Plain-dict form for JSON."""
        return asdict(self)


def algorithm_arguments(name: str, case_options: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Options and keyword arguments of :func:`rivercal.problem.calibrate` for algorithm ``name``.

    DuD and Sparse DuD take the case's stopping rules (thesis Table 4-3); the grid spans the parameters'
    bounds with ``points_per_axis`` points.
    """
    kwargs = dict(ALGORITHMS[name])
    options = dict(kwargs.pop("options", {}))
    if name in ("dud", "sparse_dud"):
        options = {**case_options, **options}
    if name == "sparse_dud":
        kwargs["dependency"] = None  # every station sees both parameters: the dense map
    return options, kwargs


def bench_calibrate(algorithms: list[str] | None = None, workers: int | None = None) -> dict[str, Any]:
    """Run the FaWc twin calibration with each algorithm; return the setup and one row per algorithm."""
    t0 = time.perf_counter()
    sim = load_model("dommel")
    params = ParameterSet(p for p in sim.case.spec.parameters if p.name in ("FA", "Wc"))
    window = next((w.start, w.end) for w in sim.case.spec.windows if w.name == "moderate")
    truth = twin_truth(sim, params.quantities(TRUTH), window)
    setup_s = time.perf_counter() - t0
    rows = []
    for name in algorithms or list(ALGORITHMS):
        problem = CalibrationProblem(sim, params.with_initial(START), truth.observations, window, state=truth.state)
        options, kwargs = algorithm_arguments(name, sim.case.spec.calibration.options)
        cal = calibrate(problem, name, options, workers=workers, **kwargs)
        r = cal.result
        rows.append(CalibrationBenchmark(
            algorithm=name, model_runs=r.nfev, iterations=r.nit, wall_s=round(cal.wall_time, 3),
            fa=cal.estimates["FA"], wc=cal.estimates["Wc"], error_fa=cal.estimates["FA"] - TRUTH["FA"],
            error_wc=cal.estimates["Wc"] - TRUTH["Wc"], cost=r.cost, status=r.message,
        ).to_dict())
    return {"case": "dommel", "window": [str(window[0]), str(window[1])], "truth": TRUTH, "start": START,
            "observations": truth.observations.n_values, "setup_s": round(setup_s, 2), "results": rows}
