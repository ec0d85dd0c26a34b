"""The model contract: what the calibration core, the on-line service and the analyses see of a model.

Every model — the embedded engine, an external program behind the black box, EPA SWMM, a BMI model,
the transition wrapper — declares:

- ``name``, its period ``start`` … ``end`` (UTC), its time step ``dt`` (s) and the default
  ``output_interval`` (s) of its series;
- ``quantities``: the model quantities a calibration may set, each a :class:`Quantity` with its unit
  and, where the model knows them, bounds. Parameters target these names and nothing else;
- ``observables``: the series it simulates, named ``<station>.<quantity>`` (``h``, ``h_up``, ``h_down``
  in m; ``Q`` in m³/s);
- ``calibration``: the calibration setup it ships with (:class:`CalibrationSetup`: named parameters,
  windows, the default optimiser and its options), possibly empty;
- optionally ``numerical_noise``: the jitter of its series under a tiny parameter change, in their units
  (m, m³/s) — a solver's convergence tolerance — so that difference steps stand above it; a model
  without it is taken to have none known;
- optionally (the capability :class:`VirtualStations`) series at places where it has no station: the
  places it offers (every calculation point, either side of every structure), a place at a chainage of a
  branch, and a copy of itself that also simulates the series of such places;
- how its state is saved and restored: ``state_format`` (a tag stored beside the bytes),
  ``save_state(state) -> bytes`` and ``load_state(data, fmt) -> state``. A state carries its simulated
  ``time``. Models whose state lives in files (a SWMM hotstart file, restart files of an external
  program) keep the files' bytes in a :class:`FileState`;

and runs::

    simulate(parameters, start=None, end=None, state=None, *, output_interval=None)
        -> (SimulationResult, state at end)

with ``parameters`` a mapping of quantity names to values (the rest keep the model's own values),
``start``/``end`` defaulting to the model's period and ``state`` a state at ``start`` (None: the model's
cold start). A run that cannot be completed raises :class:`~rivercal.errors.ModelRunError`, never
returns NaN. The result is a :class:`~rivercal.results.SimulationResult` (its water balance optional).

Optional capabilities
---------------------
What only some models can do is declared beside :class:`Model` as a protocol of its own, and asked for by
name (:func:`capability`, :func:`require`); a model without it gets a :class:`MissingCapability` error that
names what it lacks and what needed it:

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
"""

from __future__ import annotations

import io
import math
import time as _time
import zipfile
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol, runtime_checkable

import numpy as np
import pandas as pd

from rivercal._time import utc
from rivercal.errors import ModelRunError, OptionError
from rivercal.parameters import Parameter
from rivercal.results import SimulationResult

__all__ = [
    "CAPABILITIES",
    "BatchRuns",
    "CalibrationSetup",
    "EnsembleRuns",
    "ExternalRunError",
    "FileState",
    "FromCase",
    "Location",
    "MemberRuns",
    "MissingCapability",
    "Model",
    "ModelState",
    "PerturbableForcing",
    "PerturbableLevels",
    "Quantity",
    "RunRequest",
    "Snapshots",
    "StateArrays",
    "StateLayout",
    "VariantInputs",
    "Variants",
    "VirtualStations",
    "capability",
    "check_parameters",
    "check_run",
    "check_settable",
    "has_capability",
    "require",
    "run_members",
    "spun_up",
    "utc",
]


@dataclass(frozen=True)
class Quantity:
    """A model quantity that a calibration may set.

    Attributes
    ----------
    name
        The name parameters target (``weir:W1.crest_level``, ``roughness:factor``, ``FA`` …).
    unit
        Unit of the value (``m AD``, ``m^(1/3)/s``, ``-`` …).
    min, max
        Bounds of the value where the model knows them (None: unbounded on that side).
    description
        One line for users.
    """

    name: str
    unit: str = ""
    min: float | None = None
    max: float | None = None
    description: str = ""

    def check(self, value: float) -> float:
        """The value as a float, or ValueError naming the quantity when it is not finite or out of bounds."""
        value = float(value)
        if not math.isfinite(value):
            raise ValueError(f"{self.name}: value {value} is not finite")
        if (self.min is not None and value < self.min) or (self.max is not None and value > self.max):
            raise ValueError(f"{self.name}: value {value:g} {self.unit} is outside its range "
                             f"[{_bound(self.min)}, {_bound(self.max)}] {self.unit}".rstrip())
        return value


