"""The ``rivercal`` command line: parse, call the library, print.

Every command that produces numbers prints them as one JSON object on stdout with ``--json`` and
writes its files under ``--out``. Errors go to stderr with a non-zero exit status: 2 for invalid
input (a bad case, a bad option value), 3 for a failed model run, 1 for anything else (an internal
error says so, and ``--debug`` shows its traceback). See :mod:`rivercal.cli.common`.
"""

from __future__ import annotations

import logging
import os
import sys
from typing import Annotated

import typer

from rivercal import __version__
from rivercal._options import options
from rivercal.cli import advise, analyse, bench, calibrate, case, dashboard, dhydro, fews, model, online, simulate, twin
from rivercal.cli.common import guard, out_console, set_debug, set_verbose
from rivercal.cli.mascaret import import_mascaret_cmd
from rivercal.cli.sobek3 import import_sobek3_cmd

__all__ = ["app", "main"]

def _help_width() -> None:
    """Help printed without a terminal (into a file, a pager, a CI log) is laid out 120 columns wide.

    rich takes 80 columns when it cannot ask a terminal, and cuts the option table's long names to fit
    (``--dependency-th…``); a terminal's own width (or ``COLUMNS``, ``TERMINAL_WIDTH``) still rules.
    """
    import typer.rich_utils

    if typer.rich_utils.MAX_WIDTH is None and not os.environ.get("COLUMNS") and not sys.stdout.isatty():
        typer.rich_utils.MAX_WIDTH = 120


_help_width()

app = typer.Typer(
    name="rivercal",
    help="On-line parameter estimation for 1D river-network models.",
    epilog="Documentation (tutorial, how-to guides, explanations, reference): the docs/ folder of the source "
    "repository; 'make docs' builds it into docs/_build/html/index.html.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

#: Versions shown by ``rivercal --version --verbose``: what the numbers depend on.
DEPENDENCIES = ("numpy", "numba", "llvmlite", "scipy", "pandas", "xarray", "netCDF4", "pydantic", "matplotlib",
                "typer", "rich")


@app.callback(invoke_without_command=True)
def _main(
    ctx: typer.Context,
    version: Annotated[bool, typer.Option("--version", help="Show the version and exit (with --verbose: also the "
                                                            "versions of Python, numpy, numba …).")] = False,
    verbose: Annotated[bool, typer.Option(
        "--verbose", "-v", help="Log progress details on stderr, and print the optimiser's own terms (stopping rule, "
                                "status) beside the words.")] = False,
    debug: Annotated[bool, typer.Option("--debug", help="Show the traceback of an error (also RIVERCAL_DEBUG=1).")]
    = False,
) -> None:
    set_debug(debug)
    set_verbose(verbose)
    if version:
        out_console.print(version_text(verbose), highlight=False)
        raise typer.Exit(0)
    if ctx.invoked_subcommand is None:
        out_console.print(ctx.get_help())
        raise typer.Exit(0)
    os.environ.setdefault("MPLBACKEND", "Agg")  # files only; the library never chooses a backend
    level = logging.DEBUG if verbose else getattr(logging, options.log_level.upper(), logging.WARNING)
    handler = logging.StreamHandler(sys.stderr)
    handler.setLevel(level)  # also for the records of libraries that set their own loggers' level (Dask: INFO)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s", handlers=[handler])


def version_text(verbose: bool = False) -> str:
    """'rivercal 0.1.0'; with ``verbose`` one more line per dependency and for Python."""
    lines = [f"rivercal {__version__}"]
    if verbose:
        import platform
        from importlib.metadata import PackageNotFoundError, version

        lines.append(f"python {platform.python_version()} ({platform.python_implementation()}, "
                     f"{platform.system()} {platform.machine()})")
        for name in DEPENDENCIES:
            try:
                lines.append(f"{name} {version(name)}")
            except PackageNotFoundError:
                lines.append(f"{name} (not installed)")
    return "\n".join(lines)


app.add_typer(case.app, name="case")
app.add_typer(model.app, name="model")
app.add_typer(bench.app, name="bench")
dhydro.import_app.command("sobek3")(import_sobek3_cmd)
dhydro.import_app.command("mascaret")(import_mascaret_cmd)
app.add_typer(advise.app, name="advise")
app.add_typer(dhydro.import_app, name="import")
app.add_typer(dhydro.export_app, name="export")
for _name, _command in (("simulate", simulate.simulate), ("calibrate", calibrate.calibrate), ("twin", twin.twin),
                        ("analyse", analyse.analyse), ("online", online.online), ("report", online.report),
                        ("demo", online.demo), ("dashboard", dashboard.dashboard),
                        ("compile", simulate.compile_engine)):
    app.command(_name)(guard(_command))
app.command("fews", help=fews.HELP)(guard(fews.fews))


def main() -> None:  # pragma: no cover - console entry point
    """Entry point of the ``rivercal`` console script."""
    app()
