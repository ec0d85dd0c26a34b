"""The black box: an external program behind the model contract, run once per evaluation.

Per run, :class:`BlackBoxModel`

1. makes a run folder (:class:`~rivercal.models.blackbox.runs.RunFolders`: one per evaluation and worker
   process, the model folder copied into it, nothing shared written);
2. writes the restart files of a hot start (``[blackbox.state] restart_in``) and renders the templates
   with the run's quantities and times (:mod:`~rivercal.models.blackbox.templates`);
3. runs the command as an argv list (never a shell; parameter values reach the program only through
   files and argv items, literally) in the run folder, with the model's environment added to rivercal's,
   stdout and stderr to ``stdout.txt`` / ``stderr.txt``, under a supervisor
   (:mod:`~rivercal.models.blackbox.supervisor`) that stops the program and everything it started when it
   ends, after ``timeout`` seconds, and when rivercal stops (Ctrl-C, SIGTERM, SIGKILL);
4. reads the outputs (:mod:`~rivercal.models.blackbox.readers`), keeps the rows on the output grid of
   [start, end], and keeps the ``restart_out`` files as the state at ``end``.

Files stay in their place: every file a ``model.toml`` names is checked at load to lie in the model
folder (template sources) or the run folder (targets, restart files, outputs), and the model folder to
hold no link that leads outside it (:mod:`~rivercal.models.blackbox.paths`); a bad one is a
:class:`~rivercal.models.config.ModelFileError` naming the field.

A run that exits non-zero, times out, writes nothing, a truncated file or a non-finite value raises
:class:`BlackBoxRunError` naming the run folder (kept: the newest ``keep_failed`` failed folders) and the
cause, files named relative to the run folder; the calibration then follows its failure policy
(``raise`` or ``penalty``).

The row at ``start``: a cold start runs from ``spinup`` hours before ``start`` and takes the row from the
output; a hot start takes it from the state (its last row), since programs that report after their first
step (SWMM) do not write it.
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import logging
import os
import re
import selectors
import signal
import stat
import subprocess
import sys
import tempfile
import time as _time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal.models.blackbox.paths import check_tree, inside, kind_of, relative_path
from rivercal.models.blackbox.readers import excerpt, read_output
from rivercal.models.blackbox.runs import MARKER, RunFolders, default_base
from rivercal.models.blackbox.templates import Template, render_argv
from rivercal.models.config import ModelFile, ModelFileError
from rivercal.models.contract import CalibrationSetup, ExternalRunError, FileState, Quantity, check_run, utc
from rivercal.results import SimulationResult

__all__ = ["BUILTINS", "MAX_STATE_BYTES", "MAX_TEMPLATE_BYTES", "BlackBoxModel", "BlackBoxRunError"]

log = logging.getLogger(__name__)

#: Placeholders rivercal fills itself (templates and argv).
BUILTINS = ("start", "end", "run_start", "run_dir", "hot", "cold", "dt", "output_interval", "python")
#: File of a black-box state that holds the last row of the run (the next hot-started run's first row).
LAST_ROW = "rivercal-last-row.json"
#: Most output times of a run (the model's period and spin-up over its output interval).
MAX_ROWS = 10_000_000
#: Largest template read, bytes (64 MiB).
MAX_TEMPLATE_BYTES = 64 << 20
#: Largest restart file kept as (part of) a state, bytes (1 GiB).
MAX_STATE_BYTES = 1 << 30
#: The supervisor script that starts each run's program (run by path: it imports nothing of rivercal).
SUPERVISOR = Path(__file__).with_name("supervisor.py")
#: Seconds the supervisor gets to stop a program's processes before it is killed itself.
_STOP_GRACE_S = 30.0


class BlackBoxRunError(ExternalRunError):
    """A run of an external program failed; names the run folder and the cause."""

    what = "external model run"


class BlackBoxModel:
    """An external program described by the ``[blackbox]`` table of a ``model.toml`` (module docstring).

    Parameters
    ----------
    spec
        The validated ``model.toml``.
    root
        The folder of ``model.toml`` (relative paths start there).
    calibration
        Parameters, windows and optimiser defaults that ship with the model.

    Raises
    ------
    ModelFileError
        For a model folder, template, restart file or output that is missing or lies outside its folder, a
        link in the model folder that leads outside it, a placeholder that is no quantity, an output series
        named twice, a runs folder that cannot be written, naming the field.
    """

    def __init__(self, spec: ModelFile, root: str | Path, calibration: CalibrationSetup | None = None):
        bb = spec.blackbox
        if bb is None:
            raise ValueError("the model file has no [blackbox] table")
        self.spec = bb
        self.meta = spec.model
        self.name = spec.model.name
        root = Path(root)
        label = str(root / "model.toml")

        def error(field: str, message: str) -> ModelFileError:
            return ModelFileError(message, file=label, field=field)

        self.folder = _model_folder(bb.folder, root, error)
        interval = float(self.meta.output_interval)
        rows = ((self.meta.end - self.meta.start).total_seconds() + 3600.0 * self.meta.spinup) / interval
        if interval < 1.0 or rows > MAX_ROWS:
            raise error("model.output_interval", f"{interval:g} s gives {rows:,.0f} output times over the model's "
                        f"period and spin-up: a black box reads at most {MAX_ROWS:,}, at least 1 s apart")
        self._calibration = calibration or CalibrationSetup()
        self._formats = {name: q.format for name, q in bb.quantities.items()}
        for name, q in bb.quantities.items():
            if _too_wide(q.format):
                raise error(f"blackbox.quantities.{_key(name)}.format", f"{excerpt(q.format)}: a width or precision "
                            "above 999")
        runs_dir = _runs_dir(bb.runs_dir, root, self.folder, self.name, error)
        self.templates: list[tuple[Template, str]] = []
        sources: list[str] = []
        for i, t in enumerate(bb.templates):
            field = f"blackbox.templates[{i}]"
            self.templates.append((self._template(t.source, field, error), _target(t, field, error)))
            sources.append(relative_path(t.source, "the model folder"))
        targets = [target for _, target in self.templates]
        for i, target in enumerate(targets):
            if target in targets[:i]:
                raise error(f"blackbox.templates[{i}].target", f"{target!r} is the target of two templates")
        epoch = pd.Timestamp(0, tz="UTC")
        dummy = {**dict.fromkeys(bb.quantities, 1.0), **self._builtins(epoch, epoch, epoch, Path("."), False)}
        for i, (template, _) in enumerate(self.templates):
            try:
                template.render(dummy, self._formats)
            except (ValueError, TypeError, OverflowError) as exc:
                raise error(f"blackbox.templates[{i}]", f"{template.source}: cannot be rendered ({exc})") from None
        if not bb.command[0].strip():
            raise error("blackbox.command[0]", "the program is empty: give its path or name")
        for i, item in enumerate(bb.command):
            if "\0" in item:
                raise error(f"blackbox.command[{i}]", f"{excerpt(item)} holds a NUL character")
        try:
            render_argv(bb.command, dummy, self._formats)
        except KeyError as exc:
            raise error("blackbox.command", exc.args[0]) from None
        except (ValueError, TypeError, OverflowError) as exc:
            raise error("blackbox.command", f"an item cannot be rendered ({exc})") from None
        for key, value in bb.env.items():
            if not key or "=" in key or "\0" in key or "\0" in value:
                raise error(f"blackbox.env.{_key(key)}", f"{excerpt(key)} = {excerpt(value)} is not an environment "
                            "variable (a name without '=' and NUL, a value without NUL)")
        self.outputs: list[str] = []
        self.observables: list[str] = []
        for i, out in enumerate(bb.outputs):
            self.outputs.append(_in_run_folder(out.file, f"blackbox.outputs[{i}].file", error))
            if out.reader == "swmm":
                _check_swmm_output(out.series, f"blackbox.outputs[{i}]", error)
            for name in out.series:
                if name in self.observables:
                    raise error(f"blackbox.outputs[{i}].series", f"series {name} is read from two outputs")
                self.observables.append(name)
        self.restart_out: list[str] = []
        self.restart_in: list[str] = []
        if bb.state is not None:
            for key, names, kept in (("restart_out", bb.state.restart_out, self.restart_out),
                                     ("restart_in", bb.state.restart_in, self.restart_in)):
                for i, name in enumerate(names):
                    kept.append(_in_run_folder(name, f"blackbox.state.{key}[{i}]", error))
                    if Path(kept[-1]).name in [Path(k).name for k in kept[:-1]]:
                        raise error(f"blackbox.state.{key}[{i}]", f"{Path(kept[-1]).name!r} is named twice (a "
                                    "state holds its files by name)")
        for i, name in enumerate(self.restart_in):
            if name in targets:
                raise error(f"blackbox.state.restart_in[{i}]", f"{name!r} is also a template's target (the rendered "
                            "template would overwrite the restart file)")
        self.runs = RunFolders(self.name, base=runs_dir, keep_failed=bb.keep_failed, keep=bb.keep, exclude=sources)
        try:
            check_tree(self.folder, skip=[runs_dir])
        except ValueError as exc:
            raise error("blackbox.folder", str(exc)) from None
        with contextlib.suppress(OSError):
            self.runs.sweep()  # the run folders of processes that were killed
        self._origin = f"blackbox:{self.name}"

    def _template(self, source: str, field: str, error: Any) -> Template:
        """The template ``source`` (a file in the model folder), parsed and checked."""
        try:
            rel = relative_path(source, "the model folder")
        except ValueError as exc:
            raise error(f"{field}.source", str(exc)) from None
        path = self.folder / rel
        shown = _shown(path)
        if not inside(path, self.folder):
            raise error(f"{field}.source", f"{shown} leads outside the model folder {self.folder}")
        try:
            info = os.stat(path)
        except OSError:
            what = kind_of(path)
            raise error(f"{field}.source", f"no such template {shown}" if what == "missing" else
                        f"the template {shown} is {what}") from None
        if not stat.S_ISREG(info.st_mode):
            raise error(f"{field}.source", f"the template {shown} is {kind_of(path)}, not a file")
        if info.st_size > MAX_TEMPLATE_BYTES:
            raise error(f"{field}.source", f"the template {shown} holds {info.st_size:,} bytes, more than the "
                        f"{MAX_TEMPLATE_BYTES:,} rivercal reads")
        try:
            with open(path, "rb") as f:
                text = f.read(MAX_TEMPLATE_BYTES + 1).decode("utf-8")
            template = Template(text, source=str(path))
            template.check(self.spec.quantities, BUILTINS)
        except UnicodeDecodeError:
            raise error(field, f"{shown}: not UTF-8 text") from None
        except OSError as exc:
            raise error(f"{field}.source", f"{shown} cannot be read ({exc.strerror})") from None
        except ValueError as exc:
            raise error(field, str(exc)) from None
        return template

    # -- contract facts ---------------------------------------------------------------------------

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({self.name!r}, {self.start:%Y-%m-%d %H:%M} … {self.end:%Y-%m-%d %H:%M} UTC, "
                f"Δt {self.dt:g} s, {len(self.quantities)} quantities, {len(self.observables)} series, "
                f"program {' '.join(self.spec.command)!r})")

    @property
    def start(self) -> pd.Timestamp:
        """Start of the model's period (UTC)."""
        return utc(self.meta.start)

    @property
    def end(self) -> pd.Timestamp:
        """End of the model's period (UTC)."""
        return utc(self.meta.end)

    @property
    def dt(self) -> float:
        """Time step of the program, s (``model.dt``)."""
        return float(self.meta.dt)  # type: ignore[arg-type]

    @property
    def output_interval(self) -> float:
        """Default interval of the series, s."""
        return float(self.meta.output_interval)

    @property
    def calibration(self) -> CalibrationSetup:
        """Parameters, windows and optimiser defaults of the model."""
        return self._calibration

    @property
    def quantities(self) -> dict[str, Quantity]:
        """The settable quantities: the placeholders declared in ``[blackbox.quantities]``."""
        return {name: Quantity(name, q.unit, q.min, q.max, q.description) for name, q in self.spec.quantities.items()}

    def default_parameters(self) -> dict[str, float]:
        """The defaults of the quantities that have one."""
        return {name: q.default for name, q in self.spec.quantities.items() if q.default is not None}

    @property
    def state_format(self) -> str:
        """Format tag of :meth:`save_state`: a zip of the restart files."""
        return "rivercal-blackbox-restart-1"

    def save_state(self, state: FileState) -> bytes:
        """The state as bytes."""
        return state.to_bytes()

    def load_state(self, data: bytes, fmt: str) -> FileState:
        """A state of this model from :meth:`save_state` bytes; ValueError for another format or model."""
        if fmt != self.state_format:
            raise ValueError(f"state format {fmt!r} is not {self.state_format!r}")
        return FileState.from_bytes(data, origin=self._origin)

    # -- running ----------------------------------------------------------------------------------

    def _builtins(self, start, end, run_start, run_dir: Path, hot: bool) -> dict[str, Any]:
        return {"start": start, "end": end, "run_start": run_start, "run_dir": str(run_dir), "hot": hot,
                "cold": not hot,
                "dt": float(self.meta.dt or 0.0), "output_interval": float(self.meta.output_interval),
                "python": sys.executable}

    def simulate(self, parameters: Mapping[str, float] | None = None, start: Any = None, end: Any = None,
                 state: FileState | None = None, *, output_interval: float | None = None
                 ) -> tuple[SimulationResult, FileState | None]:
        """Run the program once from ``start`` to ``end`` (module docstring).

        Parameters
        ----------
        parameters
            Quantities to set; the others take their defaults (a quantity without one must be set).
        start, end
            Period (UTC; default the model's); ``end - start`` a multiple of the output interval.
        state
            Hot-start state at ``start`` (needs ``[blackbox.state]``); None: cold start.
        output_interval
            Interval of the series, s; must be ``model.output_interval`` (the program's own reporting).

        Returns
        -------
        (SimulationResult, FileState or None)
            The series (``balance`` None) and the restart files at ``end`` (None without
            ``[blackbox.state]``).

        Raises
        ------
        BlackBoxRunError
            For a failed run (module docstring).
        ValueError
            For an unknown quantity, a value out of bounds or missing, a period off the grid, a state at
            another time or a hot start without ``[blackbox.state]``.
        """
        if output_interval is not None and float(output_interval) != self.output_interval:
            raise ValueError(f"model {self.name!r} reports every {self.output_interval:g} s (model.output_interval); "
                             f"cannot give {float(output_interval):g} s")
        if state is not None and self.spec.state is None:
            raise ValueError(f"model {self.name!r} has no [blackbox.state]: it cannot hot start")
        run = check_run(self, parameters, start, end, state, None)
        values, start, end = self._values(run.parameters), run.start, run.end
        run_start = start - pd.Timedelta(hours=self.meta.spinup) if state is None else start
        try:
            run_dir = self.runs.new(self.folder)
        except (OSError, ValueError) as exc:
            raise BlackBoxRunError(str(self.runs.base), f"cannot make a run folder: {_cause(exc)}") from None
        t0 = _time.perf_counter()
        try:
            series, files = self._run(run_dir, values, start, end, run_start, state)
        except BlackBoxRunError as exc:
            kept = self.runs.failed(run_dir)
            raise BlackBoxRunError(str(kept), _cause(exc.cause, run_dir)) from None
        except (OSError, ValueError) as exc:  # writing inputs or restart files
            kept = self.runs.failed(run_dir)
            raise BlackBoxRunError(str(kept), _cause(exc, run_dir)) from None
        except BaseException:  # interrupted (Ctrl-C): the program is stopped, its folder tells nothing
            self.runs.discard(run_dir)
            raise
        wall = _time.perf_counter() - t0
        self.runs.done(run_dir)
        new_state = None
        if files is not None:
            last = {"time": end.isoformat(), "values": {k: float(v) for k, v in series.iloc[-1].items()}}
            new_state = FileState(time=end, files={**files, LAST_ROW: json.dumps(last).encode()}, origin=self._origin)
        source = f"external model {self.name} (rivercal black box)"
        return SimulationResult(series=series, wall_time=wall, source=source), new_state

    def _values(self, parameters: Mapping[str, float]) -> dict[str, float]:
        """Every quantity's value: the checked ones given, the defaults of the rest."""
        values: dict[str, float] = {}
        for name, q in self.spec.quantities.items():
            if name in parameters:
                values[name] = parameters[name]
            elif q.default is not None:
                values[name] = float(q.default)
            else:
                raise ValueError(f"quantity {name} of model {self.name!r} has no default: set it")
        return values

    def _run(self, run_dir: Path, values: Mapping[str, float], start: pd.Timestamp, end: pd.Timestamp,
             run_start: pd.Timestamp, state: FileState | None) -> tuple[pd.DataFrame, dict[str, bytes] | None]:
        fail = lambda cause: BlackBoxRunError(str(run_dir), cause)  # noqa: E731
        hot = state is not None
        if hot:
            for target in self.restart_in:
                name = Path(target).name
                if name not in state.files:
                    raise ValueError(f"the state has no restart file {name} (has {', '.join(sorted(state.files))})")
                _write(run_dir, target, state.files[name])
        placeholders = {**values, **self._builtins(start, end, run_start, run_dir, hot)}
        for template, target in self.templates:
            _write(run_dir, target, template.render(placeholders, self._formats).encode("utf-8"))
        argv = render_argv(self.spec.command, placeholders, self._formats)
        env = {**os.environ, **self.spec.env, MARKER: str(run_dir)}
        outcome = _supervised(argv, run_dir, env, self.spec.timeout)
        if outcome == "timeout":
            raise fail(f"the program did not finish within its timeout of {self.spec.timeout:g} s and was stopped "
                       "(with every process it started)")
        kind, _, number = outcome.partition(" ")
        if kind == "error":
            raise fail(f"cannot start {excerpt(argv[0], 200)}: {os.strerror(int(number))}")
        if kind == "signal":
            raise fail(f"the program was ended by signal {_signal_name(int(number))}" + _tail(run_dir / "stderr.txt"))
        if kind != "exit":
            raise fail("the program was stopped before it finished")
        if int(number) != 0:
            raise fail(f"the program exited with status {int(number)}" + _tail(run_dir / "stderr.txt"))
        frames = []
        for out, name in zip(self.spec.outputs, self.outputs, strict=True):
            path = run_dir / name
            if not inside(path, run_dir):
                raise fail(f"{name} leads outside the run folder (a link to {os.path.realpath(path)})")
            try:
                frames.append(read_output(out.reader, path, out.series, out.time_column, label=name))
            except ValueError as exc:
                raise fail(str(exc)) from None
        series = pd.concat(frames, axis=1) if len(frames) > 1 else frames[0]
        written = series.index
        series = series[self.observables]
        times = pd.date_range(start, end, freq=pd.Timedelta(seconds=self.output_interval))
        if hot and start not in series.index:
            last = json.loads(state.files[LAST_ROW]) if LAST_ROW in state.files else None  # type: ignore[union-attr]
            if last is not None:
                row = pd.DataFrame([last["values"]], index=pd.DatetimeIndex([start]))
                series = pd.concat([row[self.observables], series])
        present = times.isin(series.index)
        series = series.reindex(times)
        series.index.name = "time"
        bad = ~np.isfinite(series.to_numpy())
        if bad.any():
            row, col = np.argwhere(bad)[0]
            when, what = series.index[row], series.columns[col]
            if len(written) == 0 or when > written.max() or when < written.min():
                span = f"{written.min()} .. {written.max()}" if len(written) else "nothing"
                raise fail(f"no value of {what} at {when}: the output covers {span} (truncated?)")
            if not present[row]:
                raise fail(f"no value of {what} at {when}: the output has no row at that time (the run's series are "
                           f"every {self.output_interval:g} s, model.output_interval)")
            raise fail(f"non-finite value of {what} at {when}")
        files = None
        if self.spec.state is not None:
            files = {}
            for produced, target in zip(self.restart_out, self.restart_in, strict=True):
                files[Path(target).name] = _read_restart(run_dir, produced, fail)
        return series, files


