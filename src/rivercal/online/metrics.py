"""Run metrics of the on-line service, in one place: forecast scores, skill, MAE by lead, band coverage, reaction.

The service computes them at the end of every cycle from what the store holds and stores them with the cycle
(:meth:`OnlineService.run_cycle <rivercal.online.service.OnlineService.run_cycle>`: :func:`run_metrics`), so
that the terminal, the JSON summary, the report and the dashboard read one value instead of each computing its
own. Everything here reads a store; nothing runs a model.

- :func:`score_forecasts`: RMSE and bias of forecasts against the observations that arrived later, by cycle,
  kind (``updated``, ``dss``), series and lead-time bucket (the scores the store keeps per cycle);
- :func:`forecast_errors`: mean absolute level error of the forecasts at the stations, rivercal against the
  fixed DSS, of the cycles whose window lies after a twin's change;
- :func:`run_figures`: the headline figures a water manager asks of the service (below);
- :func:`mae_by_lead`: the level forecasts' mean absolute error per kind and lead bucket (against the
  observations, or against a twin's noise-free truth);
- :func:`band_coverage`: the share of the observations inside the stored forecast bands.

Readings and forecasts are paired by time, not by equal time stamps (:func:`at_readings`): each reading is
compared with the forecast interpolated linearly to the reading's time, between the forecast's values either
side of it, and only inside the forecast's span (from its first to its last time; never extrapolated). A
reading on a forecast's own time is compared with that value, so readings on the whole hours score as before;
a sensor every 31 minutes, or a reading a minute off the hour, is scored as well. The reading's lead time is
interpolated alike (a reading 1 min after the 1 h value has a lead of 1.017 h).

Headline figures (:func:`run_figures`)
--------------------------------------

``forecast_mae_ratio``
    The DSS's mean absolute error over rivercal's, of the level forecasts at the stations with lead
    times in (0, ``lead_h``] h (default 24 h), of the cycles issued after the change (a twin scenario's
    change time; every cycle when there is none). "rivercal" is the forecast each cycle *issued*: the
    updated one (with state updating, the analysed ensemble's mean) or, after a fallback
    (:mod:`rivercal.online.skill`), the DSS's. The errors are against the stored observations that were not
    flagged as outliers — what the service itself can measure, sensor errors included; in an identical
    twin these are the truth. ``updated_mae_ratio`` is the same for the updated forecasts of every cycle,
    issued or not.
``time_to_correct_cycles``
    For a twin scenario: the number of cycles issued after the change up to and including the first in
    which every changed parameter that the run estimates has made its change: the estimated change (the
    accepted value minus the value accepted by the last cycle issued before the change) is within 5 %
    of the true change (1 cm for a crest shift). The estimated change, not the value, is compared with
    the truth: when the truth differs from the model in structure (a finer grid, other inflows), the
    global parameter is an effective one that settles away from the truth's global value before the
    change already (13–14 instead of 16 m^(1/3)/s of friction in a realistic twin), and what the service
    must find is the change. In an identical twin the value before is the truth's, and this is the
    distance to the true value after. None when nothing changed (PI-0), when the run estimates none of
    the changed parameters (``time_to_correct_reason`` says so), or when it never gets there in the run.
    ``time_to_settle_cycles`` is the number of cycles up to the first from which on every changed
    parameter stays within the same tolerance of the run's *last* estimate: the reaction alone.
``jump_alerts``
    The number of ``jump`` alerts (probable interventions) of the run.
``fallbacks``
    The number of cycles that issued the DSS's forecast although an earlier forecast of the updated
    parameters had been scored (the do-no-harm rule; the first cycles, with nothing scored yet, issue
    the DSS's forecast too and are counted apart in ``unscored_cycles``).

A twin's facts (the scenario's name, the time of its change and the true values of the parameters before
and after it) reach this module through the run's stored ``meta`` (:class:`ChangeFacts`), never from the
twin package itself.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from rivercal._time import utc
from rivercal.analysis.residuals import summary_statistics
from rivercal.store import Run, Store

__all__ = ["CREST_TOLERANCE_M", "LEAD_BUCKETS_H", "MAE_BUCKETS_H", "RELATIVE_TOLERANCE", "SCORE_COLUMNS",
           "ChangeFacts", "at_readings", "band_coverage", "forecast_errors", "mae_by_lead", "run_figures",
           "run_metrics", "score_forecasts"]

#: Default lead-time bucket edges of the scores, h: (0, 6], (6, 12], (12, 24], (24, 48] (the first includes 0).
LEAD_BUCKETS_H: tuple[float, ...] = (0, 6, 12, 24, 48)
#: Columns of a score table.
SCORE_COLUMNS = ["cycle", "kind", "series", "lead_from_h", "lead_to_h", "rmse", "bias", "n"]
#: Lead-time buckets of :func:`mae_by_lead`, h: (0, 6] with lead 0 included, (6, 12], (12, 24], (24, 48].
MAE_BUCKETS_H = ((0, 6), (6, 12), (12, 24), (24, 48))
#: A changed parameter is corrected when its estimated change is within this share of the true change …
RELATIVE_TOLERANCE = 0.05
#: … or, for a crest shift (unit m), within this many m.
CREST_TOLERANCE_M = 0.01

_LEVELS = ("h", "h_up", "h_down")


@dataclass(frozen=True)
class ChangeFacts:
    """What a twin scenario changed, as the run's ``meta`` stores it (``meta["truth"]``).

    Attributes
    ----------
    scenario
        The scenario's name (``PI-Fg`` …).
    change_time
        When the truth changed (UTC).
    true_before, true_after
        True values of the run's parameters before and after the change (their units), None where the truth
        is not of that form.
    """

    scenario: str
    change_time: pd.Timestamp
    true_before: Mapping[str, float | None] = field(default_factory=dict)
    true_after: Mapping[str, float | None] = field(default_factory=dict)

    @classmethod
    def from_meta(cls, meta: Mapping[str, Any] | None) -> ChangeFacts | None:
        """The facts of a run's ``meta`` (None for a run on observations, or stored without them)."""
        truth = (meta or {}).get("truth")
        if not meta or not meta.get("scenario") or not truth:
            return None
        return cls(scenario=str(meta["scenario"]), change_time=utc(truth["change_time"]),
                   true_before=dict(truth.get("true_before") or {}), true_after=dict(truth.get("true_after") or {}))

    def to_meta(self) -> dict[str, Any]:
        """The facts as ``meta["truth"]`` holds them (JSON types)."""
        return {"change_time": self.change_time.isoformat(), "true_before": dict(self.true_before),
                "true_after": dict(self.true_after)}


