"""``rivercal bench``: the benchmarks.

The engine (alone, as a batched ensemble and beside EPA SWMM), the calibration, the rainfall-runoff model,
the on-line service (its speed, and its figures at each realism level), the black box, and real measurements
(the Oriège's gauges, the Western Scheldt's storm surge).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from rivercal.cli.common import JsonOpt, emit_json, guard, out_console, watch_compilation
from rivercal.cli.mascaret import oriege_bench
from rivercal.cli.options import OptionError, check_choice, check_number, check_workers, parse_names, parse_time

__all__ = ["app"]

app = typer.Typer(help="Benchmarks (JSON output).", no_args_is_help=True)


@app.command("engine")
@guard
def engine(
    case: Annotated[str, typer.Option(help="Case to time.")] = "synthetic",
    days: Annotated[float, typer.Option(help="Simulated days.")] = 7.0,
    repeats: Annotated[int, typer.Option(help="Timed runs after warm-up (median reported).")] = 7,
    points: Annotated[int | None, typer.Option(
        help="Time a generated lowland network of about this many points instead of --case.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the network generated for --points.")] = 0,
    spun_up: Annotated[bool, typer.Option(
        "--spun-up", help="Start from the state the case's spin-up leaves (not timed), not its cold state.")] = False,
    as_json: JsonOpt = False,
) -> None:
    """Time one simulated week of the synthetic benchmark network, or of a generated one (Δt = 60 s)."""
    from rivercal.bench.engine import bench_engine, bench_engine_points
    from rivercal.cli.options import open_model
    from rivercal.errors import OptionError

    check_number(days, "--days", low=0, high=366, low_open=True)
    check_number(repeats, "--repeats", low=1, high=1000)
    if abs(days * 24 - round(days * 24)) > 1e-9:
        raise OptionError(f"--days {days:g}: give whole hours (a multiple of 1/24 day), the output interval",
                          option="--days")
    if points is not None:
        check_number(points, "--points", low=100, high=10_000_000)
        check_number(seed, "--seed", low=0)
        check_number(days, "--days", high=14)  # the generated case spans three weeks, two days of spin-up
        watch_compilation(True)
        result = bench_engine_points(points, seed, days=days, repeats=repeats, spun_up=spun_up).to_dict()
        _print_flat(result, "engine benchmark", as_json)
        return
    model = open_model(case)  # a bad case fails here, with its file and field
    span = (model.end - model.start).total_seconds() / 86400
    check_number(days, "--days", high=span)
    result = bench_engine(case, days=days, repeats=repeats, spun_up=spun_up).to_dict()
    _print_flat(result, "engine benchmark", as_json)


@app.command("ensemble")
@guard
def ensemble(
    members: Annotated[int, typer.Option(help="Ensemble members.")] = 64,
    case: Annotated[str, typer.Option(help="Case to time.")] = "dommel",
    days: Annotated[float, typer.Option(help="Simulated days.")] = 7.0,
    repeats: Annotated[int, typer.Option(help="Timed calls, interleaved with single runs (medians reported).")] = 3,
    threads: Annotated[int | None, typer.Option(help="Threads over the members (default: all).")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Time N members (own friction, own perturbed laterals) through one simulated week in one batched call."""
    import numba

    from rivercal.bench.ensemble import bench_ensemble
    from rivercal.cli.options import open_model

    check_number(members, "--members", low=1, high=10_000)
    check_number(days, "--days", low=0, high=366, low_open=True)
    check_number(repeats, "--repeats", low=1, high=1000)
    check_number(threads, "--threads", low=1, high=numba.config.NUMBA_NUM_THREADS)
    model = open_model(case)
    check_number(days, "--days", high=(model.end - model.start).total_seconds() / 86400)
    watch_compilation(True)
    result = bench_ensemble(case, members=members, days=days, repeats=repeats, threads=threads).to_dict()
    _print_flat(result, "ensemble benchmark", as_json)


