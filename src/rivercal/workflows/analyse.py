"""Sensitivity, identifiability and residual analysis of a model over a window (thesis §4-5-1).

The observations are a twin truth (by default at the parameters' initial values, as in the thesis'
initial analysis) or given. The analysis point is the parameters' initial values. The sensitivity
scenarios and the Jacobian runs share one pool of worker processes; ``model_runs`` in the summary
counts the runs of the analyses (not the twin truth or the spin-up to the start state).

Files under ``out``: ``sensitivity_scenarios.csv`` (thesis Table 4-4), ``sensitivity_costs.csv`` (total and
per station), ``sensitivity_costs_series.csv``, ``sensitivity_long.csv`` (tidy), ``jacobian.csv``,
``singular_values.csv``, ``singular_vectors.csv``, ``covariance.csv``, ``correlation.csv``,
``identifiability.csv`` (the verdict), ``dependency.csv`` (from the same Jacobian: the effect of each
parameter's first DuD step on each series, in σ, the dependency map of Sparse DuD;
:mod:`rivercal.analysis.dependency`), ``residual_statistics.csv`` (weighted) and
``residual_statistics_units.csv``, ``moving_bias.csv``, ``bias_significance.csv``, the figures
``sensitivity.png``, ``sensitivity_stations.png``, ``svd.png``, ``correlation.png``, ``bias.png``, and
``analysis.json`` (the summary).
"""

from __future__ import annotations

import json
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from rivercal.models.contract import Model
from rivercal.parameters import ParameterSet
from rivercal.workflows.progress import NO_PROGRESS, Progress, jsonable

__all__ = ["ANALYSES", "analyse_window"]

#: The analyses :func:`analyse_window` can run.
ANALYSES = ("sensitivity", "identifiability", "residuals")


