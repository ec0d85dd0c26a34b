"""``rivercal advise gauges``: where to put the next gauge (identifiability and data worth of candidate places).

The work and the files are :func:`rivercal.workflows.advise.advise_gauges`'s; this module checks the options
and prints.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rivercal.cli.common import CaseArg, DaskOpt, JsonOpt, QuietOpt, Reporter, emit_json, guard, out_console
from rivercal.cli.options import (
    check_choice,
    check_number,
    dask_address,
    input_file,
    open_model,
    output_dir,
    parse_assignments,
    parse_duration,
    parse_names,
    parse_window,
    select_parameters,
    workers_for,
)
from rivercal.errors import OptionError

__all__ = ["app", "gauges"]

app = typer.Typer(help="Advice from the model: where to measure next.", no_args_is_help=True)


@app.command("gauges")
@guard
def gauges(
    case: CaseArg,
    params: Annotated[str, typer.Option(
        "--params", help="Parameters the gauges should make identifiable, e.g. W1,W2,W3,W4,W5,W6,W7,W8,W9,FA.")],
    window: Annotated[str, typer.Option(
        help="START/END (UTC dates) or a window of the case: the flow conditions of the analysis.")],
    candidates: Annotated[str, typer.Option(
        help="Candidate places: points (every calculation point), structures (either side of every structure) "
             "or a CSV file with columns branch, chainage (m), name and optionally cost and id.")] = "points",
    gauges: Annotated[str | None, typer.Option(
        help="The stations that are gauges today, e.g. 0029,0031 (default: every station of the case; an imported "
             "model has one at every observation point and structure, most of them no gauge).")] = None,
    add: Annotated[int | None, typer.Option(
        "--add", help="Gauges to add (default: as many as it takes until every parameter is identifiable).")] = None,
    kind: Annotated[str, typer.Option(help="What a new gauge measures: level, discharge or both.")] = "level",
    forecast: Annotated[str | None, typer.Option(
        help="Stations or series whose forecast the gauges should sharpen, e.g. 0031 or 0029.Q (default: the "
             "parameters).")] = None,
    horizon: Annotated[str, typer.Option(help="Forecast horizon after the window, e.g. 48h.")] = "48h",
    sigma: Annotated[str | None, typer.Option(
        help="Measurement σ by quantity or series, e.g. 'h=0.025,Q=0.1' (m, m³/s; default: 2.5 cm, 0.1 m³/s).")]
    = None,
    start: Annotated[str | None, typer.Option(
        help="Analysis point, e.g. 'FA=14' (default: the case's initial values).")] = None,
    warmup: Annotated[float, typer.Option(help="Hours simulated before the window in every run.")] = 24.0,
    rel_step: Annotated[float, typer.Option(
        "--rel-step", help="Finite-difference step as a fraction of each parameter's range.")] = 0.01,
    scheme: Annotated[str, typer.Option(help="Finite differences: forward (p+1 runs) or central (2p+1).")] = "forward",
    sv_threshold: Annotated[float, typer.Option(
        "--sv-threshold", help="Singular values at least this fraction of the largest are significant.")] = 0.01,
    corr_threshold: Annotated[float, typer.Option(
        "--corr-threshold", help="|correlation| above which parameters count only in combination.")] = 0.9,
    exchange: Annotated[bool, typer.Option(
        "--exchange/--no-exchange", help="Improve the greedy choice by one-for-one swaps.")] = True,
    workers: Annotated[int | None, typer.Option(help="Worker processes (default: all cores).")] = None,
    dask: DaskOpt = None,
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out/advise"),
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Where to put the next gauges: the gain of each candidate in identifiability and in posterior uncertainty."""
    import pandas as pd

    from rivercal.analysis import IdentifiabilityOptions
    from rivercal.workflows.advise import (
        CANDIDATE_KINDS,
        MEASURES,
        advise_gauges,
        candidates_of,
        gauges_only,
        read_candidates,
    )

    # -- everything is checked before the first model run: first what needs no case
    check_choice(kind, "--kind", MEASURES)
    check_choice(scheme, "--scheme", ("forward", "central"))
    check_number(add, "--add", low=1, high=1000)
    check_number(rel_step, "--rel-step", low=0, high=0.5, low_open=True)
    check_number(warmup, "--warmup", low=0, high=8784)
    check_number(workers, "--workers", low=1)
    check_number(sv_threshold, "--sv-threshold", low=0, high=1, low_open=True, high_open=True)
    check_number(corr_threshold, "--corr-threshold", low=0, high=1, low_open=True, high_open=True)
    address = dask_address(dask, workers)
    hours = parse_duration(horizon, "--horizon")
    sig = parse_assignments(sigma, "--sigma", example="h=0.025") if sigma is not None else {}
    for key, value in sig.items():
        if not value > 0:
            raise OptionError(f"--sigma {key}={value:g}: σ must be positive (m or m³/s)", option="--sigma")
    start_values = parse_assignments(start, "--start")
    file = None
    if candidates not in CANDIDATE_KINDS:
        if not Path(candidates).is_file():
            raise OptionError(f"--candidates {candidates!r}: neither {' nor '.join(CANDIDATE_KINDS)} nor an existing "
                              "CSV file of places", option="--candidates")
        file = input_file(Path(candidates), "--candidates", (".csv",))
    output_dir(out)
    options = IdentifiabilityOptions(sv_threshold=sv_threshold, correlation=corr_threshold)
    # -- then what needs the case
    model = open_model(case, show_compilation=not quiet)
    if gauges is not None:
        model = gauges_only(model, parse_names(gauges, "--gauges"))
    pset = select_parameters(model, params, start_values, [])
    win = parse_window(model, window, warmup=pd.Timedelta(hours=warmup))
    places = candidates_of(model, candidates, kind) if file is None else read_candidates(file, model, kind)
    if not places:
        raise OptionError(f"--candidates {candidates}: every place of that kind is measured already (--kind {kind})",
                          option="--candidates")
    forecasts = _forecast_series(model, parse_names(forecast, "--forecast") if forecast else [], places)
    if forecasts and win[1] + hours > model.end:
        raise OptionError(f"--horizon {horizon}: the forecast after the window reaches {win[1] + hours}, after the "
                          f"case period ends ({model.end:%Y-%m-%d %H:%M}); choose an earlier window or a shorter "
                          "horizon", option="--horizon")
    for key in sig:
        if key not in ("h", "h_up", "h_down", "Q") and "." not in key:
            raise OptionError(f"--sigma {key}: give a quantity (h, h_up, h_down, Q) or a series '<station>.<quantity>'",
                              option="--sigma")

    reporter = Reporter(not (quiet or as_json))
    with reporter.running("starting"), workers_for(workers, address) as where:
        summary = advise_gauges(model, pset, win, out, candidates=places, add=add, forecasts=forecasts, sigma=sig,
                                horizon=horizon, warmup=pd.Timedelta(hours=warmup), rel_step=rel_step, scheme=scheme,
                                options=options, exchange=exchange, workers=where,
                                source=str(file) if file is not None else candidates, progress=reporter)
    if as_json:
        emit_json(summary)
    elif not quiet:
        _print(summary)