def _facts(run: Run, facts: ChangeFacts | None) -> ChangeFacts | None:
    return facts if facts is not None else ChangeFacts.from_meta(run.config.get("meta"))


def _run(store: Store, run: Run | str) -> Run:
    found = store.get_run(run) if isinstance(run, str) else run
    if found is None:
        raise ValueError(f"no run {run!r} in {store.path}")
    return found



# -- pairing readings with forecasts by time ----------------------------------------------------------------


def at_readings(table: pd.DataFrame, keys: Sequence[str], observed: pd.DataFrame,
                values: Sequence[str]) -> pd.DataFrame:
    """Each reading with the columns ``values`` of every forecast in ``table`` interpolated to its time.

    Parameters
    ----------
    table
        Long table of forecasts (or bands) with the columns ``keys`` (one forecast per combination; ``series``
        among them), ``time`` (UTC) and ``values`` (e.g. value and lead_h; m, m³/s or h).
    keys
        The columns that name one forecast, e.g. cycle, kind, series.
    observed
        Readings: columns series, time (UTC), value (m AD or m³/s), at any time stamps.
    values
        The columns of ``table`` to interpolate linearly in time to each reading's time.

    Returns
    -------
    DataFrame
        One row per (forecast, reading inside the forecast's span): ``keys``, ``time`` (the reading's),
        ``values`` (interpolated) and ``value_obs`` (the reading). Readings before a forecast's first time or
        after its last are not paired with it (no extrapolation); NaN values of a forecast are left out.
    """
    keys, values = list(keys), list(values)
    out_columns = [*keys, "time", *values, "value_obs"]
    table = table.dropna(subset=values)
    readings = observed[["series", "time", "value"]].dropna().rename(columns={"value": "value_obs"})
    if table.empty or readings.empty:
        return pd.DataFrame(columns=out_columns)
    table = table.sort_values([*keys, "time"], kind="stable").reset_index(drop=True)
    group = table.groupby(keys, sort=False, dropna=False).ngroup().to_numpy()
    epoch = min(table["time"].min(), readings["time"].min())
    seconds = (table["time"] - epoch).dt.total_seconds().to_numpy()
    first = table.groupby(group)["time"].transform("min")
    spans = table.assign(group=group, start=first, end=table.groupby(group)["time"].transform("max"))
    spans = spans.drop_duplicates("group")[[*keys, "group", "start", "end"]]
    pairs = spans.merge(readings, on="series")
    pairs = pairs[(pairs["time"] >= pairs["start"]) & (pairs["time"] <= pairs["end"])]
    if pairs.empty:
        return pd.DataFrame(columns=out_columns)
    # one sorted key over every forecast: its group, then its time (seconds from the earliest time)
    width = float(max(seconds.max(), (pairs["time"] - epoch).dt.total_seconds().max())) + 1.0
    key = group * width + seconds
    at = pairs["group"].to_numpy() * width + (pairs["time"] - epoch).dt.total_seconds().to_numpy()
    hi = np.clip(np.searchsorted(key, at, side="left"), 0, key.size - 1)
    lo = np.where(key[hi] == at, hi, np.maximum(hi - 1, 0))
    gap = key[hi] - key[lo]
    w = np.where(gap > 0, (at - key[lo]) / np.where(gap > 0, gap, 1.0), 0.0)   # weight of the later value
    out = pairs[[*keys, "time", "value_obs"]].reset_index(drop=True)
    for column in values:
        v = table[column].to_numpy(dtype=float)
        out[column] = (1.0 - w) * v[lo] + w * v[hi]
    return out[out_columns]