def _key(name: str, limit: int = 40) -> str:
    """A key of model.toml as a field path shows it: whole when short, else its start (the message quotes it)."""
    return name if len(name) <= limit else name[:limit] + "…"


def _shown(path: Path | str, limit: int = 200) -> str:
    """A path as a message shows it: whole when short, else its start and end with its length."""
    text = str(path)
    return text if len(text) <= limit else f"{text[:limit // 2]}…{text[-limit // 4:]} ({len(text):,} characters)"


def _model_folder(folder: str, root: Path, error: Any) -> Path:
    """The model folder: ``folder`` relative to the folder of ``model.toml`` and inside it."""
    try:
        rel = relative_path(folder, "the folder of model.toml") if folder.strip() not in (".", "./", "") else "."
    except ValueError as exc:
        raise error("blackbox.folder", str(exc)) from None
    path = root / rel
    shown = _shown(path)
    try:
        resolved = Path(os.path.realpath(path, strict=True))
    except OSError:
        raise error("blackbox.folder", f"no such folder {shown}" if kind_of(path) == "missing" else
                    f"{shown} is {kind_of(path)}") from None
    if not inside(resolved, root):
        raise error("blackbox.folder", f"{shown} leads outside the folder of model.toml ({_shown(resolved)})")
    if not resolved.is_dir():
        raise error("blackbox.folder", f"{shown} is {kind_of(resolved)}, not a folder")
    return resolved


