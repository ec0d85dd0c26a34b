"""Daily KNMI precipitation and Makkink evaporation → hourly forcing.

Time convention
---------------
Hourly series are indexed in UTC by the **end** of each hour: the value at 01:00 is the amount
that fell (or evaporated) between 00:00 and 01:00 UTC. Values are amounts per hour (mm), i.e.
mean rates in mm/h. A KNMI ``etmgeg`` day ``D`` is the UT day 00–24 UT, so it maps to the 24
hours stamped ``D 01:00`` … ``D+1 00:00``; the KNMI hour index ``RHXH = k`` (1–24) is the hour
stamped ``D + k h``.

Rain: peak hour plus a decaying, capped spread (deterministic, no random numbers)
-------------------------------------------------------------------------------------
For a day with total ``R = RH`` (mm), maximum hourly sum ``X = RHX`` (mm) in hour ``k = RHXH``
and rain duration ``DR`` (h):

1. ``R = 0`` → dry day. ``R`` missing → the day's 24 hours are NaN (never zero).
2. ``X`` is put in hour ``k``.
3. The number of wet hours is ``n = min(24, max(ceil(DR), ceil(R / X), 1))``: at least the
   reported duration, and enough hours to hold ``R`` without any hour exceeding ``X``.
4. The ``n`` wet hours form one contiguous window around ``k`` (centred, with the extra hour
   after the peak when ``n - 1`` is odd; shifted to stay inside the day).
5. The remainder ``R - X`` is spread over the other ``n - 1`` hours of the window with weights
   ``r**d`` decaying geometrically with the distance ``d`` (h) from the peak hour. ``r`` is the
   ``decay`` argument (default 0.6 per hour) unless then a neighbour of the peak would exceed
   ``X``; in that case ``r`` is raised (bisection, to 1e-12) to the smallest value for which no
   hour exceeds ``X`` (``r = 1``, uniform, always fits by step 3).
6. The tiny floating-point residual is added to the hour with the most head-room, so each day's
   sum equals ``R`` to round-off and no hour exceeds ``X``.

Inconsistent or incomplete days are handled explicitly and reported by :func:`rain_day_methods`:
``DR = 0`` with ``R > 0`` (step 3 uses ``ceil(R / X)``); ``X > R`` (a rounding inconsistency:
``X`` is lowered to ``R`` and the whole day falls in hour ``k``); ``X`` missing or zero while
``R > 0`` (uniform over ``ceil(DR)`` hours, or 24 when ``DR`` is unknown or zero, around ``k``);
``k`` missing or outside 1–24 (the window is centred on hour 12, i.e. 11–12 UT); ``R > 24 X``
(impossible; uniform over the day). Trace days (KNMI code -1, read as 0.025 mm by
:func:`rivercal.hydrology.knmi.read_knmi_daily`) have ``X = R`` and fall in hour ``k``.

Evaporation: daytime shape from the sun's elevation
---------------------------------------------------
The daily Makkink reference evaporation ``EV24`` is split in proportion to the integral over each
hour of ``max(sin(h_sun), 0)``, the sine of the solar elevation for the given latitude and
longitude (sampled at 60 one-minute midpoints per hour), so evaporation is zero at night and
peaks at solar noon, and each day's sum is ``EV24`` to round-off. Makkink evaporation is
proportional to global radiation, whose clear-sky course follows ``sin(h_sun)``. Solar position:
declination and equation of time from the Fourier series of Spencer (1971); hour angle from
UTC, longitude and the equation of time; ``sin h = sin φ sin δ + cos φ cos δ cos ω``
(the zenith-angle relation of spherical astronomy, e.g. Duffie & Beckman, *Solar Engineering of Thermal
Processes*, Wiley).

References
----------
Spencer, J. W. (1971): Fourier series representation of the position of the sun. *Search* 2(5), 172.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import pandas as pd

__all__ = [
    "EINDHOVEN_LAT",
    "EINDHOVEN_LON",
    "daylight_weights",
    "disaggregate_evaporation",
    "disaggregate_rain",
    "hourly_forcing",
    "rain_day",
    "rain_day_methods",
    "sin_solar_elevation",
]

logger = logging.getLogger(__name__)

#: Latitude of KNMI station 370 Eindhoven (degrees north).
EINDHOVEN_LAT = 51.451
#: Longitude of KNMI station 370 Eindhoven (degrees east).
EINDHOVEN_LON = 5.377

_DEFAULT_DECAY = 0.6
_SAMPLES_PER_HOUR = 60
_FALLBACK_PEAK_HOUR = 12


def rain_day(
    total_mm: float,
    peak_mm: float,
    peak_hour: float,
    duration_h: float,
    *,
    decay: float = _DEFAULT_DECAY,
) -> tuple[np.ndarray, str]:
    """Split one day's rain into 24 hourly amounts (method in the module docstring).

    Parameters
    ----------
    total_mm
        Day total ``RH`` (mm); NaN if missing.
    peak_mm
        Maximum hourly sum ``RHX`` (mm); NaN if missing.
    peak_hour
        Hour ``RHXH`` in which the maximum fell (1–24, hour ending); NaN if missing.
    duration_h
        Rain duration ``DR`` (h); NaN if missing.
    decay
        Ratio (-) between the amounts of successive hours away from the peak, in (0, 1].

    Returns
    -------
    hours : numpy.ndarray
        24 amounts (mm), element ``i`` for the hour ending at ``i + 1`` UT.
    method : str
        ``"dry"``, ``"missing"``, ``"peak"`` (the regular case), ``"peak-only"`` (R = X),
        ``"peak-lowered"`` (X > R), ``"uniform"`` (X unknown or zero), ``"overfull"`` (R > 24 X);
        ``"+hour-assumed"`` is appended when ``RHXH`` was unusable.
    """
    if not 0.0 < decay <= 1.0:
        raise ValueError(f"decay must lie in (0, 1], got {decay}")
    hours = np.zeros(24)
    if not np.isfinite(total_mm):
        return np.full(24, np.nan), "missing"
    if total_mm < 0.0:
        raise ValueError(f"negative daily rain {total_mm} mm")
    if total_mm == 0.0:
        return hours, "dry"
    suffix = ""
    if np.isfinite(peak_hour) and 1 <= peak_hour <= 24 and float(peak_hour).is_integer():
        k = int(peak_hour) - 1
    else:
        k = _FALLBACK_PEAK_HOUR - 1
        suffix = "+hour-assumed"
    dur = float(duration_h) if np.isfinite(duration_h) and duration_h > 0.0 else 0.0
    n_dur = min(24, math.ceil(dur - 1e-9)) if dur > 0.0 else 0

    if not np.isfinite(peak_mm) or peak_mm <= 0.0:
        n = n_dur if n_dur > 0 else 24
        lo, hi = _window(k, n)
        hours[lo:hi] = total_mm / n
        return hours, "uniform" + suffix
    if peak_mm >= total_mm:
        hours[k] = total_mm
        return hours, ("peak-only" if peak_mm == total_mm else "peak-lowered") + suffix
    if total_mm > 24.0 * peak_mm:
        hours[:] = total_mm / 24.0
        return hours, "overfull" + suffix

    n = min(24, max(n_dur, math.ceil(total_mm / peak_mm - 1e-12), 2))
    lo, hi = _window(k, n)
    dist = np.abs(np.arange(lo, hi) - k).astype(float)
    others = dist > 0
    rest = total_mm - peak_mm
    r = decay
    if _neighbour(rest, dist[others], decay) > peak_mm:
        r = _smallest_ratio(rest, dist[others], peak_mm, decay)
    w = r ** (dist[others] - 1.0)
    values = np.minimum(rest * w / w.sum(), peak_mm)
    window = np.zeros(hi - lo)
    window[others] = values
    window[~others] = peak_mm
    residual = total_mm - window.sum()
    slack = np.where(others, peak_mm - window, -np.inf)
    window[int(np.argmax(slack))] += residual
    hours[lo:hi] = window
    return hours, "peak" + suffix


def _window(k: int, n: int) -> tuple[int, int]:
    """Start and end (exclusive) of a window of ``n`` hours around 0-based hour ``k``."""
    before = (n - 1) // 2
    lo = k - before
    lo = min(max(lo, 0), 24 - n)
    return lo, lo + n


def _neighbour(rest: float, dist: np.ndarray, r: float) -> float:
    """Amount in an hour next to the peak for decay ratio ``r``."""
    return rest / float(np.sum(r ** (dist - 1.0)))


def _smallest_ratio(rest: float, dist: np.ndarray, cap: float, lower: float) -> float:
    """Smallest decay ratio in [lower, 1] for which the peak's neighbours stay within ``cap``."""
    lo, hi = lower, 1.0
    while hi - lo > 1e-12:
        mid = 0.5 * (lo + hi)
        if _neighbour(rest, dist, mid) <= cap:
            hi = mid
        else:
            lo = mid
    return hi