# -- forecast scores ---------------------------------------------------------------------------------------


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
        :meth:`rivercal.store.Store.observation_table` returns it), at any time stamps: each is compared with
        the forecast interpolated to its time (:func:`at_readings`), with the lead time interpolated alike.
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
    pairs = at_readings(forecasts, ["cycle", "kind", "series"], observed, ["value", "lead_h"])
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


# -- forecast errors of a run ------------------------------------------------------------------------------


def forecast_errors(store: Store, run: Run | str, *, after: Any | None = None, lead_h: float = 24.0,
                    facts: ChangeFacts | None = None, forecasts: pd.DataFrame | None = None,
                    cycles: pd.DataFrame | None = None) -> dict[str, Any]:
    """Mean absolute error of the level forecasts at the stations: rivercal (updated) against the fixed DSS.

    Parameters
    ----------
    store, run
        The store and the run (or its name).
    after
        Only cycles whose calibration window starts at or after this time (UTC); default: for a twin
        scenario its change time (the transition has left the window), else every cycle.
    facts
        The twin's change (default: from the run's ``meta``).
    lead_h
        Lead times (0, lead_h] h are scored.
    forecasts, cycles
        The run's stored forecasts and cycles as the store gives them, when the caller has read them already
        (default: read here).

    Returns
    -------
    dict
        ``n`` (compared values per kind), ``lead_h``, ``from`` (ISO time or None), ``updated_mae_m`` and
        ``dss_mae_m`` (m), ``ratio`` (DSS / rivercal; None when rivercal's error is zero or nothing was
        compared), and ``reason``: why nothing could be compared (None when ``n`` > 0).
    """
    run = _run(store, run)
    if after is None:
        known = _facts(run, facts)
        after = known.change_time if known is not None else None
    out: dict[str, Any] = {"n": 0, "lead_h": lead_h, "from": None if after is None else utc(after).isoformat(),
                           "updated_mae_m": None, "dss_mae_m": None, "ratio": None, "reason": None}
    cycles = store.cycles(run) if cycles is None else cycles
    if cycles.empty:
        out["reason"] = "the run has no finished cycle yet"
        return out
    keep = cycles if after is None else cycles[cycles["window_start"] >= utc(after)]
    if keep.empty:
        out["reason"] = _no_cycle_after(run, cycles, utc(after))
        return out
    fc = store.forecasts(run) if forecasts is None else forecasts
    fc = fc[fc["cycle"].isin(keep["cycle"]) & (fc["lead_h"] >= 0) & (fc["lead_h"] <= lead_h)]
    if not fc.empty:
        fc = fc[_levels(fc["series"])]
    if fc.empty:
        out["reason"] = f"the scored cycles stored no level forecast with a lead time of at most {lead_h:g} h"
        return out
    series = sorted(fc["series"].unique())
    obs = [s for s in store.observations(series, fc["time"].min(), fc["time"].max()) if len(s)]
    joined = fc.iloc[:0]
    if obs:
        joined = _paired(fc, obs)
    if joined.empty:
        out["reason"] = _no_observations(store, series, fc)
        return out
    joined["abs_error"] = (joined["value"] - joined["observed"]).abs()
    mae = joined.groupby("kind")["abs_error"].mean()
    n = joined.groupby("kind").size()
    if "updated" not in mae or "dss" not in mae:
        missing = "rivercal's" if "updated" not in mae else "the DSS's"
        out["reason"] = f"no observation falls on {missing} forecasts, so the two cannot be compared"
        return out
    out.update(n=int(n.min()), updated_mae_m=float(mae["updated"]), dss_mae_m=float(mae["dss"]),
               ratio=float(mae["dss"] / mae["updated"]) if mae["updated"] > 0 else None)
    return out


