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
- optionally (the capability :class:`~rivercal.models.capabilities.VirtualStations`) series at places where it has
  no station: the places it offers (every calculation point, either side of every structure), a place at a chainage
  of a branch, and a copy of itself that also simulates the series of such places;
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

What only some models can do (runs in batches, perturbed forcing, states as arrays, snapshots, variants …)
are optional capabilities, each a protocol of its own in :mod:`rivercal.models.capabilities`.
"""

from __future__ import annotations

import io
import math
import zipfile
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import pandas as pd

from rivercal._time import utc
from rivercal.errors import ModelRunError
from rivercal.parameters import Parameter
from rivercal.results import SimulationResult

__all__ = [
    "CalibrationSetup",
    "ExternalRunError",
    "FileState",
    "Model",
    "ModelState",
    "Quantity",
    "RunRequest",
    "check_parameters",
    "check_run",
    "check_settable",
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
