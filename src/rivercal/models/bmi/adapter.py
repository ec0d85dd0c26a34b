"""Any Basic Model Interface component behind the model contract, so that rivercal calibrates it.

The ``[bmi]`` table of a ``model.toml`` names the component (``package.module:Class``), its configuration
file and which BMI variables (and elements of their grids) are the model's quantities and stations.
Per run :class:`BmiModel`

1. creates the component and calls ``initialize`` with the configuration file — rendered first when it is
   a template (``.tmpl``; the built-in placeholders of :mod:`rivercal.models.blackbox.templates`, e.g.
   ``{{run_start}}``, and ``{{model_dir}}``, the folder of ``model.toml``), since BMI has no call that sets
   the clock: the configuration sets the start;
2. for a hot start, sets the state variables (``[bmi] state``) from the state; then sets the quantities;
3. calls ``update_until`` at every output time and reads the stations (``get_value_at_indices``);
4. reads the state variables at the end (the state) and calls ``finalize``.

BMI times are converted with the component's ``get_time_units`` (s, min, h, d) from its
``get_start_time``, which stands for the run's start. A component that raises is a failed run
(:class:`~rivercal.errors.ModelRunError`, naming the component and the call).

With ``[bmi.assimilate]`` the model has the optional capabilities of state updating
(:mod:`rivercal.models.capabilities`):

- **state arrays**: the state variables ``levels`` (at the nodes of an unstructured grid, m) and
  ``discharges`` (on its edges, m³/s) read and written through the state; a state written back leaves out the
  ``derived`` variables, which the component computes from them when they are set. Where the water is
  measured and how far apart the nodes lie come from the grid (``get_grid_edge_nodes``, the nodes' x and y);
  ``floor`` names the variable of the lowest level at each node (none: no floor);
- **perturbable forcing**: ``forcing`` names per inflow or lateral the variable (and element) of its scale
  factor, which the adapter sets at the start of every interval (``set_value_at_indices``).
"""

from __future__ import annotations

import importlib
import io
import tempfile
import time as _time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rivercal.errors import ModelRunError
from rivercal.models.blackbox.templates import Template
from rivercal.models.capabilities import StateLayout
from rivercal.models.config import BmiSection, ModelFile, ModelFileError
from rivercal.models.contract import CalibrationSetup, Quantity, check_run, utc
from rivercal.results import SimulationResult

__all__ = ["BmiModel", "BmiState"]

_SECONDS = {"s": 1.0, "sec": 1.0, "seconds": 1.0, "second": 1.0, "min": 60.0, "minutes": 60.0, "h": 3600.0,
            "hr": 3600.0, "hours": 3600.0, "hour": 3600.0, "d": 86400.0, "day": 86400.0, "days": 86400.0}


class BmiState:
    """The state of a BMI model: its time and the values of its state variables."""

    def __init__(self, time: pd.Timestamp, values: Mapping[str, np.ndarray]):
        self.time = time
        self.values = {k: np.array(v, dtype=float) for k, v in values.items()}

    def to_bytes(self) -> bytes:
        """An ``.npz`` archive of plain arrays (no pickle)."""
        buffer = io.BytesIO()
        np.savez(buffer, __time_ns__=np.int64(self.time.value), **self.values)
        return buffer.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes) -> BmiState:
        """Read :meth:`to_bytes`; ValueError for other bytes."""
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as f:
                values = {k: f[k] for k in f.files if k != "__time_ns__"}
                return cls(pd.Timestamp(int(f["__time_ns__"]), tz="UTC"), values)
        except (OSError, KeyError, ValueError) as exc:
            raise ValueError(f"not a BMI state archive ({exc})") from None


