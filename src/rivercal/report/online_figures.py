"""The headline figures of an on-line run in words: forecast skill against the DSS, reaction time, alerts, fallbacks.

The figures are the run metrics the service stored with its last cycle (:mod:`rivercal.online.metrics`, where
each is defined); this module only reads and formats them. A store written before the service stored them
gets them computed once, by the same functions.
"""

from __future__ import annotations

from typing import Any

from rivercal._format import plural
from rivercal.store import Run, Store

__all__ = ["figure_blocks", "final_state_lines", "forecast_words", "headline_lines", "ratio_words", "stored_metrics"]


def stored_metrics(store: Store, run: Run | str) -> dict[str, Any]:
    """The run metrics stored with the run's latest cycle (:func:`rivercal.online.metrics.run_metrics`).

    For a store written before the service stored them, they are computed from its tables (a twin's facts
    from its scenario's name).
    """
    run = store.get_run(run) if isinstance(run, str) else run
    if run is None:
        raise ValueError("no such run in the store")
    stored = store.metrics(run)
    if stored is not None:
        return stored
    from rivercal.online.metrics import ChangeFacts, figure_scope, run_metrics

    meta = dict(run.config.get("meta") or {})
    facts = ChangeFacts.from_meta(meta)
    if facts is None and meta.get("scenario"):
        from rivercal.twin.practical import SCENARIOS

        if meta["scenario"] in SCENARIOS:
            facts = ChangeFacts.from_meta({**meta, "truth": SCENARIOS[meta["scenario"]].facts()})
    return {**run_metrics(store, run, sources=run.config.get("sources"), facts=facts),
            "forecast_scope": figure_scope(store, run, facts=facts)}


def headline_lines(f: dict[str, Any]) -> list[str]:
    """The headline figures of a run in sentences, each saying which forecasts or cycles it covers.

    The terminal summary, the report (its headline and its Forecasts section) and the dashboard print
    these sentences, so one figure reads the same everywhere. ``f``: the stored run metrics
    (:func:`stored_metrics`, or the JSON summary of ``rivercal online``, which holds them).
    """
    lines = []
    if f.get("scenario"):
        lines.append(f"Twin scenario {f['scenario']}" + _twin_words(f))
    lines.append(forecast_words(f))
    if f.get("scenario"):
        ttc, settle = f.get("time_to_correct_cycles"), f.get("time_to_settle_cycles")
        lines.append("Time to correct the changed parameters: "
                     + (plural(ttc, "cycle") if ttc is not None else f"— ({f.get('time_to_correct_reason')})")
                     + (f"; to settle on the run's last estimate: {plural(settle, 'cycle')}" if settle is not None
                        else "") + ".")
    unscored = f.get("unscored_cycles") or 0
    lines.append(f"Jump alerts: {f.get('jump_alerts', 0)}; fallbacks to the DSS's forecast: {f.get('fallbacks', 0)}"
                 + (f" (besides {plural(unscored, 'first cycle')} that issued the DSS's forecast because nothing was "
                    "scored yet)" if unscored else "") + ".")
    band = f.get("band_coverage_90") or {}
    if band.get("n"):
        lines.append(f"The 90 % band held {band['fraction']:.0%} of {band['n']} level observations.")
    return lines


def final_state_lines(store: Store, run: Run | str) -> list[str]:
    """Where the run ends, in words: the forecast the last cycle issued and why, and each parameter's value.

    Each parameter's last accepted value, the cycle that accepted it and why (an estimate that jumped says
    why it was taken), and the last cycle's estimate when that cycle held it. Empty when the run has no finished cycle.
    """
    run = store.get_run(run) if isinstance(run, str) else run
    if run is None:
        raise ValueError("no such run in the store")
    cycles = store.cycles(run)
    done = cycles[cycles["status"].isin(("done", "failed", "aborted"))] if len(cycles) else cycles
    if done.empty:
        return []
    last = done.iloc[-1]
    cycle = int(last["cycle"])
    issued = last.get("issued_forecast")
    reason = str(last.get("issued_reason") or "").rstrip(".")
    whose = {"dss": "the DSS's forecast, made with its fixed parameters", "updated": "rivercal's forecast, made "
             "with the accepted values below"}.get(str(issued), "no forecast choice stored")
    lines = [f"At the end of the run, cycle {cycle} ({last['issue_time']:%Y-%m-%d %H:%M}) issued {whose}"
             + (f"; the service's reason: {reason}." if reason else ".")]
    est = store.estimates(run)
    for name, g in est.groupby("parameter", sort=False):
        unit = str(g["unit"].iloc[-1])
        mine = g[g["cycle"] == cycle]
        ok = g[g["accepted"].astype(bool)]
        if ok.empty:
            text = f"{name}: no estimate accepted yet"
        else:
            row = ok.iloc[-1]
            text = (f"{name}: last accepted {_value(float(row['value']), unit)}{_unit(unit)}, by cycle "
                    f"{int(row['cycle'])}" + (f" — {row['reason']}" if isinstance(row["reason"], str) and row["reason"]
                                              else ""))
        if len(mine) and not bool(mine["accepted"].iloc[-1]):
            text += (f"; cycle {cycle}'s estimate {_value(float(mine['value'].iloc[-1]), unit)} is held: "
                     f"{str(mine['reason'].iloc[-1]).rstrip('.')}")
        lines.append(text + ".")
    return lines


