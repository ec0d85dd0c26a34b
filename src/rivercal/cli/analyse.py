"""``rivercal analyse``: sensitivity, identifiability and residual analysis of a case (thesis §4-5-1).

The observations come from a twin truth at the case's initial parameter values (as in the thesis'
initial analysis; ``--twin NAME=VALUE,...`` changes some true values) or from ``--observations FILE``.
The analysis point is the initial values (``--start`` changes some). The sensitivity scenarios and the
Jacobian runs share one pool of worker processes. ``model_runs`` in the summary counts the runs of the
analyses (not the twin truth or the spin-up to the start state).

Files under ``--out``: ``sensitivity_scenarios.csv`` (thesis Table 4-4), ``sensitivity_costs.csv`` (total and
per station), ``sensitivity_costs_series.csv``, ``sensitivity_long.csv`` (tidy), ``jacobian.csv``,
``singular_values.csv``, ``singular_vectors.csv``, ``covariance.csv``, ``correlation.csv``,
``identifiability.csv`` (the verdict), ``residual_statistics.csv`` (weighted) and
``residual_statistics_units.csv``, ``moving_bias.csv``, ``bias_significance.csv``, the figures
``sensitivity.png``, ``sensitivity_stations.png``, ``svd.png``, ``correlation.png``, ``bias.png``, and
``analysis.json`` (the summary printed with ``--json``).
"""

from pathlib import Path
from typing import Annotated

import typer

from rivercal.cli.common import (
    emit_json,
    err_console,
    guard,
    null_context,
    out_console,
    parse_assignments,
    parse_window,
    select_parameters,
)

__all__ = ["analyse"]

WHAT = ("sensitivity", "identifiability", "residuals")


def analyse(
    case: Annotated[str, typer.Argument(help="A case folder or the name of a packaged case (e.g. 'dommel').")],
    params: Annotated[str | None, typer.Option(
        "--params", help="Parameters to analyse, e.g. W1,W2,FA (default: every single-target parameter).")] = None,
    what: Annotated[str, typer.Option(
        help="Comma-separated analyses: sensitivity, identifiability, residuals.")] = "sensitivity,identifiability",
    window: Annotated[str, typer.Option(help="START/END (UTC dates) or a window of the case.")] = "moderate",
    observations: Annotated[Path | None, typer.Option(
        help="Observation CSV (time + '<station>.<quantity>' columns); default: a twin truth.")] = None,
    twin: Annotated[str | None, typer.Option(
        help="True values of the twin observations, e.g. 'FA=20' (default: the case's initial values).")] = None,
    start: Annotated[str | None, typer.Option(
        help="Analysis point, e.g. 'FA=14' (default: the case's initial values).")] = None,
    noise: Annotated[str, typer.Option(help="Twin noise: none, white, gaussian or pink.")] = "none",
    seed: Annotated[int, typer.Option(help="Seed of the twin noise.")] = 0,
    warmup: Annotated[float, typer.Option(help="Hours simulated before the window in every run.")] = 24.0,
    workers: Annotated[int | None, typer.Option(help="Worker processes (default: all cores).")] = None,
    rel_step: Annotated[float, typer.Option(
        "--rel-step", help="Finite-difference step as a fraction of each parameter's range.")] = 0.01,
    scheme: Annotated[str, typer.Option(help="Finite differences: forward (p+1 runs) or central (2p+1).")] = "forward",
    sv_threshold: Annotated[float, typer.Option(
        "--sv-threshold", help="Singular values at least this fraction of the largest are significant.")] = 0.01,
    k: Annotated[int | None, typer.Option(
        "--k", help="Number of singular values for the identifiability index (default: the significant ones).")] = None,
    corr_threshold: Annotated[float, typer.Option(
        "--corr-threshold", help="|correlation| above which parameters count only in combination.")] = 0.9,
    bias_window: Annotated[str, typer.Option(
        "--bias-window", help="Moving window T of the bias (Eq. 2-14), e.g. 2h.")] = "2h",
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out/analyse"),
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress or summary on the terminal.")] = False,
) -> None:
    """Sensitivity (Table 4-4), identifiability (SVD, correlation, verdict) and residual bias of a case."""
    guard(_run)(case=case, params=params, what=what, window=window, observations=observations, twin=twin,
                start=start, noise=noise, seed=seed, warmup=warmup, workers=workers, rel_step=rel_step,
                scheme=scheme, sv_threshold=sv_threshold, k=k, corr_threshold=corr_threshold,
                bias_window=bias_window, out=out, as_json=as_json, quiet=quiet)


