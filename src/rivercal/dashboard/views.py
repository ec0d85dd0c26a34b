"""What the dashboard's pages show, read from the store (no model runs; nothing is written).

Each function takes an open (read-only) :class:`~rivercal.store.Store` and a run and returns plain data
for a template: rows of tables (each number as shown, in the unit the page says, and as stored in the
store's unit, ``raw``, for machines and tests) and plotly figures as dictionaries (``{"data": [...],
"layout": {...}}``) that the page's script draws with the plotly.js shipped by the ``plotly`` package.

The store is read through its public methods only: ``runs``, ``get_run``, ``cycles``, ``estimates``,
``last_accepted``, ``alerts``, ``transitions``, ``forecasts``, ``forecast_bands``, ``scores``, ``metrics`` and
``observation_table``. The run's figures (forecast error against the DSS, alerts, fallbacks) are those the
service stored with its latest cycle, in the words of the report and the terminal
(:func:`rivercal.report.online_figures.headline_lines`).

Conventions of every page: levels in m AD, level errors (forecast − observed) in cm, discharges in m³/s;
rivercal is blue, the DSS red, the observations black; on the map a forecast above the observed level is
red and one below it blue, as in the report's maps. The decisions and alerts are named as in the glossary
(:mod:`rivercal.dashboard.words`).
"""

from __future__ import annotations

import math
import re
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from rivercal._format import decimals, format_cm, format_std, format_value, plural
from rivercal.dashboard.facts import dss_values, model_facts
from rivercal.dashboard.words import ALERT_NAMES, DECISIONS, describe_series
from rivercal.online.service import OPTIMISER_NOTE
from rivercal.report.online_figures import headline_lines
from rivercal.store import FINAL_STATUSES

if TYPE_CHECKING:
    from rivercal.store import Run, Store

__all__ = ["COLOURS", "ERROR_COLOURSCALE", "cycles_view", "estimates_view", "forecast_view", "forecasts_view",
           "map_view", "now_view", "run_version"]

_LEVELS = ("h", "h_up", "h_down")
#: One colour per source on every page.
COLOURS = {"rivercal": "#2b6cb0", "dss": "#c53030", "observed": "#1a202c", "alert": "#dd6b20",
           "transition": "#6b46c1", "band": "rgba(43,108,176,0.18)", "later": "#a0aec0"}
#: The map's colour scale of a level error (forecast − observed): blue below zero (forecast too low), white at
#: zero, red above (too high) — the report's maps use matplotlib's RdBu_r, the same order.
ERROR_COLOURSCALE = [[0.0, "#2166ac"], [0.25, "#67a9cf"], [0.5, "#f7f7f7"], [0.75, "#ef8a62"], [1.0, "#b2182b"]]
#: How far back and ahead the forecast page looks around the latest issue time.
_SPAN = pd.Timedelta("48h")


def _t(value: Any) -> str | None:
    """A UTC time as plotly and people read it: 'YYYY-MM-DD HH:MM' (None for NaT)."""
    return None if pd.isna(value) else pd.Timestamp(value).strftime("%Y-%m-%d %H:%M")


def _num(value: Any) -> float | None:
    """A number for JSON (None for NaN or None)."""
    if value is None:
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _cell(value: Any, text: str | None = None, digits: int = 4) -> dict[str, Any]:
    """A number as shown (``text``, else ``digits`` significant) and as stored (``raw``, for machines and tests)."""
    x = _num(value)
    shown = text if text is not None else ("–" if x is None else f"{x:.{digits}g}")
    return {"text": shown, "raw": "" if x is None else repr(x)}


