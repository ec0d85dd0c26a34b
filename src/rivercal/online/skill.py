"""Do no harm: which forecast a cycle issues, from the recent skill of the updated parameters and the DSS's.

Every cycle forecasts twice, with its updated parameters and with the fixed parameters of the DSS, and
scores the forecasts of earlier cycles when their observations have arrived
(:func:`~rivercal.online.metrics.score_forecasts`). The updated forecast is the one the service would issue:
with state updating (``--assimilate states|both``) the analysed ensemble's mean, so the rule judges that
forecast, not the parameters' deterministic run. :func:`choose_forecast` compares the two kinds over
the last ``cycles`` cycles whose level forecasts have been scored up to ``lead_h`` hours ahead: the
pooled RMSE √(Σ n·RMSE² / Σ n) over stations and lead-time buckets, each kind over the same
(cycle, series, bucket) cells. The cycle issues the updated forecast while its RMSE is at most the
DSS's times (1 + ``tolerance``) plus ``slack_m`` (equal forecasts, e.g. before anything changed, tie);
otherwise it falls back to the DSS's forecast, and says so. With nothing scored yet (the first
cycles of a run) it issues the DSS's: the updated parameters have not shown their skill.

The comparison scores forecasts issued with earlier estimates. After an intervention that the
transition estimator found (:mod:`rivercal.online.intervention`), the forecasts issued before it used the
values before the change and say nothing about the value after it, so only the cycles from the one that
found the change on count (``since``); until one of them is scored, the cycle issues the updated
forecast: the transition test (a significant and relevant drop of the cost) is the evidence that the
river changed and the DSS's parameters no longer hold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pandas as pd

__all__ = ["ForecastChoice", "choose_forecast"]

_LEVELS = ("h", "h_up", "h_down")


@dataclass(frozen=True)
class ForecastChoice:
    """Which forecast a cycle issues.

    Attributes
    ----------
    issued
        ``updated`` or ``dss``.
    reason
        Why, in words.
    rmse_updated, rmse_dss
        Pooled RMSE (m) of the recent level forecasts of each kind, None when nothing was scored.
    cycles
        The cycles whose scores were compared.
    """

    issued: str
    reason: str
    rmse_updated: float | None
    rmse_dss: float | None
    cycles: tuple[int, ...]


def choose_forecast(scores: pd.DataFrame, cycle: int, *, cycles: int = 3, lead_h: float = 24.0,
                    tolerance: float = 0.0, slack_m: float = 0.001,
                    since: tuple[int, str] | None = None) -> ForecastChoice:
    """Issue the updated forecast or fall back to the DSS's (module docstring).

    Parameters
    ----------
    scores
        Forecast scores of the run's cycles (columns cycle, kind, series, lead_from_h, lead_to_h, rmse, n),
        the latest of each cycle.
    cycle
        The cycle that decides; only earlier cycles count.
    cycles
        How many of the latest earlier cycles with level scores count.
    lead_h
        Lead-time buckets up to this many hours count.
    tolerance, slack_m
        The updated forecast is issued while its RMSE ≤ the DSS's · (1 + tolerance) + slack_m (m).
    since
        (first cycle, what happened): only cycles from the first on count, e.g. the cycle that found an
        intervention; with none of them scored the updated forecast is issued (module docstring).
    """
    first = since[0] if since is not None else 0
    s = scores[(scores["cycle"] < cycle) & (scores["cycle"] >= first) & (scores["lead_to_h"] <= lead_h + 1e-9)]
    s = s[s["series"].map(lambda sid: str(sid).rpartition(".")[2] in _LEVELS).astype(bool)] if len(s) else s
    cells = s.pivot_table(index=["cycle", "series", "lead_from_h"], columns="kind", values=["rmse", "n"],
                          aggfunc="first") if len(s) else pd.DataFrame()
    if not cells.empty and {("rmse", "updated"), ("rmse", "dss")} <= set(cells.columns):
        cells = cells.dropna()
    else:
        cells = pd.DataFrame()
    if cells.empty and since is not None:
        return ForecastChoice("updated", f"the updated parameters' forecast: {since[1]}; no forecast made since has "
                                         "been scored, and those before it used the values before the change",
                              None, None, ())
    if cells.empty:
        return ForecastChoice("dss", "the DSS's forecast: no forecast of the updated parameters has been scored yet",
                              None, None, ())
    chosen = sorted(cells.index.get_level_values("cycle").unique())[-cycles:]
    cells = cells[cells.index.get_level_values("cycle").isin(chosen)]
    pooled = {}
    for kind in ("updated", "dss"):
        n = cells[("n", kind)].astype(float)
        pooled[kind] = math.sqrt(float((n * cells[("rmse", kind)] ** 2).sum() / n.sum()))
    limit = pooled["dss"] * (1.0 + tolerance) + slack_m
    words = (f"level forecasts up to {lead_h:g} h of cycle{'s' if len(chosen) > 1 else ''} "
             f"{', '.join(str(c) for c in chosen)}: RMSE rivercal {pooled['updated'] * 100:.2f} cm, "
             f"DSS {pooled['dss'] * 100:.2f} cm")
    if pooled["updated"] <= limit:
        return ForecastChoice("updated", f"the updated parameters' forecast ({words})", pooled["updated"],
                              pooled["dss"], tuple(int(c) for c in chosen))
    return ForecastChoice("dss", f"fallback to the DSS's parameters: the updated ones forecast worse recently "
                                 f"({words})", pooled["updated"], pooled["dss"], tuple(int(c) for c in chosen))
