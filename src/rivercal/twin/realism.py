"""Error models that make a twin experiment look like a water board's reality (seeded, reproducible).

An identical twin (thesis §4-2-3) shares everything with its truth: the engine, the grid, the
rainfall-runoff inflow, and its observations are exact. A realism level adds the errors of practice,
each in its own table:

``sensor`` (:class:`SensorErrors`)
    What the gauges add to the true levels and discharges: white noise, AR(1)-correlated noise,
    gaps (telemetry outages, per station), outliers (spikes, per value) and a slowly drifting level
    sensor.
``rain`` (:class:`RainErrors`)
    The true rain is the measured rain times a factor per rain event (lognormal, one factor for all
    hours of an event), run through the truth's rainfall-runoff model: the model keeps the measured
    rain, also in its forecasts. A model whose inflows are given series (no rainfall-runoff catchments:
    SWMM ``[INFLOWS]``, a BMI component) takes it on them instead (:func:`inflow_factors`): the flow above
    the flow at an event's start is that event's, and the truth's is the model's times the event's factor.
``runoff`` (:class:`RunoffErrors`)
    The truth's rainfall-runoff parameters differ from the model's a-priori ones by a lognormal
    factor per catchment and parameter; on given inflow series, one constant lognormal factor per series.
``structure`` (:class:`StructureErrors`)
    The truth runs on a finer grid, and each branch's friction differs from the global value by a
    lognormal factor (normalised so that their length-weighted mean is 1: the global value is the
    truth's mean friction).

The levels of :data:`REALISM_LEVELS`:

- ``ideal`` — none of them (the identical twin of thesis chapters 4 and 5);
- ``noisy`` — the sensor errors only;
- ``realistic`` — all four;
- ``realistic-forcing`` — those of ``realistic`` but the structural error: for a model whose structure a
  twin cannot vary (SWMM, BMI), and to compare the embedded engine with it under the same errors.

The magnitudes of ``noisy`` and ``realistic`` and where they come from are in ``docs/realism.md``. A
TOML file with the same tables (:func:`load_realism`) defines other levels. The same seed gives the same
errors; the errors of a series, a station, a rain event or a catchment are drawn from a generator of
their own (seed and name), on a time grid anchored at the model's start, so that two scenarios or two
periods of one model see the same errors where they overlap.
"""

from __future__ import annotations

import tomllib
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from rivercal.errors import CaseError

__all__ = [
    "REALISM_LEVELS",
    "RainErrors",
    "Realism",
    "RunoffErrors",
    "SensorErrors",
    "StructureErrors",
    "apply_sensor_errors",
    "event_factors",
    "generator",
    "get_realism",
    "inflow_event_starts",
    "inflow_factors",
    "layered_event_factors",
    "load_realism",
]


