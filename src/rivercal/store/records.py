"""What the store takes and gives back: records, the cycle schedule and the store's errors.

Nothing here touches the database (only :mod:`rivercal.store.sqlite` imports ``sqlite3``). Times
are pandas Timestamps in UTC; a naive time is read as UTC, the convention of
:mod:`rivercal.observations`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

import pandas as pd

from rivercal._time import utc
from rivercal.errors import RivercalError

__all__ = [
    "CYCLE_STATUSES",
    "FINAL_STATUSES",
    "FORECAST_KINDS",
    "OBSERVATION_FLAGS",
    "RUN_STATUSES",
    "AlertRecord",
    "BandRecord",
    "CycleRecord",
    "CycleSpec",
    "CycleStateError",
    "EstimateRecord",
    "IngestResult",
    "Run",
    "Schedule",
    "StoreError",
    "StoreVersionError",
    "TransitionRecord",
]

#: Status of a cycle. ``pending`` and ``running`` are unfinished (a restarted service resumes them);
#: ``done``, ``failed`` and ``aborted`` are final and are only ever written by
#: :meth:`Store.commit_cycle <rivercal.store.sqlite.Store.commit_cycle>`, together with the cycle's results.
CYCLE_STATUSES = ("pending", "running", "done", "failed", "aborted")
#: Final cycle statuses (see :data:`CYCLE_STATUSES`).
FINAL_STATUSES = ("done", "failed", "aborted")
#: Status of a run.
RUN_STATUSES = ("active", "stopped", "finished", "failed")
#: Forecast kinds: with the cycle's updated parameters, and with the fixed parameters of the DSS.
FORECAST_KINDS = ("updated", "dss")
#: Flags of a stored observation: ``ok``, or ``outlier`` (a spike found at ingestion; kept, not used).
OBSERVATION_FLAGS = ("ok", "outlier")


class StoreError(RivercalError):
    """The store cannot do what was asked (bad file, wrong state, inconsistent input)."""


class StoreVersionError(StoreError):
    """The file's schema version cannot be used by this rivercal (newer file, or read-only and older)."""


class RunMismatchError(StoreError):
    """A run of that name exists with another model or configuration: resuming it would mix two set-ups."""


class CycleStateError(StoreError):
    """A cycle is not in a state that allows the operation (already final, owned by a live process, a gap)."""


@dataclass(frozen=True)
class Run:
    """A stored run of the on-line service.

    Attributes
    ----------
    id
        Database id.
    name
        Unique name (``"dommel-2010"``).
    case
        Case name or path the run serves.
    created
        When the run was created (UTC).
    config
        The run's configuration, as stored (JSON object).
    status
        One of :data:`RUN_STATUSES`.
    """

    id: int
    name: str
    case: str
    created: pd.Timestamp
    config: dict[str, Any]
    status: str


@dataclass(frozen=True)
class CycleSpec:
    """Which cycle to compute: its index, calibration window and forecast issue time.

    Attributes
    ----------
    cycle
        Cycle index, 0, 1, 2, ... within its run (contiguous).
    window_start, window_end
        Calibration window [start, end] (UTC).
    issue_time
        Forecast issue time t₀ (UTC); normally ``window_end``.
    status
        Stored status (``pending`` for a cycle not stored yet).
    attempts
        How many times the cycle was begun before (0 for a new cycle).
    """

    cycle: int
    window_start: pd.Timestamp
    window_end: pd.Timestamp
    issue_time: pd.Timestamp
    status: str = "pending"
    attempts: int = 0

    def __post_init__(self) -> None:
        object.__setattr__(self, "window_start", utc(self.window_start))
        object.__setattr__(self, "window_end", utc(self.window_end))
        object.__setattr__(self, "issue_time", utc(self.issue_time))
        if self.cycle < 0:
            raise ValueError(f"cycle index must be >= 0, got {self.cycle}")
        if not self.window_end > self.window_start:
            raise ValueError(f"cycle {self.cycle}: window end {self.window_end} is not after its start "
                             f"{self.window_start}")


_ONE_DAY = pd.Timedelta(days=1)
_ONE_WEEK = pd.Timedelta(days=7)
_TWO_DAYS = pd.Timedelta(hours=48)


