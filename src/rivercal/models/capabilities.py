"""The optional capabilities of a model: what only some models of the contract can do.

:class:`~rivercal.models.contract.Model` is what every model offers. What only some models can do is declared
beside it as a protocol of its own, and asked for by name (:func:`capability`, :func:`require`); a model without it
gets a :class:`MissingCapability` error that names what it lacks and what needed it:

=======================  ===========================  ===============================================================
name                     protocol                     what the model offers
=======================  ===========================  ===============================================================
``batch runs``           :class:`BatchRuns`           several parameter sets at once (:meth:`~BatchRuns.run_batch`)
``perturbable forcing``  :class:`PerturbableForcing`  runs with its inflows and laterals scaled per interval
``ensemble runs``        :class:`EnsembleRuns`        advances several members (states, perturbed forcing) at once
``perturbable levels``   :class:`PerturbableLevels`   runs with its level boundaries offset per interval
``state arrays``         :class:`StateArrays`         its state as levels (m AD) and discharges (m³/s), read, written
``snapshots``            :class:`Snapshots`           levels and discharges at every point, per output time
``case``                 :class:`FromCase`            the rivercal case it was built from (network, stations, map)
``variants``             :class:`Variants`            a variant of itself for a twin's truth (rain, runoff, grid,
                                                      friction per branch, forcing)
=======================  ===========================  ===============================================================

The embedded engine has all of them; SWMM has the forcing and the state arrays (its hotstart file); a BMI
component has them where its ``model.toml`` names the variables. Every protocol holds methods only, so
that asking a model for one never runs it.

Besides these, :class:`VirtualStations` (series at places where the model has no station, each a
:class:`Location`), and :func:`run_members`, which advances ensemble members with a model's
:class:`EnsembleRuns` where it has them, else one run after another.
"""

from __future__ import annotations

import time as _time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np
import pandas as pd

from rivercal.errors import ModelRunError, OptionError
from rivercal.models.contract import Model, ModelState
from rivercal.results import SimulationResult

__all__ = [
    "CAPABILITIES",
    "BatchRuns",
    "EnsembleRuns",
    "FromCase",
    "Location",
    "MemberRuns",
    "MissingCapability",
    "PerturbableForcing",
    "PerturbableLevels",
    "Snapshots",
    "StateArrays",
    "StateLayout",
    "VariantInputs",
    "Variants",
    "VirtualStations",
    "capability",
    "has_capability",
    "require",
    "run_members",
]


class MissingCapability(OptionError):
    """A model lacks an optional capability that was asked for; the message names both and what needed it.

    The request, not the model, is what is wrong (an option such as ``--assimilate both`` or ``--realism``
    asked for what this model cannot do): a command reports it as bad input.
    """


@dataclass(frozen=True)
class MemberRuns:
    """Runs of several members over one period (:class:`BatchRuns`, :class:`EnsembleRuns`).

    Attributes
    ----------
    times
        Output times (UTC), the first the period's start.
    observables
        Names of the simulated series (``"<station>.<quantity>"``).
    values
        Series of every member, shape (members, times, observables); m and m³/s; NaN for a failed member.
    states
        Each member's state at the end (None for a failed member).
    failures
        Failed members → what happened (empty when all ran).
    wall_time
        Wall-clock time of the runs, s.
    """

    times: pd.DatetimeIndex
    observables: tuple[str, ...]
    values: np.ndarray
    states: tuple[Any, ...]
    failures: Mapping[int, str] = field(default_factory=dict)
    wall_time: float = 0.0

    @property
    def members(self) -> int:
        """Number of members."""
        return int(self.values.shape[0])

    def series(self, member: int) -> pd.DataFrame:
        """The series of one member as :attr:`SimulationResult.series <rivercal.results.SimulationResult.series>`."""
        frame = pd.DataFrame(self.values[member], index=self.times, columns=list(self.observables))
        frame.index.name = "time"
        return frame


@runtime_checkable
class BatchRuns(Protocol):
    """Runs several parameter sets over one period in one call (e.g. on threads), each as its single run."""

    def run_batch(self, parameters: Sequence[Mapping[str, float] | None], start: Any = None, end: Any = None,
                  states: Sequence[Any] | None = None, *, output_interval: float | None = None,
                  threads: int | None = None, on_failure: Literal["raise", "report"] = "raise") -> MemberRuns:
        """One member per parameter set; ``states`` one per member at ``start`` (None: cold starts).

        ``on_failure``: ``raise`` the first failed member's :class:`~rivercal.errors.ModelRunError`, or
        ``report`` it in :attr:`MemberRuns.failures` (its values NaN, its state None).
        """
        ...