def _run(*, case, params, what, window, observations, twin, start, noise, seed, warmup, workers, rel_step, scheme,
         sv_threshold, k, corr_threshold, bias_window, out, as_json, quiet) -> None:
    import json
    import time

    import pandas as pd

    from rivercal.analysis import IdentifiabilityOptions
    from rivercal.case import load_case
    from rivercal.evaluate import Evaluator
    from rivercal.io.observations import read_observations_csv
    from rivercal.model import build_model
    from rivercal.problem import CalibrationProblem
    from rivercal.twin import NOISE_MODELS, twin_truth

    # -- everything is checked before the first model run
    tasks = [w.strip() for w in what.split(",") if w.strip()]
    for task in tasks:
        if task not in WHAT:
            raise ValueError(f"--what {task!r}: choose from {', '.join(WHAT)}")
    if not tasks:
        raise ValueError(f"--what: give at least one of {', '.join(WHAT)}")
    if observations is not None and (twin or noise != "none"):
        raise ValueError("--twin and --noise make twin observations; they do not combine with --observations")
    if noise not in NOISE_MODELS:
        raise ValueError(f"--noise {noise!r}: choose one of {', '.join(NOISE_MODELS)}")
    if scheme not in ("forward", "central"):
        raise ValueError(f"--scheme {scheme!r}: choose forward or central")
    if not 0.0 < rel_step <= 0.5:
        raise ValueError(f"--rel-step {rel_step}: must be in (0, 0.5]")
    if warmup < 0:
        raise ValueError(f"--warmup {warmup}: must not be negative")
    if not pd.Timedelta(bias_window) > pd.Timedelta(0):
        raise ValueError(f"--bias-window {bias_window!r}: must be positive")
    options = IdentifiabilityOptions(sv_threshold=sv_threshold, k=k, correlation=corr_threshold)
    c = load_case(case)
    if params is None:
        single = [p.name for p in c.spec.parameters if len(p.targets) == 1 and not p.cluster]
        if not single:
            raise ValueError(f"case {c.name!r} defines no single-target parameter; name some with --params")
        params = ",".join(single)
    pset = select_parameters(c, params, parse_assignments(start, "--start"), [])
    win = parse_window(c, window)
    truth_values = parse_assignments(twin, "--twin") if twin else {}
    for name, value in truth_values.items():
        p = pset[name] if name in pset.names else None
        if p is None:
            raise ValueError(f"--twin {name}: {name!r} is not in --params")
        if not p.min <= value <= p.max:
            raise ValueError(f"--twin {name}={value:g}: outside its bounds [{p.min:g}, {p.max:g}]")
    obs = None
    if observations is not None:
        obs = read_observations_csv(observations).within(*win)
        if obs.n_values == 0:
            raise ValueError(f"{observations}: no observations in the window {win[0]} .. {win[1]}")

    # -- runs
    t0 = time.perf_counter()
    show = not (quiet or as_json)
    status = err_console.status("loading the model", spinner="dots") if show else null_context()
    files: dict[str, str] = {}
    summary: dict = {"case": c.name, "window": [win[0].isoformat(), win[1].isoformat()], "parameters": pset.names,
                     "units": {p.name: p.unit for p in pset}, "analysis_point": {p.name: p.initial for p in pset}}
    out.mkdir(parents=True, exist_ok=True)
    with status as live:
        sim = build_model(c)
        state = None
        if obs is None:
            case_initial = {p.name: p.initial for p in c.spec.parameters}
            truth = {**case_initial, **truth_values}
            truth_q = {q: v for p in c.spec.parameters for q, v in p.quantities(truth[p.name]).items()
                       if p.name in pset.names}
            _update(live, "computing the twin truth")
            tw = twin_truth(sim, truth_q, win, warmup=pd.Timedelta(hours=warmup), noise=noise, seed=seed)
            obs, state = tw.observations, tw.state
            summary["observations_source"] = {"twin": {n: truth[n] for n in pset.names}, "noise": noise,
                                              "seed": seed}
        else:
            summary["observations_source"] = {"file": str(observations)}
        problem = CalibrationProblem(sim, pset, obs, win, state=state, warmup=pd.Timedelta(hours=warmup))
        summary["observations"] = {"series": problem.observations.ids, "values": problem.observations.n_values}
        _update(live, "computing the start state")
        problem.state  # noqa: B018 - before the workers fork
        problem.sqrt_weights  # noqa: B018
        nfev = 0
        with Evaluator(problem.residuals, workers=workers) as batch:
            if "sensitivity" in tasks:
                _update(live, "sensitivity: one-at-a-time scenarios (thesis Table 4-4)")
                summary["sensitivity"], n = _sensitivity(problem, batch, out, files, c.name)
                nfev += n
            if "identifiability" in tasks:
                _update(live, f"identifiability: Jacobian of {len(pset)} parameters")
                summary["identifiability"], n = _identifiability(problem, batch, out, files, c.name, rel_step,
                                                                  scheme, options)
                nfev += n
        if "residuals" in tasks:
            _update(live, "residuals at the analysis point")
            summary["residuals"] = _residuals(problem, out, files, c.name, bias_window)
            nfev += 1
    summary["model_runs"] = nfev
    summary["wall_s"] = round(time.perf_counter() - t0, 2)
    summary["files"] = files
    files["summary"] = str(out / "analysis.json")
    summary = _clean(summary)
    (out / "analysis.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    if as_json:
        emit_json(summary)
        return
    if not quiet:
        _print(summary, out_console)


def _update(live, text: str) -> None:
    if live is not None and hasattr(live, "update"):
        live.update(text)


def _clean(value):
    """JSON-safe: numpy scalars to Python, NaN and ±inf to None, containers recursively."""
    import math

    import numpy as np

    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if value is None or isinstance(value, bool | int | float | str):
        return value
    return str(value)


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
    from rivercal.analysis.figures import plot_correlation, plot_svd

    result = identifiability(problem, rel_step=rel_step, scheme=scheme, options=options, batch=batch)
    jac = result.extra["jacobian"]
    jac.to_frame().to_csv(out / "jacobian.csv")
    result.singular_frame().to_csv(out / "singular_values.csv")
    result.vectors_frame().to_csv(out / "singular_vectors.csv")
    result.covariance_frame().to_csv(out / "covariance.csv")
    result.correlation_frame().to_csv(out / "correlation.csv")
    result.verdict.to_csv(out / "identifiability.csv")
    for name in ("jacobian", "singular_values", "singular_vectors", "covariance", "correlation", "identifiability"):
        files[name] = str(out / f"{name}.csv")
    files["svd_figure"] = str(plot_svd(result, out / "svd.png",
                                       title=f"{case_name}: singular value decomposition (Fig. 4-6)"))
    files["correlation_figure"] = str(plot_correlation(result, out / "correlation.png",
                                                       title=f"{case_name}: parameter correlation (Fig. 4-7)"))
    summary = result.summary()
    summary["scale"] = {n: float(d) for n, d in zip(result.names, result.scale, strict=True)}
    summary["rel_step"] = rel_step
    summary["scheme"] = scheme
    summary["model_runs"] = jac.nfev
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


def _print(summary: dict, console) -> None:
    from rich.table import Table

    console.print(f"[bold]{summary['case']}[/]: analysis of {', '.join(summary['parameters'])} over "
                  f"{summary['window'][0]} .. {summary['window'][1]} ({summary['model_runs']} model runs, "
                  f"{summary['wall_s']} s)")
    if "sensitivity" in summary:
        table = Table(title="sensitivity: largest total cost per parameter (most influential first)")
        for col in ("parameter", "max cost", "scenario"):
            table.add_column(col, justify="right" if col != "parameter" else "left")
        for r in summary["sensitivity"]["ranking"]:
            table.add_row(r["parameter"], f"{r['max_cost']:.4g}", r["scenario"])
        console.print(table)
    if "identifiability" in summary:
        ident = summary["identifiability"]
        console.print("singular values: " + ", ".join(f"{v:.3g}" for v in ident["singular_values"])
                      + f" (k = {ident['k']} significant)")
        table = Table(title="identifiability")
        for col in ("parameter", "verdict", "identifiability index", "std", "unit"):
            table.add_column(col, justify="right" if col in ("identifiability index", "std") else "left")
        for n in ident["parameters"]:
            std = ident["std"][n]
            table.add_row(n, ident["verdict"][n], f"{ident['identifiability_index'][n]:.2f}",
                          "-" if std is None else f"{std:.3g}", summary.get("units", {}).get(n, ""))
        console.print(table)
        for n in ident["parameters"]:
            console.print(f"- {ident['explanations'][n]}", highlight=False)
        for c in ident["clusters"]:
            console.print(f"[bold]suggestion[/]: {c['explanation']}", highlight=False)
    if "residuals" in summary:
        total = summary["residuals"]["weighted"]["total"]
        console.print(f"residuals (weighted): cost {total['cost']:.4g}, RMSE {total['rmse']:.3g}, "
                      f"bias {total['bias']:.3g}, std {total['std']:.3g}")
    console.print("wrote " + ", ".join(summary["files"].values()))
