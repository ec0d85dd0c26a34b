"""Observation series: what was measured, when, and how much each value counts.

An :class:`ObservationSeries` is named like the simulated series it is compared with,
``"<station>.<quantity>"`` (quantity ``h``, ``h_up``, ``h_down`` in m AD, ``Q`` in m³/s). Its values
are at UTC times; missing values (NaN) are dropped when the series is made and counted in
``n_missing``, never treated as zero. Each series has a weight per thesis Eq. 2-3: either a standard
deviation σ (W = 1/σ²) or, when σ is None, the weight of thesis Eq. 2-6, W = 1/Δŷ²_max, where Δŷ_max is
the largest absolute difference between the observations and a prior simulation (set by the
calibration problem from its first run).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from rivercal._time import utc_index

__all__ = ["CF_VARIABLES", "DEFAULT_SIGMA", "CFVariable", "ObservationSeries", "ObservationSet", "ScreenRule",
           "measurable", "screen_outliers"]

#: Default standard deviations by quantity: ±2.5 cm for levels and ±0.1 m³/s for discharges, the noise
#: amplitudes of the reference study's twin experiments (thesis §4-2-3).
DEFAULT_SIGMA = {"h": 0.025, "h_up": 0.025, "h_down": 0.025, "Q": 0.1}
QUANTITIES = ("h", "h_up", "h_down", "Q")


def measurable(series_ids: Iterable[str]) -> list[str]:
    """The series among ``series_ids`` that stations measure (``h``, ``h_up``, ``h_down``, ``Q``), in their order.

    A model may simulate more (e.g. the crests of controlled weirs, ``<weir>.crest``); twin experiments and the
    on-line service observe these by default.
    """
    return [s for s in series_ids if str(s).rpartition(".")[2] in QUANTITIES]


@dataclass(frozen=True)
class CFVariable:
    """How series of some quantities are written to CF-1.8 NetCDF: one variable over a dimension of series ids.

    Attributes
    ----------
    name
        Variable name (``water_level``).
    dimension
        Name of the dimension whose coordinate holds the series ids ``"<station>.<quantity>"``.
    quantities
        The quantities it holds (``h``, ``h_up``, ``h_down``).
    units, standard_name
        CF units and standard name.
    """

    name: str
    dimension: str
    quantities: tuple[str, ...]
    units: str
    standard_name: str

    def attrs(self, long_name: str) -> dict[str, str]:
        """The variable's attributes, with a ``long_name`` that says what the values are."""
        return {"standard_name": self.standard_name, "units": self.units, "long_name": long_name}

    def columns(self, series_ids: Iterable[str]) -> list[str]:
        """The series ids among ``series_ids`` that this variable holds, in their order."""
        return [s for s in series_ids if str(s).rpartition(".")[2] in self.quantities]


#: Levels (m) and discharges (m³/s) in CF-1.8 NetCDF files (simulations, forecasts).
CF_VARIABLES = (
    CFVariable("water_level", "level_series", ("h", "h_up", "h_down"), "m",
               "water_surface_height_above_reference_datum"),
    CFVariable("discharge", "discharge_series", ("Q",), "m3 s-1", "water_volume_transport_in_river_channel"),
)