def _runs_dir(runs_dir: str | None, root: Path, folder: Path, name: str, error: Any) -> Path:
    """Where the run folders go (``runs_dir`` relative to ``model.toml``, or the default), checked writable."""
    field = "blackbox.runs_dir"
    if runs_dir is not None and ("\0" in runs_dir or not runs_dir.strip()):
        raise error(field, f"{excerpt(runs_dir)} is not a folder name")
    base = Path(os.path.abspath(root / runs_dir)) if runs_dir is not None else default_base(name)
    if os.path.lexists(base) and not os.path.isdir(base):
        raise error(field, f"cannot hold run folders in {base}: it is {kind_of(base)}, not a folder")
    if Path(os.path.realpath(base)) == folder:
        raise error(field, f"{base} is the model folder: the run folders go elsewhere (they would be copied into "
                    "each other)")
    try:  # made now, and written to once, so that a folder that cannot be written fails the load
        base.mkdir(parents=True, exist_ok=True)
        os.rmdir(tempfile.mkdtemp(prefix=".rivercal-probe-", dir=base))
    except OSError as exc:
        where = f" ({exc.filename})" if exc.filename and str(exc.filename) != str(base) else ""
        raise error(field, f"cannot hold run folders in {base}: {exc.strerror or exc}{where}") from None
    return base


