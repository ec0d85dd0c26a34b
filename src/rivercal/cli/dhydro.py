"""``rivercal import dhydro`` and ``rivercal export dhydro``: D-HYDRO (D-Flow FM 1D) models in and out of cases."""

from pathlib import Path
from typing import Annotated

import typer

from rivercal._format import plural
from rivercal.cli.common import CaseArg, JsonOpt, QuietOpt, emit_json, guard, out_console

__all__ = ["export_app", "import_app"]

import_app = typer.Typer(help="Bring a model of another program in as a case.", no_args_is_help=True)
export_app = typer.Typer(help="Write a case as a model of another program.", no_args_is_help=True)


def _require_hydrolib() -> None:
    try:
        import hydrolib.core  # noqa: F401
        import tomli_w  # noqa: F401
    except ImportError:
        raise ValueError("reading and writing D-HYDRO models needs hydrolib-core and tomli-w: "
                         "pip install 'rivercal[dhydro]'") from None


@import_app.command("dhydro")
@guard
def import_dhydro_cmd(
    model: Annotated[Path, typer.Argument(help="The D-Flow FM model file (.mdu).")],
    out: Annotated[Path, typer.Option("--out", help="Case folder to write (case.toml, series, import.md).")],
    allow_partial: Annotated[bool, typer.Option(
        "--allow-partial", help="Write the case even when objects that change the hydraulics were refused "
                                "(they are left out; import.md lists them).")] = False,
    realtime: Annotated[list[Path], typer.Option(
        "--realtime", help="DIMR exchange file (NetCDF) with the series of 'realtime' laterals and structure "
                           "settings of a coupled run, e.g. rr_to_flow.nc, rtc_to_flow.nc; repeatable.")] = [],  # noqa: B006
    realtime_lateral: Annotated[float | None, typer.Option(
        "--realtime-lateral", help="Constant inflow (m³/s) of every 'realtime' lateral that no exchange file "
                                   "supplies; without it such laterals are refused.")] = None,
    dt: Annotated[float | None, typer.Option(help="Time step of the case, s (default: the case's own when rivercal "
                                                  "exported the model, else at most 60 s, a divisor of the output "
                                                  "interval).")] = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Convert a D-Flow FM 1D model into a case folder, accounting for every object in import.md."""
    _require_hydrolib()
    from rivercal.io.dhydro import ImportOptions, import_dhydro

    options = ImportOptions(realtime=tuple(realtime), realtime_lateral=realtime_lateral, allow_partial=allow_partial,
                            dt=dt)
    result = import_dhydro(model, out, options)
    if as_json:
        emit_json(result.summary)
        return
    if quiet:
        return
    s = result.summary
    kinds = ", ".join(plural(n, k.replace("_", " ")) for k, n in s["structures"].items()) or "no structures"
    parts = [plural(s["branches"], "branch"), plural(s["points"], "point"), plural(s["profiles"], "profile"), kinds,
             plural(s["boundaries"], "boundary"), plural(s["laterals"], "lateral"), plural(s["stations"], "station"),
             plural(len(s["parameters"]), "calibration parameter")]
    out_console.print(f"imported [bold]{model.name}[/] into {out}: {', '.join(parts)}; {s['approximated']} "
                      f"approximated, {s['refused']} refused (see {out / 'import.md'})")
    out_console.print(f"next: read {out / 'import.md'}, then `rivercal case check {out}` and `rivercal simulate {out} "
                      f"--out {out}-run`; `rivercal online {out} --help` runs the on-line service on it",
                      highlight=False)


@export_app.command("dhydro")
@guard
def export_dhydro_cmd(
    case: CaseArg,
    out: Annotated[Path, typer.Option("--out", help="Folder to write the D-Flow FM files to.")],
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Write a case as D-Flow FM 1D files (MDU, network, cross-sections, structures, forcing)."""
    _require_hydrolib()
    from rivercal.case import load_case
    from rivercal.io.dhydro import export_dhydro

    result = export_dhydro(load_case(case), out)
    summary = {"mdu": str(result.mdu), "files": [str(p) for p in result.files], "notes": result.notes}
    if as_json:
        emit_json(summary)
        return
    if quiet:
        return
    out_console.print(f"wrote {result.mdu} and {len(result.files) - 1} other files (see {out / 'export.md'})")