@app.command("calibrate")
@guard
def calibrate(
    algorithms: Annotated[str | None, typer.Option(help="Comma-separated algorithms (default: all).")] = None,
    workers: Annotated[int | None, typer.Option(help="Worker processes (default: all cores).")] = None,
    as_json: JsonOpt = False,
) -> None:
    """FaWc twin calibration of the default case (truth 20/0.8, start 14/0.1, moderate window) per algorithm."""
    from rivercal.bench.calibrate import bench_calibrate
    from rivercal.optimise import OPTIMISERS
    from rivercal.optimise.registry import RENAMED

    names = parse_names(algorithms, "--algorithms") if algorithms is not None else None
    for name in names or []:
        check_choice(name, "--algorithms", sorted(OPTIMISERS), former=RENAMED)
    check_workers(workers)
    watch_compilation(True)
    result = bench_calibrate(names or None, workers=workers)
    if as_json:
        emit_json(result)
        return
    table = Table(title="FaWc twin calibration (truth FA=20, Wc=0.8; start 14, 0.1; moderate window)")
    for col in ("algorithm", "runs", "iterations", "wall s", "FA", "Wc", "ΔFA", "ΔWc"):
        table.add_column(col, justify="right")
    for r in result["results"]:
        table.add_row(r["algorithm"], str(r["model_runs"]), str(r["iterations"]), f"{r['wall_s']:.2f}",
                      f"{r['fa']:.4f}", f"{r['wc']:.5f}", f"{r['error_fa']:+.1e}", f"{r['error_wc']:+.1e}")
    out_console.print(table)


@app.command("dask")
@guard
def dask(
    every: Annotated[int, typer.Option(help="Every N-th FaWc scenario (3: 12 of 36).")] = 3,
    repeats: Annotated[int, typer.Option(help="Timed runs per cluster size (median reported).")] = 3,
    tasks: Annotated[int, typer.Option(help="No-op tasks of the overhead measurement.")] = 400,
    as_json: JsonOpt = False,
) -> None:
    """Twin scenarios on a local Dask cluster of 1 and of 2 workers: speed-up, overhead per task, 64 workers."""
    from rivercal.bench.dask import bench_dask

    check_number(every, "--every", low=1, high=36)
    check_number(repeats, "--repeats", low=1, high=100)
    check_number(tasks, "--tasks", low=10, high=100_000)
    watch_compilation(True)
    result = bench_dask(every=every, repeats=repeats, tasks=tasks).to_dict()
    if as_json:
        emit_json(result)
        return
    _print_flat({k: v for k, v in result.items() if not isinstance(v, list)}, "Dask benchmark", False)


@app.command("hupsel")
@guard
def hupsel(as_json: JsonOpt = False) -> None:
    """Calibrate the rainfall-runoff model on Hupsel 2011/12, validate on 2012/13: DuD, TRF, Nelder-Mead, SCE-UA."""
    from rivercal.bench.hupsel import HUPSEL_METHODS, calibrate_hupsel

    watch_compilation(True)
    rows = [calibrate_hupsel(m).to_dict() for m in HUPSEL_METHODS]
    if as_json:
        emit_json({"hupsel": rows})
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


@app.command("dhydro")
@guard
def dhydro(
    out: Annotated[Path | None, typer.Option("--out", help="Also write the table per location (CSV) here.")] = None,
    as_json: JsonOpt = False,
) -> None:
    """The imported D-HYDRO model Dellen against D-HYDRO's computed levels at 144 locations over 7 days."""
    from rivercal.bench.dhydro import compare_dellen

    result = compare_dellen()
    summary = result.summary()
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        result.table.to_csv(out / "dellen_rmse.csv", index=False)
        summary["table"] = str(out / "dellen_rmse.csv")
    if as_json:
        emit_json(summary)
        return
    after = summary["after_spinup"]
    out_console.print(f"Dellen, {summary['locations']} locations over {summary['dhydro_period_s'] / 86400:g} days: "
                      f"RMSE median {summary['rmse_median_m']:.3f} m, 90 % {summary['rmse_p90_m']:.3f} m, max "
                      f"{summary['rmse_max_m']:.3f} m; after the spin-up day {after['median']:.3f}, "
                      f"{after['p90']:.3f}, {after['max']:.3f} m; simulated in {summary['wall_s']:.2f} s")


