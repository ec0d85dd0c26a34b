"""Pieces shared by the command modules: consoles, common options, JSON output, errors and progress.

Exit status of every command: 0 done; 1 an error rivercal did not expect (an internal error: its type
and text, and the hint to re-run with ``--debug``) or a purposeful error that is not the input's fault
(e.g. a store written by a newer version); 2 bad input (:class:`~rivercal.errors.CaseError`,
:class:`~rivercal.errors.OptionError`; the message names the file, field or option); 3 a failed model
run (:class:`~rivercal.errors.ModelRunError`); 130 interrupted.
"""

from __future__ import annotations

import functools
import os
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from rivercal.errors import CaseError, ModelRunError, OptionError, RivercalError

__all__ = ["CaseArg", "DaskOpt", "JsonOpt", "QuietOpt", "Reporter", "debug_enabled", "emit_json", "err_console",
           "guard", "out_console", "set_debug", "set_verbose", "stop_words", "verbose_enabled", "watch_compilation"]

out_console = Console(emoji=False)  # ":100:" in a message is text, not an emoji
err_console = Console(stderr=True, soft_wrap=True, emoji=False)

CaseArg = Annotated[str, typer.Argument(help="A case folder or the name of a packaged case (e.g. 'dommel'), or a "
                                             "model.toml of another model (or its folder; e.g. 'dommel-swmm').")]
JsonOpt = Annotated[bool, typer.Option("--json", help="Print one JSON object on stdout.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress or summary on the terminal.")]
DaskOpt = Annotated[str | None, typer.Option(
    "--dask", help="Run the model runs on a Dask cluster: local:N (N worker processes here) or tcp://HOST:PORT "
                   "(a running scheduler; see docs/cluster.md).")]
DependencyOpt = Annotated[Path | None, typer.Option(
    help="With --algorithm sparse_dud: the dependency map that 'rivercal analyse' writes (dependency.csv), which "
         "series each parameter moves.")]
DependencyThresholdOpt = Annotated[float, typer.Option(
    "--dependency-threshold", help="With --dependency: the effect of a first step, in σ of a series, above which "
                                   "the series depends on the parameter.")]

_DEBUG = {"on": False, "verbose": False}


def set_verbose(on: bool) -> None:
    """``rivercal --verbose``: the commands also print the optimiser's own words (stopping rule, status)."""
    _DEBUG["verbose"] = on


def verbose_enabled() -> bool:
    """Whether ``--verbose`` was given."""
    return _DEBUG["verbose"]


def stop_words(result: Any) -> str:
    """Why a calibration stopped, in words for the person who ran it (the optimiser's own terms are for ``--verbose``).

    ``result`` is an :class:`~rivercal.optimise.OptimiseResult`: ``success``, ``status`` (its code) and
    ``message`` (the algorithm's termination message, e.g. "T2: … at most rel_tol").
    """
    from rivercal.optimise.result import STATUS_CALLBACK, STATUS_DEADLINE, STATUS_MAX_ITER, STATUS_MAX_NFEV

    status = getattr(result, "status", None)
    if getattr(result, "success", False):
        words = "converged: another iteration would not lower the misfit noticeably"
    elif status == STATUS_DEADLINE:
        words = "stopped at the time limit (--deadline) before converging; the best values found so far are shown"
    elif status == STATUS_MAX_NFEV:
        words = "stopped at the cap on model runs (--max-nfev) before converging; the best values so far are shown"
    elif status == STATUS_MAX_ITER:
        words = "stopped after the most iterations the optimiser allows, before converging"
    elif status == STATUS_CALLBACK:
        words = "stopped on request before converging"
    else:
        words = "did not converge (rivercal --verbose … says the optimiser's reason)"
    if verbose_enabled():
        words += f" [optimiser: {getattr(result, 'message', '')} (status {status})]"
    return words


def set_debug(on: bool) -> None:
    """Show the traceback of every error (``--debug``; also the environment variable RIVERCAL_DEBUG=1)."""
    _DEBUG["on"] = on


def debug_enabled() -> bool:
    """Whether ``--debug`` or RIVERCAL_DEBUG=1 asked for tracebacks."""
    return _DEBUG["on"] or os.environ.get("RIVERCAL_DEBUG", "").strip().lower() in ("1", "true", "yes", "on")


def emit_json(obj: dict) -> None:
    """Print one JSON object on stdout (numpy numbers and timestamps as their float/str)."""
    import json

    sys.stdout.write(json.dumps(obj, default=lambda v: float(v) if hasattr(v, "__float__") else str(v)) + "\n")


def _fail(label: str, text: str, code: int, hint: str = "") -> None:
    if debug_enabled():
        import traceback

        sys.stderr.write(traceback.format_exc())
        hint = ""
    from rich.markup import escape  # a message quotes files and tables, e.g. "[calibration]": not markup

    err_console.print(f"[bold red]{label}[/] {escape(text)}" + (f"\n{escape(hint)}" if hint else ""), highlight=False)
    raise typer.Exit(code)


