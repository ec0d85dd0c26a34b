"""Residual analysis (thesis §2-3-2): error statistics and the moving-window bias of Eq. 2-14.

Everything here works on observed and simulated series (pandas), independent of any model:

- :func:`errors` aligns them: the simulated series are interpolated linearly in time to the observation
  times (as :class:`~rivercal.problem.CalibrationProblem` does), missing observations are dropped, and
  the error is e = y − ŷ (observed minus simulated, the sign of the residuals of thesis Eq. 2-3: a
  positive error means the model is too low). With σ per series the errors are weighted, e/σ, and
  dimensionless — the "weighted dimensionless values" of thesis Tables 4-6, 4-8, 4-10 and 4-12.
- :func:`error_statistics` / :func:`residual_statistics` give, per series and in total
  (:func:`summary_statistics` of one vector of errors), the columns of
  those tables: cost Σe², RMSE, bias (mean error) and the standard deviation of the errors. The standard
  deviation is the population one (ddof = 0), so that RMSE² = bias² + std² (the thesis' tables obey it).
- :func:`moving_bias` is thesis Eq. 2-14 as a time series. In a moving window of length T (default 2 h)
  holding n_w observations,

      b(t) = (1/n_w) Σ_w e²  −  σ²_w,        σ²_w = (1/n_w) Σ_w (e − ē_w)²,

  the moving mean of the squared errors (the model discrepancy) minus the variance of the errors in the
  window. With the population variance this equals ē_w², the squared moving mean error: the part of the
  squared error that is systematic rather than scatter (units: squared error, m² for levels, or
  dimensionless when weighted). The window is trailing and closed, [t − T, t]; with hourly values and
  T = 2 h it holds n_w = 3 values.
- :func:`bias_significance` applies the test of thesis §2-3-2: the bias is insignificant when it is
  smaller than 10⁻¹ times the variance of the errors σ²_w. Per time (``significant`` column of
  :func:`moving_bias`) the window's own values are compared; overall, the time mean of b(t) (the
  (1/T)∫ of Eq. 2-14) is compared with the time mean of σ²_w.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

import numpy as np
import pandas as pd

from rivercal._time import interpolate_at
from rivercal.observations import ObservationSet

__all__ = [
    "BIAS_FACTOR",
    "bias_significance",
    "error_statistics",
    "errors",
    "moving_bias",
    "residual_statistics",
    "summary_statistics",
]

log = logging.getLogger(__name__)

#: Thesis §2-3-2: the bias is insignificant when smaller than this factor times the error variance.
BIAS_FACTOR = 0.1

STAT_COLUMNS = ["n", "cost", "rmse", "bias", "std"]


def _observed_frame(observed: pd.DataFrame | pd.Series | ObservationSet) -> pd.DataFrame:
    if isinstance(observed, ObservationSet):
        return observed.to_frame()
    if isinstance(observed, pd.Series):
        return observed.to_frame()
    return observed


def _sigma_of(observed: pd.DataFrame | pd.Series | ObservationSet,
              sigma: Mapping[str, float | None] | None) -> dict[str, float] | None:
    """σ per series id: from ``sigma`` (keys: series id or quantity) or from an ObservationSet."""
    if sigma is None and isinstance(observed, ObservationSet):
        missing = [s.id for s in observed if s.sigma is None]
        if missing:
            log.warning("series %s have no sigma; their errors are not weighted", ", ".join(missing))
        return {s.id: s.sigma for s in observed if s.sigma is not None}
    if sigma is None:
        return None
    out = {}
    for col in _observed_frame(observed).columns:
        name = str(col)
        value = sigma.get(name, sigma.get(name.rpartition(".")[2]))
        if value is not None:
            if not value > 0:
                raise ValueError(f"sigma of {name} must be positive, got {value}")
            out[name] = float(value)
    return out


def errors(observed: pd.DataFrame | pd.Series | ObservationSet, simulated: pd.DataFrame | pd.Series, *,
           sigma: Mapping[str, float | None] | None = None) -> pd.DataFrame:
    """Errors e = y − ŷ at the observation times, one column per observed series.

    Parameters
    ----------
    observed
        Observations: a frame (or series) indexed by time with one column per series id
        (``"<station>.<quantity>"``; NaN = missing), or an :class:`~rivercal.observations.ObservationSet`.
        Units m (levels) or m³/s (discharges).
    simulated
        Simulated series indexed by time, with a column of the same name for every observed series.
    sigma
        σ per series id or quantity (same unit as the values): the errors are then e/σ, dimensionless.
        For an ObservationSet the default is each series' own σ; for a frame, no weighting.

    Returns
    -------
    pandas.DataFrame
        Errors indexed by the observation times (UTC where the input is tz-aware); NaN where a series
        has no observation or the time lies outside the simulated period.

    Raises
    ------
    ValueError
        When an observed series is not in ``simulated``.
    """
    obs = _observed_frame(observed)
    sim = simulated.to_frame() if isinstance(simulated, pd.Series) else simulated
    missing = [str(c) for c in obs.columns if c not in sim.columns]
    if missing:
        raise ValueError(f"observed series {missing[0]!r} is not in the simulated series "
                         f"({', '.join(map(str, sim.columns))})")
    weights = _sigma_of(observed, sigma) or {}
    if len(sim.index) == 0:
        raise ValueError("the simulated series are empty")
    inside = (obs.index >= sim.index[0]) & (obs.index <= sim.index[-1])
    out = {}
    for col in obs.columns:
        y = pd.to_numeric(obs[col], errors="coerce").to_numpy(dtype=float)
        yhat = interpolate_at(sim.index, sim[col].to_numpy(dtype=float), obs.index)
        e = np.where(inside, y - yhat, np.nan)
        sig = weights.get(str(col))
        out[col] = e / sig if sig is not None else e
    return pd.DataFrame(out, index=obs.index)


def _seconds(index: pd.Index, origin: pd.Timestamp) -> np.ndarray:
    return np.asarray((pd.DatetimeIndex(index) - origin).total_seconds(), dtype=float)


def summary_statistics(e: np.ndarray) -> dict[str, float]:
    """n, cost Σe², RMSE, bias (mean error) and standard deviation (ddof = 0) of the finite errors ``e``.

    The one place these are computed (RMSE² = bias² + std²); NaN statistics without any finite error.
    """
    e = np.asarray(e, dtype=float).ravel()
    e = e[np.isfinite(e)]
    n = int(e.size)
    if n == 0:
        return {"n": 0, "cost": 0.0, "rmse": np.nan, "bias": np.nan, "std": np.nan}
    return {"n": n, "cost": float(e @ e), "rmse": float(np.sqrt(np.mean(e**2))), "bias": float(np.mean(e)),
            "std": float(np.std(e))}


def error_statistics(errs: pd.DataFrame | pd.Series) -> pd.DataFrame:
    """Cost, RMSE, bias and standard deviation of errors per series and in total (thesis Table 4-6).

    Parameters
    ----------
    errs
        Errors (e.g. from :func:`errors`), one column per series; NaN values are skipped.

    Returns
    -------
    pandas.DataFrame
        Index: the series ids and ``"total"`` (all errors pooled); columns ``n`` (number of values),
        ``cost`` (Σe², thesis Eq. 2-3 when the errors are weighted), ``rmse`` (√mean e²), ``bias``
        (mean error, positive: the model is too low) and ``std`` (population standard deviation,
        RMSE² = bias² + std²). Units: those of the errors (dimensionless when weighted; the total of
        unweighted errors mixes m and m³/s when both kinds of series are present).
    """
    frame = errs.to_frame() if isinstance(errs, pd.Series) else errs
    rows = {str(c): summary_statistics(frame[c].to_numpy(dtype=float)) for c in frame.columns}
    rows["total"] = summary_statistics(frame.to_numpy(dtype=float).ravel())
    return pd.DataFrame.from_dict(rows, orient="index")[STAT_COLUMNS]


def residual_statistics(observed: pd.DataFrame | pd.Series | ObservationSet, simulated: pd.DataFrame, *,
                        sigma: Mapping[str, float | None] | None = None) -> pd.DataFrame:
    """:func:`error_statistics` of :func:`errors` (see both): the columns of thesis Tables 4-6 … 4-12."""
    return error_statistics(errors(observed, simulated, sigma=sigma))


def moving_bias(errs: pd.Series | pd.DataFrame, window: str | pd.Timedelta = "2h", *, min_periods: int = 2,
                factor: float = BIAS_FACTOR) -> pd.DataFrame:
    """Thesis Eq. 2-14 over a moving window: b(t) = mean_w(e²) − σ²_w (see the module docstring).

    Parameters
    ----------
    errs
        Errors indexed by time (a series, or a frame with one column per series); NaN values are skipped.
    window
        Window length T (a pandas offset such as ``"2h"``); the window is [t − T, t].
    min_periods
        Fewest values in a window for a result (fewer: NaN); at least 2 so that σ²_w means something.
    factor
        Significance factor: the bias at t is significant when b(t) > factor · σ²_w(t).

    Returns
    -------
    pandas.DataFrame
        For a series: indexed by time, columns ``n`` (values in the window), ``mse`` (mean squared error),
        ``variance`` (σ²_w, population), ``bias`` (b = mse − variance, ≥ 0 up to round-off),
        ``mean_error`` (ē_w; b = ē_w²), ``threshold`` (factor · σ²_w) and ``significant`` (bool).
        For a frame: the same stacked, with a ``series`` column and a ``time`` column.
        Units: squared error units (m², (m³/s)², or dimensionless for weighted errors).
    """
    if min_periods < 2:
        raise ValueError(f"min_periods must be at least 2 (a window variance needs two values), got {min_periods}")
    if not factor > 0:
        raise ValueError(f"factor must be positive, got {factor}")
    if isinstance(errs, pd.DataFrame):
        parts = []
        for col in errs.columns:
            part = moving_bias(errs[col], window, min_periods=min_periods, factor=factor)
            part.insert(0, "series", str(col))
            parts.append(part.rename_axis("time").reset_index())
        columns = ["time", "series", "n", "mse", "variance", "bias", "mean_error", "threshold", "significant"]
        return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=columns)
    window = pd.Timedelta(window)
    if not window > pd.Timedelta(0):
        raise ValueError(f"the window must be positive, got {window}")
    e = pd.to_numeric(errs, errors="coerce").dropna()
    if not isinstance(e.index, pd.DatetimeIndex):
        raise ValueError("the errors must be indexed by time")
    e = e.sort_index()
    roll = e.rolling(window, closed="both")
    n = roll.count()
    mean = roll.mean()
    mse = (e**2).rolling(window, closed="both").mean()
    variance = roll.var(ddof=0)
    enough = n >= min_periods
    mse, variance, mean = mse.where(enough), variance.where(enough), mean.where(enough)
    bias = mse - variance
    threshold = factor * variance
    return pd.DataFrame({"n": n.astype(int), "mse": mse, "variance": variance, "bias": bias, "mean_error": mean,
                         "threshold": threshold, "significant": (bias > threshold) & enough})


def bias_significance(moving: pd.DataFrame, *, factor: float = BIAS_FACTOR) -> pd.DataFrame:
    """Overall bias of thesis Eq. 2-14 and its significance test, per series.

    Parameters
    ----------
    moving
        The result of :func:`moving_bias` (for one series or stacked for several).
    factor
        The bias is significant when the overall bias exceeds factor × the mean window variance
        (thesis §2-3-2: 10⁻¹).

    Returns
    -------
    pandas.DataFrame
        Index: series ids (``"series"`` for a single series); columns ``bias`` (time mean of b(t),
        trapezoidal in time: the (1/T)∫ of Eq. 2-14), ``variance`` (time mean of σ²_w), ``ratio``
        (bias / variance), ``significant`` (bias > factor · variance) and ``fraction_significant``
        (share of the windows whose own bias is significant).
    """
    groups = moving.groupby("series", sort=False) if "series" in moving.columns else [("series", moving)]
    rows = {}
    for name, part in groups:
        times = part["time"] if "time" in part.columns else part.index.to_series()
        ok = part["bias"].notna().to_numpy()
        t = _seconds(pd.DatetimeIndex(times[ok]), pd.DatetimeIndex(times[ok])[0]) if ok.any() else np.array([])
        b = _time_mean(t, part["bias"].to_numpy(dtype=float)[ok])
        v = _time_mean(t, part["variance"].to_numpy(dtype=float)[ok])
        rows[name] = {"bias": b, "variance": v, "ratio": b / v if v > 0 else (0.0 if b == 0 else np.inf),
                      "significant": bool(b > factor * v), "fraction_significant":
                      float(part["significant"].to_numpy()[ok].mean()) if ok.any() else np.nan}
    return pd.DataFrame.from_dict(rows, orient="index")


def _time_mean(t: np.ndarray, y: np.ndarray) -> float:
    if y.size == 0:
        return np.nan
    if y.size == 1 or t[-1] == t[0]:
        return float(np.mean(y))
    area = float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t)))  # trapezoidal rule
    return area / float(t[-1] - t[0])
