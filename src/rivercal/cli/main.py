"""The ``rivercal`` command line: parse, call the library, print.

Every command that produces numbers prints them as one JSON object on stdout with ``--json`` and
writes its files under ``--out``. Errors go to stderr with a non-zero exit code: 2 for invalid
input (a bad case, an unknown parameter), 3 for a failed model run.
"""

import functools
import json
import logging
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

from rivercal import __version__
from rivercal._options import options
from rivercal.errors import CaseError, ModelRunError, RivercalError

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

out_console = Console()
err_console = Console(stderr=True, soft_wrap=True)

CaseArg = Annotated[str, typer.Argument(help="A case folder or the name of a packaged case (e.g. 'synthetic').")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress or summary on the terminal.")]


def _fail(exc: Exception, code: int) -> None:
    err_console.print(f"[bold red]error:[/] {exc}", highlight=False)
    raise typer.Exit(code)


def _guard(func):
    """Turn rivercal's errors into a message and an exit code."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except (CaseError, KeyError, ValueError) as exc:
            _fail(exc if not isinstance(exc, KeyError) else ValueError(exc.args[0]), 2)
        except ModelRunError as exc:
            _fail(exc, 3)
        except RivercalError as exc:
            _fail(exc, 1)

    return wrapper


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


def _parse_sets(values: list[str]) -> dict[str, float]:
    out = {}
    for item in values:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"--set {item!r}: expected NAME=VALUE, e.g. --set friction:global=20")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--set {item!r}: {value!r} is not a number") from None
    return out


def _emit_json(obj: dict) -> None:
    sys.stdout.write(json.dumps(obj, indent=None, default=str) + "\n")


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


class _null:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


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


# -- demo ---------------------------------------------------------------------------------------


@app.command()
@_guard
def demo(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("out/demo"),
    as_json: JsonOpt = False,
) -> None:
    """The main job on the embedded default case: simulate the De Dommel-like network, Sep-Nov 2010."""
    from rivercal.model import load_model
    from rivercal.report.figures import plot_network, plot_series

    with err_console.status("loading the dommel case (rainfall-runoff of 16 catchments)", spinner="dots") \
            if not as_json else _null():
        sim = load_model("dommel")
    c = sim.case
    with err_console.status("simulating Sep-Nov 2010", spinner="dots") if not as_json else _null():
        result, _ = sim.simulate()
    out.mkdir(parents=True, exist_ok=True)
    result.to_csv(out / "series.csv")
    result.to_netcdf(out / "series.nc")
    figs = [
        plot_network(c.network, out / "network.png", title="dommel: De Dommel-like weir network",
                     weir_labels=_weir_labels(c)),
        plot_series(result.series, out / "series.png", title="dommel, Sep-Nov 2010: simulated station series"),
    ]
    summary = {
        "case": c.name,
        "period": [c.start.isoformat(), c.end.isoformat()],
        "calculation_points": sim.compiled.n_hpoints,
        "wall_s": round(result.wall_time, 3),
        "volume_balance_relative_error": result.balance.relative_error,
        "outputs": [str(out / "series.csv"), str(out / "series.nc"), *map(str, figs)],
    }
    if as_json:
        _emit_json(summary)
        return
    out_console.print(f"[bold]rivercal demo[/]: simulated the [bold]{c.name}[/] network "
                      f"({sim.compiled.n_hpoints} calculation points, {len(c.network.weirs)} weirs, "
                      f"{len(c.spec.catchments)} catchments) {c.start:%Y-%m-%d} .. {c.end:%Y-%m-%d} in "
                      f"{result.wall_time:.2f} s; volume balance closes to {result.balance.relative_error:.1e}.")
    table = Table(title="station series: dry weather (1-6 Sep) and the November 2010 peak")
    for col in ("series", "1-6 Sep mean", "Nov peak"):
        table.add_column(col, justify="right" if col != "series" else "left")
    for name in result.series.columns:
        unit = "m³/s" if name.endswith(".Q") else "m AD"
        col = result.series[name]
        table.add_row(name, f"{col.loc['2010-09-01':'2010-09-06'].mean():.3f} {unit}",
                      f"{col.loc['2010-11-01':'2010-11-30'].max():.3f} {unit}")
    out_console.print(table)
    out_console.print("results: " + ", ".join(summary["outputs"]))


def main() -> None:  # pragma: no cover - console entry point
    """Entry point of the ``rivercal`` console script."""
    app()
