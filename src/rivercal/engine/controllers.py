"""The controllers of a case, compiled against its network: kernel arrays, calibration targets, per-run tables.

:class:`Controls` turns the ``[[controllers]]`` of a case (:mod:`rivercal.case.controllers`) into the
:class:`ControlArrays` of :mod:`rivercal.engine.kernels.control`. Its settable quantities are

- ``control:<id>.setpoint`` — a constant setpoint, m AD (m³/s when the measured quantity is a discharge);
- ``control:<id>.kp``, ``.ki``, ``.kd`` — PID gains (m/m, 1/s, s);
- ``control:<id>.value:<k>`` — the k-th value (from 1) of its time table (crest or setpoint, m AD) or of its
  relation table (crest, m AD).

Time tables are evaluated here, per run, at the end of every step (as a crest series is): the kernel reads
one value per step and table. During a spin-up they hold their value at the start, as the forcing does.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import NamedTuple

import numpy as np
import pandas as pd

from rivercal.case.controllers import MAX_GAIN, control_target_problem, table_values
from rivercal.engine.kernels.codes import OBS_FLUX, OBS_LEVEL
from rivercal.engine.kernels.control import (
    CTL_INTERVAL,
    CTL_PID,
    CTL_RELATION,
    CTL_TIME,
    N_PAR,
    N_STATE,
    P_BAND,
    P_BIAS,
    P_HI,
    P_INTERVAL,
    P_KD,
    P_KI,
    P_KP,
    P_LO,
    P_SETPOINT,
    P_SPEED,
    P_STEP,
)
from rivercal.network import MAX_LEVEL

__all__ = ["ControlArrays", "ControlValues", "Controls"]

_KINDS = {"pid": CTL_PID, "interval": CTL_INTERVAL, "time": CTL_TIME, "relation": CTL_RELATION}
_GAINS = {"kp": P_KP, "ki": P_KI, "kd": P_KD}


class ControlArrays(NamedTuple):
    """Kernel input of :mod:`rivercal.engine.kernels.control` (one row or entry per controller).

    ``par``, ``rel_y`` and ``sched`` hold one run's quantities, ``out`` its crest series (m AD, per output row)
    and ``state`` the controllers' state (the engine state's ``ctl``, updated in place).
    """

    kind: np.ndarray  # CTL_* of kernels.control
    weir: np.ndarray  # index in the crest array
    m_type: np.ndarray  # measured quantity: OBS_LEVEL (m AD) or OBS_FLUX (m³/s) ...
    m_i1: np.ndarray  # ... between h-points i1 and i2 (weight m_w on i1), or at link i1 (times m_w)
    m_i2: np.ndarray
    m_w: np.ndarray
    tcol: np.ndarray  # column of sched with its setpoint or crest table (-1: none)
    rel_ptr: np.ndarray  # relation tables (CSR): measured values, crest levels (m AD)
    rel_x: np.ndarray
    rel_y: np.ndarray
    par: np.ndarray  # (controller, P_* of kernels.control)
    sched: np.ndarray  # (step, table column): the table value at the end of the step
    out: np.ndarray  # (output row, controller): crest, m AD
    state: np.ndarray  # (controller, S_* of kernels.control)


class ControlValues(NamedTuple):
    """One run's controller quantities: ``par`` rows, relation crests (m AD) and the values of each time table."""

    par: np.ndarray
    rel_y: np.ndarray
    tables: tuple[np.ndarray, ...]


