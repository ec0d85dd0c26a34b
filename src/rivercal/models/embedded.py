"""The embedded engine behind the model contract: a case, its rainfall-runoff inflows, the Simulator.

:class:`EmbeddedModel` is the :class:`~rivercal.engine.Simulator` of a case (everything it offers stays
available: ``case``, ``compiled``, ``initial_state`` …) plus the declarations of the model contract
(:mod:`rivercal.models.contract`): the settable quantities with units and bounds, the calibration setup
of ``case.toml``, and its state as bytes.

Quantities:

- ``weir:<id>.crest_level`` — crest level of a weir, m AD;
- ``friction:global`` — the friction value of every branch that inherits the case's friction (unit of
  the case's friction type, e.g. k_s in m^(1/3)/s), present when some branch inherits it;
- ``friction:branch:<id>`` — the friction value of one branch (unit of its friction type);
- ``friction:group:<id>`` — the value of a friction group (``[[friction_groups]]``, unit of its law);
- ``friction:scale`` — a factor (-) on the conveyance of every channel friction coefficient, present when
  no link uses White-Colebrook friction (a factor on its coefficient does not scale its conveyance);
- ``control:<id>.setpoint`` (m AD, m³/s for a discharge), ``.kp`` (m/m), ``.ki`` (1/s), ``.kd`` (s),
  ``.value:<k>`` (m AD) — the quantities of the case's controllers (:mod:`rivercal.engine.controllers`); a
  weir driven by a controller declares no ``crest_level``.

Friction bounds are the plausible ranges of :data:`rivercal.network.FRICTION_RANGES`.

Virtual stations (the optional capability :class:`~rivercal.models.capabilities.VirtualStations`): the model
offers every calculation point and either side of every structure as a place for a new gauge, and
:meth:`EmbeddedModel.with_stations` returns the same model with those places added to the case's
``[[stations]]`` (the same grid, forcing and quantities; only the written series differ).

It has every optional capability of the contract (:data:`~rivercal.models.capabilities.CAPABILITIES`): batches of
parameter sets and ensembles of members in one batched engine call on threads (the compiled time loop releases
the interpreter lock; :func:`rivercal.engine.ensemble.run_ensemble`, each member bit-identical to its single
run), its laterals and discharge boundaries as perturbable forcing, its state as the levels at the
calculation points and the discharges at the links, snapshots of both, and the case it was built from.
"""

from __future__ import annotations

import functools
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import numba
import numpy as np
import pandas as pd

from rivercal._time import Windows
from rivercal.case.load import Case, load_case
from rivercal.engine.ensemble import run_ensemble
from rivercal.engine.kernels.batch import volumes
from rivercal.engine.kernels.codes import BOUNDARY_DISCHARGE, OBS_FLUX, OBS_LEVEL
from rivercal.engine.simulator import Simulator
from rivercal.engine.state import EngineState
from rivercal.hydrology.catchments import catchment_forcing
from rivercal.models.capabilities import Location, MemberRuns, StateLayout, VariantInputs
from rivercal.models.contract import CalibrationSetup, Quantity, utc
from rivercal.network import Station
from rivercal.results import SimulationResult

__all__ = ["EmbeddedModel", "build_model", "load_case_model"]


#: The share of ``engine.max_velocity`` that an analysed state may give a link's velocity
#: (:meth:`EmbeddedModel.with_state_arrays`).
ANALYSED_SPEED_SHARE = 0.5