@dataclass(frozen=True)
class CalibrationSetup:
    """The calibration a model ships with (from ``case.toml`` or ``model.toml``).

    Attributes
    ----------
    parameters
        Named calibration parameters (targets are the model's quantities).
    windows
        Named calibration windows, (start, end) in UTC.
    algorithm
        Default optimiser (a name of :data:`rivercal.optimise.OPTIMISERS`).
    options
        Options of that optimiser.
    """

    parameters: tuple[Parameter, ...] = ()
    windows: Mapping[str, tuple[pd.Timestamp, pd.Timestamp]] = field(default_factory=dict)
    algorithm: str = "dud"
    options: Mapping[str, Any] = field(default_factory=dict)

    def parameter(self, name: str) -> Parameter:
        """The parameter called ``name``; KeyError naming the defined ones otherwise."""
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"unknown parameter {name!r}; the model defines {', '.join(self.names) or 'none'}")

    @property
    def names(self) -> list[str]:
        """Names of the defined parameters."""
        return [p.name for p in self.parameters]


@runtime_checkable
class ModelState(Protocol):
    """A model's state: whatever the model keeps, with the simulated time it belongs to (UTC)."""

    time: pd.Timestamp


@runtime_checkable
class Model(Protocol):
    """The model contract (module docstring)."""

    name: str
    observables: list[str]

    @property
    def start(self) -> pd.Timestamp: ...  # noqa: D102

    @property
    def end(self) -> pd.Timestamp: ...  # noqa: D102

    @property
    def dt(self) -> float: ...  # noqa: D102

    @property
    def output_interval(self) -> float: ...  # noqa: D102

    @property
    def quantities(self) -> Mapping[str, Quantity]: ...  # noqa: D102

    @property
    def calibration(self) -> CalibrationSetup: ...  # noqa: D102

    @property
    def state_format(self) -> str: ...  # noqa: D102

    def default_parameters(self) -> dict[str, float]:
        """The model's own values of the quantities it knows (name → value)."""
        ...

    def simulate(self, parameters: Mapping[str, float] | None = None, start: Any = None, end: Any = None,
                 state: ModelState | None = None, *,
                 output_interval: float | None = None) -> tuple[SimulationResult, ModelState]:
        """Run from ``start`` to ``end``; return (SimulationResult, state at ``end``)."""
        ...

    def save_state(self, state: ModelState) -> bytes:
        """A state as bytes (tagged :attr:`state_format`)."""
        ...

    def load_state(self, data: bytes, fmt: str) -> ModelState:
        """A state from :meth:`save_state` bytes; ValueError when they are not this model's."""
        ...


# -- optional capabilities --------------------------------------------------------------------------------


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
        """:meth:`Model.simulate` with the forcing scaled by ``factors`` (class docstring)."""
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
        """:meth:`Model.simulate` whose result also holds ``levels`` (m AD) and ``discharges`` (m³/s)."""
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
    (with ``factors``) or :meth:`Model.simulate`; ``mapper(fn, items)``, when given, maps the members'
    runs (e.g. over worker processes: ``fn(model, *item)``), else they run here in turn.
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


@dataclass(frozen=True)
class FileState:
    """A model state that lives in files: their bytes by file name, and the simulated time.

    Attributes
    ----------
    time
        Simulated time of the state (UTC).
    files
        File name (no folders) → contents.
    origin
        What wrote it (a model's name and kind), checked when the state is loaded.
    """

    time: pd.Timestamp
    files: Mapping[str, bytes]
    origin: str = ""

    def to_bytes(self) -> bytes:
        """One zip archive with the files and a ``rivercal-state.txt`` that holds time and origin."""
        buffer = io.BytesIO()
        with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as z:
            z.writestr("rivercal-state.txt", f"{self.time.isoformat()}\n{self.origin}\n")
            for name, data in sorted(self.files.items()):
                z.writestr(f"files/{name}", data)
        return buffer.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes, origin: str = "") -> FileState:
        """Read :meth:`to_bytes`; ValueError for other bytes or, when ``origin`` is given, another origin."""
        try:
            with zipfile.ZipFile(io.BytesIO(data)) as z:
                when, _, stored = z.read("rivercal-state.txt").decode("utf-8").partition("\n")
                files = {n[len("files/"):]: z.read(n) for n in z.namelist() if n.startswith("files/")}
        except (zipfile.BadZipFile, KeyError, UnicodeDecodeError) as exc:
            raise ValueError(f"not a rivercal file-state archive ({exc})") from None
        stored = stored.strip()
        if origin and stored != origin:
            raise ValueError(f"the state was written by {stored!r}, not by {origin!r}")
        return cls(time=utc(when), files=files, origin=stored)