def analyse_window(model: Model, parameters: ParameterSet, window: tuple[pd.Timestamp, pd.Timestamp],
                   out: str | Path, *,
                   analyses: Sequence[str] = ("sensitivity", "identifiability"), observations: Any = None,
                   source: Mapping[str, Any] | None = None, truth: Mapping[str, float] | None = None,
                   noise: str = "none", seed: int = 0, warmup: pd.Timedelta | str = "24h",
                   workers: int | None = None, rel_step: float = 0.01, scheme: str = "forward",
                   identifiability_options: Any = None, bias_window: str = "2h",
                   progress: Progress = NO_PROGRESS) -> dict[str, Any]:
    """Run ``analyses`` of ``parameters`` over ``window`` and write the files of the module docstring.

    Parameters
    ----------
    model
        A loaded model (:func:`rivercal.model.load_model`).
    parameters
        The :class:`~rivercal.parameters.ParameterSet`; the analysis point is their initial values.
    window
        (start, end), UTC, inside the case period; the runs start ``warmup`` earlier.
    out
        Output folder (created).
    analyses
        Any of :data:`ANALYSES`.
    observations, source
        Given observations and a description of where they come from (e.g. ``{"file": path}``); with
        None a twin truth is computed.
    truth
        True values of (some of) the case's parameters for the twin truth (the others: the case's
        initial values), with ``noise`` seeded by ``seed``.
    rel_step, scheme, identifiability_options
        The Jacobian's step (fraction of each parameter's range), ``forward`` or ``central``, and
        :class:`~rivercal.analysis.IdentifiabilityOptions`.
    bias_window
        Moving window T of the bias of thesis Eq. 2-14, e.g. '2h'.
    progress
        Where to say what happens.

    Returns
    -------
    dict
        The summary (also written to ``analysis.json``).
    """
    from rivercal.problem import CalibrationProblem, problem_evaluator
    from rivercal.twin import twin_truth

    unknown = [a for a in analyses if a not in ANALYSES]
    if unknown:
        raise ValueError(f"unknown analysis {unknown[0]!r}; choose from {', '.join(ANALYSES)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    warmup = pd.Timedelta(warmup)
    t0 = time.perf_counter()
    defined = model.calibration.parameters
    files: dict[str, str] = {}
    summary: dict[str, Any] = {"case": model.name, "window": [window[0].isoformat(), window[1].isoformat()],
                               "parameters": parameters.names, "units": {p.name: p.unit for p in parameters},
                               "analysis_point": {p.name: p.initial for p in parameters}}
    state = None
    if observations is None:
        initial = {p.name: p.initial for p in defined}
        values = {**initial, **dict(truth or {})}
        quantities = {q: v for p in defined for q, v in p.quantities(values[p.name]).items()
                      if p.name in parameters.names}
        progress.stage("computing the twin truth")
        twin = twin_truth(model, quantities, window, warmup=warmup, noise=noise, seed=seed)
        observations, state = twin.observations, twin.state
        summary["observations_source"] = {"twin": {n: values[n] for n in parameters.names}, "noise": noise,
                                          "seed": seed}
    else:
        summary["observations_source"] = dict(source or {})
    problem = CalibrationProblem(model, parameters, observations, window, state=state, warmup=warmup)
    summary["observations"] = {"series": problem.observations.ids, "values": problem.observations.n_values}
    progress.stage("computing the start state")
    problem.state  # noqa: B018 - before the workers fork
    problem.sqrt_weights  # noqa: B018
    nfev = 0
    with problem_evaluator(problem, workers) as batch:
        if "sensitivity" in analyses:
            progress.stage("sensitivity: one-at-a-time scenarios (thesis Table 4-4)")
            summary["sensitivity"], n = _sensitivity(problem, batch, out, files, model.name)
            nfev += n
        if "identifiability" in analyses:
            progress.stage(f"identifiability: Jacobian of {len(parameters)} parameters")
            summary["identifiability"], n = _identifiability(problem, batch, out, files, model.name, rel_step,
                                                              scheme, identifiability_options)
            nfev += n
    if "residuals" in analyses:
        progress.stage("residuals at the analysis point")
        summary["residuals"] = _residuals(problem, out, files, model.name, bias_window)
        nfev += 1
    summary["model_runs"] = nfev
    summary["wall_s"] = round(time.perf_counter() - t0, 2)
    files["summary"] = str(out / "analysis.json")
    summary["files"] = files
    summary = jsonable(summary)
    (out / "analysis.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    return summary


def _sensitivity(problem, batch, out: Path, files: dict, case_name: str) -> tuple[dict, int]:
    from rivercal.analysis import sensitivity
    from rivercal.analysis.figures import plot_sensitivity, plot_sensitivity_stations

    result = sensitivity(problem, batch=batch)
    result.table.to_csv(out / "sensitivity_scenarios.csv")
    result.costs("station").to_csv(out / "sensitivity_costs.csv")
    result.costs("series").to_csv(out / "sensitivity_costs_series.csv")
    result.frame.to_csv(out / "sensitivity_long.csv", index=False)
    files["sensitivity_scenarios"] = str(out / "sensitivity_scenarios.csv")
    files["sensitivity_costs"] = str(out / "sensitivity_costs.csv")
    files["sensitivity_costs_series"] = str(out / "sensitivity_costs_series.csv")
    files["sensitivity_long"] = str(out / "sensitivity_long.csv")
    files["sensitivity_figure"] = str(plot_sensitivity(
        result, out / "sensitivity.png", title=f"{case_name}: total cost per one-at-a-time scenario (Fig. 4-5)"))
    files["sensitivity_stations_figure"] = str(plot_sensitivity_stations(
        result, out / "sensitivity_stations.png", title=f"{case_name}: cost per station (Figs. C-1 … C-5)"))
    summary = result.summary()
    total = result.costs("station")["total"]
    return {"model_runs": summary["model_runs"], "base_cost": summary["base_cost"], "ranking": summary["ranking"],
            "total_cost": {str(k): float(v) for k, v in total.items()}}, result.nfev


def _identifiability(problem, batch, out: Path, files: dict, case_name: str, rel_step: float, scheme: str,
                     options) -> tuple[dict, int]:
    from rivercal.analysis import identifiability
    from rivercal.analysis.dependency import DependencyMap, effects_of
    from rivercal.analysis.figures import plot_correlation, plot_svd
    from rivercal.report.identifiability import summary as explained
    from rivercal.report.identifiability import verdict_table

    result = identifiability(problem, rel_step=rel_step, scheme=scheme, options=options, batch=batch)
    jac = result.extra["jacobian"]
    jac.to_frame().to_csv(out / "jacobian.csv")
    result.singular_frame().to_csv(out / "singular_values.csv")
    result.vectors_frame().to_csv(out / "singular_vectors.csv")
    result.covariance_frame().to_csv(out / "covariance.csv")
    result.correlation_frame().to_csv(out / "correlation.csv")
    verdict_table(result).to_csv(out / "identifiability.csv")
    dependency = DependencyMap(effects_of(jac, problem.parameters.initial_steps()))
    dependency.to_csv(out / "dependency.csv")
    for name in ("jacobian", "singular_values", "singular_vectors", "covariance", "correlation", "identifiability",
                 "dependency"):
        files[name] = str(out / f"{name}.csv")
    files["svd_figure"] = str(plot_svd(result, out / "svd.png",
                                       title=f"{case_name}: singular value decomposition (Fig. 4-6)"))
    files["correlation_figure"] = str(plot_correlation(result, out / "correlation.png",
                                                       title=f"{case_name}: parameter correlation (Fig. 4-7)"))
    summary = explained(result)
    summary["scale"] = {n: float(d) for n, d in zip(result.names, result.scale, strict=True)}
    summary["rel_step"] = rel_step
    summary["scheme"] = scheme
    summary["model_runs"] = jac.nfev
    per_series = dependency.seen.sum(axis=1).astype(int)
    summary["dependency"] = {"threshold_sigma": dependency.threshold, "most_parameters_per_series": dependency.k,
                             "parameters_per_series": per_series.to_dict(),
                             "widest": per_series.sort_values(ascending=False, kind="stable").head(3).to_dict()}
    return summary, jac.nfev


def _residuals(problem, out: Path, files: dict, case_name: str, bias_window: str) -> dict:
    from rivercal.analysis import bias_significance, error_statistics, errors, moving_bias
    from rivercal.analysis.figures import plot_bias

    result = problem.simulate(problem.x0)
    weighted = errors(problem.observations, result.series)
    plain = errors(problem.observations.to_frame(), result.series)
    stats = error_statistics(weighted)
    stats_plain = error_statistics(plain)
    moving = moving_bias(weighted, bias_window)
    significance = bias_significance(moving)
    stats.to_csv(out / "residual_statistics.csv")
    stats_plain.to_csv(out / "residual_statistics_units.csv")
    moving.to_csv(out / "moving_bias.csv", index=False)
    significance.to_csv(out / "bias_significance.csv")
    files["residual_statistics"] = str(out / "residual_statistics.csv")
    files["residual_statistics_units"] = str(out / "residual_statistics_units.csv")
    files["moving_bias"] = str(out / "moving_bias.csv")
    files["bias_significance"] = str(out / "bias_significance.csv")
    files["bias_figure"] = str(plot_bias(moving, out / "bias.png", title=f"{case_name}: moving-window bias "
                                         f"(Eq. 2-14, T = {bias_window}, weighted errors)"))
    return {"weighted": _records(stats), "units": _records(stats_plain), "bias_window": bias_window,
            "bias": _records(significance)}


def _records(frame) -> dict:
    out = {}
    for name, row in frame.iterrows():
        out[str(name)] = {k: (v.item() if hasattr(v, "item") else v) for k, v in row.items()}
    return out
