"""Observations checked against the model before the service stores them: known series, plausible values.

A delivery of observations is refused (:class:`~rivercal.errors.CaseError` naming the file and the series)
when

- a series is not one the model simulates: an unknown station, or a quantity the model does not give
  there (the message lists what the model has);
- most of a series' values lie outside the range the model makes plausible there (:class:`PlausibleRange`):
  a unit (levels in cm, discharges in l/s), another datum, or a no-data code such as ``-999`` — the
  message gives the range and, where the values are a known multiple of the model's, the likely unit.

A few values outside the range (a sensor's spike, a code for a missing value) do not refuse the delivery:
they are stored flagged as outliers and left out, like the spikes the ingestion's screening finds
(:meth:`rivercal.store.Store.ingest` with ``plausible``).

The plausible range of a series comes from the model's own run of the data period with the DSS's
quantities, and judges only the values inside that period (a file may hold months before it, a flood the
period's levels say nothing about, which no cycle uses and which are stored unjudged). For a level (``h``,
``h_up``, ``h_down``, m AD) it is the simulated levels widened by :data:`LEVEL_MARGIN_M` or by their own
range, whichever is larger (a level metres below the lowest the model ever simulates there lies below the
bed); for a discharge (``Q``, m³/s) up to :data:`DISCHARGE_FACTOR` times the largest simulated discharge plus
:data:`DISCHARGE_FLOOR`, in either direction. The margins are wide on purpose: they catch units and
datums, not model error.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from rivercal.errors import CaseError
from rivercal.models.contract import Model, spun_up
from rivercal.observations import ObservationSet

if TYPE_CHECKING:
    from rivercal.online.config import OnlineConfig

__all__ = ["DISCHARGE_FACTOR", "DISCHARGE_FLOOR", "LEVEL_MARGIN_M", "REFUSE_SHARE", "PlausibleRange",
           "check_delivery", "check_series", "data_end", "plausible_ranges"]

log = logging.getLogger(__name__)

#: Smallest widening of the simulated levels of a series, m.
LEVEL_MARGIN_M = 3.0
#: Largest observed discharge, as a multiple of the largest simulated one (plus :data:`DISCHARGE_FLOOR`).
DISCHARGE_FACTOR = 10.0
#: Added to the discharge bound, m³/s (a stream the model keeps nearly dry may still carry some water).
DISCHARGE_FLOOR = 1.0
#: A series whose share of values outside its plausible range is larger than this refuses the delivery.
REFUSE_SHARE = 0.5
#: Multiples of the model's values that mean another unit: (factor, what the values are likely in).
_UNIT_FACTORS = {"level": ((100.0, "cm"), (1000.0, "mm"), (1 / 0.3048, "feet"), (10.0, "dm")),
                 "discharge": ((1000.0, "l/s"), (3600.0, "m³/h"), (60.0, "m³/min"), (1 / 0.0283168, "cfs"))}


@dataclass(frozen=True)
class PlausibleRange:
    """The values of a series that the model makes plausible (module docstring).

    Attributes
    ----------
    series
        ``"<station>.<quantity>"``.
    low, high
        The plausible range, m AD (levels) or m³/s (discharges).
    simulated_low, simulated_high
        The model's own range over the data period, same unit.
    simulated_median
        The median of the model's values, same unit (for the unit hint).
    start, end
        The period of the model's run (UTC): only values inside it are judged.
    """

    series: str
    low: float
    high: float
    simulated_low: float
    simulated_high: float
    simulated_median: float
    start: pd.Timestamp
    end: pd.Timestamp

    @property
    def unit(self) -> str:
        """The unit of the values: m AD for levels, m³/s for discharges."""
        return "m³/s" if self.series.rpartition(".")[2] == "Q" else "m AD"

    def judged(self, times: pd.DatetimeIndex) -> np.ndarray:
        """Which of ``times`` (UTC) lie in the period of the model's run, whose values the range judges."""
        return np.asarray((times >= self.start) & (times <= self.end), dtype=bool)

    def outside(self, values: np.ndarray, times: pd.DatetimeIndex | None = None) -> np.ndarray:
        """Which of ``values`` lie outside the range (a boolean mask); with ``times``, only those in its period."""
        v = np.asarray(values, dtype=float)
        out = (v < self.low) | (v > self.high)
        return out & self.judged(times) if times is not None else out

    def bounds(self) -> tuple[float, float, pd.Timestamp, pd.Timestamp]:
        """The range as the store takes it (:meth:`rivercal.store.Store.ingest`, ``plausible``)."""
        return self.low, self.high, self.start, self.end

    def describe(self) -> str:
        """The range in words, with where it comes from."""
        what = (f"the model's own levels there, {self.simulated_low:.2f} to {self.simulated_high:.2f} m AD, widened"
                if self.unit == "m AD" else
                f"up to {DISCHARGE_FACTOR:g} times the model's largest discharge there "
                f"({max(abs(self.simulated_low), abs(self.simulated_high)):.3g} m³/s)")
        return (f"{self.low:.4g} to {self.high:.4g} {self.unit} ({what}; for the values from "
                f"{self.start:%Y-%m-%d %H:%M} to {self.end:%Y-%m-%d %H:%M}, the period the model ran)")


