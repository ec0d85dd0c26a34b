"""Pieces shared by the command modules: consoles, common options, JSON output, error handling."""

import functools
import sys
from typing import Annotated

import typer
from rich.console import Console

from rivercal.errors import CaseError, ModelRunError, RivercalError

__all__ = ["CaseArg", "JsonOpt", "QuietOpt", "emit_json", "err_console", "guard", "null_context", "out_console",
           "parse_assignments", "parse_sets", "parse_window", "select_parameters"]

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


def parse_sets(values: list[str]) -> dict[str, float]:
    """Parse repeated ``--set NAME=VALUE`` options into a dict of floats."""
    out: dict[str, float] = {}
    for item in values:
        out.update(parse_assignments(item, "--set", example="friction:global=20"))
    return out


def parse_assignments(text: str | None, what: str, example: str = "FA=20") -> dict[str, float]:
    """'FA=20,Wc=0.8' → {'FA': 20.0, 'Wc': 0.8}; ``what`` names the option in error messages."""
    out: dict[str, float] = {}
    for item in filter(None, (part.strip() for part in (text or "").split(","))):
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"{what} {item!r}: expected NAME=VALUE, e.g. {what} {example}")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise ValueError(f"{what} {item!r}: {value!r} is not a number") from None
    return out


def parse_window(case, text: str):
    """A window of the case by name, or ``START/END``, as UTC timestamps inside the case period."""
    import pandas as pd

    named = {w.name: (w.start, w.end) for w in case.spec.windows}
    if text in named:
        a, b = named[text]
    else:
        first, sep, second = text.partition("/")
        if not sep:
            known = ", ".join(named) or "none"
            raise ValueError(f"--window {text!r}: expected START/END (e.g. 2010-09-27/2010-10-04) or a window of "
                             f"the case ({known})")
        try:
            a, b = pd.Timestamp(first), pd.Timestamp(second)
        except ValueError:
            raise ValueError(f"--window {text!r}: not two dates START/END") from None
    a = pd.Timestamp(a).tz_localize("UTC") if pd.Timestamp(a).tzinfo is None else pd.Timestamp(a).tz_convert("UTC")
    b = pd.Timestamp(b).tz_localize("UTC") if pd.Timestamp(b).tzinfo is None else pd.Timestamp(b).tz_convert("UTC")
    if not b > a:
        raise ValueError(f"--window {text!r}: the end is not after the start")
    if a < case.start or b > case.end:
        raise ValueError(f"--window {text!r}: lies outside the case period {case.start} .. {case.end}")
    return a, b


def select_parameters(case, names: str, start: dict[str, float], bounds: list[str]):
    """The case's parameters named in ``names`` (comma-separated), with start values and bounds overridden."""
    from rivercal.parameters import ParameterSet

    wanted = [n.strip() for n in names.split(",") if n.strip()]
    if not wanted:
        raise ValueError("--params: give at least one parameter name")
    known = {p.name: p for p in case.spec.parameters}
    for n in wanted:
        if n not in known:
            raise ValueError(f"--params: unknown parameter {n!r}; the case defines {', '.join(known) or 'none'}")
    updates: dict[str, dict[str, float]] = {n: {} for n in wanted}
    for item in bounds:
        name, sep, rng = item.partition("=")
        low, colon, high = rng.partition(":")
        if not sep or not colon or name not in updates:
            raise ValueError(f"--bounds {item!r}: expected NAME=MIN:MAX for a parameter in --params")
        try:
            updates[name].update(min=float(low), max=float(high))
        except ValueError:
            raise ValueError(f"--bounds {item!r}: MIN and MAX must be numbers") from None
        if not updates[name]["min"] < updates[name]["max"]:
            raise ValueError(f"--bounds {item!r}: min must be below max")
    for name, value in start.items():
        if name not in updates:
            raise ValueError(f"--start {name}={value}: {name!r} is not in --params")
        updates[name]["initial"] = value
    chosen = []
    for n in wanted:
        p = known[n]
        merged = {**p.model_dump(), **updates[n]}
        lo, hi, x0 = merged["min"], merged["max"], merged["initial"]
        if not lo <= x0 <= hi:
            raise ValueError(f"parameter {n}: start value {x0:g} lies outside its bounds [{lo:g}, {hi:g}]")
        chosen.append(type(p).model_validate(merged))
    return ParameterSet(chosen)