def _forecast_series(model, names: list[str], places) -> list[str]:
    """Series ids of ``--forecast``: a series id as it is, a station or candidate id as all its series."""
    known = set(model.observables) | {s for c in places for s in c.series}
    stations: dict[str, list[str]] = {}
    for s in [*model.observables, *(s for c in places for s in c.series)]:
        stations.setdefault(s.rpartition(".")[0], []).append(s)
    out: list[str] = []
    for n in names:
        if n in known:
            out.append(n)
        elif n in stations:
            out.extend(s for s in stations[n] if s.rpartition(".")[2] in ("h", "h_up", "h_down", "Q"))
        else:
            shown = ", ".join(sorted({s.rpartition('.')[0] for s in model.observables}))
            raise OptionError(f"--forecast {n!r}: neither a station of the model ({shown}), a candidate place nor one "
                              "of their series ('<station>.<quantity>')", option="--forecast")
    return list(dict.fromkeys(out))


def _print(summary: dict) -> None:
    from rich.table import Table

    names = summary["parameters"]
    console = out_console
    window = " .. ".join(str(t)[:16].replace("T", " ") for t in summary["window"])  # UTC, as the other commands
    console.print(f"[bold]{summary['case']}[/]: where to add gauges for {', '.join(names)} over "
                  f"{window} UTC ({summary['candidates']['count']} candidates, "
                  f"{summary['jacobian_runs']} model runs, {summary['wall_s']} s)")
    before = summary["before"]
    console.print(f"present stations ({', '.join(summary['stations'])}): {before['identifiable']} of {len(names)} "
                  f"parameters identifiable; smallest singular value {before['smallest_singular_value']:.3g}")
    table = Table(title="the advised gauges, one at a time (worth: mean fractional variance reduction of "
                  + ("the forecasts" if summary["forecasts"] else "the parameters") + ")")
    for col in ("step", "place", "measures", "worth", "identifiable", "smallest s.v."):
        table.add_column(col, justify="left" if col in ("place", "measures") else "right")
    for s in summary["steps"]:
        table.add_row(str(s["step"]), s["name"], ", ".join(s["series"]), f"{s['worth']:.3f}",
                      f"{s['identifiable']}/{len(names)}", f"{s['smallest_singular_value']:.3g}")
    if summary["steps"]:
        console.print(table)
    else:  # not an empty table: say why nothing is advised
        console.print("no gauge advised: the present stations make every parameter identifiable already (--add N "
                      "ranks N candidates all the same; candidates.csv has the worth of each)")
    verdicts = Table(title="verdict per parameter")
    for col in ("parameter", "present stations", "with the advised gauges", "σ before", "σ after", "unit"):
        verdicts.add_column(col, justify="right" if col.startswith("σ") else "left")
    after = summary["after"]
    for n in names:
        verdicts.add_row(n, before["verdict"][n], after["verdict"][n], f"{before['posterior_std'][n]:.3g}",
                         f"{after['posterior_std'][n]:.3g}", summary["units"].get(n, ""))
    console.print(verdicts)
    enough = summary["enough"]
    if enough:
        console.print(f"every parameter is identifiable with {enough} added gauge{'s' if enough != 1 else ''}")
    elif enough == 0:
        console.print("every parameter is identifiable with the present stations")
    else:
        console.print("not every parameter is identifiable with the chosen gauges (see after.csv)")
    console.print("wrote " + ", ".join(summary["files"].values()))


