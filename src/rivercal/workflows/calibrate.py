"""A calibration over one window, on observations or on a twin truth, with its files.

Files under ``out``: ``history.csv`` (per iteration), ``evaluations.csv`` (every model run),
``convergence.png`` and ``cost.png`` (thesis Figs. 4-8, 4-9) and ``result.json`` (the summary).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pandas as pd

from rivercal.models.contract import Model
from rivercal.parameters import ParameterSet
from rivercal.workflows.progress import NO_PROGRESS, Progress, jsonable

__all__ = ["calibrate_window", "undetermined"]


def calibrate_window(model: Model, parameters: ParameterSet, window: tuple[pd.Timestamp, pd.Timestamp],
                     out: str | Path, *,
                     observations: Any = None, truth: Mapping[str, float] | None = None, noise: str = "none",
                     seed: int = 0, warmup: pd.Timedelta | str = "24h", algorithm: str = "dud",
                     options: Mapping[str, Any] | None = None, workers: int | None = None,
                     max_nfev: int | None = None, deadline: float | None = None, on_failure: str = "raise",
                     dependency: Any = None, progress: Progress = NO_PROGRESS) -> tuple[dict[str, Any], Any]:
    """Estimate ``parameters`` over ``window`` and write the files of the module docstring.

    Parameters
    ----------
    model
        A loaded model (:func:`rivercal.model.load_model`).
    parameters
        The :class:`~rivercal.parameters.ParameterSet` to estimate (start values, bounds).
    window
        (start, end), UTC, inside the case period; the runs start ``warmup`` earlier.
    out
        Output folder (created).
    observations
        An :class:`~rivercal.observations.ObservationSet`; or None for a twin experiment.
    truth
        Twin experiment: the true values of (some of) the parameters (the others: their start values);
        the observations are the model's own series at the truth, with ``noise`` (seeded by ``seed``).
    algorithm, options, workers, max_nfev, deadline, on_failure
        As :func:`rivercal.problem.calibrate` and :class:`~rivercal.problem.CalibrationProblem`.
    dependency
        Sparse DuD's dependency map (:class:`~rivercal.analysis.dependency.DependencyMap`); None: dense.
    progress
        Where to say what happens (one step per iteration).

    Returns
    -------
    (dict, Calibration)
        The summary (also written to ``result.json``) and the calibration itself.
    """
    from rivercal.problem import CalibrationProblem, calibrate
    from rivercal.report.figures import plot_convergence, plot_cost
    from rivercal.twin import twin_truth

    if (observations is None) == (truth is None):
        raise ValueError("give either observations or the true values of a twin experiment")
    out = Path(out)
    warmup = pd.Timedelta(warmup)
    state = None
    if truth is not None:
        progress.stage("computing the twin truth")
        quantities = parameters.quantities({p.name: truth.get(p.name, p.initial) for p in parameters})
        twin = twin_truth(model, quantities, window, warmup=warmup, noise=noise, seed=seed)
        observations, state = twin.observations, twin.state
    problem = CalibrationProblem(model, parameters, observations, window, state=state, warmup=warmup,
                                 on_failure=on_failure)
    progress.stage(f"calibrating with {algorithm}")

    def callback(record) -> None:
        values = ", ".join(f"{k}={v:.4g}" for k, v in parameters.values(record.x).items())
        progress.step(record.nfev, max_nfev, f"iteration {record.nit}: cost {record.cost:.4g}, {values}; model runs")

    extra = {"dependency": dependency} if dependency is not None else {}
    cal = calibrate(problem, algorithm, dict(options or {}), workers=workers, max_nfev=max_nfev, deadline=deadline,
                    callback=callback, **extra)
    progress.stage("writing the files")
    out.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(cal.history).to_csv(out / "history.csv", index=False)
    runs = [{"run": i + 1, "cost": cost, **parameters.values(x)} for i, (x, cost) in enumerate(cal.result.evaluations)]
    pd.DataFrame(runs).to_csv(out / "evaluations.csv", index=False)
    files = {"history": str(out / "history.csv"), "evaluations": str(out / "evaluations.csv")}
    if cal.history:
        units = {p.name: p.unit for p in parameters}
        title = f"{model.name}: {algorithm}, window {window[0]:%Y-%m-%d}..{window[1]:%Y-%m-%d}"
        files["convergence"] = str(plot_convergence(cal.history, parameters.names, out / "convergence.png",
                                                    truth=dict(truth) if truth else None, units=units, title=title))
        files["cost"] = str(plot_cost(cal.history, out / "cost.png", title=f"{model.name}: cost per iteration"))
    files["summary"] = str(out / "result.json")
    summary: dict[str, Any] = {
        "case": model.name, "window": [window[0].isoformat(), window[1].isoformat()],
        "observations": {"series": len(problem.observations), "values": problem.observations.n_values,
                         "missing_dropped": problem.observations.n_missing},
        **cal.summary(), "files": files}
    summary["undetermined"] = undetermined(parameters, cal.std)
    if truth is not None:
        summary["truth"] = dict(truth)
        summary["error"] = {n: cal.estimates[n] - truth[n] for n in truth}
    summary = jsonable(summary)
    (out / "result.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return summary, cal


def undetermined(parameters: ParameterSet, std: Mapping[str, float]) -> dict[str, str]:
    """The parameters a calibration could not determine, each with why, in words.

    A parameter whose σ (thesis Eq. 2-12, from the observations' σ) is wider than its whole range
    (``max − min``, in its unit), or infinite, is one the observations in the window hardly depend on: its
    estimate says little, however well the optimiser converged (e.g. a bed friction seen only through discharges
    that its boundaries set). A method that gives no σ (``std`` without the name) judges none.
    """
    out: dict[str, str] = {}
    for p in parameters:
        sd = std.get(p.name)
        if sd is None:
            continue
        if not math.isfinite(sd) or sd > float(p.max) - float(p.min):
            shown = f"{sd:.2g}" if math.isfinite(sd) else "infinite"
            out[p.name] = (f"σ {shown} is wider than its whole range {p.min:g} .. {p.max:g}: the observations in "
                           "this window hardly depend on it, so its estimate says little")
    return out
