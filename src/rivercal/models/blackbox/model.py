"""The black box: an external program behind the model contract, run once per evaluation.

Per run, :class:`BlackBoxModel`

1. makes a run folder (:class:`~rivercal.models.blackbox.runs.RunFolders`: one per evaluation and worker
   process, the model folder copied into it, nothing shared written);
2. writes the restart files of a hot start (``[blackbox.state] restart_in``) and renders the templates
   with the run's quantities and times (:mod:`~rivercal.models.blackbox.templates`);
3. runs the command as an argv list (never a shell; parameter values reach the program only through
   files and argv items, literally) in the run folder, with the model's environment added to rivercal's,
   stdout and stderr to ``stdout.txt`` / ``stderr.txt``, and stops it (its whole process group) after
   ``timeout`` seconds;
4. reads the outputs (:mod:`~rivercal.models.blackbox.readers`), keeps the rows on the output grid of
   [start, end], and keeps the ``restart_out`` files as the state at ``end``.

A run that exits non-zero, times out, writes nothing, a truncated file or a non-finite value raises
:class:`BlackBoxRunError` naming the run folder (kept: the newest ``keep_failed`` failed folders) and the
cause; the calibration then follows its failure policy (``raise`` or ``penalty``).

The row at ``start``: a cold start runs from ``spinup`` hours before ``start`` and takes the row from the
output; a hot start takes it from the state (its last row), since programs that report after their first
step (SWMM) do not write it.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
import time as _time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal.engine.state import SimulationResult
from rivercal.models.blackbox.readers import read_output
from rivercal.models.blackbox.runs import RunFolders
from rivercal.models.blackbox.templates import Template, render_argv
from rivercal.models.config import ModelFile, ModelFileError
from rivercal.models.contract import CalibrationSetup, ExternalRunError, FileState, Quantity, check_run, utc

__all__ = ["BUILTINS", "BlackBoxModel", "BlackBoxRunError"]

log = logging.getLogger(__name__)

#: Placeholders rivercal fills itself (templates and argv).
BUILTINS = ("start", "end", "run_start", "run_dir", "hot", "cold", "dt", "output_interval", "python")
#: File of a black-box state that holds the last row of the run (the next hot-started run's first row).
LAST_ROW = "rivercal-last-row.json"


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
        For a missing model folder or template, a placeholder that is no quantity, an output series
        named twice, naming the field.
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
        self.folder = (root / bb.folder).resolve()
        if not self.folder.is_dir():
            raise ModelFileError(f"no such folder {self.folder}", file=label, field="blackbox.folder")
        self._calibration = calibration or CalibrationSetup()
        self._formats = {name: q.format for name, q in bb.quantities.items()}
        self.templates: list[tuple[Template, str]] = []
        for i, t in enumerate(bb.templates):
            source = self.folder / t.source
            if not source.is_file():
                raise ModelFileError(f"no such template {source}", file=label, field=f"blackbox.templates[{i}].source")
            try:
                template = Template(source.read_text(encoding="utf-8"), source=str(source))
                template.check(bb.quantities, BUILTINS)
                target = t.target_name
            except (ValueError, UnicodeDecodeError) as exc:
                raise ModelFileError(str(exc), file=label, field=f"blackbox.templates[{i}]") from None
            self.templates.append((template, target))
        epoch = pd.Timestamp(0, tz="UTC")
        dummy = {**dict.fromkeys(bb.quantities, 1.0), **self._builtins(epoch, epoch, epoch, Path("."), False)}
        try:
            render_argv(bb.command, dummy, self._formats)
        except KeyError as exc:
            raise ModelFileError(exc.args[0], file=label, field="blackbox.command") from None
        self.observables: list[str] = []
        for i, out in enumerate(bb.outputs):
            for name in out.series:
                if name in self.observables:
                    raise ModelFileError(f"series {name} is read from two outputs", file=label,
                                         field=f"blackbox.outputs[{i}].series")
                self.observables.append(name)
        runs_dir = (root / bb.runs_dir).resolve() if bb.runs_dir else None
        self.runs = RunFolders(self.name, base=runs_dir, keep_failed=bb.keep_failed, keep=bb.keep,
                               exclude={t.source for t in bb.templates})
        self._origin = f"blackbox:{self.name}"

    # -- contract facts ---------------------------------------------------------------------------

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
        run_dir = self.runs.new(self.folder)
        t0 = _time.perf_counter()
        try:
            series, files = self._run(run_dir, values, start, end, run_start, state)
        except BlackBoxRunError as exc:
            kept = self.runs.failed(run_dir)
            raise BlackBoxRunError(str(kept), exc.cause) from None
        except (OSError, ValueError) as exc:  # writing inputs or restart files
            kept = self.runs.failed(run_dir)
            raise BlackBoxRunError(str(kept), " ".join(str(exc).split())) from None
        wall = _time.perf_counter() - t0
        self.runs.done(run_dir)
        new_state = None
        if files is not None:
            last = {"time": end.isoformat(), "values": {k: float(v) for k, v in series.iloc[-1].items()}}
            new_state = FileState(time=end, files={**files, LAST_ROW: json.dumps(last).encode()}, origin=self._origin)
        return SimulationResult(series=series, balance=None, wall_time=wall), new_state

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
            for target in self.spec.state.restart_in:  # type: ignore[union-attr]
                name = Path(target).name
                if name not in state.files:
                    raise ValueError(f"the state has no restart file {name} (has {', '.join(state.files)})")
                (run_dir / target).parent.mkdir(parents=True, exist_ok=True)
                (run_dir / target).write_bytes(state.files[name])
        placeholders = {**values, **self._builtins(start, end, run_start, run_dir, hot)}
        for template, target in self.templates:
            (run_dir / target).parent.mkdir(parents=True, exist_ok=True)
            (run_dir / target).write_text(template.render(placeholders, self._formats), encoding="utf-8")
        argv = render_argv(self.spec.command, placeholders, self._formats)
        env = {**os.environ, **self.spec.env}
        with open(run_dir / "stdout.txt", "wb") as out, open(run_dir / "stderr.txt", "wb") as err:
            try:
                proc = subprocess.Popen(argv, cwd=run_dir, stdout=out, stderr=err, stdin=subprocess.DEVNULL, env=env,
                                        start_new_session=True)
            except OSError as exc:
                raise fail(f"cannot start {argv[0]!r}: {exc.strerror or exc}") from None
            try:
                code = proc.wait(timeout=self.spec.timeout)
            except subprocess.TimeoutExpired:
                _stop(proc)
                raise fail(f"the program did not finish within its timeout of {self.spec.timeout:g} s and was "
                           "stopped") from None
        if code != 0:
            raise fail(f"the program exited with status {code}" + _tail(run_dir / "stderr.txt"))
        frames = []
        for out in self.spec.outputs:
            try:
                frames.append(read_output(out.reader, run_dir / out.file, out.series, out.time_column))
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
        series = series.reindex(times)
        series.index.name = "time"
        bad = ~np.isfinite(series.to_numpy())
        if bad.any():
            row, col = np.argwhere(bad)[0]
            when, what = series.index[row], series.columns[col]
            if len(written) == 0 or when > written.max() or when < written.min():
                span = f"{written.min()} .. {written.max()}" if len(written) else "nothing"
                raise fail(f"no value of {what} at {when}: the output covers {span} (truncated?)")
            raise fail(f"non-finite value of {what} at {when}")
        files = None
        if self.spec.state is not None:
            files = {}
            for produced, target in zip(self.spec.state.restart_out, self.spec.state.restart_in, strict=True):
                path = run_dir / produced
                if not path.is_file():
                    raise fail(f"the program wrote no restart file {produced}")
                files[Path(target).name] = path.read_bytes()
        return series, files


def _stop(proc: subprocess.Popen) -> None:
    """Stop a program and everything it started (its process group), then reap it."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        proc.kill()
    proc.wait()


def _tail(path: Path, lines: int = 3) -> str:
    try:
        text = path.read_text(encoding="utf-8", errors="replace").strip().splitlines()
    except OSError:
        return ""
    return ("; stderr: " + " | ".join(line.strip() for line in text[-lines:])) if text else ""