def _target(spec: Any, field: str, error: Any) -> str:
    """The file a template becomes, relative to the run folder."""
    try:
        name = spec.target_name
    except ValueError as exc:
        raise error(f"{field}.target", str(exc)) from None
    return _in_run_folder(name, f"{field}.target", error)


def _in_run_folder(name: str, field: str, error: Any) -> str:
    """``name`` normalised as a file in the run folder, or a ModelFileError naming ``field``."""
    try:
        rel = relative_path(name, "the run folder")
    except ValueError as exc:
        raise error(field, str(exc)) from None
    if rel in ("stdout.txt", "stderr.txt"):
        raise error(field, f"{rel!r} is where the program's output goes: name another file")
    return rel


def _check_swmm_output(series: Mapping[str, str], field: str, error: Any) -> None:
    from rivercal.models.swmm.output import parse_element

    for name, spec in series.items():
        try:
            parse_element(spec)
        except ValueError as exc:
            raise error(f"{field}.series", f"{name}: {exc}") from None
    if importlib.util.find_spec("swmm") is None:
        raise error(f"{field}.reader", "reading SWMM output needs swmm-toolkit: install rivercal[swmm]")


_WIDTH = re.compile(r"\d{4,}")


def _too_wide(spec: str | None) -> bool:
    """Whether a number format asks for a width or precision above 999 (it would render megabytes)."""
    return bool(spec) and bool(_WIDTH.search(spec))  # type: ignore[arg-type]