@runtime_checkable
class PerturbableForcing(Protocol):
    """Runs with its inflows and laterals multiplied by factors that hold for whole intervals.

    ``factors`` has one row per interval of ``interval`` seconds from the run's start (at least as many as
    the run needs) and one column per key of :meth:`perturbable_forcing`, in that order; a factor multiplies
    that forcing's discharge (m³/s) during its interval.
    """

    def perturbable_forcing(self) -> tuple[str, ...]:
        """The inflows and laterals that may be scaled (``"boundary:<id>"``, ``"lateral:<id>"``)."""
        ...

    def simulate_perturbed(self, parameters: Mapping[str, float] | None, start: Any, end: Any,
                           state: ModelState | None, factors: np.ndarray, interval: float, *,
                           output_interval: float | None = None) -> tuple[SimulationResult, ModelState]:
        """:meth:`~rivercal.models.contract.Model.simulate` with the forcing scaled by ``factors`` (class docstring)."""
        ...


@runtime_checkable
class PerturbableLevels(Protocol):
    """Runs with its level boundaries (a tide at a river's mouth) offset by amounts that hold for whole intervals.

    A model with this capability and :class:`PerturbableForcing` takes, in the ``factors`` of
    :meth:`PerturbableForcing.simulate_perturbed` and :meth:`EnsembleRuns.run_members`, after the columns of
    :meth:`PerturbableForcing.perturbable_forcing`, one further column per key of :meth:`perturbable_levels`:
    an offset (m) added to that boundary's level during the interval (not a factor: a level has no natural
    zero). ``factors`` without those columns leaves the levels as they are.
    """

    def perturbable_levels(self) -> tuple[str, ...]:
        """The level boundaries that may be offset (``"boundary:<id>"``)."""
        ...


@runtime_checkable
class EnsembleRuns(Protocol):
    """Advances several members (each its state and perturbed forcing, shared parameters) in one call."""

    def run_members(self, parameters: Mapping[str, float] | None, start: Any, end: Any,
                    states: Sequence[ModelState], *,
                    factors: np.ndarray | None = None, interval: float | None = None,
                    output_interval: float | None = None, threads: int | None = None,
                    on_failure: Literal["raise", "report"] = "raise") -> MemberRuns:
        """Each member from its state; ``factors`` (members, intervals, forcing) as :class:`PerturbableForcing`."""
        ...


@dataclass(frozen=True)
class StateLayout:
    """Where the values of a state's arrays (:class:`StateArrays`) lie in the model's network.

    Attributes
    ----------
    levels
        Labels of the level points (calculation points, nodes), in array order.
    discharges
        Labels of the discharge points (links, conduits), in array order.
    link_ends
        Per discharge point, the level points at either end, shape (discharges, 2); -1 where there is none.
    link_length
        Per discharge point, the distance between its ends along the water, m.
    floor
        Per level point, the lowest level the water may take (the bed), m AD.
    places
        Per observable the level point it is measured at (a discharge: the upstream end of its link).
    forcing_places
        Per perturbable forcing (:class:`PerturbableForcing`) and level boundary (:class:`PerturbableLevels`) the
        level point where it enters.
    """

    levels: tuple[str, ...]
    discharges: tuple[str, ...]
    link_ends: np.ndarray
    link_length: np.ndarray
    floor: np.ndarray
    places: Mapping[str, int]
    forcing_places: Mapping[str, int] = field(default_factory=dict)


@runtime_checkable
class StateArrays(Protocol):
    """Its state as arrays of levels (m AD) and discharges (m³/s) that can be read and written back."""

    def state_layout(self) -> StateLayout:
        """Where each value of the arrays lies (:class:`StateLayout`)."""
        ...

    def state_arrays(self, state: ModelState) -> tuple[np.ndarray, np.ndarray]:
        """Levels (m AD) and discharges (m³/s) of a state, in the order of :meth:`state_layout`."""
        ...

    def with_state_arrays(self, state: ModelState, levels: np.ndarray, discharges: np.ndarray) -> ModelState:
        """A new state like ``state`` with these levels and discharges (the rest made consistent with them)."""
        ...


@runtime_checkable
class Snapshots(Protocol):
    """Gives the levels and discharges at every point of its network at the output times."""

    def simulate_fields(self, parameters: Mapping[str, float] | None = None, start: Any = None, end: Any = None,
                        state: ModelState | None = None, *,
                        output_interval: float | None = None) -> tuple[SimulationResult, ModelState]:
        """:meth:`~.contract.Model.simulate` whose result also holds ``levels`` (m AD) and ``discharges`` (m³/s)."""
        ...


