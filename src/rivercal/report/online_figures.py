"""The headline figures of an on-line run in words: forecast skill against the DSS, reaction time, alerts, fallbacks.

The figures are the run metrics the service stored with its last cycle (:mod:`rivercal.online.metrics`, where
each is defined); this module only reads and formats them. A store written before the service stored them
gets them computed once, by the same functions.
"""

from __future__ import annotations

from typing import Any

from rivercal.store import Run, Store

__all__ = ["figure_blocks", "stored_metrics"]


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
    from rivercal.online.metrics import ChangeFacts, run_metrics

    meta = dict(run.config.get("meta") or {})
    facts = ChangeFacts.from_meta(meta)
    if facts is None and meta.get("scenario"):
        from rivercal.twin.practical import SCENARIOS

        if meta["scenario"] in SCENARIOS:
            facts = ChangeFacts.from_meta({**meta, "truth": SCENARIOS[meta["scenario"]].facts()})
    return run_metrics(store, run, sources=run.config.get("sources"), facts=facts)


def figure_blocks(store: Store, run: Run) -> list[Any]:
    """Report blocks: the headline figures in words and the forecast each cycle issued, with why."""
    from rivercal.report.html import paragraph, table

    f = stored_metrics(store, run)
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