class Controls:
    """The controllers of a case compiled against its network.

    Parameters
    ----------
    controllers
        The case's ``[[controllers]]`` (validated).
    compiled
        The compiled network (:class:`~rivercal.engine.compile.CompiledNetwork`).
    """

    def __init__(self, controllers: Sequence, compiled):
        self.specs = list(controllers)
        self.ids = [c.id for c in self.specs]
        weir_pos = {w: i for i, w in enumerate(compiled.weir_ids)}
        n = len(self.specs)
        #: Names of the simulated crest series, ``"<weir>.crest"`` (m AD).
        self.series = [f"{c.weir}.crest" for c in self.specs]
        par = np.zeros((n, N_PAR))
        m = np.zeros((4, n))
        tcol = np.full(n, -1, dtype=np.int64)
        self._tables = []  # the TimeTable of each sched column
        rel_ptr, rel_x, rel_y = [0], [], []
        for c, spec in enumerate(self.specs):
            crest0 = float(compiled.crest_levels[weir_pos[spec.weir]])
            par[c, P_LO], par[c, P_HI] = spec.min, spec.max
            par[c, P_SPEED] = np.inf if spec.max_speed is None else spec.max_speed / 60.0
            if spec.type == "pid":
                par[c, P_KP], par[c, P_KI], par[c, P_KD] = spec.kp, spec.ki, spec.kd
                par[c, P_BIAS] = crest0 if spec.bias is None else spec.bias
            elif spec.type == "interval":
                par[c, P_BAND], par[c, P_STEP], par[c, P_INTERVAL] = spec.dead_band, spec.step, spec.interval
            if getattr(spec, "setpoint", None) is not None:
                par[c, P_SETPOINT] = spec.setpoint
            table = spec.table if spec.type == "time" else getattr(spec, "setpoint_table", None)
            if table is not None:
                tcol[c] = len(self._tables)
                self._tables.append(table)
            if spec.type == "relation":
                rel_x += spec.table.x
                rel_y += spec.table.crest
            rel_ptr.append(len(rel_x))
            if hasattr(spec, "measure"):
                m[:, c] = _measurement(spec.measure, compiled)
        self._static = dict(
            kind=np.array([_KINDS[s.type] for s in self.specs], dtype=np.int64),
            weir=np.array([weir_pos[s.weir] for s in self.specs], dtype=np.int64),
            m_type=m[0].astype(np.int64), m_i1=m[1].astype(np.int64), m_i2=m[2].astype(np.int64), m_w=m[3].copy(),
            tcol=tcol, rel_ptr=np.array(rel_ptr, dtype=np.int64), rel_x=np.array(rel_x, dtype=float),
        )
        self._values = ControlValues(par=par, rel_y=np.array(rel_y, dtype=float),
                                     tables=tuple(np.array(t.values, dtype=float) for t in self._tables))
        self._by_id = {c.id: (i, c) for i, c in enumerate(self.specs)}

    def __len__(self) -> int:
        return len(self.specs)

    # -- quantities ----------------------------------------------------------------------------------

    def default_parameters(self) -> dict[str, float]:
        """Every settable controller quantity with its case value (module docstring)."""
        out: dict[str, float] = {}
        for i, c in enumerate(self.specs):
            if getattr(c, "setpoint", None) is not None:
                out[f"control:{c.id}.setpoint"] = float(c.setpoint)
            if c.type == "pid":
                for name, col in _GAINS.items():
                    out[f"control:{c.id}.{name}"] = float(self._values.par[i, col])
            for k, v in enumerate(table_values(c) or [], start=1):
                out[f"control:{c.id}.value:{k}"] = float(v)
        return out

    def describe(self) -> dict[str, tuple[str, float, float, str]]:
        """Every settable controller quantity: its unit, bounds and a line for users."""
        out: dict[str, tuple[str, float, float, str]] = {}
        units = {"kp": ("m/m", "proportional gain"), "ki": ("1/s", "integral gain"), "kd": ("s", "derivative gain")}
        for target in self.default_parameters():
            ident, _, quantity = target[len("control:"):].rpartition(".")
            spec = self._by_id[ident][1]
            if quantity in units:
                unit, what = units[quantity]
                out[target] = (unit, -MAX_GAIN, MAX_GAIN, f"{what} of PID controller {ident} (weir {spec.weir})")
            elif quantity == "setpoint":
                unit = "m³/s" if spec.measure.endswith(".Q") else "m AD"
                out[target] = (unit, -MAX_LEVEL, MAX_LEVEL, f"setpoint of controller {ident} ({spec.measure})")
            else:
                unit = "m³/s" if spec.type != "time" and spec.type != "relation" and spec.measure.endswith(".Q") \
                    else "m AD"
                table = {"time": "crest table", "relation": "relation table crest"}.get(spec.type, "setpoint table")
                out[target] = (unit, -MAX_LEVEL, MAX_LEVEL,
                               f"value {quantity[6:]} of the {table} of controller {ident} (weir {spec.weir})")
        return out

    def values(self, parameters: Mapping[str, float] | None) -> ControlValues:
        """The controller quantities of a run: the case's, with the ``control:`` targets of ``parameters`` set.

        Raises
        ------
        KeyError
            For a controller or quantity that does not exist.
        ValueError
            For a value that is not finite or a level outside ±MAX_LEVEL m AD.
        """
        par, rel_y = self._values.par.copy(), self._values.rel_y.copy()
        tables = [t.copy() for t in self._values.tables]
        for target, value in (parameters or {}).items():
            if not target.startswith("control:"):
                continue
            ident, _, quantity = target[len("control:"):].rpartition(".")
            if ident not in self._by_id:
                raise KeyError(f"{target}: no controller {ident!r} (controllers: {', '.join(self.ids) or 'none'})")
            c, spec = self._by_id[ident]
            problem = control_target_problem(spec, quantity)
            if problem:
                raise KeyError(f"{target}: {problem}")
            value = float(value)
            if not np.isfinite(value):
                raise ValueError(f"{target}: value {value} is not finite")
            if quantity in _GAINS:
                par[c, _GAINS[quantity]] = value
                continue
            if abs(value) > MAX_LEVEL:
                raise ValueError(f"{target}: {value:g} is outside ±{MAX_LEVEL:g} m AD")
            if quantity == "setpoint":
                par[c, P_SETPOINT] = value
            elif spec.type == "relation":
                rel_y[self._static["rel_ptr"][c] + int(quantity[6:]) - 1] = value
            else:
                tables[int(self._static["tcol"][c])][int(quantity[6:]) - 1] = value
        return ControlValues(par=par, rel_y=rel_y, tables=tuple(tables))

    # -- runs ----------------------------------------------------------------------------------------

    def initial_state(self) -> np.ndarray:
        """A cold-start state: every controller starts from its weir's crest at the first step."""
        return np.zeros((len(self.specs), N_STATE))

    def arrays(self, values: ControlValues, start: pd.Timestamp, n_steps: int, dt: float, n_out: int,
               state: np.ndarray, *, held: bool = False) -> ControlArrays:
        """The kernel arrays of a run of ``n_steps`` steps of ``dt`` s from ``start`` with ``n_out`` output rows.

        ``state`` (the engine state's ``ctl``) is used in place. With ``held`` every step takes the tables'
        values at the end of the run (a spin-up, which ends where the simulated period starts).
        """
        ends = start.value / 1e9 + dt * (np.full(n_steps, n_steps) if held else np.arange(1, n_steps + 1))
        sched = np.empty((n_steps, len(self._tables)))
        for k, table in enumerate(self._tables):
            sched[:, k] = table_at(table, values.tables[k], ends)
        return ControlArrays(**self._static, rel_y=values.rel_y, par=values.par, sched=sched,
                             out=np.full((n_out, len(self.specs)), np.nan), state=state)


