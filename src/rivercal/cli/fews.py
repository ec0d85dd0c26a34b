"""``rivercal fews RUN_INFO.xml``: the Delft-FEWS General Adapter module (:mod:`rivercal.fews`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rivercal.cli.common import JsonOpt, QuietOpt, emit_json, err_console

__all__ = ["HELP", "fews"]

_LEVELS = {0: "fatal", 1: "error", 2: "warning", 3: "info", 4: "debug"}


def _help() -> str:
    from rivercal.fews.properties import PROPERTIES

    lines = [
        "Run one on-line cycle as a Delft-FEWS General Adapter module, from a PI run file.",
        "",
        "Reads the run file's time0 (the calibration window ends there, the forecast starts there), its "
        "inputTimeSeriesFile (observations at stations: locationId = station, parameterId = h, h_up, h_down or Q; "
        "forcing at boundaries and laterals: parameterId Q in m3/s or h in m; structure settings: parameterId "
        "crestLevel, gateLowerEdgeLevel in m or capacity in m3/s), its inputStateDescriptionFile (the "
        "rivercal store of the previous run), and writes the outputTimeSeriesFile (forecasts with qualifierId "
        "updated or dss; estimates, their sigma and the values used), the outputStateDescriptionFile and the "
        "outputDiagnosticFile. Every problem goes to the diagnostics file with level error and a non-zero exit "
        "status (2 bad input, 3 a failed model run, 1 otherwise).",
        "",
        "Properties read from the run file's <properties> (key: meaning (default)):",
        "",
    ]
    for key, (default, meaning) in PROPERTIES.items():
        shown = "required" if default is None else (f"default {default}" if default else "optional")
        lines += [f"{key}: {meaning} ({shown})", ""]
    lines.append("A sample module configuration is in docs/fews.md.")
    return "\n".join(lines)


HELP = _help()


def fews(
    run_file: Annotated[Path, typer.Argument(help="The PI run file the General Adapter wrote (run_info.xml).")],
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Run one on-line cycle as a Delft-FEWS General Adapter module (the help text is :data:`HELP`)."""
    from rivercal.fews.adapter import run_module

    outcome = run_module(run_file)
    if not quiet:
        for line in outcome.diagnostics:
            err_console.print(f"{_LEVELS.get(line.level, line.level)}: {line.text}", highlight=False, markup=False)
        if outcome.diag_file is None:
            err_console.print("error: the run file names no diagnostics file that could be written", highlight=False)
    if as_json:
        emit_json({"exit_code": outcome.exit_code, "diagnostics": str(outcome.diag_file) if outcome.diag_file else None,
                   **outcome.summary})
    raise typer.Exit(outcome.exit_code)


fews.__doc__ = HELP
