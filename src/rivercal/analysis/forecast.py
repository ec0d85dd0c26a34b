"""Forecast skill: RMSE and bias of issued forecasts against the observations that arrived later.

A forecast value is compared with the observation of the same series at the same time (no
interpolation), grouped by cycle, kind (``updated``, ``dss``), series and lead-time bucket. The
store keeps the forecasts, the observations and the scores; this module only computes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from rivercal.analysis.residuals import summary_statistics

__all__ = ["LEAD_BUCKETS_H", "SCORE_COLUMNS", "score_forecasts"]

#: Default lead-time bucket edges, h: (0, 6], (6, 12], (12, 24], (24, 48] (the first includes 0).
LEAD_BUCKETS_H: tuple[float, ...] = (0, 6, 12, 24, 48)
#: Columns of a score table.
SCORE_COLUMNS = ["cycle", "kind", "series", "lead_from_h", "lead_to_h", "rmse", "bias", "n"]


def score_forecasts(forecasts: pd.DataFrame, observed: pd.DataFrame,
                    buckets_h: Sequence[float] = LEAD_BUCKETS_H) -> pd.DataFrame:
    """RMSE and bias of forecast − observation per (cycle, kind, series, lead bucket).

    Parameters
    ----------
    forecasts
        Long table with columns cycle, kind, series, lead_h (h), time (UTC), value (m AD or m³/s), as
        :meth:`rivercal.store.Store.forecasts` returns it.
    observed
        Columns series, time (UTC), value, one value per series and time (as
        :meth:`rivercal.store.Store.observation_table` returns it); matched to forecasts at equal times.
    buckets_h
        Increasing bucket edges, h; bucket (a, b] (the first includes a). Leads outside are not scored.

    Returns
    -------
    DataFrame
        Columns cycle, kind, series, lead_from_h, lead_to_h (h), rmse, bias (forecast − observation, m or
        m³/s), n; ordered by cycle, kind, series and lead. A (cycle, kind, series, bucket) without any
        observation has no row.

    Raises
    ------
    ValueError
        If ``buckets_h`` is not at least two increasing edges.
    """
    edges = np.asarray(buckets_h, dtype=float)
    if edges.ndim != 1 or edges.size < 2 or not (np.diff(edges) > 0).all():
        raise ValueError(f"lead-time buckets must be at least two increasing edges (h), got {list(buckets_h)}")
    pairs = forecasts.merge(observed[["series", "time", "value"]], on=["series", "time"], suffixes=("", "_obs"))
    if pairs.empty:
        return pd.DataFrame(columns=SCORE_COLUMNS)
    lead = pairs["lead_h"].to_numpy(float)
    k = np.searchsorted(edges, lead, side="left")
    k = np.where(lead == edges[0], 1, k)
    inside = (k >= 1) & (k < edges.size)
    pairs = pairs[inside].assign(bucket=k[inside], err=lambda f: f["value"] - f["value_obs"])
    grouped = pairs.groupby(["cycle", "kind", "series", "bucket"], sort=True)["err"]
    out = grouped.agg(rmse=lambda e: summary_statistics(e.to_numpy())["rmse"], bias="mean", n="size").reset_index()
    out["lead_from_h"] = edges[out["bucket"].to_numpy() - 1]
    out["lead_to_h"] = edges[out["bucket"].to_numpy()]
    return out[SCORE_COLUMNS]
