"""``rivercal analyse``: sensitivity, identifiability and residual analysis of a case (thesis §4-5-1).

The observations come from a twin truth at the case's initial parameter values (as in the thesis'
initial analysis; ``--twin NAME=VALUE,...`` changes some true values) or from ``--observations FILE``.
The analysis point is the initial values (``--start`` changes some). The work and the files are
:func:`rivercal.workflows.analyse.analyse_window`'s; this module checks the options and prints.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rivercal.cli.common import CaseArg, DaskOpt, JsonOpt, QuietOpt, Reporter, emit_json, out_console
from rivercal.cli.options import (
    WINDOW_HELP,
    check_choice,
    check_number,
    check_truth,
    check_workers,
    dask_address,
    open_model,
    output_dir,
    parse_assignments,
    parse_duration,
    parse_names,
    parse_window,
    select_parameters,
    window_observations,
    workers_for,
)
from rivercal.errors import OptionError

__all__ = ["analyse"]


def analyse(
    case: CaseArg,
    params: Annotated[str | None, typer.Option(
        "--params", help="Parameters to analyse, e.g. W1,W2,FA (default: every single-target parameter).")] = None,
    what: Annotated[str, typer.Option(
        help="Comma-separated analyses: sensitivity, identifiability, residuals.")] = "sensitivity,identifiability",
    window: Annotated[str, typer.Option(help=WINDOW_HELP)] = "moderate",
    observations: Annotated[Path | None, typer.Option(
        help="Observations: a CSV (time + '<station>.<quantity>' columns), a PI-XML file or a sidecar TOML "
             "(docs/howto/your-gauges.md); default: a twin truth.")] = None,
    twin: Annotated[str | None, typer.Option(
        help="True values of the twin observations, e.g. 'FA=20' (default: the case's initial values).")] = None,
    start: Annotated[str | None, typer.Option(
        help="Analysis point, e.g. 'FA=14' (default: the case's initial values).")] = None,
    noise: Annotated[str, typer.Option(help="Twin noise: none, white, gaussian or pink.")] = "none",
    seed: Annotated[int, typer.Option(help="Seed of the twin noise (≥ 0).")] = 0,
    warmup: Annotated[float, typer.Option(help="Hours simulated before the window in every run.")] = 24.0,
    workers: Annotated[int | None, typer.Option(help="Worker processes (default: all cores).")] = None,
    dask: DaskOpt = None,
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
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Sensitivity (Table 4-4), identifiability (SVD, correlation, verdict) and residual bias of a case."""
    import pandas as pd

    from rivercal.analysis import IdentifiabilityOptions
    from rivercal.twin import NOISE_MODELS
    from rivercal.workflows.analyse import ANALYSES, analyse_window

    # -- everything is checked before the first model run: first what needs no case
    tasks = parse_names(what, "--what")
    for task in tasks:
        check_choice(task, "--what", ANALYSES)
    if not tasks:
        raise OptionError(f"--what: give at least one of {', '.join(ANALYSES)}", option="--what")
    if observations is not None and (twin is not None or noise != "none"):
        raise OptionError("--twin and --noise make twin observations; they do not combine with --observations",
                          option="--observations")
    check_choice(noise, "--noise", NOISE_MODELS)
    check_choice(scheme, "--scheme", ("forward", "central"))
    check_number(rel_step, "--rel-step", low=0, high=0.5, low_open=True)
    check_number(seed, "--seed", low=0)
    check_number(warmup, "--warmup", low=0, high=8784)  # at most a (leap) year, in hours
    check_workers(workers)
    address = dask_address(dask, workers)
    check_number(sv_threshold, "--sv-threshold", low=0, high=1, low_open=True, high_open=True)
    check_number(k, "--k", low=1)
    check_number(corr_threshold, "--corr-threshold", low=0, high=1, low_open=True, high_open=True)
    parse_duration(bias_window, "--bias-window")
    truth = parse_assignments(twin, "--twin") if twin is not None else {}
    start_values = parse_assignments(start, "--start")
    output_dir(out)
    try:
        options = IdentifiabilityOptions(sv_threshold=sv_threshold, k=k, correlation=corr_threshold)
    except ValueError as exc:  # the options' own rules between the values
        raise OptionError(f"--sv-threshold/--k/--corr-threshold: {exc}", option="--sv-threshold") from None
    # -- then what needs the case
    model = open_model(case, show_compilation=not quiet)
    if params is None:
        single = [p.name for p in model.calibration.parameters if len(p.targets) == 1 and not p.cluster]
        if not single:
            raise OptionError(f"--params: {model.name!r} defines no single-target parameter; name some",
                              option="--params")
        params = ",".join(single)
    pset = select_parameters(model, params, start_values, [])
    if k is not None and k > len(pset):
        raise OptionError(f"--k {k}: more than the {len(pset)} parameters analysed", option="--k")
    hours = pd.Timedelta(hours=warmup)
    win = parse_window(model, window, warmup=hours)
    check_truth(pset, truth)
    obs = window_observations(observations, model, win) if observations is not None else None

    reporter = Reporter(not (quiet or as_json))
    with reporter.running("starting"), workers_for(workers, address) as where:
        summary = analyse_window(model, pset, win, out, analyses=tasks, observations=obs,
                                 source={"file": str(observations)} if observations is not None else None,
                                 truth=truth, noise=noise, seed=seed, warmup=hours, workers=where,
                                 rel_step=rel_step, scheme=scheme, identifiability_options=options,
                                 bias_window=bias_window, progress=reporter)
    if as_json:
        emit_json(summary)
    elif not quiet:
        _print(summary, out_console)


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
        dep = ident["dependency"]
        widest = ", ".join(f"{s} {n}" for s, n in dep["widest"].items())
        console.print(f"dependency map (for --algorithm sparse_dud --dependency): each series depends on at most "
                      f"{dep['most_parameters_per_series']} of the {len(ident['parameters'])} parameters (those whose "
                      f"first step moves it by more than {dep['threshold_sigma']:g} σ; most: {widest})",
                      highlight=False)
    if "residuals" in summary:
        total = summary["residuals"]["weighted"]["total"]
        console.print(f"residuals (weighted): cost {total['cost']:.4g}, RMSE {total['rmse']:.3g}, "
                      f"bias {total['bias']:.3g}, std {total['std']:.3g}")
    console.print("wrote " + ", ".join(summary["files"].values()))