def table_at(table, values: np.ndarray, seconds: np.ndarray) -> np.ndarray:
    """A time table's values (m AD) at ``seconds`` (since 1970-01-01 UTC), with its interpolation and repetition."""
    times = pd.DatetimeIndex(table.times)
    vals = np.asarray(values, dtype=float)
    if table.repeat == "yearly" and seconds.size:
        first = pd.Timestamp(seconds.min(), unit="s", tz="UTC").year - times[0].year - 1
        last = pd.Timestamp(seconds.max(), unit="s", tz="UTC").year - times[0].year + 1
        shifted = [times + pd.DateOffset(years=k) for k in range(first, last + 1)]
        times = shifted[0].append(shifted[1:])
        vals = np.tile(vals, len(shifted))
    t = times.as_unit("ns").asi8 / 1e9
    if table.interpolation == "linear":
        return np.interp(seconds, t, vals)
    return vals[np.clip(np.searchsorted(t, seconds, side="right") - 1, 0, None)]


def _measurement(name: str, compiled) -> tuple[int, int, int, float]:
    """(kind, i1, i2, weight) of a measured series ``"<station or structure>.<quantity>"``."""
    if name in compiled.observables:
        o = compiled.observables.index(name)
        a = compiled.arrays
        return int(a.ob_type[o]), int(a.ob_i1[o]), int(a.ob_i2[o]), float(a.ob_w[o])
    structure, quantity = name.rsplit(".", 1)
    li = compiled.structure_link[structure]
    if quantity == "Q":
        return OBS_FLUX, li, li, 1.0
    k = int(compiled.arrays.lk_k1[li] if quantity == "h_up" else compiled.arrays.lk_k2[li])
    return OBS_LEVEL, k, k, 1.0