def _levels(series: pd.Series) -> np.ndarray:
    """Which rows of a column of series ids are level series (``<station>.h``, ``.h_up``, ``.h_down``)."""
    return series.isin([s for s in series.unique() if str(s).rpartition(".")[2] in _LEVELS]).to_numpy()


def _paired(fc: pd.DataFrame, obs: Sequence[Any]) -> pd.DataFrame:
    """Forecasts (cycle, kind, series) at the times of the readings ``obs`` (observation series), lead > 0.

    Paired as :func:`at_readings` pairs them: columns cycle, kind, series, time, value, lead_h, observed.
    """
    observed = pd.concat([pd.DataFrame({"series": s.id, "time": s.times, "value": np.asarray(s.values, float)})
                          for s in obs], ignore_index=True)
    pairs = at_readings(fc, ["cycle", "kind", "series"], observed, ["value", "lead_h"])
    pairs = pairs[(pairs["lead_h"] > 0) & (pairs["lead_h"] <= fc["lead_h"].max())] if len(pairs) else pairs
    return pairs.rename(columns={"value_obs": "observed"})


def _no_cycle_after(run: Run, cycles: pd.DataFrame, after: pd.Timestamp) -> str:
    """Why no cycle counts: none has a calibration window that starts at or after ``after``."""
    window = pd.Timedelta(run.config["window"])
    period = pd.Timedelta(run.config["period"])
    first = utc(run.config.get("first_issue") or cycles["issue_time"].min())
    k = max(0, -(-(after + window - first) // period))  # the first cycle whose window starts at or after
    return (f"the comparison counts only cycles whose calibration window ({_span(run.config['window'])}) starts at or "
            f"after the change at {after:%Y-%m-%d %H:%M}; the first such cycle is issued at "
            f"{first + k * period:%Y-%m-%d %H:%M}, the last cycle of this run at "
            f"{cycles['issue_time'].max():%Y-%m-%d %H:%M}")


def _no_observations(store: Store, series: list[str], fc: pd.DataFrame) -> str:
    """Why no forecast meets an observation: the observations end (or start) outside the forecasts' times."""
    table = store.availability(series)
    ahead = fc[fc["lead_h"] > 0] if "lead_h" in fc and (fc["lead_h"] > 0).any() else fc
    first_fc = ahead["time"].min()  # lead 0 is the issue time, which no forecast is scored at
    if table.empty:
        return "the store holds no observation of the forecast series"
    last_obs = pd.Timestamp(table["last"].max())
    if last_obs < first_fc:
        return (f"the observations end at {last_obs:%Y-%m-%d %H:%M}, before the forecasts' first lead time "
                f"({first_fc:%Y-%m-%d %H:%M})")
    return (f"no observation falls in the forecasts' times between {first_fc:%Y-%m-%d %H:%M} and "
            f"{fc['time'].max():%Y-%m-%d %H:%M}")


def _span(text: str) -> str:
    """'7D' → '7 days', '48h' → '48 hours', '90min' → '90 minutes' (a duration as a reader says it)."""
    seconds = pd.Timedelta(text).total_seconds()
    for unit, size in (("day", 86400), ("hour", 3600), ("minute", 60)):
        if seconds >= size and seconds % size == 0:
            return _count(int(seconds // size), unit)
    return _count(int(seconds), "second") if seconds == int(seconds) else f"{seconds:g} s"


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


# -- headline figures ----------------------------------------------------------------------------------------


def run_figures(store: Store, run: Run | str, *, lead_h: float = 24.0, facts: ChangeFacts | None = None,
                forecasts: pd.DataFrame | None = None, cycles: pd.DataFrame | None = None) -> dict[str, Any]:
    """The headline figures of a run (module docstring); MAE in m.

    ``lead_h`` (h): the longest lead time scored, or the forecasts' own horizon where that is shorter (the
    figures then say that horizon). ``facts``: default from the run's ``meta``; ``forecasts`` and ``cycles``:
    the run's stored forecasts and cycles when the caller has read them already (default: read here).
    """
    run = _run(store, run)
    meta = dict(run.config.get("meta") or {})
    scenario = _facts(run, facts)
    cycles = store.cycles(run) if cycles is None else cycles
    forecasts = store.forecasts(run) if forecasts is None else forecasts
    change = scenario.change_time if scenario is not None else None
    if len(forecasts) and float(forecasts["lead_h"].max()) < lead_h:  # a shorter horizon: say what was scored
        lead_h = float(forecasts["lead_h"].max())
    out: dict[str, Any] = {"scenario": scenario.scenario if scenario else None,
                           "realism": (meta.get("realism") or {}).get("name", "ideal") if scenario else None,
                           "noise": meta.get("noise", "none") if scenario else None,
                           "rain_error": float(meta.get("rain_error") or 0.0) if scenario else None,
                           "change_time": change.isoformat() if change is not None else None, "lead_h": lead_h}
    out.update(_forecast_figures(store, run, cycles, change, lead_h, forecasts))
    out.update(_time_to_correct(store, run, cycles, scenario))
    alerts = store.alerts(run)
    out["jump_alerts"] = int((alerts["kind"] == "jump").sum()) if len(alerts) else 0
    issued = cycles["issued_forecast"] if "issued_forecast" in cycles else pd.Series(dtype=object)
    skill = cycles["skill_updated"] if "skill_updated" in cycles else pd.Series(dtype=float)
    dss = issued == "dss"
    out["fallbacks"] = int((dss & skill.notna()).sum())
    out["unscored_cycles"] = int((dss & skill.isna()).sum())
    out["issued"] = [{"cycle": int(r.cycle), "issue_time": r.issue_time.isoformat(), "issued": r.issued_forecast}
                     for r in cycles.itertuples()] if "issued_forecast" in cycles else []
    return out


def _forecast_figures(store: Store, run: Run, cycles: pd.DataFrame, change: pd.Timestamp | None,
                      lead_h: float, forecasts: pd.DataFrame | None = None) -> dict[str, Any]:
    """MAE of the issued, the updated and the DSS's level forecasts of the cycles after the change."""
    out: dict[str, Any] = {"forecast_mae_ratio": None, "rivercal_mae_m": None, "dss_mae_m": None,
                           "updated_mae_ratio": None, "updated_mae_m": None, "forecast_values": 0}
    keep = cycles if change is None else cycles[cycles["issue_time"] > change]
    if keep.empty:
        return out
    fc = store.forecasts(run) if forecasts is None else forecasts
    fc = fc[fc["cycle"].isin(keep["cycle"]) & (fc["lead_h"] >= 0) & (fc["lead_h"] <= lead_h)]
    fc = fc[_levels(fc["series"])] if len(fc) else fc
    if fc.empty:
        return out
    obs = [s for s in store.observations(sorted(fc["series"].unique()), fc["time"].min(), fc["time"].max())
           if len(s)]
    if not obs:
        return out
    joined = _paired(fc, obs)
    if joined.empty:
        return out
    joined["abs_error"] = (joined["value"] - joined["observed"]).abs()
    wide = joined.pivot_table(index=["cycle", "series", "time"], columns="kind", values="abs_error").dropna()
    if wide.empty or not {"updated", "dss"} <= set(wide.columns):
        return out
    issued = keep.set_index("cycle")["issued_forecast"].reindex(wide.index.get_level_values("cycle"))
    use_dss = (issued == "dss").to_numpy()
    rivercal = wide["updated"].where(~use_dss, wide["dss"])
    dss_mae, riv_mae, upd_mae = float(wide["dss"].mean()), float(rivercal.mean()), float(wide["updated"].mean())
    out.update(forecast_mae_ratio=_ratio(dss_mae, riv_mae), rivercal_mae_m=riv_mae, dss_mae_m=dss_mae,
               updated_mae_ratio=_ratio(dss_mae, upd_mae), updated_mae_m=upd_mae, forecast_values=len(wide))
    return out


def _ratio(a: float, b: float) -> float | None:
    return float(a / b) if b > 0 and math.isfinite(a / b) else None


def _time_to_correct(store: Store, run: Run, cycles: pd.DataFrame, scenario: ChangeFacts | None) -> dict[str, Any]:
    """Cycles after the change until every changed, estimated parameter stays near its true value."""
    if scenario is None:
        return {"time_to_correct_cycles": None, "time_to_settle_cycles": None,
                "time_to_correct_reason": "not a twin scenario"}
    changed = {n: v for n, v in scenario.true_after.items()
               if v is not None and scenario.true_before.get(n) is not None and v != scenario.true_before[n]}
    if not changed:
        return {"time_to_correct_cycles": None, "time_to_settle_cycles": None,
                "time_to_correct_reason": "nothing changes in this scenario"}
    none = {"time_to_correct_cycles": None, "time_to_settle_cycles": None}
    est = store.estimates(run)
    estimated = set(est["parameter"]) if len(est) else set()
    unseen = sorted(set(changed) - estimated)
    if unseen:
        return {**none, "time_to_correct_reason":
                f"the run does not estimate {', '.join(unseen)}, which the change sets"}
    change = scenario.change_time
    after = cycles[cycles["issue_time"] > change].sort_values("cycle")
    if after.empty:
        return {**none, "time_to_correct_reason": "no cycle was issued after the change"}
    units = est.groupby("parameter")["unit"].first()
    table = _accepted(est)
    accepted = table.reindex(after["cycle"])
    prior = cycles[cycles["issue_time"] <= change]
    settled = table.reindex(prior["cycle"]).ffill().iloc[-1] if len(prior) else pd.Series(dtype=float)
    base = {n: float(settled[n]) if n in settled and math.isfinite(settled[n]) else float(scenario.true_before[n])
            for n in changed}
    target = {n: base[n] + v - scenario.true_before[n] for n, v in changed.items()}
    tol = {n: CREST_TOLERANCE_M if units.get(n) == "m" else RELATIVE_TOLERANCE * abs(v - scenario.true_before[n])
           for n, v in changed.items()}
    correct = _first_within(accepted, target, tol)
    settle = _cycles_until(accepted, {n: float(accepted[n].iloc[-1]) for n in changed}, tol)
    return {"time_to_correct_cycles": correct, "time_to_settle_cycles": settle,
            "value_before_change": {n: round(v, 4) for n, v in base.items()},
            "estimated_change": {n: round(float(accepted[n].iloc[-1]) - base[n], 4) for n in changed},
            "true_change": {n: v - scenario.true_before[n] for n, v in changed.items()},
            "time_to_correct_reason": None if correct is not None else "the estimated change does not come within "
            "the tolerance of the true change in the run"}


def _first_within(accepted: pd.DataFrame, target: dict[str, float], tol: dict[str, float]) -> int | None:
    """Cycles (1 = the first row) up to the first in which every parameter is within tol of target."""
    ok = np.ones(len(accepted), dtype=bool)
    for name, value in target.items():
        ok &= ((accepted[name] - value).abs() <= tol[name]).to_numpy()
    hits = np.flatnonzero(ok)
    return int(hits[0]) + 1 if hits.size else None


def _cycles_until(accepted: pd.DataFrame, target: dict[str, float], tol: dict[str, float]) -> int | None:
    """Cycles (1 = the first row) up to the first from which on every parameter stays within tol of target."""
    ok = np.ones(len(accepted), dtype=bool)
    for name, value in target.items():
        ok &= ((accepted[name] - value).abs() <= tol[name]).to_numpy()
    if not ok[-1]:
        return None
    k = len(ok)
    while k > 0 and ok[k - 1]:
        k -= 1
    return k + 1


def _accepted(est: pd.DataFrame) -> pd.DataFrame:
    """The accepted value of each parameter after each cycle (a held estimate keeps the previous one)."""
    table = est.pivot_table(index="cycle", columns="parameter", values="value", aggfunc="first")
    ok = est.pivot_table(index="cycle", columns="parameter", values="accepted", aggfunc="first").astype(bool)
    return table.where(ok).ffill()


# -- error by lead time and band coverage ------------------------------------------------------------------


def mae_by_lead(store: Store, run: Run, series: Sequence[str], truth: pd.DataFrame | None = None, *,
                forecasts: pd.DataFrame | None = None) -> dict[str, Any]:
    """Mean absolute error (m) of the stored level forecasts per kind and lead bucket.

    Against ``truth`` (a twin's noise-free series: wide, UTC index) when given, else against the stored
    observations (whose error then adds to the forecast's), each paired with the forecast interpolated to its
    time (:func:`at_readings`). ``forecasts``: the run's stored forecasts when the caller has read them already.
    """
    levels = [s for s in series if s.rpartition(".")[2] in ("h", "h_up", "h_down")]
    fc = store.forecasts(run) if forecasts is None else forecasts
    fc = fc[fc["series"].isin(levels)]
    out: dict[str, Any] = {"against": "observations" if truth is None else "truth"}
    if fc.empty:
        return out
    if truth is None:
        reference = store.observation_table(levels, fc["time"].min(), fc["time"].max(), sources=None)
    else:
        long = truth[[c for c in levels if c in truth.columns]].rename_axis("time").reset_index()
        reference = long.melt(id_vars="time", var_name="series", value_name="value")
    pairs = at_readings(fc, ["cycle", "kind", "series"], reference, ["value", "lead_h"])
    for kind, part in pairs.groupby("kind"):
        err = (part["value"] - part["value_obs"]).abs()
        out[str(kind)] = {}
        for lo, hi in MAE_BUCKETS_H:
            lead = part["lead_h"]
            inside = ((lead > lo) | ((lead == lo) & (lo == 0))) & (lead <= hi)
            out[str(kind)][f"{lo}-{hi}h"] = float(err[inside].mean()) if inside.any() else None
    return out


def band_coverage(store: Store, run: Run, *, sources: Sequence[str] | None = None) -> dict[str, Any]:
    """Share of the stored level observations inside the run's stored forecast bands, lead > 0.

    Each reading is compared with the band interpolated linearly to its time (:func:`at_readings`).

    ``n`` is the number of (band, observation) pairs; ``sources`` as for the store's observation table.
    """
    bands = store.forecast_bands(run)
    if len(bands):
        bands = bands[bands["series"].str.rpartition(".")[2].isin(("h", "h_up", "h_down")) & (bands["lead_h"] >= 0)]
    if bands.empty:
        return {"n": 0, "fraction": None}
    obs = store.observation_table(sorted(bands["series"].unique()), bands["time"].min(), bands["time"].max(),
                                  sources=sources)
    pairs = at_readings(bands, ["cycle", "series"], obs, ["low", "high", "lead_h"])
    pairs = pairs[pairs["lead_h"] > 0]
    inside = (pairs["value_obs"] >= pairs["low"]) & (pairs["value_obs"] <= pairs["high"])
    return {"n": len(pairs), "fraction": float(inside.mean()) if len(pairs) else None,
            "probability": float(bands["probability"].iloc[0])}


def run_metrics(store: Store, run: Run | str, series: Sequence[str] | None = None, *,
                sources: Sequence[str] | None = None, facts: ChangeFacts | None = None,
                lead_h: float = 24.0) -> dict[str, Any]:
    """Every run metric of this module, as the service stores it with a cycle (JSON types; MAE in m).

    ``forecast_errors`` (:func:`forecast_errors`), the headline figures of :func:`run_figures` at the top
    level, ``forecast_mae_by_lead`` (:func:`mae_by_lead`, against the observations) and, where the run stored
    forecast bands, ``band_coverage_90`` (:func:`band_coverage`). ``series``: the level series to score
    (default every series forecast). The run's forecasts and cycles are read from the store once for all of them.
    """
    run = _run(store, run)
    fc, cycles = store.forecasts(run), store.cycles(run)
    series = list(series) if series is not None else sorted(fc["series"].unique())
    out: dict[str, Any] = {
        "forecast_errors": forecast_errors(store, run, lead_h=lead_h, facts=facts, forecasts=fc, cycles=cycles),
        **run_figures(store, run, lead_h=lead_h, facts=facts, forecasts=fc, cycles=cycles),
        "forecast_mae_by_lead": mae_by_lead(store, run, series, forecasts=fc)}
    bands = band_coverage(store, run, sources=sources)
    if bands["n"]:
        out["band_coverage_90"] = bands
    return _json(out)


def _json(value: Any) -> Any:
    """``value`` in JSON types: numpy numbers as Python's, a non-finite number as None (null)."""
    if isinstance(value, Mapping):
        return {str(k): _json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json(v) for v in value]
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    return value


def figure_scope(store: Store, run: Run | str, *, facts: ChangeFacts | None = None) -> dict[str, Any]:
    """Which cycles the forecast figures of :func:`run_figures` cover, for saying so beside each figure.

    Those issued after the change (a twin's change time; every cycle when there is none), the rule of
    ``forecast_mae_ratio``. Returns ``first_cycle`` and ``last_cycle`` (None when no cycle qualifies),
    ``cycles`` (how many) and ``after`` (the change time, ISO, or None).
    """
    run = _run(store, run)
    known = _facts(run, facts)
    cycles = store.cycles(run)
    change = known.change_time if known is not None else None
    keep = cycles if change is None or cycles.empty else cycles[cycles["issue_time"] > change]
    numbers = sorted(int(c) for c in keep["cycle"]) if len(keep) else []
    return {"first_cycle": numbers[0] if numbers else None, "last_cycle": numbers[-1] if numbers else None,
            "cycles": len(numbers), "after": None if change is None else change.isoformat()}