@dataclass(frozen=True)
class ObservationSeries:
    """One observed series.

    Attributes
    ----------
    id
        ``"<station>.<quantity>"``.
    times
        UTC times (DatetimeIndex, strictly increasing), without the missing values.
    values
        Observed values, m AD (levels) or m³/s (discharges); finite.
    sigma
        Standard deviation, same unit as the values, or None for the thesis Eq. 2-6 weight.
    n_missing
        Number of missing values that were dropped.
    source
        Where the values came from (file, twin truth, ...), for reports.
    """

    id: str
    times: pd.DatetimeIndex
    values: np.ndarray
    sigma: float | None = None
    n_missing: int = 0
    source: str = ""

    @classmethod
    def from_series(cls, series: pd.Series, *, id: str | None = None, sigma: float | None = None,
                    source: str = "") -> ObservationSeries:
        """Make a series from a pandas Series indexed by time, dropping (and counting) missing values.

        Raises
        ------
        ValueError
            For a bad id, a non-increasing or non-UTC-convertible index, or a non-positive σ.
        """
        name = id or str(series.name)
        station, _, quantity = name.rpartition(".")
        if not station or quantity not in QUANTITIES:
            shown = repr(name) if len(name) <= 80 else f"{name[:60]!r}… ({len(name)} characters)"
            raise ValueError(f"observation id {shown} must be '<station>.<quantity>' with quantity one of "
                             f"{', '.join(QUANTITIES)}")
        if sigma is not None and not sigma > 0:
            raise ValueError(f"{name}: sigma must be positive, got {sigma}")
        index = utc_index(series.index)
        values = pd.to_numeric(pd.Series(series.to_numpy()), errors="coerce").to_numpy(dtype=float)
        if index.has_duplicates or not index.is_monotonic_increasing:
            raise ValueError(f"{name}: times must be strictly increasing")
        keep = np.isfinite(values)
        return cls(id=name, times=index[keep], values=values[keep], sigma=sigma,
                   n_missing=int((~keep).sum()), source=source)

    @property
    def station(self) -> str:
        """Station id."""
        return self.id.rpartition(".")[0]

    @property
    def quantity(self) -> str:
        """Quantity: ``h``, ``h_up``, ``h_down`` or ``Q``."""
        return self.id.rpartition(".")[2]

    def __len__(self) -> int:
        return int(self.values.size)

    def within(self, start: pd.Timestamp, end: pd.Timestamp) -> ObservationSeries:
        """The part of the series in [start, end]."""
        keep = (self.times >= start) & (self.times <= end)
        return replace(self, times=self.times[keep], values=self.values[keep])

    def to_series(self) -> pd.Series:
        """As a pandas Series (m AD or m³/s) indexed by UTC time."""
        return pd.Series(self.values, index=self.times, name=self.id)

    def __repr__(self) -> str:
        sigma = "Eq. 2-6 weight" if self.sigma is None else f"σ={self.sigma:g}"
        period = _period(self.times)
        return f"ObservationSeries({self.id!r}, {len(self)} values{period}, {sigma}, {self.n_missing} missing)"