@runtime_checkable
class FromCase(Protocol):
    """Was built from a rivercal case, whose network places its stations and draws its maps."""

    def source_case(self) -> Any:
        """The :class:`rivercal.case.Case` the model was built from."""
        ...


@dataclass(frozen=True)
class VariantInputs:
    """What a twin draws the errors of a variant on (:class:`Variants`).

    Attributes
    ----------
    branches
        Branch id → length, m.
    inherit
        The branches whose friction is the model's global friction (``friction:global`` sets them).
    catchments
        Ids of the catchments whose rainfall-runoff model feeds the model.
    rain
        The measured rain per hour (mm, UTC index) that feeds them, or None without catchments.
    forcing
        Per key of :meth:`PerturbableForcing.perturbable_forcing` the series the model runs with (m³/s, UTC
        index), which ``variant(forcing_factors=…)`` scales; None: not given. A twin puts the rain and runoff
        errors of a model without catchments on them (:func:`rivercal.twin.realism.inflow_factors`).
    """

    branches: Mapping[str, float]
    inherit: tuple[str, ...]
    catchments: tuple[str, ...]
    rain: pd.Series | None
    forcing: Mapping[str, pd.Series] | None = None


@runtime_checkable
class Variants(Protocol):
    """Makes a variant of itself for a twin's truth (:mod:`rivercal.models.variants`)."""

    def variant_inputs(self) -> VariantInputs:
        """The branches, catchments and rain a twin draws the variant's errors on."""
        ...

    def variant(self, *, branch_factors: Mapping[str, float] | None = None, grid_factor: float = 1.0,
                rain_factor: pd.Series | None = None, runoff_factors: Mapping[str, Mapping[str, float]] | None = None,
                forcing_factors: Mapping[str, pd.Series] | None = None) -> Model:
        """A model of the variant (friction factors per branch, grid factor, rain, runoff and forcing factors)."""
        ...


#: The optional capabilities by the name they are asked for (module docstring).
CAPABILITIES: dict[str, type] = {
    "batch runs": BatchRuns,
    "perturbable forcing": PerturbableForcing,
    "perturbable levels": PerturbableLevels,
    "ensemble runs": EnsembleRuns,
    "state arrays": StateArrays,
    "snapshots": Snapshots,
    "case": FromCase,
    "variants": Variants,
}


def has_capability(model: object, name: str) -> bool:
    """Whether ``model`` offers the capability ``name`` (a key of :data:`CAPABILITIES`)."""
    if name not in CAPABILITIES:
        raise KeyError(f"unknown model capability {name!r}; the capabilities are {', '.join(CAPABILITIES)}")
    return isinstance(model, CAPABILITIES[name])


def require(model: object, *names: str, purpose: str) -> None:
    """:class:`MissingCapability` unless ``model`` has every capability of ``names``.

    ``purpose`` says what needs them (``state updating``), for the message.
    """
    lacking = [n for n in names if not has_capability(model, n)]
    if lacking:
        kind = type(model).__name__
        raise MissingCapability(f"{purpose} needs a model with {' and '.join(repr(n) for n in names)}; model "
                                f"{getattr(model, 'name', '?')!r} ({kind}) lacks {' and '.join(map(repr, lacking))}")


def capability(model: object, name: str, *, purpose: str) -> Any:
    """``model`` itself once it is known to have the capability ``name`` (:func:`require`)."""
    require(model, name, purpose=purpose)
    return model