@app.command("models")
@guard
def models(
    model: Annotated[list[str] | None,
                     typer.Option("--model", help="A shared model (repeatable; default: all).")] = None,
    steps: Annotated[str | None, typer.Option(
        "--sweep", help="Also run each model at these longest time steps, e.g. 10,60,300,600 (s), against the "
        "shortest one.")] = None,
    out: Annotated[Path | None, typer.Option("--out", help="Keep the imported cases here.")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Every real model of the shared data, imported and run as imported, against its own engine's results."""
    from rivercal.bench.models import MODELS, model_row, sweep

    names = [check_choice(name, "--model", MODELS, "shared model") for name in model or list(MODELS)]
    dts = None
    if steps is not None:
        try:
            dts = tuple(float(v) for v in parse_names(steps, "--sweep"))
        except ValueError:
            raise OptionError(f"--sweep {steps!r}: give time steps in s, e.g. 10,60,300,600",
                              option="--sweep") from None
        for dt in dts:
            check_number(dt, "--sweep", low=0.1, high=3600.0)
    for name in names:
        row = model_row(name, None if out is None else out / name).row()
        if dts is not None:
            row["sweep"] = sweep(name, dts, None if out is None else out / f"{name}-sweep")
        if as_json:
            emit_json(row)
            continue
        after = row.get("after_spinup") or {}
        rmse = after.get("level_rmse_m") or row.get("level_rmse_m")
        scores = (f"level RMSE median {rmse['median'] * 100:.1f} cm, p90 {rmse['p90'] * 100:.1f} cm, max "
                  f"{rmse['max'] * 100:.1f} cm at {row['points_compared']} points" if rmse else "no reference")
        ran = "runs as imported" if row["runs_as_imported"] else f"does not run as imported: {row.get('error')}"
        out_console.print(f"{name} ({row['format']}): {row['objects']} objects, {row['exact']} exact, "
                          f"{row['approximated']} approximated, {row['refused']} refused; {ran} at "
                          f"{row['dt_s']:g} s; {scores}; {row['wall_s']:.1f} s")
        for item in row.get("sweep", {}).get("steps", []):
            what = (f"level RMSE against the shortest step {item['level_rmse_m'] * 100:.2f} cm at most "
                    f"({item['rmse_where']}); largest difference {item['max_diff_m'] * 100:.2f} cm ({item['where']}, "
                    f"{item['when']})" if item["ok"] else f"stopped: {item['error']}")
            out_console.print(f"    longest step {item['dt_s']:g} s: {what}")


@app.command("online")
@guard
def online(
    scenario: Annotated[str, typer.Option(help="Practical scenario that makes the observations.")] = "PI-Fg",
    first_issue: Annotated[str, typer.Option("--from", help="Issue time of the first (untimed) cycle.")] = "2010-11-09",
    cycles: Annotated[int, typer.Option(help="Timed warm-started cycles (median reported).")] = 5,
    workers: Annotated[int | None, typer.Option(help="Worker processes per calibration (default: all cores).")] = None,
    replay: Annotated[bool, typer.Option(help="Also time the four-week replay 2010-10-18 .. 2010-11-15.")] = False,
    replay_repeats: Annotated[int, typer.Option(help="Timed replays (median reported).")] = 3,
    mode: Annotated[str, typer.Option(help="parameters (the daily estimate alone) or both (with hourly ensemble "
                                           "analyses, the service's default).")] = "parameters",
    members: Annotated[int, typer.Option(help="Ensemble members of --mode both.")] = 64,
    as_json: JsonOpt = False,
) -> None:
    """Time warm-started cycles of the on-line service (7-day window, FA and Wd, DuD) on dommel, cold apart."""
    import pandas as pd

    from rivercal.bench.online import bench_online
    from rivercal.cli.options import open_model
    from rivercal.errors import OptionError
    from rivercal.twin.practical import PRACTICAL_SCENARIOS

    check_choice(scenario, "--scenario", PRACTICAL_SCENARIOS)
    first = parse_time(first_issue, "--from")
    check_number(cycles, "--cycles", low=1, high=1000)
    check_workers(workers)
    check_number(replay_repeats, "--replay-repeats", low=1, high=100)
    check_choice(mode, "--mode", ("parameters", "both"), "mode")
    check_number(members, "--members", low=2, high=10_000)
    model = open_model("dommel")
    earliest = model.start + pd.Timedelta("8D")  # the 7-day window and the 24 h warm-up
    latest = model.end - pd.Timedelta("1D") * cycles
    if not earliest <= first <= latest:
        raise OptionError(f"--from {first_issue}: the first cycle must be issued between {earliest:%Y-%m-%d %H:%M} "
                          f"and {latest:%Y-%m-%d %H:%M} for {cycles} more daily cycles in the case period",
                          option="--from")
    result = bench_online("dommel", scenario, first_issue=first_issue, cycles=cycles, workers=workers,
                          replay=replay, replay_repeats=replay_repeats, mode=mode, members=members).to_dict()
    _print_flat(result, "on-line service benchmark", as_json)


@app.command("realism")
@guard
def realism(
    scenarios: Annotated[str | None, typer.Option(help="Comma-separated practical scenarios (default: all).")] = None,
    levels: Annotated[str | None, typer.Option(
        help="Comma-separated realism levels (default: ideal, noisy, realistic).")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the realism errors (≥ 0).")] = 0,
    workers: Annotated[int | None, typer.Option(help="Worker processes per calibration (default: all cores).")] = None,
    keep: Annotated[Path | None, typer.Option(help="Keep the stores in this folder (for reports).")] = None,
    assimilate: Annotated[str, typer.Option(help="Comma-separated modes of the service: both, parameters, states.")]
    = "both,parameters",
    members: Annotated[int, typer.Option(help="Ensemble members of state updating.")] = 64,
    as_json: JsonOpt = False,
) -> None:
    """The on-line service's four weeks (2010-10-18 .. 11-15) per scenario × realism level × mode on dommel."""
    from rivercal.bench.realism import bench_realism
    from rivercal.twin.practical import PRACTICAL_SCENARIOS
    from rivercal.twin.realism import REALISM_LEVELS

    names = parse_names(scenarios, "--scenarios") if scenarios is not None else None
    for name in names or []:
        check_choice(name, "--scenarios", PRACTICAL_SCENARIOS, "practical scenario")
    kinds = parse_names(levels, "--levels") if levels is not None else None
    for name in kinds or []:
        check_choice(name, "--levels", REALISM_LEVELS, "realism level")
    check_number(seed, "--seed", low=0)
    check_workers(workers)
    modes = parse_names(assimilate, "--assimilate")
    for mode in modes:
        check_choice(mode, "--assimilate", ("both", "parameters", "states"), "mode")
    check_number(members, "--members", low=2, high=10_000)
    watch_compilation(True)
    result = bench_realism(scenarios=names, levels=kinds, seed=seed, workers=workers, keep=keep, modes=modes,
                           members=members)
    if as_json:
        emit_json(result)
        return
    table = Table(title=f"on-line service on {result['case']}, {result['from']} .. {result['to']} (seed {seed})")
    for col in ("scenario", "realism", "updates", "MAE ratio", "rivercal cm", "DSS cm", "time to correct",
                "jump alerts", "fallbacks", "90 % band", "wall s"):
        table.add_column(col, justify="right")
    for r in result["rows"]:
        ratio = r["forecast_mae_ratio"]
        ttc = r["time_to_correct_cycles"]
        band = r.get("band_coverage_90")
        table.add_row(r["scenario"], r["realism"], r["assimilate"], "-" if ratio is None else f"{ratio:.2f}",
                      "-" if r["rivercal_mae_m"] is None else f"{r['rivercal_mae_m'] * 100:.2f}",
                      "-" if r["dss_mae_m"] is None else f"{r['dss_mae_m'] * 100:.2f}",
                      "-" if ttc is None else str(ttc), str(r["jump_alerts"]), str(r["fallbacks"]),
                      "-" if band is None else f"{band:.0%}", f"{r['wall_s']:.0f}")
    out_console.print(table)


@app.command("realism-bound")
@guard
def realism_bound_cmd(
    scenario: Annotated[str, typer.Option(help="The practical scenario.")] = "PI-Fg",
    level: Annotated[str, typer.Option(help="The realism level.")] = "realistic",
    seed: Annotated[int, typer.Option(help="Seed of the realism errors (≥ 0).")] = 0,
    values: Annotated[str | None, typer.Option(help="Comma-separated values after the change of the parameter "
                                                    "the scenario changes (FA, Wd, FL) to try.")] = None,
    flood: Annotated[str | None, typer.Option(help="START/END (UTC) of hours also left out in a second set of "
                                                   "figures, e.g. 2010-11-12/2010-11-16.")] = None,
    as_json: JsonOpt = False,
) -> None:
    """The best any parameter estimator can do: MAE ratio of forecasts with the truth's own parameters."""
    from rivercal.bench.realism_bound import realism_bound
    from rivercal.twin.practical import PRACTICAL_SCENARIOS
    from rivercal.twin.realism import REALISM_LEVELS

    check_choice(scenario, "--scenario", PRACTICAL_SCENARIOS, "practical scenario")
    check_choice(level, "--level", REALISM_LEVELS, "realism level")
    check_number(seed, "--seed", low=0)
    try:
        tried = [float(v) for v in parse_names(values, "--values")] if values else None
    except ValueError as exc:
        raise OptionError(f"--values {values!r}: give numbers separated by commas ({exc})", option="--values") from exc
    period = None
    if flood is not None:
        parts = flood.split("/")
        if len(parts) != 2:
            raise OptionError(f"--flood {flood!r}: give START/END, e.g. 2010-11-12/2010-11-16", option="--flood")
        period = (parse_time(parts[0], "--flood").isoformat(), parse_time(parts[1], "--flood").isoformat())
    result = realism_bound(scenario, level, seed=seed, values=tried, flood=period)
    _print_flat(result, "the best a parameter estimator can do", as_json)


@app.command("engines")
@guard
def engines(
    points: Annotated[int, typer.Option(help="About this many calculation points (100 m apart).")] = 400,
    weirs: Annotated[int, typer.Option(help="Free weirs along the channel.")] = 9,
    days: Annotated[float, typer.Option(help="Simulated days of the flood wave (after a 48 h spin-up).")] = 7.0,
    repeats: Annotated[int, typer.Option(help="Interleaved runs of each engine (medians reported).")] = 5,
    as_json: JsonOpt = False,
) -> None:
    """The embedded engine beside EPA SWMM on one weir chain, in one process (SWMM: 10 s routing, variable)."""
    from rivercal.bench.engines import bench_engines

    check_number(points, "--points", low=20, high=100_000)
    check_number(weirs, "--weirs", low=1, high=points // 10)
    check_number(days, "--days", low=3, high=366)  # the flood wave peaks 2 days after the start
    check_number(repeats, "--repeats", low=1, high=100)
    watch_compilation(True)
    result = bench_engines(points=points, weirs=weirs, days=days, repeats=repeats).to_dict()
    _print_flat(result, "embedded engine and EPA SWMM on one network", as_json)


@app.command("blackbox")
@guard
def blackbox(
    runs: Annotated[int, typer.Option(help="Timed runs (medians reported).")] = 40,
    as_json: JsonOpt = False,
) -> None:
    """The black box's own time per run beside a trivial external program (cp of a prepared output file)."""
    from rivercal.bench.blackbox import bench_blackbox

    check_number(runs, "--runs", low=3, high=10_000)
    _print_flat(bench_blackbox(runs=runs).to_dict(), "black-box overhead per run (ms)", as_json)


@app.command("westerscheldt")
@guard
def westerscheldt(
    members: Annotated[int, typer.Option(help="Ensemble members of the state updating.")] = 64,
    seed: Annotated[int, typer.Option(help="Seed of the ensemble's perturbations (≥ 0).")] = 0,
    out: Annotated[Path | None, typer.Option(help="Keep the stores and forecasts.csv here.")] = None,
    as_json: JsonOpt = False,
) -> None:
    """The storm surge of December 2013 in the Western Scheldt: held-out Bath by lead, with and without updating."""
    from rivercal.bench.westerscheldt import bench_westerscheldt

    check_number(members, "--members", low=2, high=10_000)
    check_number(seed, "--seed", low=0)
    watch_compilation(True)
    result = bench_westerscheldt(members=members, seed=seed, out=out)
    if as_json:
        emit_json(result)
        return
    table = Table(title=f"Bath (held out), RMSE by lead, m; friction KS = {result['calibration']['ks']:g} from the "
                        "calm tide")
    for col in ("lead h", "without", "with", "ratio"):
        table.add_column(col, justify="right")
    for h, wo, w, r in zip(result["lead_h"], result["bath_rmse_without_m"], result["bath_rmse_with_m"],
                           result["ratio_with_to_without"], strict=True):
        table.add_row(str(h), f"{wo:.3f}", f"{w:.3f}", f"{r:.2f}")
    out_console.print(table)
    peak = result["surge_peak"]
    out_console.print(f"peak level {peak['measured_level_m']} m NAP: error at lead 1 h "
                      f"{peak['level_error_m']['1h']:+.3f} m; peak surge {peak['measured_surge_m']} m: error at "
                      f"lead 1 h {peak['surge_error_m']['1h']:+.3f} m")
    for note in result["workarounds"]:
        out_console.print(f"note: {note}")


def _print_flat(result: dict, title: str, as_json: bool) -> None:
    """One benchmark's numbers: a JSON object, or a two-column table."""
    if as_json:
        emit_json(result)
        return
    table = Table(title=title, show_header=False)
    for key, value in result.items():
        table.add_row(key, f"{value:.4g}" if isinstance(value, float) else str(value))
    out_console.print(table)


app.command("oriege")(oriege_bench)
# the gauge advice's benchmark lives with its command (rivercal.cli.advise)
from rivercal.cli.advise import bench as _advise_bench  # noqa: E402

app.command("advise")(guard(_advise_bench))