@dataclass(frozen=True)
class Schedule:
    """When cycles run (thesis §6-2: a daily cycle over a one-week window).

    Cycle 0 is issued at ``first_issue``; each later cycle ``period`` after the previous stored one. The
    calibration window of a cycle issued at t₀ is [t₀ − ``window``, t₀]; its forecasts run to
    t₀ + ``horizon``.

    Attributes
    ----------
    first_issue
        Issue time of cycle 0 (UTC).
    period
        Time between cycles (default 1 day).
    window
        Calibration window length (default 7 days).
    horizon
        Forecast horizon (default 48 h).
    """

    first_issue: pd.Timestamp
    period: pd.Timedelta = _ONE_DAY
    window: pd.Timedelta = _ONE_WEEK
    horizon: pd.Timedelta = _TWO_DAYS

    def __post_init__(self) -> None:
        object.__setattr__(self, "first_issue", utc(self.first_issue))
        for name in ("period", "window", "horizon"):
            value = pd.Timedelta(getattr(self, name))
            if not value > pd.Timedelta(0):
                raise ValueError(f"schedule {name} must be positive, got {value}")
            object.__setattr__(self, name, value)

    def spec(self, cycle: int, issue_time: Any | None = None) -> CycleSpec:
        """The spec of cycle ``cycle`` issued at ``issue_time`` (default: ``first_issue + cycle * period``)."""
        t0 = utc(issue_time) if issue_time is not None else self.first_issue + cycle * self.period
        return CycleSpec(cycle=cycle, window_start=t0 - self.window, window_end=t0, issue_time=t0)


@dataclass(frozen=True)
class EstimateRecord:
    """One parameter's estimate in one cycle.

    Attributes
    ----------
    parameter
        Parameter name (``"friction:global"``, ``"weirs"``).
    value
        Estimated value, in ``unit`` (the optimiser's estimate, also when it was not accepted).
    unit
        Unit of ``value`` and ``std`` (``"m"``, ``"m1/3 s-1"``, ``"1"`` for dimensionless).
    std
        Standard deviation of the estimate (thesis Eq. 2-12), in ``unit``; None if unknown.
    accepted
        Whether the estimate was accepted (passed to the forecast and to the next cycle's warm start).
    reason
        Why it was held or rejected; required when ``accepted`` is False.
    """

    parameter: str
    value: float
    unit: str
    std: float | None = None
    accepted: bool = True
    reason: str | None = None

    def __post_init__(self) -> None:
        if not self.parameter:
            raise ValueError("estimate: empty parameter name")
        if not math.isfinite(self.value):
            raise ValueError(f"estimate {self.parameter}: value must be finite, got {self.value}")
        if self.std is not None and not (math.isfinite(self.std) and self.std >= 0):
            raise ValueError(f"estimate {self.parameter}: std must be finite and >= 0, got {self.std}")
        if not self.accepted and not self.reason:
            raise ValueError(f"estimate {self.parameter}: a held or rejected estimate needs a reason")


@dataclass(frozen=True)
class AlertRecord:
    """An alert raised by a cycle (a probable intervention, a failed calibration, stale data, ...).

    Attributes
    ----------
    kind
        What kind of alert (``"jump"``, ``"bound"``, ``"failed"``, ...); free text chosen by the service.
    message
        What happened, in words.
    parameter
        The parameter concerned, or None for an alert about the whole cycle.
    magnitude
        Size of the change in standard deviations of the estimate, |Δθ| / σ (dimensionless), if known.
    """

    kind: str
    message: str
    parameter: str | None = None
    magnitude: float | None = None

    def __post_init__(self) -> None:
        if not self.kind or not self.message:
            raise ValueError("alert: kind and message must not be empty")
        if self.magnitude is not None and not math.isfinite(self.magnitude):
            raise ValueError(f"alert {self.kind}: magnitude must be finite, got {self.magnitude}")


