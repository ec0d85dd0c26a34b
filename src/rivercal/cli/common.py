"""Pieces shared by the command modules: consoles, common options, JSON output, error handling."""

import functools
import sys
from typing import Annotated

import typer
from rich.console import Console

from rivercal.errors import CaseError, ModelRunError, RivercalError

__all__ = ["CaseArg", "JsonOpt", "QuietOpt", "emit_json", "err_console", "guard", "null_context", "out_console"]

out_console = Console()
err_console = Console(stderr=True, soft_wrap=True)

CaseArg = Annotated[str, typer.Argument(help="A case folder or the name of a packaged case (e.g. 'dommel').")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress or summary on the terminal.")]


def emit_json(obj: dict) -> None:
    """Print one JSON object on stdout (numpy numbers and timestamps as their str/float)."""
    import json

    sys.stdout.write(json.dumps(obj, default=lambda v: float(v) if hasattr(v, "__float__") else str(v)) + "\n")


def fail(exc: Exception, code: int) -> None:
    """Print an error on stderr and exit with ``code``."""
    err_console.print(f"[bold red]error:[/] {exc}", highlight=False)
    raise typer.Exit(code)


def guard(func):
    """Turn rivercal's errors into a message and an exit code: 2 bad input, 3 failed model run, 1 other."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except (CaseError, KeyError, ValueError) as exc:
            fail(exc if not isinstance(exc, KeyError) else ValueError(exc.args[0]), 2)
        except ModelRunError as exc:
            fail(exc, 3)
        except RivercalError as exc:
            fail(exc, 1)

    return wrapper


class null_context:
    """A context manager that does nothing (in place of a progress display under --json or --quiet)."""

    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False
