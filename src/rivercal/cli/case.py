"""``rivercal case``: print the case schema, validate and summarise a case, draw its network."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from rivercal.cli.common import CaseArg, JsonOpt, emit_json, guard, out_console
from rivercal.cli.options import open_model, output_file

__all__ = ["app"]

app = typer.Typer(help="Inspect and validate cases.", no_args_is_help=True)


@app.command("schema")
@guard
def schema() -> None:
    """Print the JSON Schema of case.toml."""
    from rivercal.case.schema import CaseFile

    emit_json(CaseFile.model_json_schema())


@app.command("generate")
@guard
def generate(
    points: Annotated[int, typer.Option(help="Calculation points wanted (about; dx = 100 m).")],
    out: Annotated[Path, typer.Option("--out", help="The case folder to write.")],
    seed: Annotated[int, typer.Option(help="Seed of the random network (≥ 0).")] = 0,
    name: Annotated[str | None, typer.Option(help="Case name (default generated-POINTS-SEED).")] = None,
    dt: Annotated[float, typer.Option(help="The engine's time step, s (a divisor of 3600).")] = 60.0,
    as_json: JsonOpt = False,
) -> None:
    """Write a realistic lowland network of about POINTS points: catchments of weir-controlled streams, loops."""
    from rivercal.case.generate import divides_the_hour, generate_case
    from rivercal.cli.options import check_number, output_dir
    from rivercal.errors import OptionError

    check_number(points, "--points", low=100, high=10_000_000)
    check_number(seed, "--seed", low=0)
    if not divides_the_hour(dt):
        raise OptionError(f"--dt {dt:g}: must divide 3600 s, the hourly output interval (e.g. 60, 300, 600)",
                          option="--dt")
    output_dir(out)
    try:
        made = generate_case(out, points, seed, name=name, dt=dt)
    except FileExistsError as exc:
        raise OptionError(f"--out {out}: holds a case.toml that the generator did not write; give another folder "
                          "(nothing was written)", option="--out") from exc
    summary = {"case": str(made.path), "catchments": made.catchments, "branches": made.branches,
               "length_km": made.length_km, "weirs": made.weirs, "culverts": made.culverts,
               "laterals": made.laterals, "stations": made.stations}
    if as_json:
        emit_json(summary)
        return
    out_console.print(f"wrote {made.path}: {made.catchments} catchments, {made.branches} branches "
                      f"({made.length_km:g} km), {made.weirs} weirs, {made.culverts} culverts, {made.laterals} "
                      f"laterals, {made.stations} stations (rivercal case check {made.path} counts its points)")


@app.command("check")
@guard
def check(case: CaseArg, as_json: JsonOpt = False) -> None:
    """Validate a case and summarise it (a model.toml: what the model declares, as ``rivercal model check``)."""
    model = open_model(case)
    if not hasattr(model, "case"):
        from rivercal.cli.model import model_summary, print_summary

        summary = model_summary(model)
        if as_json:
            emit_json(summary)
        else:
            print_summary(summary, f"model {model.name} — valid")
        return
    c = model.case
    net = c.network
    compiled = model.compiled
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
        "controllers": len(c.spec.controllers),
        "observables": model.observables,
    }
    if as_json:
        emit_json(summary)
        return
    table = Table(title=f"case {c.name} — valid", show_header=False)
    for key, value in summary.items():
        table.add_row(key, _listed(value) if isinstance(value, list) else str(value))
    out_console.print(table)


#: A list longer than this is shown by its length and its first names (``--json`` gives all).
_LISTED = 12


def _listed(values: list) -> str:
    """A list for the terminal: all of it when short, else its length, the first few and where the rest are."""
    if len(values) <= _LISTED:
        return ", ".join(map(str, values))
    return f"{len(values)}: {', '.join(map(str, values[:_LISTED]))} … (--json lists all)"


@app.command("plot")
@guard
def plot(
    case: CaseArg,
    out: Annotated[Path, typer.Option("--out", help="PNG file to write.")] = Path("network.png"),
) -> None:
    """Draw the network: branches, weirs (labelled), stations, laterals, boundaries."""
    from rivercal.report.figures import case_weir_labels, plot_network

    if out.suffix.lower() != ".png":
        from rivercal.errors import OptionError

        raise OptionError(f"--out {out}: expected a .png file", option="--out")
    output_file(out, "--out")
    model = open_model(case)
    if not hasattr(model, "case"):
        from rivercal.errors import OptionError

        raise OptionError(f"{case}: 'case plot' draws a case's network; model {model.name!r} "
                          f"({type(model).__name__}) has none", option="CASE")
    c = model.case
    path = plot_network(c.network, out, title=f"{c.name}: {c.spec.case.description}"[:110],
                        weir_labels=case_weir_labels(c))
    out_console.print(f"wrote {path}")


@app.command("copy")
@guard
def copy(
    name: Annotated[str, typer.Argument(help="A packaged case (e.g. 'westerscheldt').", show_default=False)],
    out: Annotated[Path, typer.Argument(help="The folder to write (must not exist).", show_default=False)],
) -> None:
    """Copy a packaged case into a folder of your own, to read its files or start from it."""
    import shutil

    from rivercal.case.load import available_cases, resolve_case_path
    from rivercal.errors import OptionError

    if name not in available_cases():
        raise OptionError(f"{name!r} is not a packaged case (packaged: {', '.join(available_cases())})",
                          option="NAME")
    if out.exists():
        raise OptionError(f"{out} exists; give a new folder", option="OUT")
    shutil.copytree(resolve_case_path(name), out, ignore=shutil.ignore_patterns("__pycache__", "__init__.py"))
    out_console.print(f"copied the packaged case {name!r} into {out}")