class BmiModel:
    """A BMI component described by a ``model.toml`` (module docstring).

    Parameters
    ----------
    component
        The BMI class.
    section
        The ``[bmi]`` table.
    root
        Folder of ``model.toml`` (the configuration file is relative to it).
    name, start, end, output_interval, spinup
        From ``[model]``.
    state
        BMI variables that make up the state (hot starts); empty: no hot starts.
    calibration
        Parameters, windows and optimiser defaults that ship with the model.
    """

    def __init__(self, component: type, section: BmiSection, root: Path, *, name: str, start: Any, end: Any,
                 output_interval: float, spinup: float = 0.0, state: tuple[str, ...] = (),
                 calibration: CalibrationSetup | None = None, dt: float | None = None):
        self.component = component
        self.section = section
        self.root = Path(root)
        self.name = name
        self._start, self._end = utc(start), utc(end)
        self._interval = float(output_interval)
        self.spinup = float(spinup)
        self.state_vars = tuple(state)
        self._calibration = calibration or CalibrationSetup()
        self.config = self.root / section.config if section.config else None
        self._template = None
        if self.config is not None and self.config.suffix in (".tmpl", ".template"):
            self._template = Template(self.config.read_text(encoding="utf-8"), source=str(self.config))
            self._template.check((), ("start", "end", "run_start", "run_dir", "model_dir", "hot", "cold", "dt",
                                      "output_interval"))
        self.observables = list(section.stations)
        self._dt = dt

    @classmethod
    def from_spec(cls, spec: ModelFile, root: Path, calibration: CalibrationSetup | None = None) -> BmiModel:
        """The model of a ``model.toml`` with ``kind = "bmi"``.

        Raises
        ------
        ModelFileError
            When the component cannot be imported or the configuration file is missing.
        """
        section = spec.bmi
        label = str(Path(root) / "model.toml")
        module, _, attr = section.component.partition(":")  # type: ignore[union-attr]
        try:
            component = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError) as exc:
            raise ModelFileError(f"cannot import {section.component!r} ({exc})", file=label,  # type: ignore[union-attr]
                                 field="bmi.component") from None
        if section.config and not (Path(root) / section.config).is_file():  # type: ignore[union-attr]
            raise ModelFileError(f"no such file {Path(root) / section.config}", file=label,  # type: ignore[union-attr]
                                 field="bmi.config")
        return cls(component, section, Path(root), name=spec.model.name, start=spec.model.start,  # type: ignore[arg-type]
                   end=spec.model.end, output_interval=spec.model.output_interval, spinup=spec.model.spinup,
                   state=tuple(section.state), calibration=calibration, dt=spec.model.dt)  # type: ignore[union-attr]

    # -- contract facts ---------------------------------------------------------------------------

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({self.name!r}, {self.start:%Y-%m-%d %H:%M} … {self.end:%Y-%m-%d %H:%M} UTC, "
                f"Δt {self.dt:g} s, {len(self.quantities)} quantities, {len(self.observables)} series" + ")")

    @property
    def start(self) -> pd.Timestamp:
        """Start of the model's period (UTC)."""
        return self._start

    @property
    def end(self) -> pd.Timestamp:
        """End of the model's period (UTC)."""
        return self._end

    @property
    def dt(self) -> float:
        """The component's time step, s (``model.dt``, else asked from the component once)."""
        if self._dt is None:
            bmi = self._open(self._start, self._start + pd.Timedelta(seconds=self._interval), hot=False)
            try:
                self._dt = float(bmi.get_time_step()) * _SECONDS[bmi.get_time_units()]
            finally:
                bmi.finalize()
        return self._dt

    @property
    def output_interval(self) -> float:
        """Default interval of the series, s."""
        return self._interval

    @property
    def calibration(self) -> CalibrationSetup:
        """Parameters, windows and optimiser defaults of the model."""
        return self._calibration

    @property
    def quantities(self) -> dict[str, Quantity]:
        """The settable quantities of ``[bmi.quantities]``."""
        return {name: Quantity(name, v.unit, v.min, v.max, f"BMI variable {v.var}" +
                               (f" at element {v.index}" if v.index is not None else ""))
                for name, v in self.section.quantities.items()}

    def default_parameters(self) -> dict[str, float]:
        """The component's own values of the quantities after ``initialize`` (at the model's start)."""
        bmi = self._open(self._start, self._end, hot=False)
        try:
            out = {}
            for name, v in self.section.quantities.items():
                out[name] = float(_get(bmi, v.var, 0 if v.index is None else v.index))
            return out
        finally:
            bmi.finalize()

    @property
    def state_format(self) -> str:
        """Format tag of :meth:`save_state`."""
        return f"rivercal-bmi-state-1:{self.name}"

    def save_state(self, state: BmiState) -> bytes:
        """The state as bytes."""
        return state.to_bytes()

    def load_state(self, data: bytes, fmt: str) -> BmiState:
        """A state from :meth:`save_state` bytes; ValueError for another format or variables."""
        if fmt != self.state_format:
            raise ValueError(f"state format {fmt!r} is not {self.state_format!r}")
        state = BmiState.from_bytes(data)
        if set(state.values) != set(self.state_vars):
            raise ValueError(f"the state holds {sorted(state.values)}, the model's state is {sorted(self.state_vars)}")
        return state

    # -- state updating ([bmi.assimilate]; rivercal.models.capabilities) -----------------------------

    def _assimilate(self, what: str) -> Any:
        section = self.section.assimilate
        if section is None:
            raise AttributeError(f"model {self.name!r} has no [bmi.assimilate] table: no {what}")
        return section

    def __getattr__(self, name: str) -> Any:
        # the capabilities of state updating exist only where model.toml names their variables
        section = self.__dict__.get("section")
        a = section.assimilate if section is not None else None
        if a is not None and (name in ("state_layout", "state_arrays", "with_state_arrays") or
                              (a.forcing and name in ("perturbable_forcing", "simulate_perturbed"))):
            return getattr(self, f"_{name}")
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def _state_layout(self) -> StateLayout:
        """Levels at the nodes of the ``levels`` variable's grid, discharges on its edges (module docstring)."""
        if getattr(self, "_layout_cache", None) is None:
            self._layout_cache = self._read_layout()
        return self._layout_cache

    def _read_layout(self) -> StateLayout:
        a = self._assimilate("state arrays")
        bmi = self._open(self._start, self._start + pd.Timedelta(seconds=self._interval), hot=False)
        try:
            grid = bmi.get_var_grid(a.levels)
            n = int(bmi.get_grid_node_count(grid))
            n_edges = int(bmi.get_grid_edge_count(grid))
            ends = bmi.get_grid_edge_nodes(grid, np.empty(2 * n_edges, dtype=np.int64)).reshape(-1, 2).astype(np.int64)
            x = bmi.get_grid_x(grid, np.empty(n))
            y = bmi.get_grid_y(grid, np.empty(n))
            floor = np.full(n, -np.inf)
            if a.floor is not None:
                floor = bmi.get_value(a.floor, np.empty(n)).astype(float)
            forcing_xy = {}
            for key, v in a.forcing.items():
                g = bmi.get_var_grid(v.var)
                size = int(bmi.get_grid_node_count(g))
                gx, gy = bmi.get_grid_x(g, np.empty(size)), bmi.get_grid_y(g, np.empty(size))
                k = 0 if v.index is None else v.index
                forcing_xy[key] = (gx[k], gy[k])
        finally:
            bmi.finalize()
        length = np.hypot(x[ends[:, 0]] - x[ends[:, 1]], y[ends[:, 0]] - y[ends[:, 1]]) if n_edges else np.zeros(0)
        places = {}
        for obs, v in self.section.stations.items():
            if v.var == a.levels:
                places[obs] = int(v.index)
            elif v.var == a.discharges:
                places[obs] = int(ends[int(v.index), 0])
        nearest = {key: int(np.argmin(np.hypot(x - px, y - py))) for key, (px, py) in forcing_xy.items()}
        return StateLayout(levels=tuple(f"node:{i}" for i in range(n)), discharges=tuple(f"edge:{i}" for i in
                                                                                          range(n_edges)),
                           link_ends=ends, link_length=np.maximum(length, 1.0), floor=floor, places=places,
                           forcing_places=nearest)

    def _state_arrays(self, state: BmiState) -> tuple[np.ndarray, np.ndarray]:
        """The ``levels`` (m) and ``discharges`` (m³/s) of a state."""
        a = self._assimilate("state arrays")
        return state.values[a.levels], state.values[a.discharges]

    def _with_state_arrays(self, state: BmiState, levels: np.ndarray, discharges: np.ndarray) -> BmiState:
        """The state with these levels (never below ``floor``) and discharges, without the ``derived`` variables."""
        a = self._assimilate("state arrays")
        floor = self._state_layout().floor
        values = {k: v for k, v in state.values.items() if k not in a.derived}
        values[a.levels] = np.maximum(np.asarray(levels, dtype=float), floor)
        values[a.discharges] = np.asarray(discharges, dtype=float)
        return BmiState(state.time, values)

    def _perturbable_forcing(self) -> tuple[str, ...]:
        """The inflows and laterals of ``[bmi.assimilate.forcing]``."""
        return tuple(self._assimilate("perturbable forcing").forcing)

    def _simulate_perturbed(self, parameters: Mapping[str, float] | None, start: Any, end: Any,
                            state: BmiState | None, factors: np.ndarray, interval: float, *,
                            output_interval: float | None = None) -> tuple[SimulationResult, BmiState | None]:
        """:meth:`simulate` with each scale factor set to its row of ``factors`` at the start of every interval."""
        factors = np.asarray(factors, dtype=float)
        keys = self._perturbable_forcing()
        if factors.ndim != 2 or factors.shape[1] != len(keys):
            raise ValueError(f"factors must have shape (intervals, {len(keys)}), got {factors.shape}")
        return self.simulate(parameters, start, end, state, output_interval=output_interval,
                             _factors=(factors, float(interval)))

    def _set_factors(self, bmi: Any, row: np.ndarray) -> None:
        for (var, index), value in zip(((v.var, v.index) for v in self.section.assimilate.forcing.values()), row,
                                       strict=True):
            _set(bmi, var, index, float(value))

    # -- running ----------------------------------------------------------------------------------

    def _open(self, run_start: pd.Timestamp, end: pd.Timestamp, *, hot: bool) -> Any:
        bmi = self.component()
        config = self.config
        tmp = None
        if self._template is not None:
            tmp = tempfile.TemporaryDirectory(prefix=f"bmi-{self.name}-")
            text = self._template.render({"start": run_start, "end": end, "run_start": run_start, "run_dir": tmp.name,
                                          "model_dir": str(self.root.resolve()), "hot": hot, "cold": not hot,
                                          "dt": float(self._dt or 0.0), "output_interval": self._interval}, {})
            config = Path(tmp.name) / self.config.name.rsplit(".", 1)[0]  # type: ignore[union-attr]
            config.write_text(text, encoding="utf-8")
        try:
            bmi.initialize(str(config) if config is not None else "")
        except Exception as exc:  # a component's own error: a failed run, named
            raise ModelRunError(f"BMI component {self.section.component} failed in initialize: {exc}") from None
        finally:
            if tmp is not None:
                tmp.cleanup()
        return bmi

    def simulate(self, parameters: Mapping[str, float] | None = None, start: Any = None, end: Any = None,
                 state: BmiState | None = None, *, output_interval: float | None = None,
                 _factors: tuple[np.ndarray, float] | None = None) -> tuple[SimulationResult, BmiState | None]:
        """Run the component from ``start`` to ``end`` (module docstring).

        Returns
        -------
        (SimulationResult, BmiState or None)
            Station series at the output times (first row: after initialize, state and quantities set;
            ``balance`` None) and the state at ``end`` (None when the model declares no state variables).

        Raises
        ------
        ModelRunError
            When the component raises or returns non-finite values.
        ValueError
            For unknown quantities or values out of bounds, a period off the output grid, a state at another
            time or a hot start without state variables.
        """
        if state is not None and not self.state_vars:
            raise ValueError(f"model {self.name!r} declares no BMI state variables: it cannot hot start")
        run = check_run(self, parameters, start, end, state, output_interval)
        parameters, start, end, interval = run.parameters, run.start, run.end, run.interval
        run_start = start - pd.Timedelta(hours=self.spinup) if state is None else start
        t0 = _time.perf_counter()
        bmi = self._open(run_start, end, hot=state is not None)
        try:
            return self._run(bmi, parameters, start, end, run_start, interval, state, t0, _factors)
        except ModelRunError:
            raise
        except Exception as exc:  # a component's own error: a failed run, named
            raise ModelRunError(f"BMI component {self.section.component} failed: {exc}") from None
        finally:
            try:
                bmi.finalize()
            except Exception:  # finalizing after a failure must not hide the failure
                pass

    def _run(self, bmi: Any, parameters: Mapping[str, float], start: pd.Timestamp, end: pd.Timestamp,
             run_start: pd.Timestamp, interval: float, state: BmiState | None, t0: float,
             factors: tuple[np.ndarray, float] | None = None):
        unit = _SECONDS.get(bmi.get_time_units())
        if unit is None:
            raise ModelRunError(f"BMI component {self.section.component}: time units {bmi.get_time_units()!r} are "
                                f"not one of {', '.join(_SECONDS)}")
        origin = float(bmi.get_start_time())

        def at(t: pd.Timestamp) -> float:
            return origin + (t - run_start).total_seconds() / unit

        if state is not None:
            for name, values in state.values.items():
                bmi.set_value(name, values)
        for name, value in parameters.items():
            v = self.section.quantities[name]
            if v.index is None:
                n = bmi.get_grid_size(bmi.get_var_grid(v.var))
                bmi.set_value(v.var, np.full(n, value))
            else:
                bmi.set_value_at_indices(v.var, np.array([v.index]), np.array([value]))
        if run_start < start:
            bmi.update_until(at(start))
        times = pd.date_range(start, end, freq=pd.Timedelta(seconds=interval))
        rows = np.empty((len(times), len(self.observables)))
        current = -1
        for k, t in enumerate(times):
            if k:
                if factors is not None:  # the scale factors of the interval this output step lies in
                    j = int((times[k - 1] - start).total_seconds() // factors[1])
                    if j != current:
                        self._set_factors(bmi, factors[0][min(j, len(factors[0]) - 1)])
                        current = j
                bmi.update_until(at(t))
            rows[k] = [_get(bmi, v.var, v.index) for v in self.section.stations.values()]
        if not np.all(np.isfinite(rows)):
            row, col = np.argwhere(~np.isfinite(rows))[0]
            raise ModelRunError(f"BMI component {self.section.component} returned a non-finite "
                                f"{self.observables[col]} at {times[row]}")
        new_state = None
        if self.state_vars:
            values = {}
            for name in self.state_vars:
                buffer = np.empty(bmi.get_var_nbytes(name) // bmi.get_var_itemsize(name))
                values[name] = bmi.get_value(name, buffer).copy()
            new_state = BmiState(end, values)
        series = pd.DataFrame(rows, index=pd.DatetimeIndex(times, name="time"), columns=self.observables)
        return SimulationResult(series=series, wall_time=_time.perf_counter() - t0,
                                source=f"BMI component {self.section.component}"), new_state


def _set(bmi: Any, var: str, index: int | None, value: float) -> None:
    if index is None:
        bmi.set_value(var, np.full(bmi.get_grid_size(bmi.get_var_grid(var)), value))
    else:
        bmi.set_value_at_indices(var, np.array([index]), np.array([value]))


def _get(bmi: Any, var: str, index: int | None) -> float:
    out = np.empty(1)
    bmi.get_value_at_indices(var, out, np.array([0 if index is None else index]))
    return float(out[0])
