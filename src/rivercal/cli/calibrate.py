"""``rivercal calibrate``: estimate parameters over a window, from observations or in a twin experiment."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from rivercal.cli.common import (
    CaseArg,
    DaskOpt,
    DependencyOpt,
    DependencyThresholdOpt,
    JsonOpt,
    QuietOpt,
    Reporter,
    emit_json,
    out_console,
    stop_words,
)
from rivercal.cli.options import (
    WINDOW_HELP,
    check_choice,
    check_number,
    check_truth,
    check_workers,
    dask_address,
    open_model,
    optimiser_options,
    output_dir,
    parse_assignments,
    parse_window,
    read_dependency,
    select_parameters,
    window_observations,
    workers_for,
)
from rivercal.errors import OptionError

__all__ = ["DEFAULT_OUT", "calibrate", "new_folder"]

#: Where calibrations go without ``--out``: each into a new folder of its own below this one.
DEFAULT_OUT = Path("out/calibrate")


def new_folder(parent: Path, name: str) -> Path:
    """A folder that does not exist yet below ``parent``: ``<name>-<UTC time>`` (``-2``, ``-3`` … when taken)."""
    import datetime

    stamp = datetime.datetime.now(datetime.UTC).strftime("%Y%m%dT%H%M%SZ")
    base = parent / f"{Path(name).name}-{stamp}"
    folder, n = base, 1
    while True:
        try:
            folder.mkdir(parents=True)
            return folder
        except FileExistsError:
            n += 1
            folder = base.with_name(f"{base.name}-{n}")


def calibrate(
    case: CaseArg,
    params: Annotated[str, typer.Option("--params", help="Parameters to estimate, e.g. FA,Wc (defined by the case).")],
    window: Annotated[str, typer.Option(help=WINDOW_HELP)],
    observations: Annotated[Path | None, typer.Option(
        help="Observations: a CSV (time + '<station>.<quantity>' columns), a PI-XML file, or a sidecar TOML "
             "describing gauge files (docs/howto/your-gauges.md).")] = None,
    twin: Annotated[str | None, typer.Option(help="Twin experiment: true values, e.g. 'FA=20,Wc=0.8'.")] = None,
    start: Annotated[str | None, typer.Option(help="Start values, e.g. 'FA=14,Wc=0.1' (default: the case's).")] = None,
    bounds: Annotated[list[str], typer.Option("--bounds", help="Override bounds NAME=MIN:MAX; repeatable.")] = [],  # noqa: B006
    algorithm: Annotated[str | None, typer.Option(help="Optimiser (default: the case's, usually dud).")] = None,
    option: Annotated[list[str], typer.Option("--option", help="Optimiser option KEY=VALUE; repeatable.")] = [],  # noqa: B006
    noise: Annotated[str, typer.Option(help="Twin noise: none, white, gaussian or pink.")] = "none",
    seed: Annotated[int, typer.Option(help="Seed of the twin noise (≥ 0).")] = 0,
    warmup: Annotated[float, typer.Option(help="Hours simulated before the window in every run.")] = 24.0,
    workers: Annotated[int | None, typer.Option(help="Worker processes (default: all cores).")] = None,
    dask: DaskOpt = None,
    dependency: DependencyOpt = None,
    dependency_threshold: DependencyThresholdOpt = 0.1,
    max_nfev: Annotated[int | None, typer.Option("--max-nfev", help="Cap on model runs.")] = None,
    deadline: Annotated[float | None, typer.Option(help="Wall-clock limit, s.")] = None,
    on_failure: Annotated[str, typer.Option(help="Failed model run: raise or penalty.")] = "raise",
    out: Annotated[Path | None, typer.Option(
        "--out", help="Output folder (files of an earlier calibration there are replaced). Default: a new folder "
                      "out/calibrate/<case>-<UTC time> for each calibration, so none replaces another.")] = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Estimate parameters from observations (or a twin experiment) over a window."""
    import pandas as pd

    from rivercal.optimise import OPTIMISERS
    from rivercal.optimise.registry import RENAMED
    from rivercal.twin import NOISE_MODELS
    from rivercal.workflows.calibrate import calibrate_window

    # -- everything is checked before the first model run: first what needs no case
    if (observations is None) == (twin is None):
        raise OptionError("give either --observations FILE or --twin 'NAME=VALUE,...'")
    check_choice(noise, "--noise", NOISE_MODELS)
    if observations is not None and noise != "none":
        raise OptionError("--noise applies to twin experiments (--twin) only", option="--noise")
    check_number(seed, "--seed", low=0)
    check_number(warmup, "--warmup", low=0, high=8784)  # at most a (leap) year, in hours
    check_workers(workers)
    address = dask_address(dask, workers)
    check_number(max_nfev, "--max-nfev", low=1)
    check_number(deadline, "--deadline", low=0, low_open=True)
    check_choice(on_failure, "--on-failure", ("raise", "penalty"))
    if algorithm is not None:
        check_choice(algorithm, "--algorithm", sorted(OPTIMISERS), former=RENAMED)
    truth = parse_assignments(twin, "--twin") if twin is not None else None
    start_values = parse_assignments(start, "--start")
    output_dir(out if out is not None else DEFAULT_OUT)  # a folder that cannot be written fails before any run
    # -- then what needs the case
    model = open_model(case, show_compilation=not quiet)
    setup = model.calibration
    algo = algorithm or setup.algorithm
    pset = select_parameters(model, params, start_values, bounds)
    defaults = dict(setup.options) if algo == setup.algorithm else {}
    opts = optimiser_options(algo, option, defaults, pset)
    dependency_map = read_dependency(dependency, dependency_threshold, algo, pset.names)
    hours = pd.Timedelta(hours=warmup)
    win = parse_window(model, window, warmup=hours)
    check_truth(pset, truth or {})
    obs = window_observations(observations, model, win) if observations is not None else None

    if out is None:
        out = new_folder(DEFAULT_OUT, model.name)
    reporter = Reporter(not (quiet or as_json))
    with reporter.running("calibrating"), workers_for(workers, address) as where:
        summary, cal = calibrate_window(model, pset, win, out, observations=obs, truth=truth, noise=noise, seed=seed,
                                        warmup=hours, algorithm=algo, options=opts, workers=where,
                                        max_nfev=max_nfev, deadline=deadline, on_failure=on_failure,
                                        dependency=dependency_map, progress=reporter)
    if as_json:
        emit_json(summary)
    elif not quiet:
        _print(summary, cal, pset, win)