@dataclass(frozen=True)
class TransitionRecord:
    """A change of a parameter inside a cycle's window (thesis §6-3), as the cycle estimated it.

    Attributes
    ----------
    parameter
        Parameter name.
    time
        Estimated time of the change (UTC).
    before, after
        Values before and after the change, in ``unit``.
    unit
        Unit of the values.
    found_cycle
        The cycle that found the change; later cycles whose window still holds it keep this index (one
        intervention, updated while the window slides over it).
    cost_single, cost_transition, p_value
        Costs S (dimensionless) of the one-value and the transition fit and the F-test's p-value of the
        cycle that found it (None in later cycles).
    """

    parameter: str
    time: pd.Timestamp
    before: float
    after: float
    unit: str
    found_cycle: int
    cost_single: float | None = None
    cost_transition: float | None = None
    p_value: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "time", utc(self.time))
        if not self.parameter:
            raise ValueError("transition: empty parameter name")
        if not (math.isfinite(self.before) and math.isfinite(self.after)):
            raise ValueError(f"transition {self.parameter}: values must be finite, got {self.before}, {self.after}")
        if self.found_cycle < 0:
            raise ValueError(f"transition {self.parameter}: found_cycle must be >= 0, got {self.found_cycle}")


@dataclass(frozen=True)
class BandRecord:
    """The uncertainty band of a cycle's ``updated`` forecast (e.g. an ensemble's spread).

    Attributes
    ----------
    low, high
        Frames like the forecast's (time index at or after the issue time, UTC; one column per series), m AD
        or m³/s: the observation is expected between them with ``probability``. NaN values are not stored.
    probability
        The band's probability (0.9: the 5 % and 95 % quantiles).
    """

    low: pd.DataFrame
    high: pd.DataFrame
    probability: float = 0.9

    def __post_init__(self) -> None:
        if not 0.0 < self.probability < 1.0:
            raise ValueError(f"a band's probability must be between 0 and 1, got {self.probability}")
        if not (self.low.index.equals(self.high.index) and list(self.low.columns) == list(self.high.columns)):
            raise ValueError("a band's low and high frames must have the same times and series")


