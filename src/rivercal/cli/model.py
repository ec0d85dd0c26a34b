"""``rivercal model``: the schema of model.toml, and a check that summarises any model (a case too)."""

from __future__ import annotations

import math
from typing import Any

import typer
from rich.markup import escape
from rich.table import Table

from rivercal.cli.common import CaseArg, JsonOpt, emit_json, guard, out_console
from rivercal.cli.options import open_model

__all__ = ["app", "model_summary", "print_summary", "quantity_groups"]

app = typer.Typer(help="Models described by a model.toml (an external program, EPA SWMM, a BMI component).",
                  no_args_is_help=True)


@app.command("schema")
@guard
def schema() -> None:
    """Print the JSON Schema of model.toml."""
    from rivercal.models.config import ModelFile

    emit_json(ModelFile.model_json_schema())


def _bound(value: Any) -> float | None:
    """A declared bound, None when there is none (or the engine's stand-in for none, ±10 km of level)."""
    from rivercal.network import MAX_LEVEL

    if value is None:
        return None
    x = float(value)
    return None if not math.isfinite(x) or abs(x) >= MAX_LEVEL else x


def model_summary(model: Any) -> dict[str, Any]:
    """What every model declares (the model contract): period, time step, quantities, series, parameters.

    ``quantities`` lists every settable quantity with its unit, bounds (None: no bound) and description;
    ``n_quantities`` counts them.
    """
    kind = "case" if hasattr(model, "case") else type(model).__name__
    quantities = [{"name": q.name, "unit": q.unit, "min": _bound(q.min), "max": _bound(q.max),
                   "description": q.description} for q in model.quantities.values()]
    return {
        "model": model.name,
        "kind": kind,
        "start": model.start.isoformat(),
        "end": model.end.isoformat(),
        "dt_s": model.dt,
        "output_interval_s": model.output_interval,
        "n_quantities": len(quantities),
        "quantities": quantities,
        "parameters": {p.name: p.unit for p in model.calibration.parameters},
        "windows": {name: f"{a:%Y-%m-%d %H:%M} .. {b:%Y-%m-%d %H:%M}" for name, (a, b) in
                    model.calibration.windows.items()},
        "state_format": model.state_format,
        "observables": list(model.observables),
    }


def quantity_groups(quantities: list[dict[str, Any]]) -> list[tuple[str, str, str, list[str]]]:
    """The quantities in groups of one form and unit: (form, unit, range, ids), in declaration order.

    ``weir:ZL1-5.crest_level`` and ``weir:ZL1-3014.crest_level`` are the form ``weir:<id>.crest_level`` with ids
    ``ZL1-5`` and ``ZL1-3014``; a name without an id part is a group of its own. The range is the group's
    when all its quantities share it, else ``varies`` (``--json`` gives each).
    """
    import re

    groups: dict[tuple[str, str], list[tuple[str, str]]] = {}
    for q in quantities:
        match = re.fullmatch(r"(?P<head>[^:]+(?::(?:branch|group|node|link))?:)(?P<id>[^:]+?)(?P<tail>\.[A-Za-z_]+)?",
                             q["name"])
        if match and (match.group("tail") or match.group("head").count(":") == 2):
            form, ident = f"{match.group('head')}<id>{match.group('tail') or ''}", match.group("id")
        else:
            form, ident = q["name"], ""
        low, high = q["min"], q["max"]
        if low is None and high is None:
            limits = "no bounds"
        else:
            limits = f"{'−∞' if low is None else f'{low:g}'} … {'∞' if high is None else f'{high:g}'}"
        groups.setdefault((form, q["unit"] or "-"), []).append((ident, limits))
    out = []
    for (form, unit), members in groups.items():
        ranges = {limits for _, limits in members}
        out.append((form, unit, ranges.pop() if len(ranges) == 1 else "varies", [i for i, _ in members if i]))
    return out


def print_summary(summary: dict[str, Any], title: str) -> None:
    """The summary as a table, then the settable quantities grouped by form (every one named)."""
    table = Table(title=title, show_header=False)
    for key, value in summary.items():
        if key == "quantities":
            continue
        if isinstance(value, dict):
            shown = ", ".join(f"{k} ({v})" if v else k for k, v in value.items())
        else:
            shown = ", ".join(map(str, value)) if isinstance(value, list) else str(value)
        table.add_row(key, shown)
    out_console.print(table)
    quantities = Table(title=escape(f"settable quantities ({summary['n_quantities']}): what --set and "
                                    "[[parameters]] targets may name"), title_justify="left")  # no markup in it
    for col in ("quantity", "unit", "range", "count", "ids"):
        quantities.add_column(col, justify="right" if col == "count" else "left", overflow="fold",
                              no_wrap=col in ("quantity", "count"))
    for form, unit, limits, ids in quantity_groups(summary["quantities"]):
        quantities.add_row(form, unit, limits, str(max(len(ids), 1)), ", ".join(ids))
    out_console.print(quantities)


@app.command("check")
@guard
def check(model: CaseArg, as_json: JsonOpt = False) -> None:
    """Load a model (a model.toml or a case), check it and list what it declares: quantities, series, period."""
    loaded = open_model(model)
    summary = model_summary(loaded)
    if as_json:
        emit_json(summary)
        return
    print_summary(summary, f"model {loaded.name} — valid")
