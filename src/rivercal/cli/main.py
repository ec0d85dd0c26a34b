"""The ``rivercal`` command line: parse, call the library, print.

Every command that produces numbers prints them as one JSON object on stdout with ``--json`` and
writes its files under ``--out``. Errors go to stderr with a non-zero exit code: 2 for invalid
input (a bad case, an unknown parameter), 3 for a failed model run.
"""

import logging
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from rivercal import __version__
from rivercal._options import options
from rivercal.cli.analyse import analyse as _analyse
from rivercal.cli.common import (
    CaseArg,
    JsonOpt,
    QuietOpt,
    emit_json,
    err_console,
    guard,
    null_context,
    out_console,
    parse_assignments,
    parse_sets,
    parse_window,
    select_parameters,
)
from rivercal.cli.online import demo as _demo
from rivercal.cli.online import online as _online
from rivercal.cli.online import report as _report
from rivercal.cli.twin import twin as _twin

app = typer.Typer(
    name="rivercal",
    help="On-line parameter estimation for 1D river-network models.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
case_app = typer.Typer(help="Inspect and validate cases.", no_args_is_help=True)
bench_app = typer.Typer(help="Benchmarks (JSON output).", no_args_is_help=True)
app.add_typer(case_app, name="case")
app.add_typer(bench_app, name="bench")

_guard = guard
_emit_json = emit_json
_null = null_context
_parse_sets = parse_sets
_parse_assignments = parse_assignments
_parse_window = parse_window
_select_parameters = select_parameters


@app.callback()
def _main(
    version: Annotated[bool, typer.Option("--version", help="Show the version and exit.")] = False,
    verbose: Annotated[bool, typer.Option("--verbose", "-v", help="Log progress details on stderr.")] = False,
) -> None:
    if version:
        out_console.print(f"rivercal {__version__}")
        raise typer.Exit(0)
    logging.basicConfig(
        level=logging.DEBUG if verbose else getattr(logging, options.log_level.upper(), logging.WARNING),
        format="%(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )




# -- case ---------------------------------------------------------------------------------------


@case_app.command("schema")
def case_schema() -> None:
    """Print the JSON Schema of case.toml."""
    from rivercal.case.schema import CaseFile

    _emit_json(CaseFile.model_json_schema())


@case_app.command("check")
@_guard
def case_check(case: CaseArg, as_json: JsonOpt = False) -> None:
    """Validate a case and summarise it."""
    from rivercal.model import load_model

    sim = load_model(case)
    c = sim.case
    net = c.network
    compiled = sim.compiled
    summary = {
        "case": c.name,
        "folder": str(c.root),
        "start": c.start.isoformat(),
        "end": c.end.isoformat(),
        "branches": len(net.branches),
        "calculation_points": compiled.n_hpoints,
        "links": compiled.n_links,
        "weirs": len(net.weirs),
        "culverts": len(net.culverts),
        "pumps": len(net.pumps),
        "boundaries": len(net.boundaries),
        "laterals": len(net.laterals),
        "catchments": len(c.spec.catchments),
        "catchment_area_km2": round(sum(x.area for x in c.spec.catchments) / 100.0, 1),
        "observables": compiled.observables,
    }
    if as_json:
        _emit_json(summary)
        return
    table = Table(title=f"case {c.name} — valid", show_header=False)
    for key, value in summary.items():
        table.add_row(key, ", ".join(value) if isinstance(value, list) else str(value))
    out_console.print(table)


@case_app.command("plot")
@_guard
def case_plot(
    case: CaseArg,
    out: Annotated[Path, typer.Option("--out", help="PNG file to write.")] = Path("network.png"),
) -> None:
    """Draw the network: branches, weirs (labelled), stations, laterals, boundaries."""
    from rivercal.case import load_case
    from rivercal.report.figures import plot_network

    c = load_case(case)
    labels = _weir_labels(c)
    path = plot_network(c.network, out, title=f"{c.name}: {c.spec.case.description}"[:110], weir_labels=labels)
    out_console.print(f"wrote {path}")


def _weir_labels(case) -> dict[str, str]:
    """Weir labels for the schematic: the calibration name where the case defines one."""
    names = {}
    for p in getattr(case.spec, "parameters", []) or []:
        for target in getattr(p, "targets", []):
            if target.startswith("weir:") and target.endswith(".crest_level"):
                names[target[5:-12]] = f"{p.name} {target[5:-12]}"
    return names


# -- simulate -----------------------------------------------------------------------------------


@app.command()
@_guard
def simulate(
    case: CaseArg,
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out/simulate"),
    set_: Annotated[list[str], typer.Option("--set", help="Model quantity NAME=VALUE, e.g. friction:global=20 or "
                                                          "weir:ZL1-3014.crest_level=10.3; repeatable.")] = [],  # noqa: B006
    start: Annotated[str | None, typer.Option(help="Start (UTC, ISO 8601); default: the case start.")] = None,
    end: Annotated[str | None, typer.Option(help="End (UTC, ISO 8601); default: the case end.")] = None,
    plot: Annotated[bool, typer.Option("--plot", help="Also draw series.png (adds ~1.5 s).")] = False,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Run a case and write series.csv and series.nc (CF-1.8); with --plot also a hydrograph figure."""
    from rivercal.model import load_model
    from rivercal.report.figures import plot_series

    parameters = _parse_sets(set_)
    sim = load_model(case)
    c = sim.case
    with err_console.status(f"simulating {c.name}", spinner="dots") if not (quiet or as_json) else _null():
        result, _ = sim.simulate(parameters, start=start, end=end)
    out.mkdir(parents=True, exist_ok=True)
    result.to_csv(out / "series.csv")
    result.to_netcdf(out / "series.nc")
    files = {"csv": str(out / "series.csv"), "netcdf": str(out / "series.nc")}
    if plot:
        files["figure"] = str(plot_series(result.series, out / "series.png", title=f"{c.name}: simulated series"))
    summary = {
        "case": c.name,
        "start": result.series.index[0].isoformat(),
        "end": result.series.index[-1].isoformat(),
        "parameters": parameters,
        "wall_s": round(result.wall_time, 4),
        "volume_balance_relative_error": result.balance.relative_error,
        "files": files,
        "final": {k: round(float(v), 4) for k, v in result.series.iloc[-1].items()},
    }
    if as_json:
        _emit_json(summary)
    elif not quiet:
        out_console.print(f"simulated [bold]{c.name}[/] {summary['start']} .. {summary['end']} "
                          f"in {result.wall_time:.2f} s (volume balance error {result.balance.relative_error:.1e})")
        out_console.print("wrote " + ", ".join(files.values()))




# -- calibrate ----------------------------------------------------------------------------------



@app.command()
@_guard
def calibrate(
    case: CaseArg,
    params: Annotated[str, typer.Option("--params", help="Parameters to estimate, e.g. FA,Wc (defined by the case).")],
    window: Annotated[str, typer.Option(help="START/END (UTC dates) or a window of the case (e.g. moderate).")],
    observations: Annotated[Path | None, typer.Option(
        help="Observation CSV (time + '<station>.<quantity>' columns).")] = None,
    twin: Annotated[str | None, typer.Option(help="Twin experiment: true values, e.g. 'FA=20,Wc=0.8'.")] = None,
    start: Annotated[str | None, typer.Option(help="Start values, e.g. 'FA=14,Wc=0.1' (default: the case's).")] = None,
    bounds: Annotated[list[str], typer.Option("--bounds", help="Override bounds NAME=MIN:MAX; repeatable.")] = [],  # noqa: B006
    algorithm: Annotated[str | None, typer.Option(help="Optimiser (default: the case's, usually dud).")] = None,
    option: Annotated[list[str], typer.Option("--option", help="Optimiser option KEY=VALUE; repeatable.")] = [],  # noqa: B006
    noise: Annotated[str, typer.Option(help="Twin noise: none, white, gaussian or pink.")] = "none",
    seed: Annotated[int, typer.Option(help="Seed of the twin noise.")] = 0,
    warmup: Annotated[float, typer.Option(help="Hours simulated before the window in every run.")] = 24.0,
    workers: Annotated[int | None, typer.Option(help="Worker processes (default: all cores).")] = None,
    max_nfev: Annotated[int | None, typer.Option("--max-nfev", help="Cap on model runs.")] = None,
    deadline: Annotated[float | None, typer.Option(help="Wall-clock limit, s.")] = None,
    on_failure: Annotated[str, typer.Option(help="Failed model run: raise or penalty.")] = "raise",
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out/calibrate"),
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Estimate parameters from observations (or a twin experiment) over a window."""
    import json as _json

    import pandas as pd

    from rivercal.case import load_case
    from rivercal.io.observations import read_observations_csv
    from rivercal.model import build_model
    from rivercal.optimise import OPTIMISERS
    from rivercal.problem import CalibrationProblem
    from rivercal.problem import calibrate as run_calibration
    from rivercal.report.figures import plot_convergence, plot_cost
    from rivercal.twin import NOISE_MODELS, twin_truth

    # -- everything is checked before the first model run
    if (observations is None) == (twin is None):
        raise ValueError("give either --observations FILE or --twin 'NAME=VALUE,...'")
    if noise not in NOISE_MODELS:
        raise ValueError(f"--noise {noise!r}: choose one of {', '.join(NOISE_MODELS)}")
    if observations is not None and noise != "none":
        raise ValueError("--noise applies to twin experiments only")
    c = load_case(case)
    algo = algorithm or c.spec.calibration.algorithm
    if algo not in OPTIMISERS:
        raise ValueError(f"--algorithm {algo!r}: choose one of {', '.join(sorted(OPTIMISERS))}")
    opts = dict(c.spec.calibration.options) if algo == c.spec.calibration.algorithm else {}
    opts.update(_parse_assignments(",".join(option), "--option"))
    pset = _select_parameters(c, params, _parse_assignments(start, "--start"), bounds)
    win = _parse_window(c, window)
    truth_values = _parse_assignments(twin, "--twin") if twin else {}
    for name in truth_values:
        if name not in pset.names:
            raise ValueError(f"--twin {name}: {name!r} is not in --params")
    for p in pset:
        if p.name in truth_values and not p.min <= truth_values[p.name] <= p.max:
            raise ValueError(f"--twin {p.name}={truth_values[p.name]:g}: outside its bounds [{p.min:g}, {p.max:g}]")
    obs = read_observations_csv(observations) if observations is not None else None
    if obs is not None:
        obs = obs.within(*win)
        if obs.n_values == 0:
            raise ValueError(f"{observations}: no observations in the window {win[0]} .. {win[1]}")
        unknown = [s for s in obs.ids if s not in c.network.observables]
        if unknown:
            raise ValueError(f"{observations}: series {unknown[0]!r} is not simulated by case {c.name!r} "
                             f"(it simulates {', '.join(c.network.observables)})")

    # -- runs
    sim = build_model(c)
    status = err_console.status("calibrating", spinner="dots") if not (quiet or as_json) else _null()
    state = None
    truth_q = None
    with status as live:
        if twin:
            truth_q = pset.quantities({p.name: truth_values.get(p.name, p.initial) for p in pset})
            tw = twin_truth(sim, truth_q, win, warmup=pd.Timedelta(hours=warmup), noise=noise, seed=seed)
            obs, state = tw.observations, tw.state
        problem = CalibrationProblem(sim, pset, obs, win, state=state, warmup=pd.Timedelta(hours=warmup),
                                     on_failure=on_failure)

        def progress(record) -> None:
            if live is not None and hasattr(live, "update"):
                values = ", ".join(f"{k}={v:.4g}" for k, v in pset.values(record.x).items())
                live.update(f"iteration {record.nit}: cost {record.cost:.4g}, {record.nfev} runs, {values}")

        cal = run_calibration(problem, algo, opts, workers=workers, max_nfev=max_nfev, deadline=deadline,
                              callback=progress)
    out.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(cal.history).to_csv(out / "history.csv", index=False)
    evals = [{"run": i + 1, "cost": cost, **pset.values(x)} for i, (x, cost) in enumerate(cal.result.evaluations)]
    pd.DataFrame(evals).to_csv(out / "evaluations.csv", index=False)
    files = {"history": str(out / "history.csv"), "evaluations": str(out / "evaluations.csv")}
    if cal.history:
        units = {p.name: p.unit for p in pset}
        title = f"{c.name}: {algo}, window {win[0]:%Y-%m-%d}..{win[1]:%Y-%m-%d}"
        files["convergence"] = str(plot_convergence(cal.history, pset.names, out / "convergence.png",
                                                    truth=truth_values or None, units=units, title=title))
        files["cost"] = str(plot_cost(cal.history, out / "cost.png", title=f"{c.name}: cost per iteration"))
    summary = {"case": c.name, "window": [win[0].isoformat(), win[1].isoformat()],
               "observations": {"series": len(problem.observations), "values": problem.observations.n_values,
                                "missing_dropped": problem.observations.n_missing},
               **cal.summary(), "files": files}
    if twin:
        summary["truth"] = truth_values
        summary["error"] = {n: cal.estimates[n] - truth_values[n] for n in truth_values}
    (out / "result.json").write_text(_json.dumps(summary, indent=2, default=float) + "\n", encoding="utf-8")
    if as_json:
        _emit_json(summary)
        return
    if quiet:
        return
    table = Table(title=f"{c.name}: {algo} over {win[0]:%Y-%m-%d %H:%M} .. {win[1]:%Y-%m-%d %H:%M}")
    for col in ("parameter", "start", "estimate", "std", *(["true"] if twin else [])):
        table.add_column(col, justify="right" if col != "parameter" else "left")
    for p in pset:
        row = [p.name, f"{cal.initial[p.name]:.4f}", f"{cal.estimates[p.name]:.4f}",
               f"{cal.std[p.name]:.2g}" if p.name in cal.std else "-"]
        if twin:
            row.append(f"{truth_values.get(p.name, float('nan')):.4f}")
        table.add_row(*row)
    out_console.print(table)
    r = cal.result
    out_console.print(f"cost {r.cost:.4g} after {r.nit} iterations, {r.nfev} model runs, {cal.wall_time:.1f} s; "
                      f"{r.message}" + (" [aborted]" if r.aborted else ""))
    out_console.print("wrote " + ", ".join(files.values()))


# -- bench --------------------------------------------------------------------------------------


@bench_app.command("engine")
@_guard
def bench_engine_cmd(
    case: Annotated[str, typer.Option(help="Case to time.")] = "synthetic",
    days: Annotated[float, typer.Option(help="Simulated days.")] = 7.0,
    repeats: Annotated[int, typer.Option(help="Timed runs after warm-up (median reported).")] = 7,
    as_json: JsonOpt = False,
) -> None:
    """Time one simulated week of the synthetic benchmark network (Δt = 60 s)."""
    from rivercal.bench.engine import bench_engine

    result = bench_engine(case, days=days, repeats=repeats).to_dict()
    if as_json:
        _emit_json(result)
        return
    table = Table(title="engine benchmark", show_header=False)
    for key, value in result.items():
        table.add_row(key, f"{value:.4g}" if isinstance(value, float) else str(value))
    out_console.print(table)


@bench_app.command("calibrate")
@_guard
def bench_calibrate_cmd(
    algorithms: Annotated[str | None, typer.Option(help="Comma-separated algorithms (default: all).")] = None,
    workers: Annotated[int | None, typer.Option(help="Worker processes (default: all cores).")] = None,
    as_json: JsonOpt = False,
) -> None:
    """FaWc twin calibration of the default case (truth 20/0.8, start 14/0.1, moderate window) per algorithm."""
    from rivercal.bench.calibrate import bench_calibrate

    names = [a.strip() for a in algorithms.split(",")] if algorithms else None
    result = bench_calibrate(names, workers=workers)
    if as_json:
        _emit_json(result)
        return
    table = Table(title="FaWc twin calibration (truth FA=20, Wc=0.8; start 14, 0.1; moderate window)")
    for col in ("algorithm", "runs", "iterations", "wall s", "FA", "Wc", "ΔFA", "ΔWc"):
        table.add_column(col, justify="right")
    for r in result["results"]:
        table.add_row(r["algorithm"], str(r["model_runs"]), str(r["iterations"]), f"{r['wall_s']:.2f}",
                      f"{r['fa']:.4f}", f"{r['wc']:.5f}", f"{r['error_fa']:+.1e}", f"{r['error_wc']:+.1e}")
    out_console.print(table)


@bench_app.command("hupsel")
@_guard
def bench_hupsel_cmd(as_json: JsonOpt = False) -> None:
    """Calibrate the rainfall-runoff model on Hupsel 2011/12, validate on 2012/13: DuD, LM, Nelder-Mead, SCE-UA."""
    from rivercal.bench.hupsel import HUPSEL_METHODS, calibrate_hupsel

    rows = [calibrate_hupsel(m).to_dict() for m in HUPSEL_METHODS]
    if as_json:
        _emit_json({"hupsel": rows})
        return
    table = Table(title="Hupsel Brook: calibration 2011-04..2012-03, validation 2012-04..2013-03")
    for col in ("method", "runs", "wall s", "NSE cal", "NSE val", "KGE cal", "KGE val"):
        table.add_column(col, justify="right")
    for r in rows:
        table.add_row(r["method"], str(r["model_runs"]), f"{r['wall_s']:.2f}", f"{r['nse_calibration']:.3f}",
                      f"{r['nse_validation']:.3f}", f"{r['kge_calibration']:.3f}", f"{r['kge_validation']:.3f}")
    out_console.print(table)
    out_console.print(f"a-priori parameters: NSE cal {rows[0]['nse_calibration_default']:.3f}, "
                      f"val {rows[0]['nse_validation_default']:.3f}")


@bench_app.command("online")
@_guard
def bench_online_cmd(
    scenario: Annotated[str, typer.Option(help="Practical scenario that makes the observations.")] = "PI-Fg",
    first_issue: Annotated[str, typer.Option("--from", help="Issue time of the first (untimed) cycle.")] = "2010-11-09",
    cycles: Annotated[int, typer.Option(help="Timed warm-started cycles (median reported).")] = 5,
    workers: Annotated[int | None, typer.Option(help="Worker processes per calibration (default: all cores).")] = None,
    replay: Annotated[bool, typer.Option(help="Also time the four-week replay 2010-10-18 .. 2010-11-15.")] = False,
    replay_repeats: Annotated[int, typer.Option(help="Timed replays (median reported).")] = 3,
    as_json: JsonOpt = False,
) -> None:
    """Time one warm-started cycle of the on-line service (7-day window, FA and Wd, DuD) on dommel."""
    from rivercal.bench.online import bench_online

    result = bench_online("dommel", scenario, first_issue=first_issue, cycles=cycles, workers=workers,
                          replay=replay, replay_repeats=replay_repeats).to_dict()
    if as_json:
        _emit_json(result)
        return
    table = Table(title="on-line service benchmark", show_header=False)
    for key, value in result.items():
        table.add_row(key, f"{value:.4g}" if isinstance(value, float) else str(value))
    out_console.print(table)


# -- demo ---------------------------------------------------------------------------------------


app.command("twin")(guard(_twin))
app.command("analyse")(_analyse)
app.command("online")(guard(_online))
app.command("report")(guard(_report))
app.command("demo")(guard(_demo))


def main() -> None:  # pragma: no cover - console entry point
    """Entry point of the ``rivercal`` console script."""
    app()