def _print(summary: dict, cal, pset, win) -> None:
    twin = "truth" in summary
    table = Table(title=f"{summary['case']}: {summary['algorithm']} over {win[0]:%Y-%m-%d %H:%M} .. "
                        f"{win[1]:%Y-%m-%d %H:%M}")
    # σ from the observations' σ as given, and σ scaled by the fit's own residual variance S/(m − p):
    # the second is right when the given σ are not (uniform or unknown observation errors).
    for col in ("parameter", "start", "estimate", "σ", "σ scaled", *(["true"] if twin else [])):
        table.add_column(col, justify="right" if col != "parameter" else "left")
    for p in pset:
        row = [p.name, f"{cal.initial[p.name]:.4f}", f"{cal.estimates[p.name]:.4f}",
               *(f"{std[p.name]:.2g}" if p.name in std else "-" for std in (cal.std, cal.std_scaled))]
        if twin:
            row.append(f"{summary['truth'][p.name]:.4f}" if p.name in summary["truth"] else "-")
        table.add_row(*row)
    out_console.print(table)
    r = cal.result
    out_console.print(f"cost {r.cost:.4g} after {r.nit} iterations, {r.nfev} model runs, {cal.wall_time:.1f} s; "
                      f"{stop_words(r)}", highlight=False, markup=False)
    for name, why in (summary.get("undetermined") or {}).items():
        out_console.print(f"not determined: {name}: {why}", style="yellow", highlight=False, markup=False)
    out_console.print("wrote " + ", ".join(summary["files"].values()), highlight=False, markup=False)