def _write(run_dir: Path, target: str, data: bytes) -> None:
    """Write ``data`` to ``target`` in the run folder (its folders made), never through a link outside."""
    path = run_dir / target
    if not inside(path.parent, run_dir):
        raise ValueError(f"{target} leads outside the run folder")
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.is_symlink() or not inside(path, run_dir):
        path.unlink()
    path.write_bytes(data)


def _read_restart(run_dir: Path, produced: str, fail: Any) -> bytes:
    """The bytes of a restart file the program wrote (a regular file in the run folder, bounded)."""
    path = run_dir / produced
    if not inside(path, run_dir):
        raise fail(f"the restart file {produced} leads outside the run folder (a link to {os.path.realpath(path)})")
    try:
        info = os.stat(path)
    except OSError:
        what = kind_of(path)
        raise fail(f"the program wrote no restart file {produced}" if what == "missing" else
                   f"the restart file {produced} is {what}") from None
    if not stat.S_ISREG(info.st_mode):
        raise fail(f"the restart file {produced} is {kind_of(path)}, not a file")
    if info.st_size > MAX_STATE_BYTES:
        raise fail(f"the restart file {produced} holds {info.st_size:,} bytes, more than the {MAX_STATE_BYTES:,} "
                   "rivercal keeps as a state")
    return path.read_bytes()