def spun_up(model: Model, parameters: Mapping[str, float] | None, at: Any) -> ModelState:
    """The model's state at ``at`` after a cold start at its own start with ``parameters``.

    That is ``model.simulate(parameters, end=at)[1]``; a model that offers ``state_at(parameters, at)`` (the
    embedded engine: :meth:`rivercal.engine.Simulator.state_at`) answers it from the spin-ups it ran
    before, and from those that this machine's processes kept on disk (:mod:`rivercal.models.spinups`).
    """
    if getattr(model, "state_at", None) is not None:
        from rivercal.models.spinups import cached_state_at

        return cached_state_at(model, parameters, at)
    return model.simulate(parameters, end=at)[1]


def check_settable(model: Model, quantities: Iterable[str], *, what: str = "") -> None:
    """ValueError unless the model declares every name in ``quantities`` as settable.

    ``what`` says where the names come from (``parameter FA``), for the message.
    """
    declared = model.quantities
    for name in quantities:
        if name not in declared:
            known = sorted(declared)
            shown = ", ".join(known[:12]) + (f" … ({len(known)} in all)" if len(known) > 12 else "")
            raise ValueError(f"{what + ': ' if what else ''}model {getattr(model, 'name', '?')!r} has no settable "
                             f"quantity {name!r} (it has: {shown or 'none'})")


def check_parameters(model: Model, parameters: Iterable[Parameter], fixed: Iterable[str] = ()) -> None:
    """Check parameters and fixed quantities against the quantities a model declares.

    Raises ValueError unless every target of ``parameters`` and every ``fixed`` name is settable in the
    model, and each parameter's range keeps its targets inside the bounds the model declares for them.
    """
    declared = model.quantities
    for p in parameters:
        low, high = p.quantities(p.min), p.quantities(p.max)
        check_settable(model, low, what=f"parameter {p.name}")
        for target in low:
            q = declared[target]
            for value in (low[target], high[target]):
                try:
                    q.check(value)
                except ValueError as exc:
                    raise ValueError(f"parameter {p.name}: its range [{p.min:g}, {p.max:g}] {p.unit} reaches "
                                     f"outside the model's bounds ({exc})".replace("  ", " ")) from None
    check_settable(model, fixed, what="fixed quantity")


class ExternalRunError(ModelRunError):
    """A run of a model that works in a run folder failed; names the folder (kept) and the cause."""

    #: How the message names the run (``SWMM run``, ``external model run``).
    what = "model run"

    def __init__(self, run_dir: str, cause: str):
        self.run_dir = run_dir
        self.cause = cause
        super().__init__(f"{self.what} in {run_dir} failed: {cause}")

    def __reduce__(self):  # keep the fields when the error crosses a process boundary
        return (type(self), (self.run_dir, self.cause))


@dataclass(frozen=True)
class RunRequest:
    """A run's checked arguments (:func:`check_run`): quantities, period (UTC) and output interval (s)."""

    parameters: dict[str, float]
    start: pd.Timestamp
    end: pd.Timestamp
    interval: float


def check_run(model: Model, parameters: Mapping[str, float] | None, start: Any, end: Any, state: ModelState | None,
              output_interval: float | None) -> RunRequest:
    """The checks every adapter makes before a run, in one place.

    Every quantity is declared and inside its bounds, the period defaults to the model's and is a positive
    multiple of the output interval (default the model's), and a state is at the run's start.

    Raises
    ------
    ValueError
        Naming the quantity, the period or the state's time.
    """
    values = dict(parameters or {})
    check_settable(model, values)
    declared = model.quantities
    values = {key: declared[key].check(value) for key, value in values.items()}
    start = model.start if start is None else utc(start)
    end = model.end if end is None else utc(end)
    interval = float(output_interval or model.output_interval)
    steps = (end - start).total_seconds() / interval
    if not end > start or abs(steps - round(steps)) > 1e-9:
        raise ValueError(f"the period {start} .. {end} must be a positive multiple of the output interval "
                         f"({interval:g} s)")
    if state is not None and state.time != start:
        raise ValueError(f"the state is at {state.time}, the run starts at {start}")
    return RunRequest(values, start, end, interval)


def _bound(value: float | None) -> str:
    return "…" if value is None else f"{value:g}"
