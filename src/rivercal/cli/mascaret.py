"""``rivercal import mascaret``: a Mascaret model (``.xcas`` with its ``.geo`` and ``.loi`` files) into a case."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rivercal._format import plural
from rivercal.cli.common import JsonOpt, QuietOpt, emit_json, guard, out_console
from rivercal.errors import RivercalError

__all__ = ["import_mascaret_cmd", "oriege_bench"]


@guard
def import_mascaret_cmd(
    model: Annotated[Path, typer.Argument(help="The Mascaret case file (.xcas); the geometry and laws it names are "
                                               "read from its folder.")],
    out: Annotated[Path, typer.Option("--out", help="Case folder to write (case.toml, forcing.csv, import.md).")],
    allow_partial: Annotated[bool, typer.Option(
        "--allow-partial", help="Write the case even when objects that change the hydraulics were refused "
                                "(they are left out; import.md lists them).")] = False,
    stations: Annotated[Path | None, typer.Option(
        help="CSV file 'id,reach,abscissa' of stations to add (gauges): reach name or number, abscissa in m "
             "along the reach.")] = None,
    origin: Annotated[str, typer.Option(help="Date and time of Mascaret's time 0 (UTC); Mascaret counts seconds, "
                                             "a case dates.")] = "2000-01-01T00:00:00Z",
    dt: Annotated[float | None, typer.Option(help="Time step of the case, s (default: Mascaret's pasTemps).")] = None,
    output_interval: Annotated[float | None, typer.Option(
        help="Output interval, s (default: Mascaret's storage interval).")] = None,
    hours: Annotated[float | None, typer.Option(
        help="Length of the simulated period, h (default: Mascaret's, from its stopping criterion).")] = None,
    cross_sections: Annotated[str, typer.Option(
        "--cross-sections", help="'points' (Mascaret's way: each calculation point takes the profile interpolated "
                                 "at it between the two around it) or 'nearest'.")] = "points",
    spinup: Annotated[float, typer.Option(help="Spin-up before the period, h.")] = 0.0,
    initial_depth: Annotated[float, typer.Option(
        help="Depth of the cold start, m (Mascaret's initial water line is not carried over).")] = 0.5,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Convert a Mascaret model into a case folder, accounting for every object in import.md."""
    from rivercal.cli.options import check_choice, check_number, parse_time

    check_choice(cross_sections, "--cross-sections", ("points", "nearest"))
    check_number(dt, "--dt", low=0.1, high=3600)
    check_number(output_interval, "--output-interval", low=0.1, high=86400 * 366, low_open=False)
    check_number(hours, "--hours", low=0, high=24 * 366 * 10, low_open=True)
    check_number(spinup, "--spinup", low=0, high=8784)
    check_number(initial_depth, "--initial-depth", low=0, high=100)
    start = parse_time(origin, "--origin")
    try:
        import tomli_w  # noqa: F401
    except ImportError:
        raise RivercalError("writing the case needs tomli-w: pip install 'rivercal[mascaret]'") from None
    from rivercal.io.mascaret import ImportOptions, StationSpec, import_mascaret, read_station_list

    specs = ()
    if stations is not None:
        specs = tuple(StationSpec(sid, reach, x, file=str(stations), line=line)
                      for sid, reach, x, line in read_station_list(stations))
    options = ImportOptions(allow_partial=allow_partial, origin=start.isoformat(), dt=dt,
                            output_interval=output_interval, hours=hours, cross_sections=cross_sections,
                            stations=specs, spinup=spinup, initial_depth=initial_depth)
    result = import_mascaret(model, out, options)
    if as_json:
        emit_json({"folder": str(result.folder), **result.summary})
        return
    if quiet:
        return
    s = result.summary
    parts = [plural(s["branches"], "branch"), plural(s["points"], "point"), plural(s["profiles"], "profile"),
             plural(s["friction_groups"], "friction group"), plural(s["boundaries"], "boundary"),
             plural(s["laterals"], "lateral"), plural(s["stations"], "station"),
             plural(len(s["parameters"]), "calibration parameter")]
    out_console.print(f"imported [bold]{model.name}[/] into {out}: {', '.join(parts)}, {s['start']} .. {s['end']}; "
                      f"{s['approximated']} approximated, {s['refused']} refused (see {out / 'import.md'})")


@guard
def oriege_bench(
    out: Annotated[Path | None, typer.Option(
        "--out", help="Keep the imported case, the gauge list, the observation file and the table per gauge "
                      "here (default: a temporary folder).")] = None,
    cross_sections: Annotated[str, typer.Option(
        "--cross-sections", help="'nearest' (each calculation point takes the nearest profile) or 'points' "
                                 "(as imported: the profile interpolated at each point, Mascaret's way).")] = "nearest",
    as_json: JsonOpt = False,
) -> None:
    """Calibrate the Oriège (Mascaret test 19) on 7 measured levels, validate on 6, then on all 13."""
    from rich.table import Table

    from rivercal.bench.oriege import calibrate_oriege, oriege_folder
    from rivercal.cli.common import watch_compilation
    from rivercal.cli.options import check_choice

    try:
        folder = oriege_folder()
    except FileNotFoundError as exc:
        raise RivercalError(str(exc)) from None
    check_choice(cross_sections, "--cross-sections", ("points", "nearest"))
    watch_compilation(True)
    result = calibrate_oriege(folder, out, cross_sections=cross_sections)
    summary = result.summary()
    if out is not None:
        result.gauges.to_csv(out / "gauges_levels.csv", index=False)
        summary["table"] = str(out / "gauges_levels.csv")
    if as_json:
        emit_json(summary)
        return
    table = Table(title="Oriège: levels at the 13 staff gauges (m)")
    for col in ("gauge", "x m", "role", "measured", "Mascaret", "K=20", "cal. on 7", "cal. on 13"):
        table.add_column(col, justify="right")
    for g in summary["gauges"]:
        table.add_row(g["id"], f"{g['x']:g}", g["role"], f"{g['measured']:.2f}", f"{g['mascaret']:.2f}",
                      f"{g['initial']:.3f}", f"{g['calibrated_7']:.3f}", f"{g['calibrated_13']:.3f}")
    out_console.print(table)
    out_console.print(f"RMSE against the measurements: Mascaret {summary['mascaret_rmse_m']:.3f} m; rivercal "
                      f"calibrated on all 13 {summary['rmse_m']:.3f} m (max {summary['max_abs_m']:.3f} m); calibrated "
                      f"on 7, the 6 held-out gauges {summary['held_out_rmse_m']:.3f} m (Mascaret there "
                      f"{summary['mascaret_held_out_rmse_m']:.3f} m)", highlight=False)