class EmbeddedModel(Simulator):
    """A case ready to run on the embedded engine, with the model contract's declarations.

    Parameters
    ----------
    case
        A loaded case.
    forcing
        Replacement series for boundaries and laterals (see :class:`~rivercal.engine.Simulator`).

    Examples
    --------
    >>> from rivercal.models import build_model
    >>> from rivercal.case import load_case
    >>> model = build_model(load_case("synthetic"))
    >>> model.quantities["weir:W1.crest_level"].unit
    'm AD'
    """

    def __init__(self, case: Case, forcing: Mapping[str, pd.Series] | None = None):
        super().__init__(case, forcing=forcing)

    @property
    def name(self) -> str:
        """The case's name."""
        return self.case.name

    @property
    def output_interval(self) -> float:
        """Default interval of the station series, s."""
        return float(self.settings.output_interval)

    @property
    def numerical_noise(self) -> float:
        """The Picard level tolerance of a time step, m.

        An upper bound of the jitter a tiny parameter change causes in the simulated levels.
        """
        return float(self.settings.tolerance)

    @functools.cached_property
    def quantities(self) -> dict[str, Quantity]:
        """The settable quantities (module docstring): the engine's table, without the controlled crests.

        One table (:func:`rivercal.engine.quantities.settable_table`) defines the names the engine takes and
        those the model declares, with the same units and bounds.
        """
        return {name: Quantity(name, q.unit, q.low, q.high, q.description)
                for name, q in self.settable.items() if not q.controlled}

    @functools.cached_property
    def calibration(self) -> CalibrationSetup:
        """Parameters, windows and optimiser defaults of ``case.toml``."""
        spec = self.case.spec
        windows = Windows({w.name: (w.start, w.end) for w in spec.windows}, f"case {self.case.name}")
        return CalibrationSetup(parameters=tuple(spec.parameters), windows=windows,
                                algorithm=spec.calibration.algorithm, options=dict(spec.calibration.options))

    # -- virtual stations (the optional capability VirtualStations) ----------------------------------

    def candidate_locations(self, where: str, measure: str) -> list[Location]:
        """Places for a new gauge: every calculation point (``points``) or either side of every structure.

        Parameters
        ----------
        where
            ``points`` (every calculation point, connection nodes included) or ``structures`` (the points
            either side of every structure, and its discharge).
        measure
            What the gauge measures: ``level``, ``discharge`` or ``both``.

        Returns
        -------
        list of Location
            In grid order. What the case's stations already measure is left out (a place whose every
            quantity is measured is left out altogether); a link's discharge is offered once, at the
            first point whose nearest link it is.
        """
        if where not in ("points", "structures"):
            raise ValueError(f"unknown kind of place {where!r}; choose points or structures")
        levels, flows = _wanted(measure)
        c = self.compiled
        seen_h, seen_q = self._observed()
        taken = {st.id for st in self.case.network.stations}
        out: list[Location] = []
        if where == "structures":
            k1, k2 = c.arrays.lk_k1, c.arrays.lk_k2
            for sid, li in c.structure_link.items():
                q = ("Q",) if flows and li not in seen_q else ()
                sides = (("up", "h_up", int(k1[li])), ("down", "h_down", int(k2[li]))) if levels else ()
                if not levels and q:
                    out.append(self._location(_unique(f"{sid}_Q", taken), q, f"discharge at {sid}", None, None, sid,
                                              None, int(k1[li])))
                for side, quantity, k in sides:
                    quantities = ((quantity,) if k not in seen_h else ()) + q
                    if quantities:
                        out.append(self._location(_unique(f"{sid}_{side}", taken), quantities,
                                                  f"{'upstream' if side == 'up' else 'downstream'} of {sid}",
                                                  None, None, sid, side, k))
            return out
        ends = self._node_ends()
        for k, label in enumerate(c.hp_label):
            branch = c.hp_branch[k]
            if branch:
                chainage = float(c.hp_chainage[k])
            elif label.startswith("node:") and label[5:] in ends:
                branch, chainage = ends[label[5:]]
            else:
                continue
            li = _link_at(c, branch, chainage)
            quantities = (("h",) if levels and k not in seen_h else ()) + (("Q",) if flows and li not in seen_q
                                                                           else ())
            seen_q.add(li)  # a link's discharge is offered once, at the first point that reaches it
            if quantities:
                stem = label[5:] if label.startswith("node:") else f"{branch}_{round(chainage)}"
                out.append(self._location(_unique(stem.replace(".", "_"), taken), quantities, label, branch,
                                          chainage, None, None, k))
        return out

    def location_at(self, branch: str, chainage: float, *, id: str, measure: str, name: str = "") -> Location:
        """A place on ``branch`` at ``chainage`` (m from its start) for a gauge measuring ``measure``.

        Raises
        ------
        ValueError
            For an unknown branch, a chainage outside it, or an id that is not a station id.
        """
        levels, flows = _wanted(measure)
        branches = {b.id: b for b in self.case.network.branches}
        if branch not in branches:
            raise ValueError(f"unknown branch {branch!r}")
        length = float(branches[branch].length)
        if not (0.0 <= float(chainage) <= length):
            raise ValueError(f"chainage {chainage:g} m is outside branch {branch!r} (0 … {length:g} m)")
        if not id or "." in id:
            raise ValueError(f"{id!r} cannot be a station id: it must be non-empty and contain no '.'")
        c = self.compiled
        on = [k for k, b in enumerate(c.hp_branch) if b == branch]
        k = on[int(np.argmin(np.abs(c.hp_chainage[on] - float(chainage))))] if on else None
        quantities = (("h",) if levels else ()) + (("Q",) if flows else ())
        return self._location(id, quantities, name or f"{branch}@{float(chainage):.1f}", branch, float(chainage),
                              None, None, k)

    def with_stations(self, locations: Iterable[Location]) -> EmbeddedModel:
        """The model with ``locations`` added to the case's stations (same grid, forcing and quantities).

        Raises
        ------
        ValueError
            When a place cannot be a station of the case (its id taken, a level inside a structure's
            segment …); the message names the place.
        """
        from pydantic import ValidationError

        from rivercal.errors import FieldProblem

        spec = self.case.spec
        new = []
        for loc in locations:
            fields = {"id": loc.id, "quantities": list(loc.quantities)}
            fields.update({"structure": loc.structure} if loc.structure is not None else
                          {"branch": loc.branch, "chainage": loc.chainage})
            try:
                new.append(Station(**fields))
            except (ValidationError, FieldProblem, ValueError) as exc:
                raise ValueError(f"place {loc.id!r} ({loc.name}): {_first_error(exc)}") from None
        data = spec.model_dump(by_alias=True)
        data["stations"] = [st.model_dump(by_alias=True, exclude_none=True) for st in [*spec.stations, *new]]
        try:
            extended = type(spec).model_validate(data)
        except (ValidationError, FieldProblem, ValueError) as exc:
            raise ValueError(f"the places cannot be stations of case {self.name!r}: {_first_error(exc)}") from None
        case = Case(spec=extended, root=self.case.root, forcing=self.case.forcing)
        return EmbeddedModel(case, forcing={k: v for k, v in self.forcing.items() if k in self.compiled.forcing_keys})

    def only_stations(self, ids: Iterable[str]) -> EmbeddedModel:
        """The model with only the stations ``ids`` of the case (same grid, forcing and quantities).

        Raises
        ------
        ValueError
            Naming an id that is not a station of the case.
        """
        from pydantic import ValidationError

        from rivercal.errors import FieldProblem

        keep = list(dict.fromkeys(ids))
        spec = self.case.spec
        known = [st.id for st in spec.stations]
        unknown = [i for i in keep if i not in known]
        if unknown:
            raise ValueError(f"{unknown[0]!r} is not a station of case {self.name!r} (its stations: "
                             f"{', '.join(known[:12])}{' …' if len(known) > 12 else ''})")
        data = spec.model_dump(by_alias=True)
        data["stations"] = [st.model_dump(by_alias=True, exclude_none=True) for st in spec.stations if st.id in keep]
        try:
            reduced = type(spec).model_validate(data)
        except (ValidationError, FieldProblem, ValueError) as exc:  # e.g. a controller reads a station left out
            raise ValueError(f"case {self.name!r} needs more of its stations than {', '.join(keep)}: "
                             f"{_first_error(exc)}") from None
        case = Case(spec=reduced, root=self.case.root, forcing=self.case.forcing)
        return EmbeddedModel(case, forcing={k: v for k, v in self.forcing.items() if k in self.compiled.forcing_keys})

    def _observed(self) -> tuple[set[int], set[int]]:
        """The calculation points whose level and the links whose discharge the case's stations measure."""
        a = self.compiled.arrays
        levels, flows = set(), set()
        for kind, i1, i2, w in zip(a.ob_type, a.ob_i1, a.ob_i2, a.ob_w, strict=True):
            if kind == OBS_LEVEL and w >= 1.0 - 1e-12:
                levels.add(int(i1))
            elif kind == OBS_LEVEL and w <= 1e-12:
                levels.add(int(i2))
            elif kind == OBS_FLUX:
                flows.add(int(i1))
        return levels, flows

    def _node_ends(self) -> dict[str, tuple[str, float]]:
        """Per connection node a branch end that reaches it: (branch id, chainage in m)."""
        out: dict[str, tuple[str, float]] = {}
        for b in self.case.network.branches:
            out.setdefault(b.from_node, (b.id, 0.0))
            out.setdefault(b.to_node, (b.id, float(b.length)))
        return out

    def _location(self, id: str, quantities: tuple[str, ...], name: str, branch: str | None,
                  chainage: float | None, structure: str | None, side: str | None, k: int | None) -> Location:
        xy = self.compiled.hp_xy[k] if k is not None else (np.nan, np.nan)
        x, y = (float(v) if np.isfinite(v) else None for v in xy)
        return Location(id=id, quantities=quantities, name=name, branch=branch, chainage=chainage,
                        structure=structure, side=side, point=self.compiled.hp_label[k] if k is not None else None,
                        x=x, y=y)

    # -- state ------------------------------------------------------------------------------------

    def start_state(self, start: pd.Timestamp | None = None,
                    parameters: Mapping[str, float] | None = None) -> EngineState:
        """The state a cold-started run begins from at ``start``.

        The case's initial state, then its spin-up with the forcing held at its ``start`` value and the
        given quantities (what :meth:`simulate` does without a state).
        """
        start = self.start if start is None else utc(start)
        crest, fric = self.parameter_arrays(parameters)
        state = self.initial_state(start)
        hours = self.case.spec.initial.spinup
        if hours > 0:
            n = max(1, round(hours * 3600.0 / self.dt))
            spin = self.forcing_matrix(start, n, constant=True)
            self._run(state, crest, fric, spin, n, False, start - pd.Timedelta(seconds=n * self.dt), phase="spin-up",
                      control=self.control_values(parameters))
        state.time = start
        return state

    @property
    def state_format(self) -> str:
        """Format tag of :meth:`save_state`."""
        return EngineState.BYTES_FORMAT

    def save_state(self, state: EngineState) -> bytes:
        """The engine state as bytes (:meth:`EngineState.to_bytes`, no pickle)."""
        return state.to_bytes()

    def load_state(self, data: bytes, fmt: str) -> EngineState:
        """An engine state of this network from :meth:`save_state` bytes.

        Raises
        ------
        ValueError
            For another format, bytes that are no engine state, or a state of another grid.
        """
        state = EngineState.from_bytes(data, fmt)
        if state.signature != (self.compiled.n_hpoints, self.compiled.n_links):
            raise ValueError(f"the state belongs to another grid ({state.signature[0]} points, "
                             f"{state.signature[1]} links; case {self.name!r} has {self.compiled.n_hpoints} and "
                             f"{self.compiled.n_links})")
        return state


    # -- optional capabilities (rivercal.models.capabilities) --------------------------------------

    def run_batch(self, parameters: Sequence[Mapping[str, float] | None], start: Any = None, end: Any = None,
                  states: Sequence[EngineState] | None = None, *, output_interval: float | None = None,
                  threads: int | None = None, on_failure: Literal["raise", "report"] = "raise") -> MemberRuns:
        """One member per parameter set in one batched engine call (``threads``: None all, else at most all)."""
        ens = run_ensemble(self, list(parameters), start, end, None if states is None else list(states),
                           output_interval=output_interval, n_threads=_threads(threads), on_failure=on_failure)
        return _member_runs(ens)

    def perturbable_forcing(self) -> tuple[str, ...]:
        """The laterals and the discharge boundaries, in the order of the compiled forcing columns."""
        return tuple(self.compiled.forcing_keys[col] for col in self._perturbable_columns)

    @functools.cached_property
    def _perturbable_columns(self) -> np.ndarray:
        c = self.compiled
        a = c.arrays
        mask = np.array([k.startswith("lateral:") for k in c.forcing_keys], dtype=bool)
        for bnd in range(a.b_hp.size):
            if a.b_type[bnd] == BOUNDARY_DISCHARGE and a.b_col[bnd] >= 0:
                mask[a.b_col[bnd]] = True
        return np.flatnonzero(mask)

    def perturbable_levels(self) -> tuple[str, ...]:
        """The level boundaries (``"boundary:<id>"``), in the order of the compiled forcing columns."""
        return tuple(self.compiled.forcing_keys[col] for col in self._level_columns)

    @functools.cached_property
    def _level_columns(self) -> np.ndarray:
        c = self.compiled
        a = c.arrays
        cols = {int(a.b_col[b]) for b in range(a.b_hp.size) if a.b_col[b] >= 0 and c.forcing_is_level[a.b_col[b]]}
        return np.array(sorted(cols), dtype=np.int64)

    def _perturbed_forcing(self, start: pd.Timestamp, end: pd.Timestamp, factors: np.ndarray,
                           interval: float) -> tuple[np.ndarray, np.ndarray]:
        """Per-member forcing and its course within each step: the case's, with ``factors`` applied.

        Returns the forcing (members, steps, columns) and the course (members, 2 × steps, columns; as
        :meth:`forcing_edges`). ``factors`` (members, intervals, columns): a factor per perturbable forcing, then
        optionally an offset (m) per level boundary (:class:`~.capabilities.PerturbableLevels`). A member's factor is
        constant within a step, so a divided step follows the case's own course scaled by it: with factors of one
        a member is the single run, also where the engine divides its steps.
        """
        factors = np.asarray(factors, dtype=float)
        n_steps = round((end - start).total_seconds() / self.dt)
        per = round(float(interval) / self.dt)
        if per < 1 or abs(per * self.dt - float(interval)) > 1e-6:
            raise ValueError(f"the factors' interval ({interval:g} s) must be a whole number of time steps "
                             f"({self.dt:g} s)")
        cols, levels = self._perturbable_columns, self._level_columns
        widths = (cols.size, cols.size + levels.size)
        if factors.ndim != 3 or factors.shape[2] not in widths or factors.shape[1] * per < n_steps:
            raise ValueError(f"factors must have shape (members, intervals >= {-(-n_steps // per)}, {cols.size} "
                             f"or {widths[1]}), got {factors.shape}")
        base = self.forcing_matrix(start, n_steps)
        forcing = np.repeat(base[None], factors.shape[0], axis=0)
        course = np.repeat(self.forcing_edges(start, n_steps)[None], factors.shape[0], axis=0)
        steps = np.repeat(factors, per, axis=1)[:, :n_steps]
        edges = np.repeat(steps, 2, axis=1)  # a step's factor at both of its edges
        forcing[:, :, cols] *= steps[:, :, : cols.size]
        course[:, :, cols] *= edges[:, :, : cols.size]
        if factors.shape[2] == widths[1] and levels.size:
            forcing[:, :, levels] += steps[:, :, cols.size :]
            course[:, :, levels] += edges[:, :, cols.size :]
        return forcing, course

    def run_members(self, parameters: Mapping[str, float] | None, start: Any, end: Any,
                    states: Sequence[EngineState], *, factors: np.ndarray | None = None, interval: float | None = None,
                    output_interval: float | None = None, threads: int | None = None,
                    on_failure: Literal["raise", "report"] = "raise") -> MemberRuns:
        """Every member from its state, with its forcing scaled by its ``factors``, in one batched engine call."""
        start, end = utc(start), utc(end)
        forcing = course = None
        if factors is not None:
            forcing, course = self._perturbed_forcing(start, end, factors, float(interval))
        ens = run_ensemble(self, [parameters] * len(states), start, end, list(states), forcing=forcing, edges=course,
                           output_interval=output_interval, n_threads=_threads(threads), on_failure=on_failure)
        return _member_runs(ens)

    def simulate_perturbed(self, parameters: Mapping[str, float] | None, start: Any, end: Any,
                           state: EngineState | None, factors: np.ndarray, interval: float, *,
                           output_interval: float | None = None) -> tuple[SimulationResult, EngineState]:
        """One run with the forcing scaled by ``factors`` (intervals, forcing) from a state at ``start``."""
        start, end = utc(start), utc(end)
        if state is None:
            state = self.start_state(start, parameters)
        runs = self.run_members(parameters, start, end, [state], factors=np.asarray(factors)[None],
                                interval=interval, output_interval=output_interval, threads=1)
        return SimulationResult(series=runs.series(0), wall_time=runs.wall_time), runs.states[0]

    def state_layout(self) -> StateLayout:
        """Levels at the calculation points, discharges at the links (a :class:`~.capabilities.StateLayout`)."""
        return self._layout

    @functools.cached_property
    def _layout(self) -> StateLayout:
        c = self.compiled
        a = c.arrays
        places = {}
        for col, name in enumerate(c.observables):
            i = int(a.ob_i1[col])
            places[name] = i if a.ob_type[col] == OBS_LEVEL else int(a.lk_k1[i])
        entry = {}
        for lat in range(a.lat_col.size):
            entry[int(a.lat_col[lat])] = int(a.lat_hp[lat])
        for bnd in range(a.b_hp.size):
            if a.b_col[bnd] >= 0:
                entry[int(a.b_col[bnd])] = int(a.b_hp[bnd])
        forcing_places = {c.forcing_keys[col]: entry[int(col)]
                          for col in (*self._perturbable_columns, *self._level_columns)}
        return StateLayout(levels=tuple(c.hp_label), discharges=tuple(c.link_label),
                           link_ends=np.column_stack([a.lk_k1, a.lk_k2]).astype(np.int64),
                           link_length=np.maximum(np.asarray(a.lk_len, dtype=float), 1.0),
                           floor=np.asarray(a.hp_bed, dtype=float).copy(), places=places, forcing_places=forcing_places)

    def state_arrays(self, state: EngineState) -> tuple[np.ndarray, np.ndarray]:
        """Levels at the calculation points (m AD) and discharges at the links (m³/s)."""
        return state.z, state.q

    def with_state_arrays(self, state: EngineState, levels: np.ndarray, discharges: np.ndarray) -> EngineState:
        """A copy of ``state`` with these levels (never below the bed) and discharges.

        The volumes follow from the levels; each link keeps its flow area (discharge over velocity), so its
        velocity follows the new discharge; a link at rest keeps its discharge and velocity. A discharge that
        would move the water through the link's area faster than half the engine's largest velocity
        (``engine.max_velocity``, m/s) is taken at that speed, in its direction: through a link that had little
        water (a point filling after a cold start) an analysis's discharge increment would otherwise start the
        next step at tens of m/s, and the member would diverge.
        """
        a = self.compiled.arrays
        out = state.copy()
        z = np.maximum(np.asarray(levels, dtype=float), a.hp_bed)
        out.z = z
        out.vol = np.empty_like(z)
        volumes(a, z, out.vol)
        with np.errstate(divide="ignore", invalid="ignore"):
            area = np.where(np.abs(state.u) > 1e-9, state.q / state.u, np.nan)
        moving = np.isfinite(area) & (area > 0)
        limit = ANALYSED_SPEED_SHARE * float(self.settings.max_velocity)
        discharges = np.asarray(discharges, dtype=float)
        u = np.where(moving, discharges / np.where(moving, area, 1.0), state.u)
        fast = moving & (np.abs(u) > limit)
        out.u = np.where(fast, np.sign(u) * limit, u)
        out.q = np.where(fast, out.u * np.where(fast, area, 0.0), np.where(moving, discharges, state.q))
        return out

    def simulate_fields(self, parameters: Mapping[str, float] | None = None, start: Any = None, end: Any = None,
                        state: EngineState | None = None, *,
                        output_interval: float | None = None) -> tuple[SimulationResult, EngineState]:
        """:meth:`simulate` with the levels and discharges at every point (``snapshots``)."""
        return self.simulate(parameters, start, end, state, output_interval=output_interval, snapshots=True)


    def source_case(self) -> Case:
        """The case the model was built from."""
        return self.case

    def variant_inputs(self) -> VariantInputs:
        """The case's branches (lengths, m), those inheriting its friction, its catchments, their rain, its forcing."""
        from rivercal.hydrology.catchments import hourly_weather

        spec = self.case.spec
        rain = hourly_weather(self.case)["P"] if spec.catchments else None
        return VariantInputs(branches={b.id: float(b.length) for b in spec.branches},
                             inherit=tuple(self.compiled.branch_inherits),
                             catchments=tuple(c.id for c in spec.catchments), rain=rain,
                             forcing={k: self.forcing[k] for k in self.perturbable_forcing() if k in self.forcing})

    def variant(self, *, branch_factors: Mapping[str, float] | None = None, grid_factor: float = 1.0,
                rain_factor: pd.Series | None = None, runoff_factors: Mapping[str, Mapping[str, float]] | None = None,
                forcing_factors: Mapping[str, pd.Series] | None = None) -> EmbeddedModel:
        """The embedded model of a variant of the case (:func:`rivercal.models.variants.variant_of`)."""
        from rivercal.models.variants import variant_of

        return variant_of(self, branch_factors=branch_factors, grid_factor=grid_factor, rain_factor=rain_factor,
                          runoff_factors=runoff_factors, forcing_factors=forcing_factors)


