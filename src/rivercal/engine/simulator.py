"""The embedded model: a case compiled once, run many times with different parameters.

:class:`Simulator` implements the model protocol of DESIGN.md::

    simulate(parameters, start, end, state=None) -> (SimulationResult, EngineState)

Parameters are model quantities addressed by target strings; they enter the kernel as arrays, so
changing them never recompiles anything:

- ``weir:<id>.crest_level`` — crest level of a weir, m AD;
- ``friction:global`` — the friction value of every branch that inherits the global friction
  (unit of the case's friction type, e.g. k_s in m^(1/3)/s);
- ``friction:branch:<id>`` — the friction value of one branch;
- ``friction:group:<id>`` — the value of a friction group (``[[friction_groups]]``; its values on particular
  branches stay);
- ``friction:scale`` — a factor on the conveyance of every channel friction coefficient (k_s and C times the
  factor, n divided by it; 1 leaves the case as it is). Culverts and bridges keep their own friction;
- ``friction:factor:<id>`` — the same factor (-) on the channel friction of the branches and friction groups that
  ``[[friction_factors]]`` lists under ``<id>`` only (:class:`rivercal.case.schema.FrictionFactor`);
- ``control:<id>.<quantity>`` — a controller's setpoint, gains or table values (:mod:`rivercal.engine.controllers`).

A case with controllers (``[[controllers]]``) also simulates each controlled crest, ``"<weir>.crest"`` (m AD),
and carries the controllers' state in :class:`EngineState` (``ctl``).
"""

from __future__ import annotations

import functools
import hashlib
import logging
import time as _time
from collections import OrderedDict
from collections.abc import Mapping

import numpy as np
import pandas as pd

from rivercal._time import utc
from rivercal.case.load import Case
from rivercal.engine.channels import initial_levels
from rivercal.engine.compile import CompiledNetwork, compile_network, own_friction_slots
from rivercal.engine.controllers import Controls, ControlValues
from rivercal.engine.diagnosis import divergence
from rivercal.engine.kernels.codes import (
    BOUNDARY_LEVEL,
    CONTROL_STATS,
    STAT_DRYING,
    STAT_EXPLICIT,
    STAT_FLICKERS,
    STAT_MAX_LEVEL,
    STAT_REDONE,
    STAT_REFINED,
    STAT_SOLVES,
    STAT_STEPS,
    STAT_SUBSTEPS,
    STATUS_OK,
)
from rivercal.engine.kernels.lookup import hp_volume_width
from rivercal.engine.kernels.timeloop import make_work, run, run_ext
from rivercal.engine.quantities import (
    FactorProblem,
    Settable,
    default_values,
    mixed_group_problem,
    quantities_table,
    quantity_arrays,
    settable_table,
)
from rivercal.engine.state import EngineState, Shortfall, SimulationResult, VolumeBalance
from rivercal.engine.step_forcing import ForcingSteps
from rivercal.errors import CaseError, EngineDivergedError

__all__ = ["Simulator"]

log = logging.getLogger(__name__)


#: How many spun-up states a Simulator keeps for :meth:`Simulator.state_at`.
SPUN_UP_KEPT = 8