def plausible_ranges(model: Model, series: Iterable[str], start: Any, end: Any, quantities: Mapping[str, float],
                     output_interval: float) -> dict[str, PlausibleRange]:
    """The plausible range of each series from the model's run of [start, end] (UTC) with ``quantities``.

    The run starts from the model's state at ``start`` after a cold start at its own start
    (:func:`~rivercal.models.contract.spun_up`, kept on disk by the embedded engine); ``output_interval`` in s.
    Series the run does not give, or gives without a finite value, get no range.
    """
    start, end = pd.Timestamp(start), pd.Timestamp(end)
    state = spun_up(model, dict(quantities), start) if start > model.start else None
    result, _ = model.simulate(dict(quantities), start=start, end=end, state=state, output_interval=output_interval)
    out: dict[str, PlausibleRange] = {}
    for sid in series:
        if sid not in result.series.columns:
            continue
        values = result.series[sid].to_numpy(dtype=float)
        values = values[np.isfinite(values)]
        if values.size == 0:
            continue
        lo, hi, median = float(values.min()), float(values.max()), float(np.median(values))
        if sid.rpartition(".")[2] == "Q":
            bound = DISCHARGE_FACTOR * max(abs(lo), abs(hi)) + DISCHARGE_FLOOR
            out[sid] = PlausibleRange(sid, -bound, bound, lo, hi, median, start, end)
        else:
            margin = max(LEVEL_MARGIN_M, hi - lo)
            out[sid] = PlausibleRange(sid, lo - margin, hi + margin, lo, hi, median, start, end)
    return out


def check_series(observations: ObservationSet, observables: Iterable[str], file: str, model_name: str) -> None:
    """CaseError naming the file and the series when a series cannot be stored for this model.

    A series the model does not simulate (the message names the column and the model's ids), or a time
    the store cannot keep: a fraction of a second, or a year beyond what pandas holds (1677 to 2262).
    """
    known = list(observables)
    stations = sorted({s.rpartition(".")[0] for s in known})
    for s in observations:
        sid = s.id
        column = _column(file, sid)
        if sid not in known:
            station = sid.rpartition(".")[0]
            if station in stations:
                there = ", ".join(k for k in known if k.rpartition(".")[0] == station)
                reason = f"model {model_name!r} does not simulate {sid!r}; at station {station} it has {there}"
            else:
                reason = (f"station {station!r} is not in model {model_name!r}; its stations are "
                          f"{', '.join(stations) or 'none'}")
            raise CaseError(reason + " (nothing of this file was stored)", file=file, field=column)
        if len(s) == 0:
            continue
        lo, hi = pd.Timestamp.min.tz_localize("UTC"), pd.Timestamp.max.tz_localize("UTC")
        outside = (s.times < lo) | (s.times > hi)
        if outside.any():
            raise CaseError(f"time {s.times[outside][0]:%Y-%m-%d %H:%M:%S} lies outside the times rivercal can hold "
                            f"({lo:%Y} to {hi:%Y}) (nothing of this file was stored)", file=file, field=column)
        fraction = s.times != s.times.floor("s")
        if fraction.any():
            raise CaseError(f"time {s.times[fraction][0].isoformat()} has a fraction of a second; the store keeps "
                            "whole seconds (nothing of this file was stored)", file=file, field=column)