def _supervised(argv: list[str], run_dir: Path, env: Mapping[str, str], timeout: float) -> str:
    """Run ``argv`` in ``run_dir`` under the supervisor; its report, or ``timeout``.

    The report is ``exit N``, ``signal N``, ``error ERRNO`` or ``stopped``. Whatever ends this call (a
    timeout, Ctrl-C), the program and everything it started are stopped first. The wait is on the pipe
    the supervisor reports through (it closes when the supervisor ends), so the run ends when it ends.
    """
    status_r, status_w = os.pipe()
    try:
        with open(run_dir / "stdout.txt", "wb") as out, open(run_dir / "stderr.txt", "wb") as err:
            try:
                proc = subprocess.Popen([sys.executable, "-I", "-S", str(SUPERVISOR), str(os.getpid()), str(status_w),
                                         "--", *argv], cwd=run_dir, stdout=out, stderr=err, stdin=subprocess.DEVNULL,
                                        env=dict(env), start_new_session=True, pass_fds=(status_w,))
            finally:
                os.close(status_w)
                status_w = -1
        report = b""
        deadline = _time.monotonic() + timeout
        try:
            with selectors.DefaultSelector() as waiting:  # epoll/kqueue: any descriptor number
                waiting.register(status_r, selectors.EVENT_READ)
                while True:
                    left = deadline - _time.monotonic()
                    if left <= 0:
                        _stop(proc)
                        return "timeout"
                    if waiting.select(min(left, 3600.0)):
                        chunk = os.read(status_r, 256)
                        if not chunk:  # the supervisor ended
                            break
                        report += chunk[: max(0, 256 - len(report))]
            proc.wait()
        except BaseException:
            _stop(proc)
            raise
        return report.decode("ascii", "replace").strip() or "stopped"
    finally:
        os.close(status_r)
        if status_w >= 0:
            os.close(status_w)