class Simulator:
    """A case ready to run.

    Parameters
    ----------
    case
        A loaded case.
    forcing
        Optional replacement series for boundaries and laterals (keys ``"boundary:<id>"``,
        ``"lateral:<id>"``; m³/s or m AD; UTC index), e.g. lateral inflows computed by the
        rainfall-runoff model.

    Examples
    --------
    >>> from rivercal.case import load_case
    >>> from rivercal.engine import Simulator
    >>> sim = Simulator(load_case("synthetic"))
    >>> result, state = sim.simulate({"friction:global": 25.0}, end=sim.start + pd.Timedelta("1D"))
    >>> list(result.series.columns)[:2]
    ['S1.h_up', 'S1.h_down']
    """

    def __init__(self, case: Case, forcing: Mapping[str, pd.Series] | None = None):
        self.case = case
        self.settings = case.spec.engine
        self.compiled: CompiledNetwork = compile_network(case.network, self.settings)
        factored = [b for f in case.spec.friction_factors for b in f.branches]
        if factored:  # a factor on some branches needs their links apart from a group's shared slot
            self.compiled = own_friction_slots(self.compiled, factored)
        self.forcing = dict(case.forcing)
        if forcing:
            unknown = set(forcing) - set(self.compiled.forcing_keys)
            if unknown:
                raise KeyError(f"forcing for unknown boundaries/laterals: {sorted(unknown)}")
            self.forcing.update(forcing)
        self._forcing_steps = ForcingSteps(self.forcing, self.compiled.forcing_keys, self.compiled.forcing_is_level)
        self._work = make_work(self.compiled.arrays, self.compiled.structures)
        #: The case's controllers (``None`` without ``[[controllers]]``).
        self.controls: Controls | None = Controls(case.spec.controllers, self.compiled) if case.spec.controllers \
            else None
        sx = self.compiled.structures
        #: Whether runs take the extended time loop (structures beyond weirs, setting series, controllers, summer
        #: dikes whose storage changes curve).
        self.extended = bool(sx.links.size or (sx.set_col >= 0).any() or self.controls is not None
                             or self.compiled.dikes.sc.size)
        #: Counters of the last compiled run: steps, level solves, drying re-solves, and the step control's
        #: steps divided into sub-steps, sub-steps taken and the deepest division (a step into 2^level).
        self.last_run_stats: dict[str, int] = {}
        #: What the withdrawals of the last compiled run asked and delivered (see :class:`Shortfall`).
        self.last_run_shortfalls: dict[str, Shortfall] = {}
        self._spun: OrderedDict[tuple[bytes, pd.Timestamp], EngineState] = OrderedDict()   # see state_at
        if case.spec.friction_factors:
            _ = self.settable  # a factor the network cannot honour fails here, not at the first run

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_spun"] = OrderedDict()   # the states of earlier spin-ups stay in this process
        return state

    # -- facts -------------------------------------------------------------------------------

    @property
    def start(self) -> pd.Timestamp:
        """Start of the case period (UTC)."""
        return self.case.start

    @property
    def end(self) -> pd.Timestamp:
        """End of the case period (UTC)."""
        return self.case.end

    @property
    def dt(self) -> float:
        """Time step, s."""
        return float(self.settings.dt)

    @property
    def observables(self) -> list[str]:
        """Names of the simulated series (the stations', then the controlled crests ``"<weir>.crest"``)."""
        return list(self.compiled.observables) + (self.controls.series if self.controls else [])

    def default_parameters(self) -> dict[str, float]:
        """The model quantities of the case as targets → values."""
        return default_values(self.compiled, self.case.spec.friction.value, self.controls)

    def control_values(self, parameters: Mapping[str, float] | None) -> ControlValues | None:
        """The controllers' quantities for a set of targets.

        ``None`` without controllers; see :mod:`rivercal.engine.controllers`.
        """
        if self.controls is None:
            unknown = [t for t in (parameters or {}) if t.startswith("control:")]
            if unknown:
                raise KeyError(f"{unknown[0]}: case {self.case.name!r} has no controllers")
            return None
        return self.controls.values(parameters)

    @functools.cached_property
    def settable(self) -> dict[str, Settable]:
        """The settable quantities of the case, by name (:func:`rivercal.engine.quantities.settable_table`)."""
        factors = self.case.spec.friction_factors
        try:
            return settable_table(self.compiled, self.case.spec.friction.type, self.controls, factors)
        except FactorProblem as exc:  # a factor that the network cannot honour: say which, where
            raise CaseError(exc.reason, file=str(self.case.root / "case.toml"),
                            field=f"friction_factors[{exc.index}]") from None

    def parameter_arrays(self, parameters: Mapping[str, float] | None) -> tuple[np.ndarray, np.ndarray]:
        """Crest levels (m AD, per weir) and friction values (per friction slot) for a set of targets.

        The targets are names of :attr:`settable`; the controllers' are taken by :meth:`control_values`.

        Values given in one call compose in a fixed order, whatever their order in ``parameters``:
        ``friction:global`` first, then the values of branches, groups and weirs (a branch-specific value wins over
        the global one), then every ``friction:factor:<id>`` on the values so set (a factor of 1.2 on a branch set
        to 30 m^(1/3)/s in the same call runs it at 36), then ``friction:scale`` on everything. A factor divides a
        Manning n and multiplies a Strickler k_s or a Chézy C, so that it scales the conveyance; a slot belongs to
        one factor at most (the case refuses overlaps).
        """
        return quantity_arrays(self.compiled, self.settable, parameters, case_name=self.case.name,
                               profiles=self.case.network.profiles)

    def mixed_group_problem(self, target: str, group: str) -> str:
        """Why ``target``, the value of friction group ``group``, cannot be set on this network (a message).

        A profile that names ``group`` beside another friction group conveys with all its sections relative to the
        first section's group (:attr:`rivercal.engine.channels.Channels.mixed_groups`): changing the first
        group's value alone would scale the other sections too, changing another group's value would not reach the
        conveyance at all.
        """
        return mixed_group_problem(target, group, self.compiled, self.case.network.profiles)

    # -- state ---------------------------------------------------------------------------------

    def initial_state(self, start: pd.Timestamp | None = None) -> EngineState:
        """The cold-start state at ``start``: level max(bed + depth, level), or a branch's initial levels, at rest."""
        start = self.start if start is None else pd.Timestamp(start)
        a = self.compiled.arrays
        init = self.case.spec.initial
        z = a.hp_bed + init.depth
        if init.level is not None:
            z = np.maximum(z, init.level)
        along = initial_levels(self.case.network, self.compiled.hp_label, self.compiled.hp_branch,
                               self.compiled.hp_chainage)  # branches' own initial levels, never below the bed
        z = np.where(np.isnan(along), z, np.maximum(along, a.hp_bed))
        for bnd in range(a.b_hp.size):
            if a.b_type[bnd] == BOUNDARY_LEVEL:
                key = self.compiled.forcing_keys[a.b_col[bnd]]
                z[a.b_hp[bnd]] = self._forcing_steps.values_at(key, np.array([0.0]), start)[0]
        vol = np.array([
            hp_volume_width(a.sc_ptr, a.sc_prof, a.sc_bed, a.sc_len, a.hp_bed, a.hp_amin, a.tab_off, a.tab_n,
                            a.tab_dd, a.tab_idd, a.tab_top, a.tab_wt_top, a.tab_at, a.tab_wt, i, z[i])[0]
            for i in range(z.size)
        ])
        return EngineState(
            time=start,
            z=z,
            dz=np.zeros_like(z),
            vol=vol,
            u=np.zeros(self.compiled.n_links),
            q=np.zeros(self.compiled.n_links),
            pump_on=np.zeros(a.p_cap.size),
            signature=(self.compiled.n_hpoints, self.compiled.n_links),
            ctl=self.controls.initial_state() if self.controls else np.zeros((0, 6)),
        )

    def state_at(self, parameters: Mapping[str, float] | None, at: pd.Timestamp | str) -> EngineState:
        """The state at ``at`` of a run that cold-starts at the case's start: ``simulate(parameters, end=at)[1]``.

        A workflow spins the same model up again and again: the on-line service for each of its models, its
        report for the same ones, every calibration of a twin suite from the same initial values. This
        process keeps the last :data:`SPUN_UP_KEPT` such states and continues from the latest one with the same
        parameters at or before ``at``; a run split in two equals the whole run to the last bit, so the
        state is the same as a spin-up from the case's start.
        """
        at = utc(at)
        key = self._run_key(parameters)
        earlier = [s for (k, _), s in self._spun.items() if k == key and s.time <= at]
        if earlier:
            base = max(earlier, key=lambda s: s.time)
            state = base.copy() if base.time == at else self.simulate(parameters, start=base.time, end=at,
                                                                      state=base)[1]
        else:
            _, state = self.simulate(parameters, end=at)
        self._remember((key, at), state)
        return state.copy()

    def _remember(self, key: tuple[bytes, pd.Timestamp], state: EngineState) -> None:
        """Keep a spun-up state for :meth:`state_at`, the last :data:`SPUN_UP_KEPT` of them."""
        self._spun[key] = state
        self._spun.move_to_end(key)
        while len(self._spun) > SPUN_UP_KEPT:
            self._spun.popitem(last=False)

    def keep_state(self, parameters: Mapping[str, float] | None, state: EngineState) -> None:
        """Take ``state`` as the state of :meth:`state_at` for ``parameters`` at ``state.time``.

        For a state spun up before, by this model or another process (:func:`rivercal.models.spun_up`
        reads them from its disk cache); later calls of :meth:`state_at` continue from it.

        Raises
        ------
        ValueError
            For a state of another grid.
        """
        self._check_grid(state)
        self._remember((self._run_key(parameters), state.time), state.copy())

    def _check_grid(self, state: EngineState) -> None:
        """ValueError for a state of another network (another number of points or links)."""
        if state.signature != (self.compiled.n_hpoints, self.compiled.n_links):
            raise ValueError("the state belongs to another network")

    def spin_up_key(self, parameters: Mapping[str, float] | None) -> str:
        """A name (hex) for the cold-started run of :meth:`state_at` with ``parameters``.

        Two models whose names are equal compute the same states at every time, to the last bit: the
        name digests what such a run depends on in the model: the case file, the compiled network, every
        forcing series, the case's start, and the parameters as the kernels receive them. (The engine's
        code and what compiles it are the caller's part: :mod:`rivercal.models.spinups`.)

        Computed afresh at each call (about 3 ms for the dommel case), so that a forcing series changed in
        place names another run too.
        """
        digest = hashlib.sha256(self.case.spec.model_dump_json().encode())
        digest.update(str(self.start.value).encode())
        c = self.compiled
        for group in (c.arrays, c.structures):
            for name, value in zip(group._fields, group, strict=True):
                array = np.ascontiguousarray(value)
                digest.update(f"{name}:{array.dtype.str}:{array.shape}".encode())
                digest.update(array.tobytes())
        for key in sorted(self.forcing):
            series = self.forcing[key]
            digest.update(key.encode())
            digest.update(series.index.as_unit("ns").asi8.tobytes())
            digest.update(series.to_numpy(dtype=float).tobytes())
        digest.update(self._run_key(parameters))
        return digest.hexdigest()

    def _run_key(self, parameters: Mapping[str, float] | None) -> bytes:
        """What a run's parameters come to in the kernels' arrays (two mappings that say the same are one key)."""
        crest, fric = self.parameter_arrays(parameters)
        parts = [crest, fric]
        control = self.control_values(parameters)
        if control is not None:
            parts += [control.par, control.rel_y, *control.tables]
        return b"|".join(np.ascontiguousarray(p, dtype=float).tobytes() for p in parts)

    # -- forcing -------------------------------------------------------------------------------

    def forcing_matrix(self, start: pd.Timestamp, n_steps: int, *, constant: bool = False) -> np.ndarray:
        """Per-step forcing: step-mean discharges (m³/s) and end-of-step levels (m AD).

        With ``constant`` every step gets the values at ``start`` (used for spin-up).
        """
        return self._forcing(start, n_steps, constant)[0]

    def forcing_edges(self, start: pd.Timestamp, n_steps: int) -> np.ndarray:
        """The course of each discharge within each step (two rows per step): its values at the step's start and end.

        Per step ``n``, rows ``2n`` and ``2n + 1`` hold, per forcing column, the ends (m³/s) of the straight line
        that the sub-steps of a divided step follow (:func:`rivercal.engine.kernels.forcing.apply_forcing`): the
        discharge at the step's edges where the series has no time within the step, else the line of the same
        volume that is nearest to the series over the step (its least-squares fit), so that a value held from one
        time of the series to the next is held within the step too. Level columns hold the level at the step's
        edges (m AD).
        """
        return self._forcing(start, n_steps, False)[1]

    def _forcing(self, start: pd.Timestamp, n_steps: int, constant: bool) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`forcing_matrix` and :meth:`forcing_edges` in one (:meth:`.step_forcing.ForcingSteps.arrays`)."""
        return self._forcing_steps.arrays(start, n_steps, self.dt, constant=constant)

    # -- running -------------------------------------------------------------------------------

    def simulate(
        self,
        parameters: Mapping[str, float] | None = None,
        start: pd.Timestamp | str | None = None,
        end: pd.Timestamp | str | None = None,
        state: EngineState | None = None,
        *,
        output_interval: float | None = None,
        snapshots: bool = False,
    ) -> tuple[SimulationResult, EngineState]:
        """Run from ``start`` to ``end``.

        Parameters
        ----------
        parameters
            Model quantities to set (targets → values); the rest keep their case values.
        start, end
            Period (UTC; default the case period). ``end - start`` must be a multiple of the
            output interval.
        state
            Hot-start state at ``start`` (not modified). Without it the run cold-starts, after the
            case's spin-up.
        output_interval
            Interval of the output series, s (default from the case; a multiple of ``dt``).
        snapshots
            Also return levels and discharges at every point at the output times.

        Returns
        -------
        (SimulationResult, EngineState)
            The result and the state at ``end``.

        Raises
        ------
        EngineDivergedError
            When the run produces a non-physical state; it never returns NaN.
        ValueError
            For a period that does not fit the time step or a state from another network or time.
        """
        start = self.start if start is None else utc(start)
        end = self.end if end is None else utc(end)
        interval = float(output_interval or self.settings.output_interval)
        out_every = _ratio(interval, self.dt, "output_interval", "dt")
        n_steps = _ratio((end - start).total_seconds(), interval, "the period", "the output interval") * out_every
        if n_steps < 0:  # end == start is a run of no steps: the (hot or cold-start) state at start
            raise ValueError(f"end {end} is before start {start}")
        crest, fric = self.parameter_arrays(parameters)
        control = self.control_values(parameters)
        if state is None:
            state = self.initial_state(start)
            if self.case.spec.initial.spinup > 0:
                n_spin = max(1, round(self.case.spec.initial.spinup * 3600.0 / self.dt))
                spin = self.forcing_matrix(start, n_spin, constant=True)
                self._run(state, crest, fric, spin, n_spin, False, start - pd.Timedelta(seconds=n_spin * self.dt),
                          phase="spin-up", control=control)
        else:
            self._check_grid(state)
            if state.ctl.shape[0] != len(self.controls or ()):
                raise ValueError(f"the state holds {state.ctl.shape[0]} controllers, the case has "
                                 f"{len(self.controls or ())}")
            if state.time != start:
                raise ValueError(f"the state is at {state.time}, the run starts at {start}")
            state = state.copy()
        forcing, edges = self._forcing(start, n_steps, False)
        t0 = _time.perf_counter()
        obs, zs, qs, balance, initial_volume = self._run(state, crest, fric, forcing, out_every, snapshots, start,
                                                         control=control, edges=edges)
        wall = _time.perf_counter() - t0
        times = pd.date_range(start, end, periods=n_steps // out_every + 1)
        series = pd.DataFrame(obs, index=times, columns=self.observables)
        series.index.name = "time"
        levels = discharges = None
        if snapshots:
            levels = pd.DataFrame(zs, index=times, columns=self.compiled.hp_label)
            discharges = pd.DataFrame(qs, index=times, columns=self.compiled.link_label)
        state.time = end
        final_volume = self._domain_volume(state)
        bal = VolumeBalance(
            initial=initial_volume,
            final=final_volume,
            boundaries=dict(zip(self.compiled.boundary_ids, balance[:-1].tolist(), strict=True)),
            laterals=float(balance[-1]),
        )
        log.debug("simulated %s .. %s in %.3f s", start, end, wall)
        return SimulationResult(series=series, balance=bal, levels=levels, discharges=discharges, wall_time=wall,
                                shortfalls=self.last_run_shortfalls), state

    def _domain_volume(self, state: EngineState) -> float:
        a = self.compiled.arrays
        mask = np.ones(state.vol.size, dtype=bool)
        mask[a.b_hp[a.b_type == BOUNDARY_LEVEL]] = False
        return float(state.vol[mask].sum())

    def _run(self, state, crest, fric, forcing, out_every, snapshots, start, phase="", control=None, edges=None):
        a = self.compiled.arrays
        n_steps = forcing.shape[0]
        n_out = n_steps // out_every + 1
        n_obs = len(self.compiled.observables)
        obs = np.full((n_out, n_obs + len(self.controls or ())), np.nan)
        cx = None
        if self.controls is not None:  # a spin-up (phase) holds the time tables at their start value, as the forcing
            cx = self.controls.arrays(control if control is not None else self.controls.values(None), start, n_steps,
                                      self.dt, n_out, state.ctl, held=bool(phase))
        zs = np.empty((n_out if snapshots else 0, self.compiled.n_hpoints))
        qs = np.empty((n_out if snapshots else 0, self.compiled.n_links))
        balance = np.zeros(a.b_hp.size + 1)
        initial_volume = self._domain_volume(state)
        self._work.stats[:] = 0
        self._work.stats[list(CONTROL_STATS)] = state.control  # the step control continues where it stopped
        self._work.flick[:] = state.flicker
        self._work.swing[:] = state.swing
        self._work.wreq_sum[:] = 0.0
        self._work.wshort_sum[:] = 0.0
        dikes = state.dike_curves(self.compiled.dikes.sc.size)
        status, step, index = time_loop(self, self._work, cx, crest, fric,
                                        (state.z, state.dz, state.vol, state.u, state.q, state.pump_on), forcing,
                                        out_every, (obs, zs, qs, balance), dikes=dikes, edges=edges)
        if cx is not None:
            obs[:, n_obs:] = cx.out
        state.control = self._work.stats[list(CONTROL_STATS)].copy()
        state.flicker = self._work.flick.copy()
        state.swing = self._work.swing.copy()
        state.dikes = dikes
        self.last_run_stats = run_stats(self._work.stats)
        log.debug("%s%s", phase + ": " if phase else "", self.last_run_stats)
        self.last_run_shortfalls = self._shortfalls(self._work.wreq_sum, self._work.wshort_sum, start, phase)
        if status != STATUS_OK:
            raise EngineDivergedError(*divergence(self, status, step, index, state.z, state.u, start, phase))
        return obs, zs, qs, balance, initial_volume

    def _shortfalls(self, asked: np.ndarray, lacking: np.ndarray, start: pd.Timestamp,
                   phase: str | None = None) -> dict[str, Shortfall]:
        """The withdrawals that took less than they asked, from a run's totals per boundary, then lateral (m³).

        Logs a warning for each (the run goes on: a withdrawal takes at most half of the water at its point
        per step, see :mod:`rivercal.engine.kernels.forcing`).
        """
        keys = [f"boundary:{b}" for b in self.compiled.boundary_ids] + \
               [f"lateral:{lat}" for lat in self.compiled.lateral_ids]
        out = {}
        for key, want, short in zip(keys, asked, lacking, strict=True):
            if short > 1e-9 * max(want, 1.0):
                out[key] = Shortfall(requested=float(want), delivered=float(want - short))
                log.warning("%s%s: the withdrawal ran short of water in the run from %s: %.6g m³ asked, %.6g m³ "
                            "delivered (%.1f %%); it takes at most half of the water at its point per time step",
                            f"{phase}: " if phase else "", key, start.isoformat(), want, want - short,
                            100.0 * (want - short) / want)
        return out

    # -- views ---------------------------------------------------------------------------------------

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({self.case.name!r}, {self.start:%Y-%m-%d %H:%M} … {self.end:%Y-%m-%d %H:%M} "
                f"UTC, Δt {self.dt:g} s, {self.compiled.n_hpoints} points, {self.compiled.n_links} links, "
                f"{len(self.observables)} series)")

    def quantities_frame(self) -> pd.DataFrame:
        """The model quantities as a table, one row per quantity name.

        Columns: the ``value`` the model runs with unless it is set (a branch that inherits the global friction
        shows the global value and says so; ``friction:scale`` and each ``friction:factor:<id>`` are 1, no
        scaling) and, where the model declares them (an :class:`~rivercal.models.EmbeddedModel` does), ``unit``,
        ``min``, ``max`` (±inf where the quantity has no bound, e.g. a crest level) and ``description``. Values in
        the unit of each quantity: m AD for crest levels, the friction law's unit for friction, - for factors.

        Examples
        --------
        >>> from rivercal.models import load_model
        >>> table = load_model("synthetic").quantities_frame()
        >>> print(table.loc["friction:global", "value"], table.loc["friction:global", "unit"])
        25.0 m^(1/3)/s
        """
        declared = getattr(self, "quantities", {})
        return quantities_table(self.default_parameters(), declared, self.compiled.branch_inherits)


def time_loop(sim: Simulator, work, cx, crest: np.ndarray, fric: np.ndarray, state: tuple, forcing: np.ndarray,
              out_every: int, out: tuple, *, private: bool = False, dikes: np.ndarray | None = None,
              edges: np.ndarray | None = None) -> tuple[int, int, int]:
    """One call of the compiled time loop of ``sim`` (the extended one where :attr:`Simulator.extended`).

    ``state`` (z m AD, dz m, vol m³, u m/s, q m³/s, pump_on) is advanced in place; ``out`` (obs, zs, qs,
    balance) is written; ``work`` and ``cx`` are the run's scratch and controller arrays. ``private`` copies
    the two arrays the extended loop writes scheduled settings into (pump capacities, orifice gates), for a
    call on a thread beside others. ``dikes`` (for a network with summer dikes whose storage changes curve,
    :class:`~rivercal.engine.compile.DikeArrays`) holds per such dike 1 while it is on its falling curve, else 0,
    and is updated in place; the run stores with its own copy of the contributions' tables. ``edges`` is the
    forcing's course within each step (:meth:`Simulator.forcing_edges`), which the sub-steps of a divided step
    follow; without it they take the step's means. Returns the status code, the step and the index where it stopped.
    """
    s, a, sx, dk = sim.settings, sim.compiled.arrays, sim.compiled.structures, sim.compiled.dikes
    settings = (float(s.dt), float(s.theta), int(s.max_iterations), float(s.tolerance), float(s.min_depth),
                float(s.max_velocity), float(s.courant or 0.0), int(out_every))
    if edges is None:
        edges = np.empty((0, forcing.shape[1]))
    if not sim.extended:
        return run(a, work, crest, fric, *state, forcing, edges, *settings, *out)
    if private:
        a, sx = a._replace(p_cap=a.p_cap.copy()), sx._replace(ogate=sx.ogate.copy())
    if not dk.sc.size:
        return run_ext(a, sx, cx, dk, work, crest, fric, *state, forcing, edges, *settings, *out)
    falling = np.zeros(dk.sc.size, dtype=bool) if dikes is None else np.asarray(dikes) != 0
    sc_prof = a.sc_prof.copy()
    sc_prof[dk.sc] = np.where(falling, dk.alt, dk.rise)
    work.zlo[dk.hp] = np.inf  # the pieces of these points' volume curves are looked up afresh with these tables
    work.zhi[dk.hp] = -np.inf
    status = run_ext(a._replace(sc_prof=sc_prof), sx, cx, dk, work, crest, fric, *state, forcing, edges, *settings,
                     *out)
    if dikes is not None:
        dikes[:] = sc_prof[dk.sc] == dk.alt
    return status


def run_stats(stats: np.ndarray) -> dict[str, int]:
    """The counters of a run (``Work.stats``) by name: steps, solves, drying re-solves and the step control's."""
    return {"steps": int(stats[STAT_STEPS]), "solves": int(stats[STAT_SOLVES]),
            "drying_resolves": int(stats[STAT_DRYING]), "divided_steps": int(stats[STAT_REFINED]),
            "substeps": int(stats[STAT_SUBSTEPS]), "max_division": 2 ** int(stats[STAT_MAX_LEVEL]),
            "redone": int(stats[STAT_REDONE]), "flickers": int(stats[STAT_FLICKERS]),
            "geometry_fallbacks": int(stats[STAT_EXPLICIT])}


def _ratio(a: float, b: float, what_a: str, what_b: str) -> int:
    r = a / b
    if abs(r - round(r)) > 1e-9:
        raise ValueError(f"{what_a} ({a:g} s) is not a multiple of {what_b} ({b:g} s)")
    return round(r)