def check_delivery(observations: ObservationSet, file: str, ranges: Mapping[str, PlausibleRange]) -> list[str]:
    """Check the values of a delivery against the plausible ranges; notes on the few values outside.

    Returns
    -------
    list of str
        One note per series with values outside its range that are few enough to be flagged (stored as
        outliers and left out).

    Raises
    ------
    CaseError
        Naming the file and the series when more than :data:`REFUSE_SHARE` of a series' values lie outside,
        with the range and the likely unit.
    """
    notes = []
    for s in observations:
        rng = ranges.get(s.id)
        if rng is None or len(s) == 0:
            continue
        outside = rng.outside(s.values, s.times)
        n = int(outside.sum())
        if n == 0:
            continue
        inside_period = rng.judged(s.times)
        judged = int(inside_period.sum())
        if n > REFUSE_SHARE * judged:
            median = float(np.median(s.values[inside_period]))
            raise CaseError(f"{n} of {judged} values lie outside the plausible range {rng.describe()}; their median is "
                            f"{median:.6g}{_unit_hint(rng, median)} (nothing of this file was stored)", file=file,
                            field=_column(file, s.id))
        first = s.times[outside][0]
        notes.append(f"{file}: {_column(file, s.id)}: {n} of {judged} values outside the plausible range "
                     f"{rng.describe()} (first {float(s.values[outside][0]):.6g} at {first:%Y-%m-%d %H:%M}): "
                     "stored as outliers, left out")
    return notes


def _column(file: str, sid: str) -> str:
    """How a message names a series of a file: a CSV column or a PI-XML series."""
    if file.lower().endswith(".xml"):
        station, _, quantity = sid.rpartition(".")
        return f"series locationId={station} parameterId={quantity}"
    return f"column {sid!r}"


def _unit_hint(rng: PlausibleRange, median: float) -> str:
    """'; they look like cm (100 times the model's levels)' where the values are a known multiple of the model's."""
    if not (math.isfinite(median) and rng.simulated_median):
        return ""
    kind = "discharge" if rng.unit == "m³/s" else "level"
    ratio = median / rng.simulated_median
    for factor, unit in _UNIT_FACTORS[kind]:
        if abs(ratio / factor - 1.0) < 0.15:
            return (f"; they look like {unit} ({ratio:.4g} times the model's {rng.simulated_median:.4g} "
                    f"{rng.unit}): give {kind}s in {rng.unit.replace(' AD', '')}")
    if kind == "level" and abs(median - rng.simulated_median) > LEVEL_MARGIN_M:
        return (f" against the model's {rng.simulated_median:.4g} m AD: levels in m above the model's datum are "
                "expected (not depths or another datum)")
    return ""


def data_end(model: Model, config: OnlineConfig, first: pd.Timestamp, last: pd.Timestamp) -> pd.Timestamp:
    """The end of the observations the cycles from ``first`` to ``last`` use: the last forecast's, within the model."""
    period = pd.Timedelta(config.period)
    final = first + ((last - first) // period) * period if last >= first else first
    return min(final + pd.Timedelta(config.horizon), model.end)