@dataclass(frozen=True)
class CycleRecord:
    """Everything one cycle produced; :meth:`Store.commit_cycle` stores it in one transaction.

    Attributes
    ----------
    cycle
        Cycle index.
    window_start, window_end, issue_time
        As in :class:`CycleSpec` (UTC).
    status
        Final status: ``done``, ``failed`` or ``aborted``.
    algorithm
        Optimiser name (``"dud"``).
    model_runs
        Number of model runs the cycle used.
    wall_time_s
        Wall time of the cycle's computation, s (default: from begin to commit).
    cost_before, cost_after
        Cost S(θ) of thesis Eq. 2-3 (dimensionless) at the warm start and at the estimate.
    message
        Optimiser termination message, or why the cycle failed or was aborted.
    estimates
        One record per parameter.
    alerts
        Alerts raised by the cycle.
    forecasts
        Forecasts by kind (``"updated"``, ``"dss"``): frames indexed by time (UTC, at or after
        ``issue_time``), one column per series ``"<station>.<quantity>"`` in m AD (levels) or m³/s
        (discharges). NaN values are not stored. Store the output step you want to score at (hourly,
        15 min); a 60-s engine step would store 2,881 values per series per cycle.
    states
        Model states handed to the next cycle, by name: (time (UTC), format, data bytes). The store
        keeps them opaque (see :meth:`EngineState.to_bytes <rivercal.engine.EngineState.to_bytes>`).
    scores
        Scores of the forecasts of earlier cycles, computed by this cycle (columns cycle, kind, series,
        lead_from_h, lead_to_h, rmse, bias, n, as :func:`rivercal.online.metrics.score_forecasts` gives
        them); stored in the same transaction, replacing the earlier scores of each cycle listed, so that
        a kill between the commit and the scoring cannot leave a cycle unscored.
    transitions
        Changes of parameters inside the window that the cycle estimated or carried on.
    issued, issued_reason
        Which forecast the cycle issued (``updated`` or ``dss``; None: not decided) and why.
    skill_updated, skill_dss
        The rolling forecast skill behind that choice: RMSE (m) of recent level forecasts of each kind
        (None when nothing was scored).
    ensemble
        The ensemble of state updating handed to the next cycle: (time (UTC), members, format, data bytes),
        opaque to the store. The store keeps the latest per run: it replaces the run's ensemble in this
        cycle's transaction (unless a later cycle's is stored).
    bands
        The uncertainty band of the ``updated`` forecast.
    """

    cycle: int
    window_start: pd.Timestamp
    window_end: pd.Timestamp
    issue_time: pd.Timestamp
    status: str = "done"
    algorithm: str | None = None
    model_runs: int | None = None
    wall_time_s: float | None = None
    cost_before: float | None = None
    cost_after: float | None = None
    message: str | None = None
    estimates: tuple[EstimateRecord, ...] = ()
    alerts: tuple[AlertRecord, ...] = ()
    forecasts: Mapping[str, pd.DataFrame] = field(default_factory=dict)
    states: Mapping[str, tuple[Any, str, bytes]] = field(default_factory=dict)
    scores: pd.DataFrame | None = None
    transitions: tuple[TransitionRecord, ...] = ()
    issued: str | None = None
    issued_reason: str | None = None
    skill_updated: float | None = None
    skill_dss: float | None = None
    ensemble: tuple[Any, int, str, bytes] | None = None
    bands: BandRecord | None = None

    def __post_init__(self) -> None:
        if self.issued is not None and self.issued not in FORECAST_KINDS:
            raise ValueError(f"cycle {self.cycle}: issued forecast must be one of {FORECAST_KINDS}, "
                             f"got {self.issued!r}")
        for name in ("skill_updated", "skill_dss"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value >= 0):
                raise ValueError(f"cycle {self.cycle}: {name} must be finite and >= 0, got {value}")
        for name, value in self.states.items():
            if not name or len(value) != 3 or not isinstance(value[2], bytes | bytearray) or not value[1]:
                raise ValueError(f"cycle {self.cycle}: state {name!r} must be (time, format, bytes)")
        if self.ensemble is not None and (len(self.ensemble) != 4 or not isinstance(self.ensemble[3], bytes | bytearray)
                                          or not self.ensemble[2] or not int(self.ensemble[1]) > 0):
            raise ValueError(f"cycle {self.cycle}: the ensemble must be (time, members > 0, format, bytes)")
        spec = CycleSpec(self.cycle, self.window_start, self.window_end, self.issue_time)
        for name in ("window_start", "window_end", "issue_time"):
            object.__setattr__(self, name, getattr(spec, name))
        object.__setattr__(self, "estimates", tuple(self.estimates))
        object.__setattr__(self, "alerts", tuple(self.alerts))
        if self.status not in FINAL_STATUSES:
            raise ValueError(f"cycle {self.cycle}: status must be one of {', '.join(FINAL_STATUSES)} when "
                             f"committed, got {self.status!r}")
        names = [e.parameter for e in self.estimates]
        if len(set(names)) != len(names):
            raise ValueError(f"cycle {self.cycle}: a parameter is estimated twice in {names}")
        unknown = set(self.forecasts) - set(FORECAST_KINDS)
        if unknown:
            raise ValueError(f"cycle {self.cycle}: forecast kinds must be among {FORECAST_KINDS}, got "
                             f"{sorted(unknown)}")
        if self.model_runs is not None and self.model_runs < 0:
            raise ValueError(f"cycle {self.cycle}: model_runs must be >= 0, got {self.model_runs}")
        if self.wall_time_s is not None and not self.wall_time_s >= 0:
            raise ValueError(f"cycle {self.cycle}: wall_time_s must be >= 0, got {self.wall_time_s}")

    @property
    def spec(self) -> CycleSpec:
        """The cycle's index, window and issue time."""
        return CycleSpec(self.cycle, self.window_start, self.window_end, self.issue_time)


@dataclass(frozen=True)
class IngestResult:
    """What :meth:`Store.ingest` did; unpacks as ``inserted, duplicates = store.ingest(...)``.

    Attributes
    ----------
    inserted
        Values stored.
    duplicates
        Values whose (series, time, source) was already stored, so not inserted again.
    conflicts
        The duplicates whose value differs from the stored one (beyond 1e-9 relative); the stored value
        was kept, or replaced with ``on_conflict="replace"``.
    outliers
        Values of the ingested series (new or stored, around the new ones) flagged as outliers after
        this ingestion (with a screening rule).
    gaps
        Gaps in the ingested series around the new values, as stored after this ingestion.
    """

    inserted: int
    duplicates: int
    conflicts: int = 0
    outliers: int = 0
    gaps: int = 0

    def __iter__(self) -> Iterator[int]:
        return iter((self.inserted, self.duplicates))