@dataclass(frozen=True)
class ObservationSet:
    """Observation series by id, in a fixed order (the order of the residual vector).

    Attributes
    ----------
    series
        The series.
    """

    series: tuple[ObservationSeries, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        ids = [s.id for s in self.series]
        if len(set(ids)) != len(ids):
            raise ValueError(f"duplicate observation series in {ids}")

    @classmethod
    def from_frame(cls, frame: pd.DataFrame, *, sigma: Mapping[str, float | None] | None = None,
                   source: str = "") -> ObservationSet:
        """One series per column ``"<station>.<quantity>"`` of a frame indexed by time.

        ``sigma`` maps a series id or a quantity (``h``, ``Q``, ...) to σ; default :data:`DEFAULT_SIGMA`.
        """
        sigma = dict(sigma if sigma is not None else DEFAULT_SIGMA)
        out = []
        for col in frame.columns:
            quantity = str(col).rpartition(".")[2]
            s = sigma.get(str(col), sigma.get(quantity))
            out.append(ObservationSeries.from_series(frame[col], id=str(col), sigma=s, source=source))
        return cls(tuple(out))

    def __iter__(self) -> Iterator[ObservationSeries]:
        return iter(self.series)

    def __len__(self) -> int:
        return len(self.series)

    def __getitem__(self, series_id: str) -> ObservationSeries:
        for s in self.series:
            if s.id == series_id:
                return s
        raise KeyError(f"no observation series {series_id!r} (have: {', '.join(self.ids)})")

    @property
    def ids(self) -> list[str]:
        """Series ids in order."""
        return [s.id for s in self.series]

    @property
    def n_values(self) -> int:
        """Total number of observed values."""
        return sum(len(s) for s in self.series)

    @property
    def n_missing(self) -> int:
        """Total number of dropped missing values."""
        return sum(s.n_missing for s in self.series)

    def within(self, start: pd.Timestamp, end: pd.Timestamp) -> ObservationSet:
        """The parts of all series in [start, end]."""
        return ObservationSet(tuple(s.within(start, end) for s in self.series))

    def select(self, ids: Iterable[str]) -> ObservationSet:
        """The series with these ids, in this order."""
        return ObservationSet(tuple(self[i] for i in ids))

    def to_frame(self) -> pd.DataFrame:
        """All series as one frame (outer join on time; NaN where a series has no value)."""
        return pd.concat([s.to_series() for s in self.series], axis=1, sort=True) if self.series else pd.DataFrame()

    def __repr__(self) -> str:
        times = pd.DatetimeIndex([]).tz_localize("UTC")
        for s in self.series:
            times = times.union(s.times[[0, -1]]) if len(s) else times
        return f"ObservationSet({len(self)} series, {self.n_values} values{_period(times)}, {self.n_missing} missing)"

    def summary(self) -> pd.DataFrame:
        """The series as a table, one row per series id.

        Columns ``values``, ``missing``, ``sigma`` (m AD or m³/s; NaN: the weight of thesis Eq. 2-6), ``first``
        and ``last`` (UTC) and ``source``.

        Examples
        --------
        >>> frame = pd.DataFrame({"S1.h": [1.0, None, 1.2]},
        ...                      index=pd.date_range("2020-01-01", periods=3, freq="h", tz="UTC"))
        >>> ObservationSet.from_frame(frame).summary()[["values", "missing", "sigma"]]
              values  missing  sigma
        series
        S1.h       2        1  0.025
        """
        rows = [{"series": s.id, "values": len(s), "missing": s.n_missing,
                 "sigma": np.nan if s.sigma is None else s.sigma,
                 "first": s.times[0] if len(s) else pd.NaT, "last": s.times[-1] if len(s) else pd.NaT,
                 "source": s.source} for s in self.series]
        columns = ["series", "values", "missing", "sigma", "first", "last", "source"]
        return pd.DataFrame(rows, columns=columns).set_index("series")


def _period(times: pd.DatetimeIndex) -> str:
    """`` from … to …`` of the first and last time (UTC, minutes), or nothing without times."""
    if not len(times):
        return ""
    return f" {times.min():%Y-%m-%d %H:%M} … {times.max():%Y-%m-%d %H:%M} UTC"

# -- screening ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ScreenRule:
    """How ingestion finds spikes in a series: a Hampel filter over a moving time window.

    A value is an outlier when it differs from the median of the values within ``half_window_h`` of it
    (itself included) by more than max(``k`` · 1.4826 · MAD, floor), MAD being the median absolute
    deviation from that median. The floor keeps the smooth rise and fall of a flood wave, whose MAD is
    small, from being flagged: ``level_floor_m`` for levels, and for discharges the larger of
    ``discharge_floor`` (m³/s) and ``discharge_floor_rel`` times the median. A value with fewer than
    ``min_values`` values in its window (itself included) is not judged.

    A spike is also short and stands out from its neighbours: a value that passes that test is flagged only when
    it lies in a block of at most ``max_run`` consecutive values that all differ from the value just before and
    the value just after the block by more than their thresholds, in the value's direction (for a discharge,
    also by more than ``discharge_floor_rel`` times that neighbour). A discharge that a pump or a
    rainfall-runoff delivery switches between nothing and a few m³/s, or a level held for an hour, has windows
    whose median and MAD are those of the other state, so the Hampel test alone flags every value of the
    shorter state; such a value lies close to a neighbour of its own state.

    Attributes
    ----------
    half_window_h
        Half width of the window, h.
    k
        Multiple of the robust standard deviation 1.4826 · MAD, -.
    level_floor_m, discharge_floor, discharge_floor_rel
        Smallest deviation that counts, m, m³/s, share of the median.
    min_values
        Fewest values in a window to judge its middle one.
    max_run
        Most consecutive values that still count as one spike.
    """

    half_window_h: float = 3.0
    k: float = 5.0
    level_floor_m: float = 0.08
    discharge_floor: float = 0.05
    discharge_floor_rel: float = 0.3
    min_values: int = 5
    max_run: int = 2

    def __post_init__(self) -> None:
        if not (self.half_window_h > 0 and self.k > 0 and self.min_values >= 3 and self.max_run >= 1):
            raise ValueError("screen rule: half_window_h and k must be positive, min_values at least 3 and "
                             "max_run at least 1")
        if min(self.level_floor_m, self.discharge_floor, self.discharge_floor_rel) < 0:
            raise ValueError("screen rule: the floors must not be negative")


def screen_outliers(times: pd.DatetimeIndex | np.ndarray, values: np.ndarray, quantity: str,
                    rule: ScreenRule | None = None) -> np.ndarray:
    """Which values of a series are spikes (:class:`ScreenRule`); a boolean mask like ``values``.

    Parameters
    ----------
    times
        Increasing times (UTC DatetimeIndex, or int64 seconds).
    values
        The values, m AD (``h``, ``h_up``, ``h_down``) or m³/s (``Q``); finite.
    quantity
        The quantity of the series (sets the floor).
    rule
        The rule (default :class:`ScreenRule`).

    Examples
    --------
    >>> t = pd.date_range("2010-11-01", periods=9, freq="h", tz="UTC")
    >>> v = np.array([1.00, 1.01, 1.02, 1.03, 1.54, 1.05, 1.06, 1.07, 1.08])
    >>> screen_outliers(t, v, "h").nonzero()[0].tolist()
    [4]
    >>> q = np.array([0.0, 0.0, 0.0, 0.0, 3.1, 3.0, 3.1, 0.0, 0.0])  # a pump on for three hours
    >>> screen_outliers(t, q, "Q").nonzero()[0].tolist()
    []
    """
    rule = rule or ScreenRule()
    v = np.asarray(values, dtype=float)
    if isinstance(times, pd.DatetimeIndex):
        seconds = times.as_unit("s").asi8.astype(np.int64)
    else:
        seconds = np.asarray(times, dtype=np.int64)
    n = v.size
    out = np.zeros(n, dtype=bool)
    if n < rule.min_values:
        return out
    half = round(rule.half_window_h * 3600)
    lo = np.searchsorted(seconds, seconds - half, side="left")
    hi = np.searchsorted(seconds, seconds + half, side="right")
    side = np.zeros(n, dtype=np.int8)  # +1 above its window's median by more than the threshold, -1 below
    threshold = np.zeros(n)
    for i in range(n):
        if hi[i] - lo[i] < rule.min_values:
            continue
        window = v[lo[i]:hi[i]]
        med = float(np.median(window))
        mad = float(np.median(np.abs(window - med)))
        if quantity == "Q":
            floor = max(rule.discharge_floor, rule.discharge_floor_rel * abs(med))
        else:
            floor = rule.level_floor_m
        threshold[i] = max(rule.k * 1.4826 * mad, floor)
        if abs(v[i] - med) > threshold[i]:
            side[i] = 1 if v[i] > med else -1
    # a Hampel candidate is a spike when it lies in a block of at most max_run candidates of its side that all
    # stand out from the values just before and just after the block
    for i in np.flatnonzero(side):
        out[i] = any(_stands_out(v, side, a, a + size, threshold, quantity, rule)
                     for size in range(1, rule.max_run + 1) for a in range(max(0, i - size + 1), min(i, n - size) + 1))
    return out


def _stands_out(v: np.ndarray, side: np.ndarray, a: int, b: int, threshold: np.ndarray, quantity: str,
                rule: ScreenRule) -> bool:
    """Whether the block ``v[a:b]`` is a spike (:class:`ScreenRule`).

    Its values all passed the Hampel test on one side (``side``: +1 above, -1 below), and each differs from
    ``v[a - 1]`` and ``v[b]`` (those that exist) by more than its threshold in that direction; for a discharge,
    also by more than ``discharge_floor_rel`` times the neighbour (the Hampel threshold of a window whose median
    is the other state of a switching flow is that state's, not this one's).
    """
    block = v[a:b]
    if side[a] == 0 or np.any(side[a:b] != side[a]):
        return False
    for j in (a - 1, b):
        if not 0 <= j < v.size:
            continue
        need = threshold[a:b]
        if quantity == "Q":
            need = np.maximum(need, rule.discharge_floor_rel * abs(v[j]))
        if not np.all(side[a] * (block - v[j]) > need):
            return False
    return True