def bench(
    candidates: Annotated[str, typer.Option(help="Candidate places: points or structures.")] = "points",
    kind: Annotated[str, typer.Option(help="What a new gauge measures: level, discharge or both.")] = "level",
    seeds: Annotated[int, typer.Option(help="Random draws of as many candidates for the twin proof.")] = 20,
    twin: Annotated[bool, typer.Option("--twin/--no-twin", help="Run the twin proof.")] = True,
    online: Annotated[bool, typer.Option("--online/--no-online", help="Run the on-line replays of PI-Wl.")] = True,
    online_params: Annotated[str, typer.Option(
        "--online-params", help="What the on-line service estimates in the replays.")] \
        = "W1,W2,W3,W4,W5,W6,W7,W8,W9,FA",
    workers: Annotated[int | None, typer.Option(help="Worker threads per model batch (default: all cores).")] = None,
    as_json: JsonOpt = False,
) -> None:
    """The gauge advice on dommel (W1…W9, FA): its cost, the twin proof against random gauges, PI-Wl on-line."""
    from rivercal.bench.advise import bench_advise
    from rivercal.cli.common import err_console, watch_compilation
    from rivercal.workflows.advise import CANDIDATE_KINDS, MEASURES

    check_choice(candidates, "--candidates", CANDIDATE_KINDS)
    check_choice(kind, "--kind", MEASURES)
    check_number(seeds, "--seeds", low=0, high=1000)
    check_number(workers, "--workers", low=1)
    names = parse_names(online_params, "--online-params")
    known = {"FA", "W1", "W2", "W3", "W4", "W5", "W6", "W7", "W8", "W9", "Wd", "Wc", "F1", "FL"}
    for n in names:
        check_choice(n, "--online-params", sorted(known))
    if online and "W4" not in names:
        raise OptionError("--online-params: PI-Wl lowers W4's crest; estimate W4 to see whether it is found",
                          option="--online-params")
    watch_compilation(True)
    result = bench_advise(candidates=candidates, kind=kind, seeds=seeds, workers=workers, twin=twin, online=online,
                          online_parameters=names,
                          progress=None if as_json else lambda line: err_console.print(line, highlight=False))
    if as_json:
        emit_json(result)
        return
    a = result["advice"]
    out_console.print(f"advice over {a['candidates']} candidates in {a['wall_s']} s ({a['jacobian_runs']} model runs): "
                      f"{', '.join(c['name'] for c in a['chosen'])}; identifiable {a['before']['identifiable']} → "
                      f"{a['after']['identifiable']} of {len(result['parameters'])}")
    if "twin" in result:
        t = result["twin"]
        out_console.print(f"twin proof: five stations {'succeed' if t['present_stations']['success'] else 'fail'}, "
                          f"advised gauges {'succeed' if t['advised']['success'] else 'fail'}, random gauges "
                          f"succeed {t['random']['successes']} of {t['random']['draws']}")
    if "online" in result:
        for key in ("present_stations", "advised"):
            o = result["online"][key]
            out_console.print(f"PI-Wl on-line, {key.replace('_', ' ')}: {o['jump_alerts_after_change']} jump alerts, "
                              f"W4 {o['w4_before_change']} → {o['w4_last']} (true {o['w4_true_after']}), time to "
                              f"correct {o['time_to_correct_cycles']} cycles, forecast MAE ratio "
                              f"{o['forecast_mae_ratio']}")
