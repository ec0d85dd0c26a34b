"""``rivercal model``: the schema of model.toml, and a check that summarises any model (a case too)."""

from __future__ import annotations

from typing import Any

import typer
from rich.table import Table

from rivercal.cli.common import CaseArg, JsonOpt, emit_json, guard, out_console
from rivercal.cli.options import open_model

__all__ = ["app", "model_summary"]

app = typer.Typer(help="Models described by a model.toml (an external program, EPA SWMM, a BMI component).",
                  no_args_is_help=True)


@app.command("schema")
@guard
def schema() -> None:
    """Print the JSON Schema of model.toml."""
    from rivercal.models.config import ModelFile

    emit_json(ModelFile.model_json_schema())


def model_summary(model: Any) -> dict[str, Any]:
    """What every model declares (the model contract): period, time step, quantities, series, parameters."""
    kind = "case" if hasattr(model, "case") else type(model).__name__
    return {
        "model": model.name,
        "kind": kind,
        "start": model.start.isoformat(),
        "end": model.end.isoformat(),
        "dt_s": model.dt,
        "output_interval_s": model.output_interval,
        "quantities": len(model.quantities),
        "parameters": {p.name: p.unit for p in model.calibration.parameters},
        "windows": list(model.calibration.windows),
        "state_format": model.state_format,
        "observables": list(model.observables),
    }


@app.command("check")
@guard
def check(model: CaseArg, as_json: JsonOpt = False) -> None:
    """Load a model (a model.toml or a case), check it and summarise what it declares."""
    loaded = open_model(model)
    summary = model_summary(loaded)
    if as_json:
        emit_json(summary)
        return
    table = Table(title=f"model {loaded.name} — valid", show_header=False)
    for key, value in summary.items():
        shown = ", ".join(f"{k} ({v})" if v else k for k, v in value.items()) if isinstance(value, dict) else (
            ", ".join(value) if isinstance(value, list) else str(value))
        table.add_row(key, shown)
    out_console.print(table)