class _Table(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class SensorErrors(_Table):
    """Errors of the gauges, added to the true series.

    Levels (``h``, ``h_up``, ``h_down``) get absolute errors in m, discharges (``Q``) relative ones.
    AR(1) noise follows η_k = φ η_{k−1} + √(1 − φ²) σ ε_k per hour (stationary σ; φ for a step Δt
    other than an hour is φ^(Δt/1 h)).
    """

    level_white_m: float = Field(0.005, ge=0, description="σ of independent level noise, m")
    level_ar1_m: float = Field(0.010, ge=0, description="stationary σ of AR(1) level noise, m")
    ar1_phi: float = Field(0.9, ge=0, lt=1, description="lag-1 correlation of the AR(1) noise per hour, -")
    discharge_white_rel: float = Field(0.02, ge=0, description="σ of independent discharge noise, share of the value")
    discharge_ar1_rel: float = Field(0.05, ge=0,
                                     description="stationary σ of AR(1) discharge noise, share of the value")
    gap_fraction: float = Field(0.02, ge=0, lt=1, description="expected share of missing hours per station, -")
    gap_hours: float = Field(6.0, ge=1, description="mean length of an outage, h")
    outlier_rate: float = Field(0.002, ge=0, lt=1, description="probability that a value is a spike, -")
    outlier_level_m: tuple[float, float] = Field((0.10, 0.50), description="size range of a level spike, m")
    outlier_discharge_rel: tuple[float, float] = Field(
        (0.5, 1.0), description="size range of a discharge spike, share of the value")
    drift_series: int = Field(1, ge=0, description="number of level series whose sensor drifts")
    drift_m_per_day: float = Field(0.0003, ge=0,
                                   description="drift rate of those sensors, m per day since the model start")

    @model_validator(mode="after")
    def _ranges(self) -> SensorErrors:
        for name in ("outlier_level_m", "outlier_discharge_rel"):
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi:
                raise ValueError(f"{name}: need 0 <= low <= high, got ({lo}, {hi})")
        return self


class RainErrors(_Table):
    """Rainfall error of the truth: the measured rain times one lognormal factor per event."""

    sigma_ln: float = Field(0.15, ge=0, description="σ of ln(factor) per rain event, -")
    dry_hours: int = Field(6, ge=1, description="dry hours that separate two rain events, h")
    rise_rel: float = Field(0.001, gt=0, description="a model without rain: the rise of its total inflow in an hour, "
                                                     "as a share of the flow, that counts as an event's, -")


class RunoffErrors(_Table):
    """Rainfall-runoff parameter error of the truth: a lognormal factor per catchment and parameter."""

    sigma_ln: float = Field(0.2, ge=0, description="σ of ln(factor), -")
    parameters: tuple[str, ...] = Field(("c_w", "c_v", "c_g", "c_q"),
                                        description="rainfall-runoff parameters that differ (WalrusParameters names)")


class StructureErrors(_Table):
    """Structural difference of the truth: a finer grid and per-branch friction around the global value."""

    grid_factor: float = Field(0.5, gt=0, le=1, description="the truth's dx as a share of the model's, -")
    friction_sigma_ln: float = Field(0.1, ge=0, description="σ of ln(branch friction / global friction), -")


class Realism(_Table):
    """A realism level: which errors a twin's truth and observations carry (module docstring).

    Attributes
    ----------
    name, description
        For reports.
    sensor, rain, runoff, structure
        The error tables; None: no such error.
    """

    name: str = Field(min_length=1)
    description: str = ""
    sensor: SensorErrors | None = None
    rain: RainErrors | None = None
    runoff: RunoffErrors | None = None
    structure: StructureErrors | None = None

    @property
    def ideal(self) -> bool:
        """True when the level adds no error at all (an identical twin)."""
        return all(getattr(self, k) is None for k in ("sensor", "rain", "runoff", "structure"))

    @property
    def changes_truth(self) -> bool:
        """True when the truth itself differs from the model (rain, runoff or structure)."""
        return any(getattr(self, k) is not None for k in ("rain", "runoff", "structure"))

    def summary(self) -> dict[str, Any]:
        """A JSON-friendly description."""
        return self.model_dump(mode="json")


#: The realism levels by name (magnitudes and sources: docs/realism.md).
REALISM_LEVELS: dict[str, Realism] = {
    "ideal": Realism(name="ideal", description="identical twin: exact observations, the truth is the model"),
    "noisy": Realism(name="noisy", description="gauge errors: noise, outages, spikes, a drifting sensor",
                     sensor=SensorErrors()),
    "realistic": Realism(name="realistic",
                         description="gauge errors, rainfall and runoff-parameter errors, and a truth on a finer grid "
                                     "with friction varying per branch",
                         sensor=SensorErrors(), rain=RainErrors(), runoff=RunoffErrors(), structure=StructureErrors()),
    "realistic-forcing": Realism(name="realistic-forcing",
                                 description="gauge errors, rainfall and runoff-parameter errors (those of 'realistic' "
                                             "without its structural error)",
                                 sensor=SensorErrors(), rain=RainErrors(), runoff=RunoffErrors()),
}


def load_realism(path: str | Path) -> Realism:
    """A realism level from a TOML file with the tables ``[sensor]``, ``[rain]``, ``[runoff]``, ``[structure]``.

    A table that is absent adds no such error; a table that is present takes the defaults of
    :data:`REALISM_LEVELS` ``realistic`` for the keys it does not set. ``name`` and ``description`` are
    optional top-level keys (default: the file's stem).

    Raises
    ------
    CaseError
        For a file that cannot be read, is no TOML, or holds an unknown key or a bad value (named).
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise CaseError(f"cannot be read: {exc.strerror or exc}", file=str(path)) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise CaseError(f"not valid TOML: {exc}", file=str(path)) from None
    data.setdefault("name", path.stem)
    try:
        return Realism.model_validate(data)
    except ValidationError as exc:
        err = exc.errors(include_url=False)[0]
        field = ".".join(str(p) for p in err.get("loc", ()))
        raise CaseError(err.get("msg", "invalid value"), file=str(path), field=field or None) from None


def get_realism(level: str | Path | Realism) -> Realism:
    """A realism level by name (:data:`REALISM_LEVELS`), from a TOML file (:func:`load_realism`), or as given.

    Raises
    ------
    CaseError
        For a name that is neither a level nor an existing file, or a bad file.
    """
    if isinstance(level, Realism):
        return level
    if str(level) in REALISM_LEVELS:
        return REALISM_LEVELS[str(level)]
    if Path(level).is_file():
        return load_realism(level)
    raise CaseError(f"unknown realism {str(level)!r}: choose one of {', '.join(REALISM_LEVELS)} or give a TOML file "
                    "of error models")


# -- random numbers ---------------------------------------------------------------------------------------


def generator(seed: int, *names: str) -> np.random.Generator:
    """A generator of its own for ``seed`` and a name (a series, a station, a purpose): reproducible per name."""
    return np.random.default_rng([int(seed), *(zlib.crc32(n.encode()) for n in names)])


def _ar1(rng: np.random.Generator, n: int, sigma: float, phi: float) -> np.ndarray:
    """Stationary AR(1) noise of standard deviation ``sigma`` and lag-1 correlation ``phi`` (n values)."""
    out = np.empty(n)
    if n == 0:
        return out
    eps = rng.standard_normal(n)
    out[0] = sigma * eps[0]
    scale = sigma * np.sqrt(1.0 - phi * phi)
    for k in range(1, n):
        out[k] = phi * out[k - 1] + scale * eps[k]
    return out


# -- sensor errors ----------------------------------------------------------------------------------------


def apply_sensor_errors(frame: pd.DataFrame, errors: SensorErrors, seed: int, origin: pd.Timestamp,
                        interval_s: float = 3600.0) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The observed series: true series plus the errors of the gauges.

    Parameters
    ----------
    frame
        True series, one column ``"<station>.<quantity>"`` each (m AD or m³/s), indexed by UTC times on
        the grid ``origin + k · interval_s``.
    errors
        The sensor errors.
    seed
        Seed; the errors of a series depend on the seed, the series id and the time only.
    origin
        Start of the time grid the errors are drawn on (the model's start), UTC.
    interval_s
        Step of that grid, s.

    Returns
    -------
    (observed, kinds)
        ``observed``: the frame with errors, NaN where a value is missing (an outage); ``kinds``: a frame
        of the same shape saying what each value is: ``ok``, ``outlier``, ``gap`` (and ``drift`` for the
        values of a drifting sensor that are not outliers or gaps).

    Raises
    ------
    ValueError
        For times off the grid or before ``origin``.
    """
    origin = pd.Timestamp(origin)
    steps = (frame.index - origin).total_seconds().to_numpy() / interval_s
    k = np.round(steps).astype(np.int64)
    if len(k) and (np.any(np.abs(steps - k) > 1e-9) or k.min() < 0):
        raise ValueError(f"the series' times must lie on the {interval_s:g} s grid from {origin.isoformat()}")
    n = int(k.max()) + 1 if len(k) else 0
    phi = errors.ar1_phi ** (interval_s / 3600.0)
    observed = frame.copy()
    kinds = pd.DataFrame("ok", index=frame.index, columns=frame.columns)
    levels = [c for c in frame.columns if str(c).rpartition(".")[2] != "Q"]
    drifting = set()
    if errors.drift_series and levels:
        pick = generator(seed, "drift").choice(len(levels), size=min(errors.drift_series, len(levels)), replace=False)
        drifting = {levels[i] for i in np.atleast_1d(pick)}
    days = k * interval_s / 86400.0
    for col in frame.columns:
        # one generator per stream: a stream's first values do not depend on how many are drawn, so a
        # shorter period sees the same errors where it overlaps a longer one
        def rng(stream: str, col: str = str(col)) -> np.random.Generator:
            return generator(seed, "sensor", col, stream)

        white, ar1 = rng("white").standard_normal(n)[k], _ar1(rng("ar1"), n, 1.0, phi)[k]
        spike, size = rng("spike").random(n)[k], rng("size").random(n)[k]
        sign = np.where(rng("sign").random(n)[k] < 0.5, -1.0, 1.0)
        true = frame[col].to_numpy(float)
        if col in levels:
            values = true + errors.level_white_m * white + errors.level_ar1_m * ar1
            if col in drifting:
                values = values + errors.drift_m_per_day * days
                kinds.loc[:, col] = "drift"
            lo, hi = errors.outlier_level_m
            outlier = sign * (lo + (hi - lo) * size)
        else:
            values = true * (1.0 + errors.discharge_white_rel * white + errors.discharge_ar1_rel * ar1)
            lo, hi = errors.outlier_discharge_rel
            outlier = sign * (lo + (hi - lo) * size) * np.abs(true)
        hit = spike < errors.outlier_rate
        values = np.where(hit, values + outlier, values)
        kinds.loc[hit, col] = "outlier"
        observed[col] = values
    for station in dict.fromkeys(str(c).rpartition(".")[0] for c in frame.columns):
        missing = _outages(generator(seed, "outage", station), n, errors.gap_fraction,
                           errors.gap_hours * 3600.0 / interval_s)[k]
        cols = [c for c in frame.columns if str(c).rpartition(".")[0] == station]
        observed.loc[missing, cols] = np.nan
        kinds.loc[missing, cols] = "gap"
    return observed, kinds


def _outages(rng: np.random.Generator, n: int, fraction: float, mean_steps: float) -> np.ndarray:
    """A mask of n steps with outages: starts at rate fraction/mean, lengths geometric with that mean."""
    mask = np.zeros(n, dtype=bool)
    if fraction <= 0 or n == 0:
        return mask
    p_start = fraction / mean_steps / max(1e-12, 1.0 - fraction)
    starts = rng.random(n) < p_start
    lengths = np.random.default_rng(rng.bit_generator.seed_seq.spawn(1)[0]).geometric(1.0 / mean_steps, n)
    for i in np.flatnonzero(starts):
        mask[i:i + int(lengths[i])] = True
    return mask


# -- rain events ------------------------------------------------------------------------------------------


def _events(active: np.ndarray, gap: int) -> tuple[np.ndarray, int]:
    """Per step the index of its event (-1 outside one) and the number of events.

    An event is a run of active steps together with the inactive spells inside it that are shorter than
    ``gap`` steps; events are counted from the first step.
    """
    event = np.full(active.size, -1)
    count, idle, current = 0, gap, -1
    for i, a in enumerate(active):
        if a:
            if idle >= gap:
                current, count = count, count + 1
            event[i] = current
            idle = 0
        else:
            idle += 1
    return event, count


def _event_epsilons(seed: int, count: int) -> np.ndarray:
    """The standard normal ε_j of the rain events j = 0 … count − 1 (generator of (seed, "rain"))."""
    return generator(seed, "rain").standard_normal(max(count, 1))


def event_factors(rain: pd.Series, errors: RainErrors, seed: int) -> pd.Series:
    """One lognormal factor (median 1) per rain event of an hourly rain series; 1 in dry hours.

    An event is a run of wet hours (rain > 0) together with the dry spells inside it that are shorter
    than ``errors.dry_hours``. Event j (counted from the series' start) takes exp(σ ε_j) with ε_j from
    the generator of (seed, "rain").
    """
    event, count = _events(rain.to_numpy(float) > 0, errors.dry_hours)
    eps = _event_epsilons(seed, count)
    factors = np.where(event >= 0, np.exp(errors.sigma_ln * eps[np.maximum(event, 0)]), 1.0)
    return pd.Series(factors, index=rain.index, name="rain_factor")


# -- rain and runoff errors on given inflow series (a model without rainfall-runoff catchments) -------------


def _hourly(forcing: Mapping[str, pd.Series]) -> pd.DataFrame:
    """The series on one hourly UTC grid over all of them, linear in time between their points (ends held)."""
    first = min(s.index[0] for s in forcing.values()).floor("h")
    last = max(s.index[-1] for s in forcing.values()).ceil("h")
    hours = pd.date_range(first, last, freq="h")
    at = (hours - first).total_seconds().to_numpy()
    return pd.DataFrame({key: np.interp(at, (s.index - first).total_seconds().to_numpy(), s.to_numpy(float))
                         for key, s in forcing.items()}, index=hours)


def inflow_event_starts(forcing: Mapping[str, pd.Series], errors: RainErrors,
                        rain: pd.Series | None = None) -> pd.DatetimeIndex:
    """The start times of the rain events behind a model's inflow series (UTC, in order).

    With the model's ``rain`` (mm per hour, UTC index): the first hour of each rain event
    (:func:`event_factors`). Without it, the inflows' own rises stand for the rain: an hour in which the
    total inflow rises by more than ``errors.rise_rel`` of its value is "wet", events are runs of them
    apart by at least ``errors.dry_hours`` hours, and an event starts at the hour before its first rise
    (the flow before the event).
    """
    if rain is not None:
        event, _ = _events(rain.to_numpy(float) > 0, errors.dry_hours)
        first = np.flatnonzero((event >= 0) & (np.r_[-1, event[:-1]] != event))
        return pd.DatetimeIndex(rain.index[first])
    frame = _hourly(forcing)
    total = frame.sum(axis=1).to_numpy()
    rise = np.r_[False, np.diff(total) > errors.rise_rel * np.abs(total[:-1])]
    event, _ = _events(rise, errors.dry_hours)
    first = np.flatnonzero((event >= 0) & (np.r_[-1, event[:-1]] != event))
    return pd.DatetimeIndex(frame.index[np.maximum(first - 1, 0)])


def layered_event_factors(flow: np.ndarray, starts: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """Per step Q*/Q: the flow above each event's start flow is that event's and is scaled by its factor.

    Event j starts at step ``starts[j]`` (ascending) with the flow b_j there: from then on the flow above
    b_j, up to the start flow of a later event still under way, is event j's (the constant-discharge
    separation of a hydrograph, one layer per event; an event whose start flow the flow has fallen below
    when a later one starts is over). The truth's flow is Q* = Q + Σ_j (F_j − 1) · layer_j; it is
    continuous in time, as the layer of a starting event is empty. Steps with Q ≤ 0 keep 1.

    Parameters
    ----------
    flow
        Q per step, m³/s (any unit: only shares count).
    starts
        Step index of each event's start.
    factors
        F_j per event, -.
    """
    flow = np.asarray(flow, dtype=float)
    out = np.ones(flow.size)
    begins = dict(zip(np.asarray(starts, dtype=int).tolist(), np.asarray(factors, dtype=float).tolist(),
                      strict=True))
    stack: list[tuple[float, float]] = []  # (start flow, factor) of the events under way, start flows rising
    for k, q in enumerate(flow):
        if k in begins:
            while stack and stack[-1][0] >= q:
                stack.pop()
            stack.append((q, begins[k]))
        if q <= 0:
            continue
        extra = 0.0
        for i, (base, f) in enumerate(stack):
            top = stack[i + 1][0] if i + 1 < len(stack) else np.inf
            layer = min(q, top) - base
            if layer <= 0:
                break
            extra += (f - 1.0) * layer
        out[k] = 1.0 + extra / q
    return out


def inflow_factors(forcing: Mapping[str, pd.Series], seed: int, *, rain: RainErrors | None = None,
                   runoff: RunoffErrors | None = None, measured_rain: pd.Series | None = None) -> dict[str, pd.Series]:
    """The rain and runoff errors of a twin's truth on given inflow series: a factor series per inflow.

    For a model without rainfall-runoff catchments, whose inflows are given series (SWMM ``[INFLOWS]``,
    a BMI component's forcing):

    - ``runoff``: each series times one constant factor exp(σ ε), ε from the generator of
      (seed, "runoff", key): the runoff error of a catchment, on the series it makes;
    - ``rain``: one factor F_j = exp(σ ε_j) per rain event (ε_j from the generator of (seed, "rain"), as
      for the rain of catchments) on every series, applied to the flow the event adds
      (:func:`layered_event_factors`); the events from ``measured_rain`` if given, else from the total
      inflow's rises (:func:`inflow_event_starts`).

    Parameters
    ----------
    forcing
        Per forcing key the series (m³/s, UTC index) the model runs with.
    seed
        Seed of the errors.
    rain, runoff
        The error tables; None: no such error.
    measured_rain
        The rain behind the inflows (mm per hour, UTC index), or None.

    Returns
    -------
    dict
        Per key a factor series (-) on an hourly grid over the series (for ``variant(forcing_factors=…)``).
    """
    frame = _hourly(forcing)
    out = {key: pd.Series(1.0, index=frame.index, name=key) for key in forcing}
    if rain is not None:
        starts = inflow_event_starts(forcing, rain, measured_rain)
        steps = np.searchsorted(frame.index, starts)
        keep = steps < len(frame.index)
        eps = _event_epsilons(seed, len(starts))[:len(starts)]
        steps, f = steps[keep], np.exp(rain.sigma_ln * eps[keep])
        steps, first = np.unique(steps, return_index=True)  # two rain events in one hour of the grid: the first
        for key in forcing:
            out[key] = out[key] * layered_event_factors(frame[key].to_numpy(), steps, f[first])
    if runoff is not None:
        for key in forcing:
            out[key] = out[key] * float(np.exp(runoff.sigma_ln * generator(seed, "runoff", key).standard_normal()))
    return out
