"""Ensembles of the embedded engine: N members in one compiled call, in parallel over members.

A member is a parameter set (model quantities, as for :meth:`Simulator.simulate`, controller
quantities included), a hot-start state (with its controllers' state) and, optionally, its own forcing
(e.g. perturbed inflows and laterals of an ensemble Kalman filter).
:func:`run_ensemble` advances every member with the single-run time loop (the compiled
:func:`.kernels.timeloop.run` or ``run_ext`` that :meth:`Simulator.simulate` calls), on its own state,
parameters, forcing, controllers and scratch arrays, the members spread over a pool of threads (the loop
releases the interpreter lock); each member's series and final state are bit-identical to its
:meth:`Simulator.simulate` from the same state. What a member writes is its own: its state rows, its output
rows, its scratch arrays, its controller arrays and — for a network with scheduled structure settings, which
the loop writes into the pump capacities and the structures' gate levels — its own copies of those arrays.

A member that diverges follows an explicit policy: ``raise`` (an :class:`~rivercal.errors.EngineDivergedError`
naming the member) or ``report`` (its series are NaN, its state is None, and ``failures`` says where and
why); the other members are unaffected either way.
"""

from __future__ import annotations

import logging
import time as _time
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Literal

import numba
import numpy as np
import pandas as pd

from rivercal._time import utc
from rivercal.engine.diagnosis import divergence
from rivercal.engine.kernels.codes import CONTROL_STATS, STATUS_OK
from rivercal.engine.kernels.timeloop import make_work
from rivercal.engine.simulator import Simulator, _ratio, time_loop
from rivercal.engine.state import EngineState
from rivercal.errors import EngineDivergedError