def guard(func):
    """Turn errors into a message and an exit status (see the module docstring)."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except (typer.Exit, typer.Abort, SystemExit):
            raise
        except (CaseError, OptionError) as exc:
            _fail("error:", str(exc), 2)
        except ModelRunError as exc:
            _fail("model run failed:", str(exc), 3)
        except RivercalError as exc:
            _fail("error:", str(exc), 1)
        except KeyboardInterrupt:
            _fail("interrupted", "", 130)
        except Exception as exc:  # everything else is rivercal's fault, never the input's
            _fail("internal error:", f"{type(exc).__name__}: {exc}", 1,
                  hint="This is a bug in rivercal, not a problem with your input. Re-run with --debug (or "
                       "RIVERCAL_DEBUG=1) to see the traceback, and please report it with the command.")

    return wrapper


# -- the first run compiles the engine ------------------------------------------------------------


#: What a compilation in a rivercal module is called on the terminal, by the module's package.
_COMPILED_WHAT = {"rivercal.engine": "the engine's time loop", "rivercal.hydrology": "the rainfall-runoff model"}


def watch_compilation(show: bool) -> None:
    """Say on stderr when numba starts compiling rivercal's kernels (a cold cache: the first run only).

    numba announces a compilation (the ``numba:compile`` event) only when it compiles, never when it
    loads a kernel from its cache, so the note appears exactly when the wait is long. It names what is
    compiled (the engine's time loop, the rainfall-runoff model): after ``rivercal compile`` nothing
    is left to compile, and nothing is said. Printed once per kind and process, also under ``--json`` (on
    stderr), not under ``--quiet``.
    """
    if not show or _COMPILE["watching"]:
        return
    from numba.core import event

    class CompileNotice(event.Listener):
        def on_start(self, ev: Any) -> None:
            if os.getpid() != _COMPILE["pid"]:  # forked workers inherit this; the parent speaks
                return
            module = getattr(getattr((ev.data or {}).get("dispatcher"), "py_func", None), "__module__", None) or ""
            if not module.startswith("rivercal."):
                return
            package = ".".join(module.split(".")[:2])
            what = _COMPILED_WHAT.get(package, "rivercal's numerical kernels")
            if what in _COMPILE["shown"]:
                return
            _COMPILE["shown"].add(what)
            err_console.print(f"compiling {what} (once per version of rivercal; later runs load it from the cache; "
                              "'rivercal compile' does it ahead) …", highlight=False)

        def on_end(self, ev: Any) -> None:
            pass

    _COMPILE.update(watching=True, pid=os.getpid())
    event.register("numba:compile", CompileNotice())


_COMPILE: dict[str, Any] = {"watching": False, "shown": set(), "pid": None}


# -- progress -------------------------------------------------------------------------------------


class Reporter:
    """Renders a workflow's progress on stderr (a spinner, a bar with totals) unless it is off.

    Implements :class:`rivercal.workflows.Progress`: ``stage`` (what happens now), ``step`` (done of
    total, with a bar) and ``note`` (a line that stays above the display). Without a terminal (stderr to a
    file or a pipe: a log, CI) there is no bar to show the count, so a note that follows a step starts with
    it: ``3/29 cycle 2 …``.
    """

    def __init__(self, show: bool):
        self.show = show
        self._progress = None
        self._task = None
        self._count = ""  # the count of the latest step, until a note has shown it

    @contextmanager
    def running(self, first: str = "starting"):
        """Show the display while the block runs (nothing when off)."""
        if not self.show:
            yield self
            return
        from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

        with Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(bar_width=24),
                      TextColumn("{task.fields[count]}"), TimeElapsedColumn(), console=err_console,
                      transient=True) as progress:
            self._progress = progress
            self._task = progress.add_task(first, total=None, count="")
            try:
                yield self
            finally:
                self._progress = self._task = None

    def stage(self, text: str) -> None:
        """What the workflow does now (no count)."""
        if self._progress is not None:
            self._progress.update(self._task, description=text, total=None, completed=0, count="")

    def step(self, done: int, total: int | None, text: str) -> None:
        """``done`` of ``total`` units of work (a bar when the total is known), e.g. '3/10 cycles'."""
        count = f"{done}/{total}" if total else f"{done}"
        self._count = count
        if self._progress is not None:
            self._progress.update(self._task, description=text, total=total, completed=done, count=count)

    def note(self, text: str) -> None:
        """A line that stays (a finished cycle, a skipped file); without a terminal, after the step's count."""
        if not self.show:
            return
        if self._count and not err_console.is_terminal:
            text = f"{self._count} {text}"
        self._count = ""
        err_console.print(text, highlight=False, markup=False)