def _stop(proc: subprocess.Popen) -> None:
    """Tell the supervisor to stop the program and everything it started, and wait; kill it if it hangs."""
    with contextlib.suppress(ProcessLookupError):
        proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(timeout=_STOP_GRACE_S)
    except subprocess.TimeoutExpired:
        log.warning("the supervisor of a black-box run did not stop within %g s; killing it", _STOP_GRACE_S)
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.kill()
        proc.wait()


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return str(number)


def _cause(cause: BaseException | str, run_dir: Path | None = None) -> str:
    """A failure's cause on one line, short, files named relative to the run folder (which may be renamed)."""
    if isinstance(cause, OSError) and cause.filename is not None:
        name = str(cause.filename)
        if run_dir is not None and name.startswith(str(run_dir) + os.sep):
            name = name[len(str(run_dir)) + 1:]
        text = f"{name}: {cause.strerror or cause}"
    else:
        text = str(cause)
    if run_dir is not None:
        text = text.replace(str(run_dir) + os.sep, "").replace(str(run_dir), "the run folder")
    text = " ".join(text.split())
    return text if len(text) <= 600 else text[:600] + "…"


def _tail(path: Path, lines: int = 3, width: int = 200) -> str:
    """``; stderr: …`` with the last lines of the program's stderr (the last 4 KiB read, lines shortened)."""
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            f.seek(max(0, f.tell() - 4096))
            text = f.read().decode("utf-8", errors="replace")
    except OSError:
        return ""
    kept = [line.strip() for line in text.strip().splitlines() if line.strip()][-lines:]
    kept = [line if len(line) <= width else line[:width] + "…" for line in kept]
    return ("; stderr: " + " | ".join(kept)) if kept else ""