def _threads(threads: int | None) -> int:
    """Threads of a batched call: None all of numba's, else at least 1 and at most those."""
    n = numba.config.NUMBA_NUM_THREADS
    return n if threads is None else max(1, min(int(threads), n))


def _member_runs(ens: Any) -> MemberRuns:
    return MemberRuns(times=ens.times, observables=ens.observables, values=ens.values, states=ens.states,
                      failures=dict(ens.failures), wall_time=ens.wall_time)


def _wanted(measure: str) -> tuple[bool, bool]:
    """(levels, discharges) a gauge measuring ``measure`` (``level``, ``discharge``, ``both``) records."""
    if measure not in ("level", "discharge", "both"):
        raise ValueError(f"unknown measurement {measure!r}; choose level, discharge or both")
    return measure != "discharge", measure != "level"


def _unique(stem: str, taken: set[str]) -> str:
    """``stem``, or ``stem_2``, ``stem_3`` … when taken; the id is then taken."""
    name, n = stem, 1
    while name in taken:
        n += 1
        name = f"{stem}_{n}"
    taken.add(name)
    return name


def _link_at(c, branch: str, chainage: float) -> int:
    """The link of ``branch`` whose midpoint is nearest to ``chainage`` (m); -1 when the branch has none."""
    on = [li for li, b in enumerate(c.link_branch) if b == branch]
    if not on:
        return -1
    return on[int(np.argmin(np.abs(c.link_chainage[on] - chainage)))]


def _first_error(exc: Exception) -> str:
    """The first message of a pydantic error (or the exception's text), on one line."""
    import re

    errors = getattr(exc, "errors", None)
    if callable(errors):
        first = errors(include_url=False)[0]
        where = ".".join(str(p) for p in first.get("loc", ()))
        text = f"{where + ': ' if where else ''}{first.get('msg', exc)}"
    else:
        text = str(getattr(exc, "reason", exc))
    # pydantic's prefix and the index among the case's stations say nothing about the place (named in the text)
    return re.sub(r"^(Value error, )?(stations\[\d+\]\.\w+: )?", "", text.replace("\n", " "))


def build_model(case: Case) -> EmbeddedModel:
    """The embedded model of ``case``; its catchment-fed laterals carry the rainfall-runoff inflow.

    A bad ``[runoff]`` table or meteo file fails here, when the model is built, before any run.
    """
    return EmbeddedModel(case, forcing=catchment_forcing(case))


def load_case_model(source: str | Path) -> EmbeddedModel:
    """Load a case (folder or packaged name) and build its embedded model."""
    return build_model(load_case(source))