def _unit(unit: str) -> str:
    """The unit after a value: `` m AD``, or nothing for a dimensionless one (``-``, ``1``, empty)."""
    return f" {unit}" if unit.strip() not in ("", "-", "1", "nan", "None") else ""


def _value(value: float, unit: str) -> str:
    """A parameter value as the terminal's table of estimates prints it: 0.1 mm for levels, 0.01 for the rest."""
    return f"{value:.4f}" if unit in ("m", "m AD") else f"{value:.2f}"


def forecast_words(f: dict[str, Any]) -> str:
    """The forecast level error of rivercal against the DSS in one sentence, with the forecasts it covers."""
    scope = f.get("forecast_scope") or {}
    after = f.get("change_time") or scope.get("after")
    which = "the cycles issued after the change at " + after[:16].replace("T", " ") if after else "every cycle"
    if scope.get("first_cycle") is not None:
        span = (f"cycle {scope['first_cycle']}" if scope["first_cycle"] == scope["last_cycle"]
                else f"cycles {scope['first_cycle']}–{scope['last_cycle']}")
        which = f"{span} ({which})"
    if not f.get("forecast_values"):
        why = (f.get("forecast_errors") or {}).get("reason")
        return ("Forecast level error, rivercal against the fixed DSS: nothing to compare yet"
                + (f" — {why}" if why else "") + ".")
    ratio = f.get("forecast_mae_ratio")
    return (f"Forecast level error (mean |forecast − observation| of the forecasts issued by {which}, lead times up "
            f"to {f['lead_h']:g} h, n = {f['forecast_values']} values against the stored observations not flagged as "
            f"outliers): rivercal as issued {f['rivercal_mae_m'] * 100:.2f} cm, the fixed DSS "
            f"{f['dss_mae_m'] * 100:.2f} cm{ratio_words(ratio)}; rivercal's updated forecasts alone, issued or not, "
            f"{f['updated_mae_m'] * 100:.2f} cm.")


def ratio_words(ratio: float | None) -> str:
    """" (1.2× smaller)", " (1.3× larger)" or " (about the same)": rivercal's error against the DSS's."""
    if not ratio:
        return ""
    if ratio > 1000:
        return " (rivercal's error more than 1000× smaller)"
    if round(ratio, 1) == 1.0 or round(1 / ratio, 1) == 1.0:
        return " (about the same)"
    if ratio >= 1:
        return f" (rivercal's error {ratio:.1f}× smaller)"
    return f" (rivercal's error {1 / ratio:.1f}× larger)"


def figure_blocks(store: Store, run: Run) -> list[Any]:
    """Report blocks: the headline figures in words and the forecast each cycle issued, with why."""
    from rivercal.report.html import paragraph, table

    f = stored_metrics(store, run)
    cycles = store.cycles(run)
    blocks: list[Any] = [paragraph(" ".join(headline_lines(f)))]
    end = final_state_lines(store, run)
    if end:
        blocks.append(paragraph(" ".join(end)))
    if len(cycles) and "issued_forecast" in cycles:
        shown = cycles[["cycle", "issue_time", "issued_forecast", "skill_updated", "skill_dss", "issued_reason"]]
        shown = shown.assign(skill_updated=shown["skill_updated"] * 100, skill_dss=shown["skill_dss"] * 100)
        shown = shown.rename(columns={"issued_forecast": "forecast issued",
                                      "skill_updated": "recent RMSE of rivercal's updated forecasts [cm]",
                                      "skill_dss": "recent RMSE of the DSS's forecasts [cm]", "issued_reason": "why"})
        blocks.append(table(shown.set_index("cycle"), "The forecast each cycle issued (do no harm): the recent RMSE "
                                                      "(cm) of the updated and the DSS's level forecasts, and why",
                            float_format=".3g"))
    return blocks


def _twin_words(f: dict[str, Any]) -> str:
    """What the twin's truth and observations were, in words."""
    if (f.get("realism") or "ideal") != "ideal":
        return (f", realism {f['realism']}: the truth differs from the model and the observations carry sensor "
                "errors (docs/realism.md).")
    errors = []
    if f.get("rain_error"):
        errors.append(f"the truth's inflows and laterals carry a rain error of about {f['rain_error']:.0%}")
    if f.get("noise") not in (None, "none"):
        errors.append(f"the observations carry {f['noise']} noise")
    if not errors:
        return (": an identical twin, whose truth is the model and whose observations are exact — an upper bound, "
                "not what a river gives (try --realism realistic).")
    return ": the model's structure is the truth's, but " + " and ".join(errors) + "."