def _words(td: Any) -> str:
    seconds = pd.Timedelta(td).total_seconds()
    for unit, size in (("day", 86400), ("hour", 3600), ("minute", 60)):
        if seconds >= size and seconds % size == 0:
            return plural(int(seconds // size), unit)
    return f"{seconds:g} s"


def _final(cycles: pd.DataFrame) -> pd.DataFrame:
    return cycles[cycles["status"].isin(FINAL_STATUSES)]


def _plain(message: Any) -> str:
    """A stored cycle message without the optimiser's own words (its stopping rule and status code)."""
    return re.sub(OPTIMISER_NOTE, "", message) if isinstance(message, str) else ""


def run_version(store: Store, run: Run) -> str:
    """A token that changes whenever a cycle of the run is stored or finished (the page polls it)."""
    cycles = store.cycles(run)
    if cycles.empty:
        return "0"
    return f"{len(cycles)}:{(cycles['status'] == 'done').sum()}:{cycles['finished'].max()}"


def _issued_words(kind: str, skill_updated: Any, skill_dss: Any, skill_cycles: int) -> str:
    """Why a cycle issued its forecast, from the stored skill (RMSE of recent level forecasts, m) in cm."""
    rivercal, dss = _num(skill_updated), _num(skill_dss)
    if rivercal is not None and dss is not None:
        compared = (f"over the last scored cycles rivercal's level forecasts erred by {format_cm(rivercal)} "
                    f"(RMSE, up to 24 h ahead), the DSS's by {format_cm(dss)}")
        if kind == "dss":
            return f"a fallback: {compared}"
        return compared
    if kind == "dss":
        return "none of rivercal's forecasts has been scored yet, so the DSS's is issued (not a fallback)"
    if skill_cycles == 0:
        return "rivercal's forecast is always issued in this run (no comparison with the DSS)"
    return ("a transition was found and none of the forecasts made since has been scored yet: the change "
            "itself is the evidence that the DSS's parameters no longer hold")


def now_view(store: Store, run: Run) -> dict[str, Any]:
    """The forecast in use and why, what changed and how sure, the parameters behind the forecast, open alerts.

    Decisions as in the glossary: an estimate is *accepted* (the parameter takes it) or *held* (it keeps its
    last accepted value; the stored reason says why — the window cannot see it, the calibration failed or
    was aborted, a change too recent to tell). The forecast in use is the one the latest cycle issued:
    rivercal's, with the accepted values, or, after a *fallback*, the DSS's, with the DSS's values; the
    column "in use" shows the values behind it, never an estimate the cycle did not use. Alerts are open
    while their cycle's issue time lies within one calibration window of the latest cycle.
    """
    cycles = store.cycles(run)
    final = _final(cycles)
    window = pd.Timedelta(run.config.get("window", "7D"))
    out: dict[str, Any] = {"n_cycles": len(cycles), "latest": None, "issued": None, "change": None,
                           "estimates": [], "alerts": [], "window": _words(window), "running": None,
                           "model_problem": "", "decisions": DECISIONS, "figures": []}
    running = cycles[~cycles["status"].isin(FINAL_STATUSES)]
    if len(running):
        out["running"] = {"cycle": int(running["cycle"].iloc[0]), "issue_time": _t(running["issue_time"].iloc[0])}
    if final.empty:
        return out
    last = final.iloc[-1]
    facts = model_facts(run.case, run.config.get("model_source"))
    out["model_problem"] = facts.problem
    kind = last.get("issued_forecast")
    kind = str(kind) if isinstance(kind, str) else ""
    out["latest"] = {"cycle": int(last["cycle"]), "issue_time": _t(last["issue_time"]), "status": str(last["status"]),
                     "message": _plain(last["message"]), "model_runs": _cell(last["model_runs"], digits=6),
                     "wall_time_s": _cell(last["wall_time_s"], digits=3), "algorithm": str(last["algorithm"] or "")}
    if kind:
        out["issued"] = {"kind": kind, "whose": "the DSS's" if kind == "dss" else "rivercal's",
                         "words": _issued_words(kind, last.get("skill_updated"), last.get("skill_dss"),
                                                int(run.config.get("skill_cycles", 3))),
                         "reason": str(last.get("issued_reason") or ""),
                         "rmse_updated": _cell(last.get("skill_updated"), format_cm(last.get("skill_updated"))),
                         "rmse_dss": _cell(last.get("skill_dss"), format_cm(last.get("skill_dss")))}
    est = store.estimates(run)
    names = list(dict.fromkeys(est["parameter"]))
    accepted = store.last_accepted(run)
    dss = dss_values(facts, run.config.get("dss") or {}, names)
    std = est.dropna(subset=["std"]).groupby("parameter")["std"].last() if len(est) else pd.Series(dtype=float)
    mine = est[est["cycle"] == last["cycle"]].set_index("parameter")
    for name in names:
        unit = str(est.loc[est["parameter"] == name, "unit"].iloc[-1])
        in_use = dss.get(name) if kind == "dss" else accepted.get(name)
        row = mine.loc[name] if name in mine.index else None
        if row is None:
            state, why, estimate = "", "this cycle stored no estimate", None
        elif bool(row["accepted"]):
            state, estimate = "accepted", row["value"]
            why = str(row["reason"]) if isinstance(row["reason"], str) else ""  # e.g. why a jump was accepted
        else:
            state, estimate = "held", row["value"]
            why = (f"this cycle's estimate {format_value(row['value'], unit)} is not used: "
                   + str(row["reason"] or "no reason stored"))
        out["estimates"].append({
            "parameter": name, "what": facts.describe(name), "unit": unit, "state": state, "why": why,
            "in_use": _cell(in_use, format_value(in_use, unit)),
            "accepted": _cell(accepted.get(name), format_value(accepted.get(name), unit)),
            "std": _cell(std.get(name), format_std(std.get(name), unit)),
            "dss": _cell(dss.get(name), format_value(dss.get(name), unit)),
            "estimate": _cell(estimate, format_value(estimate, unit))})
    out["change"] = _change(store, run, facts, int(last["cycle"]), std)
    metrics = store.metrics(run)
    out["figures"] = headline_lines(metrics) if metrics else []
    alerts = store.alerts(run)
    since = last["issue_time"] - window
    for a in alerts[alerts["issue_time"] >= since].iloc[::-1].itertuples():
        out["alerts"].append({"cycle": int(a.cycle), "issue_time": _t(a.issue_time), "kind": a.kind,
                              "name": ALERT_NAMES.get(a.kind, f"{a.kind} alert"), "parameter": a.parameter or "",
                              "message": a.message, "magnitude": _cell(a.magnitude, "" if _num(a.magnitude) is None
                                                 else f"{_num(a.magnitude):.0f} σ")})
    return out


def _change(store: Store, run: Run, facts: Any, latest: int, std: pd.Series) -> dict[str, Any] | None:
    """The latest transition the run found: what changed, since when, how sure, and whether it is still refined."""
    moves = store.transitions(run)
    if moves.empty:
        return None
    found = int(moves["found_cycle"].max())
    rows = moves[moves["found_cycle"] == found]
    now = rows[rows["cycle"] == rows["cycle"].max()].iloc[0]
    first = rows[rows["cycle"] == found]
    first = first.iloc[0] if len(first) else now
    name, unit = str(now["parameter"]), str(now["unit"])
    cycles = store.cycles(run).set_index("cycle")
    found_at = cycles["issue_time"].get(found)
    reduction = 1.0 - float(first["cost_transition"]) / float(first["cost_single"]) \
        if _num(first["cost_single"]) and _num(first["cost_transition"]) is not None else None
    return {"parameter": name, "what": facts.describe(name), "unit": unit,
            "time": _t(now["time"]), "before": _cell(now["before"], format_value(now["before"], unit)),
            "after": _cell(now["after"], format_value(now["after"], unit)),
            "std": _cell(std.get(name), format_std(std.get(name), unit)),
            "found_cycle": found, "found_at": _t(found_at), "refined": int(now["cycle"]) == latest,
            "refined_by": int(now["cycle"]),
            "reduction": None if reduction is None else f"{reduction:.0%}",
            "p_value": None if _num(first["p_value"]) is None else f"{float(first['p_value']):.1g}"}


def _events(store: Store, run: Run) -> list[dict[str, Any]]:
    """The jump alerts and transitions of a run, each with the parameter it concerns, in time order.

    A jump alert at the issue time of the cycle that raised it; a transition at the estimated time of the
    change, as the last cycle that carried it knows it.
    """
    events = []
    alerts = store.alerts(run)
    for a in alerts[alerts["kind"] == "jump"].itertuples():
        events.append({"time": a.issue_time, "kind": "jump alert", "colour": COLOURS["alert"], "dash": "dot",
                       "parameter": a.parameter or "",
                       "text": f"jump alert (cycle {int(a.cycle)}{', ' + a.parameter if a.parameter else ''})"})
    moves = store.transitions(run)
    for found, g in moves.groupby("found_cycle"):
        last = g.iloc[-1]
        events.append({"time": last["time"], "kind": "transition", "colour": COLOURS["transition"], "dash": "dash",
                       "parameter": str(last["parameter"]),
                       "text": f"transition: {last['parameter']} changed from "
                               f"{format_value(last['before'], last['unit'])} to "
                               f"{format_value(last['after'], last['unit'])} {last['unit']} "
                               f"(found by cycle {int(found)})"})
    return sorted(events, key=lambda e: e["time"])


def _event_marks(events: list[dict[str, Any]], start: pd.Timestamp | None = None, end: pd.Timestamp | None = None,
                 parameter: str | None = None) -> tuple[list[dict], list[dict], list[dict[str, Any]]]:
    """Plotly shapes and annotations marking ``events`` (:func:`_events`) on a time axis, and a list of them.

    Only those in [start, end] (when given) and, with ``parameter``, those concerning it.
    """
    shown = [e for e in events if (start is None or e["time"] >= start) and (end is None or e["time"] <= end)
             and (parameter is None or e["parameter"] in ("", parameter))]
    shown.sort(key=lambda e: e["time"])
    shapes, notes = [], []
    for i, e in enumerate(shown):
        shapes.append({"type": "line", "xref": "x", "yref": "paper", "x0": _t(e["time"]), "x1": _t(e["time"]),
                       "y0": 0, "y1": 1, "line": {"color": e["colour"], "width": 1.5, "dash": e["dash"]}})
        notes.append({"x": _t(e["time"]), "xref": "x", "yref": "paper", "y": 1.0 - 0.1 * (i % 3), "yanchor": "top",
                      "xanchor": "left", "xshift": 3, "text": e["kind"], "showarrow": False,
                      "font": {"size": 10, "color": e["colour"]}, "bgcolor": "rgba(255,255,255,0.8)"})
    listed = [{"time": _t(e["time"]), "kind": e["kind"], "text": e["text"]} for e in shown]
    return shapes, notes, listed


def estimates_view(store: Store, run: Run) -> dict[str, Any]:
    """One figure per parameter: the estimate per cycle with ±σ, held ones open, the DSS's value, alerts marked."""
    est = store.estimates(run)
    facts = model_facts(run.case, run.config.get("model_source"))
    dss = dss_values(facts, run.config.get("dss") or {}, list(dict.fromkeys(est["parameter"])))
    events = _events(store, run)
    figures = []
    for name, g in est.groupby("parameter", sort=True):
        ok, held = g[g["accepted"]], g[~g["accepted"]]
        unit = str(g["unit"].iloc[0])
        places = decimals(unit)
        data = [{"type": "scatter", "mode": "lines+markers", "name": "rivercal, accepted (±σ)",
                 "x": [_t(t) for t in ok["issue_time"]], "y": [_num(v) for v in ok["value"]],
                 "error_y": {"type": "data", "array": [_num(s) or 0.0 for s in ok["std"]], "visible": True},
                 "marker": {"color": COLOURS["rivercal"], "size": 6},
                 "line": {"color": COLOURS["rivercal"], "width": 1}}]
        if len(held):
            data.append({"type": "scatter", "mode": "markers", "name": "held (not used)",
                         "x": [_t(t) for t in held["issue_time"]], "y": [_num(v) for v in held["value"]],
                         "text": list(held["reason"].fillna("")),
                         "marker": {"color": COLOURS["rivercal"], "size": 9, "symbol": "circle-open"}})
        if name in dss and len(g):
            data.append({"type": "scatter", "mode": "lines", "name": "DSS", "hoverinfo": "y+name",
                         "x": [_t(g["issue_time"].min()), _t(g["issue_time"].max())], "y": [dss[name]] * 2,
                         "line": {"color": COLOURS["dss"], "width": 2, "dash": "dash"}})
        shapes, notes, _ = _event_marks(events, parameter=str(name))
        layout = _layout(f"{name} [{unit}]", "issue time (UTC)", shapes=shapes, annotations=notes)
        layout["yaxis"]["hoverformat"] = f".{places}f"
        figures.append({"id": f"est-{len(figures)}", "parameter": str(name), "what": facts.describe(str(name)),
                        "unit": unit, "n": len(g), "last": _cell(g["value"].iloc[-1]),
                        "dss": _cell(dss.get(name), format_value(dss.get(name), unit)),
                        "figure": {"data": data, "layout": layout}})
    return {"figures": figures, "events": _event_marks(events)[2]}


def _layout(ytitle: str, xtitle: str, **extra: Any) -> dict[str, Any]:
    return {"height": 300, "margin": {"l": 64, "r": 16, "t": 36, "b": 45}, "yaxis": {"title": {"text": ytitle}},
            "xaxis": {"title": {"text": xtitle}}, "legend": {"orientation": "h", "y": 1.02, "yanchor": "bottom",
                                                             "x": 0, "font": {"size": 11}},
            "font": {"size": 12}, **extra}


#: The least span of a forecast figure's value axis (m for a level, m³/s for a discharge): 2 cm, as the errors
#: the pages show are in cm.
_MIN_SPAN = 0.02


def _at_least(data: list[dict[str, Any]], span: float) -> list[float] | None:
    """A value-axis range of ``span`` about the figure's values when they span less; None when they span more."""
    values = [v for trace in data for v in trace.get("y", []) if v is not None]
    if not values or max(values) - min(values) >= span:
        return None
    middle = (max(values) + min(values)) / 2
    return [middle - span / 2, middle + span / 2]


def _latest_with_forecasts(store: Store, run: Run, cycles: pd.DataFrame) -> tuple[Any, pd.DataFrame]:
    """The latest final cycle that stored forecasts (among the last three) and its forecasts."""
    for cycle in _final(cycles)["cycle"].iloc[::-1][:3]:
        fc = store.forecasts(run, cycle=int(cycle))
        if len(fc):
            return cycles.set_index("cycle").loc[int(cycle)], fc
    return None, pd.DataFrame()


def forecast_view(store: Store, run: Run) -> dict[str, Any]:
    """The latest issued forecast per series: 48 h of observations before, 48 h of forecast after.

    Per series: the observations of the 48 h before the issue time (and those stored since, lighter), the
    forecast the cycle issued (thick) with its band when one is stored, the other forecast beside it (thin,
    dashed), and the jump alerts and transitions on the time axis. Only the series with an observation in those
    four days, when any has one (``latest["unobserved"]`` counts the others); else every series.
    """
    cycles = store.cycles(run)
    row, fc = _latest_with_forecasts(store, run, cycles)
    if row is None:
        return {"latest": None, "figures": [], "events": []}
    t0 = pd.Timestamp(row["issue_time"])
    kind = row.get("issued_forecast")
    kind = str(kind) if isinstance(kind, str) else "updated"
    start, end = t0 - _SPAN, t0 + _SPAN
    order = {"h_up": 0, "h": 1, "h_down": 2, "Q": 3}
    series = sorted(fc["series"].unique(), key=lambda s: (s.rpartition(".")[0], order.get(s.rpartition(".")[2], 4), s))
    observed = store.observation_table(series, start, end)
    parts = dict(tuple(observed.groupby("series", sort=False)))
    # an imported model forecasts every series of every structure (Dellen: 546); the gauges are what the
    # forecaster checks, so a series without an observation in these four days is not drawn when others have one
    unobserved = [s for s in series if s not in parts] if parts else []
    series = [s for s in series if s in parts] if parts else series
    bands = store.forecast_bands(run, cycle=int(row.name))
    shapes, notes, events = _event_marks(_events(store, run), start, end)
    shapes = [*shapes, {"type": "line", "xref": "x", "yref": "paper", "x0": _t(t0), "x1": _t(t0), "y0": 0, "y1": 1,
                        "line": {"color": "#4a5568", "width": 1}}]
    notes = [*notes, {"x": _t(t0), "xref": "x", "yref": "paper", "y": 0.0, "yanchor": "bottom", "xanchor": "right",
                      "text": "issued", "showarrow": False, "font": {"size": 10, "color": "#4a5568"}}]
    figures = []
    for sid in series:
        unit = "m³/s" if sid.endswith(".Q") else "m AD"
        data = []
        band = bands[bands["series"] == sid] if len(bands) else bands
        if len(band):
            data.append({"type": "scatter", "mode": "lines", "x": [_t(t) for t in band["time"]],
                         "y": [_num(v) for v in band["low"]], "line": {"width": 0}, "showlegend": False,
                         "hoverinfo": "skip", "name": "band low"})
            p = float(band["probability"].iloc[0])
            data.append({"type": "scatter", "mode": "lines", "x": [_t(t) for t in band["time"]],
                         "y": [_num(v) for v in band["high"]], "line": {"width": 0}, "fill": "tonexty",
                         "fillcolor": COLOURS["band"], "name": f"rivercal {p:.0%} band"})
        part = parts.get(sid)
        if part is not None:
            before, after = part[part["time"] <= t0], part[part["time"] > t0]
            data.append({"type": "scatter", "mode": "lines", "name": "observed", "x": [_t(t) for t in before["time"]],
                         "y": [_num(v) for v in before["value"]], "line": {"color": COLOURS["observed"], "width": 1.5}})
            if len(after):
                data.append({"type": "scatter", "mode": "lines", "name": "observed since",
                             "x": [_t(t) for t in after["time"]], "y": [_num(v) for v in after["value"]],
                             "line": {"color": COLOURS["later"], "width": 1.5}})
        for which, colour, label in (("updated", COLOURS["rivercal"], "rivercal"), ("dss", COLOURS["dss"], "DSS")):
            f = fc[(fc["series"] == sid) & (fc["kind"] == which)]
            issued = which == kind
            state = "issued" if issued else "not issued"
            data.append({"type": "scatter", "mode": "lines", "name": f"{label} ({state})",
                         "x": [_t(t) for t in f["time"]], "y": [_num(v) for v in f["value"]],
                         "line": {"color": colour, "width": 3 if issued else 1.5,
                                  "dash": "solid" if issued else "dash"}})
        layout = _layout(f"{'discharge' if unit == 'm³/s' else 'level'} [{unit}]", "time (UTC)", height=280,
                         shapes=shapes, annotations=notes)
        layout["xaxis"]["range"] = [_t(start), _t(end)]
        layout["yaxis"]["hoverformat"] = ".2f"
        flat = _at_least(data, _MIN_SPAN)
        if flat is not None:  # a level that does not move: not an axis of 1e-7 m with ticks to the 7th decimal
            layout["yaxis"]["range"] = flat
        figures.append({"id": f"fc-{len(figures)}", "series": sid, "title": describe_series(sid), "unit": unit,
                        "figure": {"data": data, "layout": layout}})
    latest = {"cycle": int(row.name), "issue_time": _t(t0), "kind": kind,
              "whose": "the DSS's" if kind == "dss" else "rivercal's", "bands": bool(len(bands)),
              "start": _t(start), "end": _t(end), "unobserved": len(unobserved)}
    return {"latest": latest, "figures": figures, "events": events}


def forecast_choices(store: Store, run: Run) -> tuple[list[str], list[float]]:
    """The forecast series of the run and the lead times stored (h), from its latest cycle with forecasts."""
    _, fc = _latest_with_forecasts(store, run, store.cycles(run))
    if fc.empty:
        return [], []
    return sorted(fc["series"].unique()), sorted(float(v) for v in fc["lead_h"].unique())


def forecasts_view(store: Store, run: Run, series: str, lead_h: float) -> dict[str, Any]:
    """Forecasts at one lead time against the observations and the DSS, and the scores by lead time.

    Scores of a level series are shown in cm (stored in m); of a discharge in m³/s.
    """
    fc = store.forecasts(run, series=[series])
    at = fc[np.isclose(fc["lead_h"], lead_h)]
    data = []
    if len(fc):
        obs = store.observation_table([series], fc["time"].min(), fc["time"].max())
        data.append({"type": "scatter", "mode": "lines", "name": "observed", "x": [_t(t) for t in obs["time"]],
                     "y": [_num(v) for v in obs["value"]], "line": {"color": COLOURS["observed"], "width": 1}})
    for kind, colour, label in (("dss", COLOURS["dss"], "DSS"), ("updated", COLOURS["rivercal"], "rivercal")):
        part = at[at["kind"] == kind]
        data.append({"type": "scatter", "mode": "markers", "name": f"{label}, {lead_h:g} h ahead",
                     "x": [_t(t) for t in part["time"]], "y": [_num(v) for v in part["value"]],
                     "marker": {"color": colour, "size": 5}})
    level = not series.endswith(".Q")
    unit = "m AD" if level else "m³/s"
    error_unit = "cm" if level else "m³/s"
    scores = store.scores(run)
    scores = scores[scores["series"] == series]
    table = []
    if len(scores):
        mean = scores.groupby(["lead_from_h", "lead_to_h", "kind"])[["rmse", "bias"]].mean().unstack("kind")
        n = scores.groupby(["lead_from_h", "lead_to_h"])["cycle"].nunique()
        for (a, b), row in mean.iterrows():
            cells = {}
            for m in ("rmse", "bias"):
                for k in ("updated", "dss"):
                    v = row.get((m, k))
                    text = format_cm(v, signed=m == "bias").removesuffix(" cm") if level else format_value(v, "m³/s")
                    cells[f"{m}_{k}"] = _cell(v, text)
            table.append({"lead": f"{a:g}–{b:g} h", "cycles": int(n.loc[(a, b)]), **cells})
    layout = _layout(f"{describe_series(series)} [{unit}]", "time (UTC)", height=380)
    layout["yaxis"]["hoverformat"] = ".2f"
    return {"series": series, "lead_h": lead_h, "unit": unit, "error_unit": error_unit,
            "n_points": int((at["kind"] == "updated").sum()), "figure": {"data": data, "layout": layout},
            "scores": table}


def map_view(store: Store, run: Run) -> dict[str, Any]:
    """The network with each station's mean level-forecast error (forecast − observed, cm), DSS and rivercal.

    One colour scale (:data:`ERROR_COLOURSCALE`, symmetric about zero) for both maps: red where the forecasts
    were too high, blue where too low, as in the report's maps. Station labels are placed by the page's
    script so that they do not overlap; one that finds no free place is left out (its marker names it on
    hover). The table lists the stations with a scored level forecast and counts the others (``unscored``).
    """
    from rivercal.network.coordinates import branch_polylines, station_coordinates

    facts = model_facts(run.case, run.config.get("model_source"))
    if facts.network is None:
        why = facts.problem or f"the model {run.case!r} has no river network to draw"
        return {"problem": why, "figures": [], "rows": []}
    network = facts.network
    try:
        where = station_coordinates(network)
    except ValueError as exc:  # a network without map coordinates
        return {"problem": f"the network of {run.case!r} cannot be drawn: {exc}", "figures": [], "rows": []}
    scores = store.scores(run)  # none before a cycle's forecast is scored (a run of one cycle)
    parts = scores["series"].astype(str).str.rsplit(".", n=1)  # rpartition of no rows has no columns to pick
    scores = scores.assign(station=parts.str[0])[parts.str[-1].isin(_LEVELS)]
    bias = scores.groupby(["station", "kind"])["bias"].mean().unstack("kind") if len(scores) else pd.DataFrame()
    lines_x: list[float | None] = []
    lines_y: list[float | None] = []
    for xy in branch_polylines(network).values():
        lines_x += [*xy[:, 0].tolist(), None]
        lines_y += [*xy[:, 1].tolist(), None]
    top = max([abs(float(v)) for v in bias.to_numpy().ravel() if math.isfinite(v)] or [0.01]) * 100
    top = max(top, 0.1)
    figures, rows = [], []
    for kind, label in (("dss", "DSS"), ("updated", "rivercal")):
        ids = [s for s in where if not bias.empty and s in bias.index and kind in bias]
        values = [_num(bias.loc[s, kind] * 100) for s in ids]
        data = [{"type": "scatter", "mode": "lines", "x": lines_x, "y": lines_y, "hoverinfo": "skip",
                 "line": {"color": "#a0aec0", "width": 2}, "showlegend": False},
                {"type": "scatter", "mode": "markers+text", "x": [where[s][0] for s in ids],
                 "y": [where[s][1] for s in ids], "text": ids, "textposition": "top center", "showlegend": False,
                 "customdata": [[s, v] for s, v in zip(ids, values, strict=True)],
                 "hovertemplate": "%{customdata[0]}: %{customdata[1]:+.1f} cm<extra></extra>",
                 "textfont": {"size": 11, "color": "#1a202c"}, "cliponaxis": False,
                 "marker": {"size": 16, "color": values, "colorscale": ERROR_COLOURSCALE, "cmin": -top, "cmax": top,
                            "line": {"color": "#1a202c", "width": 1},
                            "colorbar": {"title": {"text": "forecast −<br>observed<br>(cm)", "side": "top"},
                                         "thickness": 14, "len": 0.9}}}]
        layout = {"height": 420, "margin": {"l": 10, "r": 10, "t": 36, "b": 10}, "title": {"text": label},
                  "xaxis": {"visible": False}, "yaxis": {"visible": False, "scaleanchor": "x"},
                  "font": {"size": 12}}
        figures.append({"id": f"map-{kind}", "kind": kind, "figure": {"data": data, "layout": layout}})
    for s in where:
        row = bias.loc[s] if not bias.empty and s in bias.index else {}
        dss, updated = _scaled(row, "dss"), _scaled(row, "updated")
        if dss is None and updated is None:  # no level observed there (an imported model has hundreds)
            continue
        rows.append({"station": s, "dss": _cell(dss, format_cm(_m(dss), signed=True).removesuffix(" cm")),
                     "updated": _cell(updated, format_cm(_m(updated), signed=True).removesuffix(" cm"))})
    return {"problem": None, "figures": figures, "rows": rows, "top_cm": top, "unscored": len(where) - len(rows)}


def _m(cm: float | None) -> float | None:
    return None if cm is None else cm / 100.0


def _scaled(row: Any, kind: str) -> float | None:
    value = row.get(kind) if hasattr(row, "get") else None
    return None if value is None or not math.isfinite(value) else float(value) * 100


def _cost(value: Any) -> str:
    """A cost as people read it: whole numbers from 100 on (no exponent), else three significant digits."""
    x = _num(value)
    if x is None:
        return "–"
    return f"{x:,.0f}".replace(",", " ") if abs(x) >= 100 else f"{x:.3g}"


def cycles_view(store: Store, run: Run) -> dict[str, Any]:
    """The cycle log, newest first: status, the forecast issued, model runs, wall time, costs and the message."""
    cycles = store.cycles(run)
    rows = []
    for c in cycles.iloc[::-1].itertuples():
        issued = c.issued_forecast if isinstance(c.issued_forecast, str) else ""
        if issued == "dss":
            issued = "DSS (fallback)" if _num(c.skill_updated) is not None else "DSS (nothing scored yet)"
        rows.append({"cycle": int(c.cycle), "issue_time": _t(c.issue_time), "status": c.status,
                     "issued": {"updated": "rivercal", "": "–"}.get(issued, issued),
                     "algorithm": c.algorithm if isinstance(c.algorithm, str) else "",
                     "model_runs": _cell(c.model_runs, digits=6), "wall_time_s": _cell(c.wall_time_s, digits=3),
                     "cost_before": _cell(c.cost_before, _cost(c.cost_before)),
                     "cost_after": _cell(c.cost_after, _cost(c.cost_after)),
                     "message": _plain(c.message), "log": c.message if isinstance(c.message, str) else "",
                     "finished": _t(c.finished)})
    wall = cycles["wall_time_s"].dropna()
    # as the glossary (and the run's headline figures) count them: the DSS's issued although rivercal had a score
    fallbacks = int(((cycles["issued_forecast"] == "dss") & cycles["skill_updated"].notna()).sum())
    return {"rows": rows, "median_wall_s": _cell(wall.median() if len(wall) else None, digits=3),
            "total_runs": int(cycles["model_runs"].fillna(0).sum()), "fallbacks": fallbacks,
            "summary": f"{plural(len(rows), 'cycle')}, {plural(int(cycles['model_runs'].fillna(0).sum()), 'model run')}"
                       f", {plural(fallbacks, 'fallback')} to the DSS's forecast"}