def _hour_end_index(days: pd.DatetimeIndex) -> pd.DatetimeIndex:
    """Hourly index (hour ends, UTC) covering the UT days in ``days`` without gaps."""
    start = days[0] + pd.Timedelta(hours=1)
    end = days[-1] + pd.Timedelta(hours=24)
    return pd.date_range(start, end, freq="h", name="time")


def _daily_index(daily: pd.DataFrame) -> pd.DatetimeIndex:
    index = pd.DatetimeIndex(daily.index)
    if index.tz is None:
        index = index.tz_localize("UTC")
    if (index != index.normalize()).any():
        raise ValueError("the daily frame must be indexed by the start (00:00 UT) of each day")
    if not index.is_monotonic_increasing or index.has_duplicates:
        raise ValueError("the daily index must be strictly increasing")
    return index


def _column(daily: pd.DataFrame, name: str) -> np.ndarray:
    if name not in daily.columns:
        raise ValueError(f"the daily frame has no column {name!r} (columns: {list(daily.columns)})")
    return pd.to_numeric(daily[name], errors="coerce").to_numpy(dtype=float, na_value=np.nan)


def _spread(days: pd.DatetimeIndex, blocks: np.ndarray, name: str) -> pd.Series:
    """Place per-day blocks of 24 hourly values on a gap-free hourly index (NaN in gaps)."""
    index = _hour_end_index(days)
    out = pd.Series(np.nan, index=index, name=name)
    positions = ((days - days[0]) // pd.Timedelta(hours=1)).to_numpy().astype(np.int64)
    flat = (positions[:, None] + np.arange(24)[None, :]).ravel()
    out.iloc[flat] = blocks.ravel()
    gaps = len(index) - flat.size
    if gaps:
        logger.warning("%s: %d hours fall in days missing from the daily series; they are NaN", name, gaps)
    return out


def disaggregate_rain(daily: pd.DataFrame, *, decay: float = _DEFAULT_DECAY) -> pd.Series:
    """Hourly precipitation (mm per hour ending at the index) from KNMI daily ``RH, RHX, RHXH, DR``.

    Parameters
    ----------
    daily
        A frame from :func:`rivercal.hydrology.knmi.read_knmi_daily` (columns ``RH``, ``RHX`` in
        mm, ``RHXH`` hour index, ``DR`` in h), indexed by the start of each UT day.
    decay
        Ratio (-) between successive hours away from the peak, in (0, 1]; see the module docstring.

    Returns
    -------
    pandas.Series
        Named ``"P"``, in mm per hour (= mm/h), on a gap-free hourly UTC index of hour ends from
        the first day 01:00 to the day after the last day 00:00. Days missing from ``daily`` or
        with missing ``RH`` are NaN. Each day sums to its ``RH`` to round-off.
    """
    days = _daily_index(daily)
    blocks, methods = _rain_blocks(daily, decay)
    counts = pd.Series(methods).value_counts()
    unusual = {m: int(c) for m, c in counts.items() if m not in ("dry", "peak", "peak-only")}
    if unusual:
        logger.info("rain disaggregation: fallback methods used on some days: %s", unusual)
    return _spread(days, blocks, "P")


def rain_day_methods(daily: pd.DataFrame, *, decay: float = _DEFAULT_DECAY) -> pd.Series:
    """The method :func:`rain_day` used for each day (index as ``daily``); see :func:`rain_day`."""
    _daily_index(daily)
    _, methods = _rain_blocks(daily, decay)
    return pd.Series(methods, index=daily.index, name="method")


def _rain_blocks(daily: pd.DataFrame, decay: float) -> tuple[np.ndarray, list[str]]:
    total, peak, hour, dur = (_column(daily, c) for c in ("RH", "RHX", "RHXH", "DR"))
    blocks = np.empty((len(daily), 24))
    methods = []
    for i in range(len(daily)):
        blocks[i], method = rain_day(total[i], peak[i], hour[i], dur[i], decay=decay)
        methods.append(method)
    return blocks, methods


def sin_solar_elevation(times: pd.DatetimeIndex, lat_deg: float, lon_deg: float) -> np.ndarray:
    """Sine of the solar elevation angle (-) at the given UTC instants.

    Parameters
    ----------
    times
        Instants (UTC; a naive index is taken as UTC).
    lat_deg
        Latitude (degrees north).
    lon_deg
        Longitude (degrees east).

    Returns
    -------
    numpy.ndarray
        ``sin(h) = sin φ sin δ + cos φ cos δ cos ω`` (negative at night), with the declination
        ``δ`` and equation of time from Spencer (1971) and the hour angle ``ω`` from apparent
        solar time.
    """
    times = pd.DatetimeIndex(times)
    if times.tz is not None:
        times = times.tz_convert("UTC").tz_localize(None)
    hour = (times - times.normalize()) / pd.Timedelta(hours=1)
    doy = times.day_of_year.to_numpy()
    days_in_year = np.where(times.is_leap_year, 366.0, 365.0)
    gamma = 2.0 * np.pi / days_in_year * (doy - 1 + (hour.to_numpy() - 12.0) / 24.0)
    decl = (0.006918 - 0.399912 * np.cos(gamma) + 0.070257 * np.sin(gamma) - 0.006758 * np.cos(2 * gamma)
            + 0.000907 * np.sin(2 * gamma) - 0.002697 * np.cos(3 * gamma) + 0.00148 * np.sin(3 * gamma))
    eot_min = 229.18 * (0.000075 + 0.001868 * np.cos(gamma) - 0.032077 * np.sin(gamma)
                        - 0.014615 * np.cos(2 * gamma) - 0.040849 * np.sin(2 * gamma))
    solar_time_h = hour.to_numpy() + lon_deg / 15.0 + eot_min / 60.0
    omega = np.deg2rad(15.0 * (solar_time_h - 12.0))
    phi = np.deg2rad(lat_deg)
    return np.sin(phi) * np.sin(decl) + np.cos(phi) * np.cos(decl) * np.cos(omega)


def daylight_weights(day: pd.Timestamp, lat_deg: float = EINDHOVEN_LAT, lon_deg: float = EINDHOVEN_LON) -> np.ndarray:
    """Share (-) of a UT day's clear-sky radiation in each of its 24 hours (sums to 1).

    Parameters
    ----------
    day
        The day (its 00:00 UTC).
    lat_deg, lon_deg
        Latitude (degrees north) and longitude (degrees east).

    Returns
    -------
    numpy.ndarray
        24 weights, element ``i`` for the hour ending at ``i + 1`` UT: the integral of
        ``max(sin h_sun, 0)`` over the hour (60 one-minute midpoints), normalised. Uniform
        (1/24) in polar night.
    """
    return _daylight_weights(pd.DatetimeIndex([pd.Timestamp(day)]), lat_deg, lon_deg)[0]


def _daylight_weights(days: pd.DatetimeIndex, lat_deg: float, lon_deg: float) -> np.ndarray:
    offsets = (np.arange(24 * _SAMPLES_PER_HOUR) + 0.5) / _SAMPLES_PER_HOUR  # hours after 00 UT
    days = pd.DatetimeIndex(days)
    if days.tz is not None:
        days = days.tz_convert("UTC").tz_localize(None)
    instants = (days.to_numpy()[:, None] + (offsets * 3.6e12).astype("timedelta64[ns]")[None, :]).ravel()
    sine = sin_solar_elevation(pd.DatetimeIndex(instants), lat_deg, lon_deg)
    energy = np.maximum(sine, 0.0).reshape(len(days), 24, _SAMPLES_PER_HOUR).sum(axis=2)
    total = energy.sum(axis=1, keepdims=True)
    return np.where(total > 0.0, energy / np.where(total > 0.0, total, 1.0), 1.0 / 24.0)


def disaggregate_evaporation(
    daily: pd.DataFrame,
    *,
    lat_deg: float = EINDHOVEN_LAT,
    lon_deg: float = EINDHOVEN_LON,
    column: str = "EV24",
) -> pd.Series:
    """Hourly Makkink reference evaporation (mm per hour ending at the index) from daily ``EV24``.

    Parameters
    ----------
    daily
        A frame with column ``column`` in mm per UT day, indexed by the start of each day.
    lat_deg, lon_deg
        Latitude (degrees north) and longitude (degrees east) of the station (default: KNMI 370
        Eindhoven, 51.451 N 5.377 E).
    column
        The daily evaporation column (mm).

    Returns
    -------
    pandas.Series
        Named ``"ETpot"``, in mm per hour (= mm/h), hourly UTC index of hour ends (as
        :func:`disaggregate_rain`). Each day sums to its daily value to round-off; NaN for
        missing days.
    """
    days = _daily_index(daily)
    ev = _column(daily, column)
    if (ev[np.isfinite(ev)] < 0.0).any():
        raise ValueError(f"negative daily evaporation in column {column!r}")
    blocks = ev[:, None] * _daylight_weights(days, lat_deg, lon_deg)
    blocks[~np.isfinite(ev)] = np.nan
    residual = np.where(np.isfinite(ev), ev - blocks.sum(axis=1), 0.0)
    noon = np.argmax(blocks, axis=1)
    blocks[np.arange(len(days)), noon] += residual
    return _spread(days, blocks, "ETpot")


def hourly_forcing(
    daily: pd.DataFrame,
    *,
    lat_deg: float = EINDHOVEN_LAT,
    lon_deg: float = EINDHOVEN_LON,
    decay: float = _DEFAULT_DECAY,
) -> pd.DataFrame:
    """Hourly ``P`` and ``ETpot`` (mm per hour ending at the index, UTC) from a KNMI daily frame.

    Parameters
    ----------
    daily
        A frame from :func:`rivercal.hydrology.knmi.read_knmi_daily` with ``RH, RHX, RHXH, DR, EV24``.
    lat_deg, lon_deg
        Station latitude (degrees north) and longitude (degrees east).
    decay
        Rain decay ratio (-) per hour away from the peak; see :func:`rain_day`.

    Returns
    -------
    pandas.DataFrame
        Columns ``P`` and ``ETpot`` (mm/h), hourly index of hour ends (UTC).
    """
    return pd.concat([disaggregate_rain(daily, decay=decay),
                      disaggregate_evaporation(daily, lat_deg=lat_deg, lon_deg=lon_deg)], axis=1)