def run_members(model: Model, parameters: Mapping[str, float] | None, start: Any, end: Any,
                states: Sequence[ModelState], *,
                factors: np.ndarray | None = None, interval: float | None = None,
                output_interval: float | None = None, threads: int | None = None,
                on_failure: Literal["raise", "report"] = "raise",
                mapper: Any = None) -> MemberRuns:
    """Advance members from their states: the model's :class:`EnsembleRuns`, else one member after another.

    A model without :class:`EnsembleRuns` runs each member with :meth:`PerturbableForcing.simulate_perturbed`
    (with ``factors``) or :meth:`~rivercal.models.contract.Model.simulate`; ``mapper(fn, items)``, when given, maps
    the members' runs (e.g. over worker processes: ``fn(model, *item)``), else they run here in turn.
    """
    if isinstance(model, EnsembleRuns):
        return model.run_members(parameters, start, end, states, factors=factors, interval=interval,
                                 output_interval=output_interval, threads=threads, on_failure=on_failure)
    if factors is not None:
        require(model, "perturbable forcing", purpose="a run with perturbed forcing")
    items = [(parameters, start, end, s, None if factors is None else factors[m], interval, output_interval)
             for m, s in enumerate(states)]
    t0 = _time.perf_counter()
    outcomes = mapper(member_run, items) if mapper is not None else [member_run(model, *item) for item in items]
    values, out_states, failures, times = [], [], {}, None
    for m, outcome in enumerate(outcomes):
        if isinstance(outcome, ModelRunError):
            if on_failure == "raise":
                raise outcome
            failures[m] = str(outcome)
            values.append(None)
            out_states.append(None)
            continue
        series, state = outcome
        times = series.index if times is None else times
        values.append(series.to_numpy(dtype=float))
        out_states.append(state)
    if times is None:
        raise ModelRunError(f"every member failed; the first: {failures[min(failures)]}")
    shape = (len(times), len(model.observables))
    stack = np.stack([v if v is not None else np.full(shape, np.nan) for v in values])
    return MemberRuns(times=pd.DatetimeIndex(times), observables=tuple(model.observables), values=stack,
                      states=tuple(out_states), failures=failures, wall_time=_time.perf_counter() - t0)


def member_run(model: Model, parameters: Mapping[str, float] | None, start: Any, end: Any, state: ModelState | None,
               factors: np.ndarray | None, interval: float | None,
               output_interval: float | None) -> tuple[pd.DataFrame, Any] | ModelRunError:
    """One member's run for :func:`run_members` (its series and end state, or the run's error)."""
    try:
        if factors is not None:
            result, end_state = model.simulate_perturbed(parameters, start, end, state, factors, float(interval),
                                                         output_interval=output_interval)
        else:
            result, end_state = model.simulate(parameters, start, end, state, output_interval=output_interval)
    except ModelRunError as exc:
        return exc
    return result.series[list(model.observables)], end_state


@dataclass(frozen=True)
class Location:
    """A place where a model can simulate series although it has no station there (:class:`VirtualStations`).

    Attributes
    ----------
    id
        Station id of the place (no ``.``): its series are ``"<id>.<quantity>"``.
    quantities
        What a gauge there measures: ``h`` (level on a branch), ``h_up``/``h_down`` (level up-/downstream of
        a structure), ``Q`` (discharge); m AD and m³/s.
    name
        The place in words, for tables (``ZL12@1000.0``, ``upstream of weir ZL1-5``).
    branch, chainage
        Branch id and chainage (m from its start), where the place is on a branch.
    structure, side
        Structure id and ``up``/``down``, where the place is at a structure.
    point
        The model's label of the calculation point whose level the place measures (for maps), if any.
    x, y
        Map coordinates, m (None where the model has none).
    """

    id: str
    quantities: tuple[str, ...]
    name: str = ""
    branch: str | None = None
    chainage: float | None = None
    structure: str | None = None
    side: str | None = None
    point: str | None = None
    x: float | None = None
    y: float | None = None

    @property
    def series(self) -> tuple[str, ...]:
        """The series ids of the place, ``"<id>.<quantity>"``."""
        return tuple(f"{self.id}.{q}" for q in self.quantities)


@runtime_checkable
class VirtualStations(Protocol):
    """Optional capability: series at places where the model has no station (the embedded engine has it).

    A model with it offers its places (``where`` = ``points``: every calculation point; ``structures``:
    either side of every structure) for a gauge that measures ``level``, ``discharge`` or ``both``, leaving
    out what its stations already measure; a place on a branch at a chainage; a copy of itself that
    also simulates the series of given places; and a copy that keeps only some of its stations (an imported
    model has a station at every observation point and structure, of which only some are gauges). The
    copies' states are interchangeable with the model's (the places change what is written out, not what is
    computed).
    """

    def candidate_locations(self, where: str, measure: str) -> list[Location]:
        """The places of kind ``where`` (``points``, ``structures``) for a gauge measuring ``measure``."""
        ...

    def location_at(self, branch: str, chainage: float, *, id: str, measure: str, name: str = "") -> Location:
        """A place on ``branch`` at ``chainage`` (m); ValueError naming the branch or chainage when it is not."""
        ...

    def with_stations(self, locations: Iterable[Location]) -> Model:
        """A copy of the model that also simulates the series of ``locations``."""
        ...

    def only_stations(self, ids: Iterable[str]) -> Model:
        """A copy whose stations are only ``ids`` (the gauges of today): the others' places become candidates.

        ValueError naming an id that is not a station of the model.
        """
        ...