__all__ = ["EnsembleResult", "run_ensemble", "threads"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class EnsembleResult:
    """Output of :func:`run_ensemble`.

    Attributes
    ----------
    times
        Output times (UTC), first = start.
    observables
        Names of the simulated series (``"<station>.<quantity>"``).
    values
        Series of every member, shape (members, times, observables); m and m³/s; NaN for a failed member.
    states
        Each member's state at the end (None for a failed member).
    failures
        Failed members → what happened (empty when all ran).
    levels, discharges
        With snapshots: levels (m AD) and discharges (m³/s) at every point, shape (members, times, points).
    wall_time
        Wall-clock time of the compiled call, s.
    """

    times: pd.DatetimeIndex
    observables: tuple[str, ...]
    values: np.ndarray
    states: tuple[EngineState | None, ...]
    failures: dict[int, str] = field(default_factory=dict)
    levels: np.ndarray | None = None
    discharges: np.ndarray | None = None
    wall_time: float = 0.0

    @property
    def members(self) -> int:
        """Number of members."""
        return self.values.shape[0]

    def series(self, member: int) -> pd.DataFrame:
        """The series of one member as :attr:`SimulationResult.series` has them."""
        frame = pd.DataFrame(self.values[member], index=self.times, columns=list(self.observables))
        frame.index.name = "time"
        return frame


def threads(n: int | None) -> int:
    """The number of threads for ``n`` (None: numba's ``NUMBA_NUM_THREADS``, by default the cores); checked."""
    wanted = numba.config.NUMBA_NUM_THREADS if n is None else int(n)
    if not 1 <= wanted <= numba.config.NUMBA_NUM_THREADS:
        raise ValueError(f"threads must be between 1 and {numba.config.NUMBA_NUM_THREADS} (NUMBA_NUM_THREADS), "
                         f"got {n}")
    return wanted


def run_ensemble(
    sim: Simulator,
    parameters: Sequence[Mapping[str, float] | None],
    start: pd.Timestamp | str | None = None,
    end: pd.Timestamp | str | None = None,
    states: Sequence[EngineState] | None = None,
    *,
    forcing: np.ndarray | None = None,
    edges: np.ndarray | None = None,
    output_interval: float | None = None,
    snapshots: bool = False,
    n_threads: int | None = None,
    on_failure: Literal["raise", "report"] = "raise",
) -> EnsembleResult:
    """Run every member from ``start`` to ``end``, the members on parallel threads.

    Parameters
    ----------
    sim
        The compiled case (an embedded model).
    parameters
        One mapping of model quantities per member (None: the case's values); their number is the
        number of members.
    start, end
        Period (UTC; default the case period).
    states
        One hot-start state per member at ``start`` (not modified); None: every member cold-starts after
        the case's spin-up (with its own parameters, like :meth:`Simulator.simulate`).
    forcing
        Per member forcing, shape (members, steps, columns) in the columns of
        :attr:`CompiledNetwork.forcing_keys` (m³/s or m AD per step, as :meth:`Simulator.forcing_matrix`
        gives them); None: the case's forcing for all.
    edges
        With ``forcing``: each member's discharges at the edges of each step, shape (members, 2 × steps, columns)
        as :meth:`Simulator.forcing_edges` gives them for the case (the line a divided step's sub-steps follow;
        its mean is the step's value of ``forcing``); None: a divided step holds each member's step mean. Without
        ``forcing`` the case's own edges are used.
    output_interval
        Interval of the output series, s (default from the case).
    snapshots
        Also return levels and discharges at every point at the output times.
    n_threads
        Threads that run members at the same time (None: ``NUMBA_NUM_THREADS``, by default the cores).
    on_failure
        A diverging member: ``raise`` or ``report`` (module docstring).

    Raises
    ------
    EngineDivergedError
        When a member diverges and the policy is ``raise``.
    ValueError
        For a period that does not fit the time step, states or forcing of the wrong number or shape.
    """
    if on_failure not in ("raise", "report"):
        raise ValueError(f"on_failure must be 'raise' or 'report', got {on_failure!r}")
    start = sim.start if start is None else utc(start)
    end = sim.end if end is None else utc(end)
    n_mem = len(parameters)
    if n_mem < 1:
        raise ValueError("an ensemble needs at least one member")
    interval = float(output_interval or sim.settings.output_interval)
    out_every = _ratio(interval, sim.dt, "output_interval", "dt")
    n_steps = _ratio((end - start).total_seconds(), interval, "the period", "the output interval") * out_every
    if n_steps < 0:
        raise ValueError(f"end {end} is before start {start}")
    arrays = [sim.parameter_arrays(p) for p in parameters]
    crest = np.array([a[0] for a in arrays]).reshape(n_mem, -1)
    fric = np.array([a[1] for a in arrays]).reshape(n_mem, -1)
    control = [sim.control_values(p) for p in parameters]
    n_cols = len(sim.compiled.forcing_keys)
    if forcing is None:
        forcing = sim.forcing_matrix(start, n_steps)[None]
        edges = sim.forcing_edges(start, n_steps)
    else:
        forcing = np.ascontiguousarray(forcing, dtype=float)
        if forcing.shape != (n_mem, n_steps, n_cols):
            raise ValueError(f"forcing must have shape (members, steps, columns) = {(n_mem, n_steps, n_cols)}, "
                             f"got {forcing.shape}")
        if edges is not None:
            edges = np.ascontiguousarray(edges, dtype=float)
            if edges.shape != (n_mem, 2 * n_steps, n_cols):
                raise ValueError(f"edges must have shape (members, 2 x steps, columns) = "
                                 f"{(n_mem, 2 * n_steps, n_cols)}, got {edges.shape}")
    n_threads = threads(n_threads)
    if states is None:
        stack = _Stack.of([sim.initial_state(start) for _ in range(n_mem)], sim.compiled.dikes.sc.size)
        if sim.case.spec.initial.spinup > 0:
            n_spin = max(1, round(sim.case.spec.initial.spinup * 3600.0 / sim.dt))
            spin = sim.forcing_matrix(start, n_spin, constant=True)[None]
            spun = _call(sim, stack, crest, fric, control, spin, n_spin, False,
                         start - pd.Timedelta(seconds=n_spin * sim.dt), held=True, n_threads=n_threads)
            _check(sim, spun[4], start - pd.Timedelta(seconds=n_spin * sim.dt), stack, on_failure, "spin-up")
    else:
        if len(states) != n_mem:
            raise ValueError(f"{len(states)} states for {n_mem} members")
        for m, s in enumerate(states):
            if s.signature != (sim.compiled.n_hpoints, sim.compiled.n_links):
                raise ValueError(f"member {m}: the state belongs to another network")
            if s.ctl.shape[0] != len(sim.controls or ()):
                raise ValueError(f"member {m}: the state holds {s.ctl.shape[0]} controllers, the case has "
                                 f"{len(sim.controls or ())}")
            if s.time != start:
                raise ValueError(f"member {m}: the state is at {s.time}, the run starts at {start}")
        stack = _Stack.of(states, sim.compiled.dikes.sc.size)
    t0 = _time.perf_counter()
    obs, zs, qs, _, status = _call(sim, stack, crest, fric, control, forcing, out_every, snapshots, start,
                                  n_threads=n_threads, edges=edges)
    wall = _time.perf_counter() - t0
    failures = _check(sim, status, start, stack, on_failure, "")
    for m in failures:
        obs[m] = np.nan
    times = pd.date_range(start, end, periods=n_steps // out_every + 1)
    out_states = tuple(None if m in failures else stack.state(m, end) for m in range(n_mem))
    log.debug("%d members %s .. %s in %.3f s", n_mem, start, end, wall)
    return EnsembleResult(times=times, observables=tuple(sim.observables), values=obs, states=out_states,
                          failures=failures, levels=zs if snapshots else None, discharges=qs if snapshots else None,
                          wall_time=wall)


@dataclass
class _Stack:
    """The members' states as arrays with a leading member axis (updated in place by the kernel)."""

    z: np.ndarray
    dz: np.ndarray
    vol: np.ndarray
    u: np.ndarray
    q: np.ndarray
    pump_on: np.ndarray
    ctl: np.ndarray
    signature: tuple[int, int]
    control: np.ndarray  # the step control's state (CONTROL_STATS), the flicker detector's and the dikes' curves
    flicker: np.ndarray
    swing: np.ndarray
    dikes: np.ndarray

    @classmethod
    def of(cls, states: Sequence[EngineState], n_dikes: int) -> _Stack:
        return cls(*(np.array([getattr(s, k) for s in states], dtype=float)
                     for k in ("z", "dz", "vol", "u", "q", "pump_on", "ctl")), signature=states[0].signature,
                   control=np.array([s.control for s in states], dtype=np.int64),
                   flicker=np.array([s.flicker for s in states], dtype=np.int32),
                   swing=np.array([s.swing for s in states], dtype=float),
                   dikes=np.array([s.dike_curves(n_dikes) for s in states], dtype=np.int8).reshape(len(states),
                                                                                                  n_dikes))

    def state(self, m: int, time: pd.Timestamp) -> EngineState:
        return EngineState(time=time, z=self.z[m].copy(), dz=self.dz[m].copy(), vol=self.vol[m].copy(),
                           u=self.u[m].copy(), q=self.q[m].copy(), pump_on=self.pump_on[m].copy(),
                           signature=self.signature, ctl=self.ctl[m].copy(), control=self.control[m].copy(),
                           flicker=self.flicker[m].copy(), swing=self.swing[m].copy(),
                           dikes=self.dikes[m].copy() if self.dikes.shape[1] else None)


def _call(sim, stack, crest, fric, control, forcing, out_every, snapshots, start, *, held=False, n_threads=1,
          edges=None):
    """One run of every member from ``start``; returns (series, levels, discharges, balance, status).

    ``control`` holds each member's controller quantities (None entries without controllers); ``held`` holds
    the controllers' time tables at their value at the end of the run (a spin-up, as the single run does).
    The members run on ``n_threads`` threads, each its single run's compiled time loop on its own rows; ``edges``
    (the forcing at the steps' edges, :meth:`Simulator.forcing_edges`; per member with a leading members axis)
    guides divided steps.
    """
    c = sim.compiled
    a, sx = c.arrays, c.structures
    n_mem = stack.z.shape[0]
    n_steps = forcing.shape[1]
    n_out = n_steps // out_every + 1
    n_obs = len(c.observables)
    cxs = [None] * n_mem
    if sim.controls is not None:  # each member its own controller arrays, its state rows used in place
        cxs = [sim.controls.arrays(control[m], start, n_steps, sim.dt, n_out, stack.ctl[m], held=held)
               for m in range(n_mem)]
    obs = np.full((n_mem, n_out, n_obs + len(sim.controls or ())), np.nan)
    zs = np.empty((n_mem, n_out if snapshots else 0, c.n_hpoints))
    qs = np.empty((n_mem, n_out if snapshots else 0, c.n_links))
    balance = np.zeros((n_mem, a.b_hp.size + 1))
    status = np.zeros((n_mem, 3), dtype=np.int64)

    def member(m: int) -> None:
        state = (stack.z[m], stack.dz[m], stack.vol[m], stack.u[m], stack.q[m], stack.pump_on[m])
        work = make_work(a, sx)
        work.stats[list(CONTROL_STATS)] = stack.control[m]  # the step control continues where the member stopped
        work.flick[:] = stack.flicker[m]
        work.swing[:] = stack.swing[m]
        status[m] = time_loop(sim, work, cxs[m], crest[m], fric[m], state,
                              forcing[0] if forcing.shape[0] == 1 else forcing[m], out_every,
                              (obs[m], zs[m], qs[m], balance[m]), private=True, dikes=stack.dikes[m],
                              edges=edges if edges is None or edges.ndim == 2 else edges[m])
        stack.control[m] = work.stats[list(CONTROL_STATS)]
        stack.flicker[m] = work.flick
        stack.swing[m] = work.swing

    if n_threads == 1 or n_mem == 1:
        for m in range(n_mem):
            member(m)
    else:
        with ThreadPoolExecutor(max_workers=min(n_threads, n_mem), thread_name_prefix="rivercal-member") as pool:
            list(pool.map(member, range(n_mem)))  # list(): a member's exception is raised here
    for m, cx in enumerate(cxs):
        if cx is not None:
            obs[m, :, n_obs:] = cx.out
    return obs, zs, qs, balance, status


def _check(sim, status, start, stack, on_failure, phase) -> dict[int, str]:
    """Failed members → message; raises for the first under the ``raise`` policy."""
    failures = {}
    for m in np.flatnonzero(status[:, 0] != STATUS_OK):
        code, step, index = (int(v) for v in status[m])
        when, where, what = divergence(sim, code, step, index, stack.z[m], stack.u[m], start, phase)
        if on_failure == "raise":
            raise EngineDivergedError(when, where, f"member {m}: {what}")
        failures[int(m)] = str(EngineDivergedError(when, where, what))
    return failures
