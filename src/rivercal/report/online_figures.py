"""The headline figures of an on-line run: forecast skill against the DSS, reaction time, alerts, fallbacks.

:func:`run_figures` reads a finished run from the store and gives what a water manager asks of the
service (all in one JSON-friendly dict):

``forecast_mae_ratio``
    The DSS's mean absolute error over rivercal's, of the level forecasts at the stations with lead
    times in (0, ``lead_h``] h (default 24 h), of the cycles issued after the change (a twin scenario's
    change time; every cycle when there is none). "rivercal" is the forecast each cycle *issued*: the
    updated parameters' or, after a fallback (:mod:`rivercal.online.skill`), the DSS's. The errors are
    against the stored observations that were not flagged as outliers — what the service itself can
    measure, sensor errors included; in an identical twin these are the truth. ``updated_mae_ratio``
    is the same for the updated forecasts of every cycle, issued or not.
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
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from rivercal._time import utc

__all__ = ["CREST_TOLERANCE_M", "RELATIVE_TOLERANCE", "run_figures"]

#: A changed parameter is corrected when its estimated change is within this share of the true change …
RELATIVE_TOLERANCE = 0.05
#: … or, for a crest shift (unit m), within this many m.
CREST_TOLERANCE_M = 0.01

_LEVELS = ("h", "h_up", "h_down")


def run_figures(store: Any, run: Any, *, lead_h: float = 24.0) -> dict[str, Any]:
    """The headline figures of a run (module docstring); MAE in m."""
    run = store.get_run(run) if isinstance(run, str) else run
    meta = dict(run.config.get("meta") or {})
    scenario = None
    if meta.get("scenario"):
        from rivercal.twin.practical import SCENARIOS

        scenario = SCENARIOS[meta["scenario"]]
    cycles = store.cycles(run)
    change = utc(scenario.change_time) if scenario is not None else None
    out: dict[str, Any] = {"scenario": scenario.name if scenario else None,
                           "realism": (meta.get("realism") or {}).get("name", "ideal") if scenario else None,
                           "noise": meta.get("noise", "none") if scenario else None,
                           "rain_error": float(meta.get("rain_error") or 0.0) if scenario else None,
                           "change_time": change.isoformat() if change is not None else None, "lead_h": lead_h}
    out.update(_forecast_figures(store, run, cycles, change, lead_h))
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


def _forecast_figures(store: Any, run: Any, cycles: pd.DataFrame, change: pd.Timestamp | None,
                      lead_h: float) -> dict[str, Any]:
    """MAE of the issued, the updated and the DSS's level forecasts of the cycles after the change."""
    out: dict[str, Any] = {"forecast_mae_ratio": None, "rivercal_mae_m": None, "dss_mae_m": None,
                           "updated_mae_ratio": None, "updated_mae_m": None, "forecast_values": 0}
    keep = cycles if change is None else cycles[cycles["issue_time"] > change]
    if keep.empty:
        return out
    fc = store.forecasts(run)
    fc = fc[fc["cycle"].isin(keep["cycle"]) & (fc["lead_h"] > 0) & (fc["lead_h"] <= lead_h)]
    fc = fc[fc["series"].str.rpartition(".")[2].isin(_LEVELS)] if len(fc) else fc
    if fc.empty:
        return out
    obs = [s for s in store.observations(sorted(fc["series"].unique()), fc["time"].min(), fc["time"].max())
           if len(s)]
    if not obs:
        return out
    observed = pd.concat({s.id: pd.Series(s.values, index=s.times) for s in obs}, names=["series", "time"])
    joined = fc.join(observed.rename("observed"), on=["series", "time"], how="inner")
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


def _time_to_correct(store: Any, run: Any, cycles: pd.DataFrame, scenario: Any) -> dict[str, Any]:
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
    change = utc(scenario.change_time)
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


def figure_blocks(store: Any, run: Any) -> list[Any]:
    """Report blocks: the headline figures in words and the forecast each cycle issued, with why."""
    from rivercal.report.html import paragraph, table

    f = run_figures(store, run)
    words = []
    if f["scenario"]:
        words.append(f"Twin scenario {f['scenario']}, realism {f['realism']}: " + _twin_words(f))
    if f["forecast_values"]:
        words.append(f"Level forecasts up to {f['lead_h']:g} h"
                     + (f" of the cycles issued after {f['change_time'][:16].replace('T', ' ')}" if f["change_time"]
                        else "") + f", against the stored observations not flagged as outliers: rivercal as issued "
                     f"{f['rivercal_mae_m'] * 100:.2f} cm mean absolute error, the fixed DSS {f['dss_mae_m'] * 100:.2f}"
                     f" cm (ratio {f['forecast_mae_ratio']:.2f}; the updated forecasts alone "
                     f"{f['updated_mae_m'] * 100:.2f} cm).")
    if f["scenario"]:
        ttc = f["time_to_correct_cycles"]
        words.append("Time to correct the changed parameters: "
                     + (f"{ttc} cycle(s)" if ttc is not None else f"— ({f['time_to_correct_reason']})")
                     + (f"; to settle on the run's last estimate: {f['time_to_settle_cycles']} cycle(s)"
                        if f["time_to_settle_cycles"] is not None else "") + ".")
    words.append(f"Jump alerts: {f['jump_alerts']}; fallbacks to the DSS's forecast: {f['fallbacks']} (and "
                 f"{f['unscored_cycles']} first cycle(s) with nothing scored yet).")
    cycles = store.cycles(run)
    blocks: list[Any] = [paragraph(" ".join(words))]
    if len(cycles) and "issued_forecast" in cycles:
        shown = cycles[["cycle", "issue_time", "issued_forecast", "skill_updated", "skill_dss", "issued_reason"]]
        shown = shown.assign(skill_updated=shown["skill_updated"] * 100, skill_dss=shown["skill_dss"] * 100)
        blocks.append(table(shown.set_index("cycle"), "The forecast each cycle issued (do no harm): the recent RMSE "
                                                      "(cm) of the updated and the DSS's level forecasts, and why",
                            float_format=".3g"))
    return blocks


def _twin_words(f: dict[str, Any]) -> str:
    """What the twin's truth and observations were, in words."""
    if f["realism"] != "ideal":
        return "the truth differs from the model and the observations carry sensor errors (docs/realism.md)."
    errors = []
    if f.get("rain_error"):
        errors.append(f"the truth's inflows and laterals carry a rain error of about {f['rain_error']:.0%}")
    if f.get("noise") not in (None, "none"):
        errors.append(f"the observations carry {f['noise']} noise")
    if not errors:
        return ("an identical twin, whose truth is the model and whose observations are exact — an upper bound, "
                "not what a river gives.")
    return "the model's structure is the truth's, but " + " and ".join(errors) + "."
